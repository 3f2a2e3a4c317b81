"""planar_mbs: planar multibody dynamics with revolute clearance joints.

The Python API mirrors the command line (docs/python_api.md)::

    import planar_mbs as mbs
    model = mbs.load_model("models/slider_crank_clearance_a.mbs", speed="2500 rpm")
    res = mbs.simulate(model, t_end="20 ms", output="a.h5")   # settings with units, as on the CLI
    res["slider.vx"], res.time, res.to_dataframe()
    mbs.read_results("a.h5")

    model = mbs.compile_text(text)               # a model from a string
    sim = mbs.Simulation(model)                  # step by step, for notebooks and controllers
    sim.step("1 ms"); sim.run_until("10 ms", callback=...)

    eq = mbs.equilibrium(model)                  # where it rests: pose, residuals, reactions
    lin = mbs.linearize(model)                   # modes about it: lin.modes(), lin.state_matrix

Heavy modules (numba kernels, h5py) load on first use, so `import planar_mbs`
and `mbs --help` stay fast.
"""
from __future__ import annotations

from typing import TYPE_CHECKING

from .lazy import lazy
from .version import __version__

__all__ = ["load_model", "compile_text", "simulate", "Simulation", "read_results", "equilibrium", "linearize",
           "__version__"]

# Each loads on first use (lark, numpy, numba, h5py): `import planar_mbs` loads none of them.
_re = lazy("re")
if TYPE_CHECKING:  # the modules themselves, for type checkers and import-graph tools
    from . import errors as _errors
    from .mechanism import compile as _compile
    from .language import parse as _parse
    from .run import simulation as _simulation
    from .results import hdf5 as _hdf5
    from .run import static as _static
    from .run import modes as _modes
else:  # each loaded on its first use (see the comments: not on the light paths)
    _errors = lazy(".errors", __package__)
    _compile = lazy(".mechanism.compile", __package__)
    _parse = lazy(".language.parse", __package__)
    _simulation = lazy(".run.simulation", __package__)
    _hdf5 = lazy(".results.hdf5", __package__)
    _static = lazy(".run.static", __package__)
    _modes = lazy(".run.modes", __package__)


def _python_error(err, overrides: dict, func: str):
    """A `--set`-worded override error re-worded for a Python keyword argument."""
    if not isinstance(err, _errors.ModelError) or err.file != "--set":
        return err
    m = _re.search(r"`--set (\w+)(?:=[^`]*)?`", err.message)
    name = m.group(1) if m else next((k for k, v in overrides.items()
                                      if err.source_line and str(v).strip() == err.source_line.strip()), None)
    message = _re.sub(r"^`--set (\w+)(?:=[^`]*)?`: ", "", err.message)
    message = _re.sub(r"`--set (\w+)(?:=\.\.\.)?`", r"`\1=`", message)
    place = f"{func}({name}=...)" if name else f"{func}(...)"
    shown = f" (`{name}={overrides[name]!r}`)" if name in overrides and m is None else ""
    hint = err.hint if err.hint != "docs/language.md describes every statement, field and unit" else ""
    hint = _re.sub(r"`--set (\w+)=([^`]*)`", r'`\1="\2"`', hint)  # `--set speed=900rpm` -> `speed="900rpm"`
    return _errors.ModelError(message + shown, place, hint=hint)


def load_model(path, **overrides):
    """Parse and compile a `.mbs` file; keyword arguments override its `param`s
    (values are text with units, e.g. ``speed="2500 rpm"``, ``law="hertz"``)."""
    overrides = {k: str(v) for k, v in overrides.items()}
    try:
        return _compile.load_model(path, overrides)
    except _errors.ModelError as err:
        raise _python_error(err, overrides, "load_model") from None


def compile_text(text, path="<string>", **overrides):
    """Parse and compile model text held in a string (``path`` names it in error messages and
    resolves its includes); keyword arguments override its `param`s, as in `load_model`."""
    overrides = {k: str(v) for k, v in overrides.items()}
    if isinstance(text, (bytes, bytearray)):  # the bytes of a file: decoded as a model file is
        text = _parse.decode_model(bytes(text), str(path))
    elif not isinstance(text, str):
        raise _errors.ModelError(f"compile_text takes the model's text (a str), not {type(text).__name__}",
                                 "compile_text(...)", hint="load a file with load_model(path)")
    try:
        return _compile.compile_text(text, str(path), overrides)
    except _errors.ModelError as err:
        raise _python_error(err, overrides, "compile_text") from None


def simulate(model, output=None, progress=None, signals=None, **settings):
    """Run a compiled model to its end time and return its `Results`.

    ``settings`` replace fields of the model's `simulate` block, as SI numbers or as text with
    units (``t_end="1 s"``, ``output_step="10 us"``, ``integrator="dop853"``, ``rtol=1e-8``);
    ``revolutions=5`` and ``per_rev=360`` count in periods of the crank's driver.  ``output``
    writes an HDF5 file as the run goes; ``signals`` keeps only the named signals or entities
    (and the time loop computes only what they read: no accelerations, reactions or driver efforts
    asked for, no `accelerations` call per output row); ``progress(t, t_end)`` is called after each
    chunk.  See `planar_mbs.run.simulation.simulate`."""
    return _simulation.simulate(model, output=output, progress=progress, signals=signals, **settings)


def read_results(path):
    """Load an HDF5 results file written by `simulate` or `mbs run`."""
    return _hdf5.read_results(path)


def equilibrium(model, t=0.0, start=None, impact_velocity=None):
    """The static equilibrium of a compiled model (`planar_mbs.run.static.Equilibrium`): at rest under
    its loads, springs, gravity and contact forces, the drivers held at their values at time ``t``,
    found by Newton's method on the constraint manifold from the assembled pose (or ``start``, a pose
    q).  ``eq.q``, ``eq.multipliers``, ``eq.reactions()``, ``eq.gaps``, ``eq.stable()``;
    ``planar_mbs.run.static.at_rest(model, eq)`` is the model started from it.  Raises
    `planar_mbs.run.static.StaticError` (a `SimulationError`) when there is none or it is not unique."""
    return _static.equilibrium(model, t=float(t), start=start, impact_velocity=impact_velocity)


def linearize(model, state=None, t=None, impact_velocity=None, hold_drivers=None):
    """The motion linearised in its minimal coordinates (`planar_mbs.run.modes.Modes`): the state
    matrix, eigenvalues and modes (``lin.modes()``: frequency, damping ratio, shape) about ``state``:
    None (the static equilibrium, found first), an equilibrium, ``"assembled"`` or a pair (q, q')."""
    return _modes.linearize(model, state, t=t, impact_velocity=impact_velocity, hold_drivers=hold_drivers)


def __getattr__(name):  # Simulation loads the numba kernels: only on first use
    if name == "Simulation":
        return _simulation.Simulation
    raise AttributeError(f"module 'planar_mbs' has no attribute {name!r}")
