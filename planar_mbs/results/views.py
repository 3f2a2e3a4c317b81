"""What a results file holds, read for people: which signals and entities it has, which body is the
slider and which one turns, the Poincaré points once per revolution, the clearance radius of a joint,
its contact onsets and a time window of it.  The figures (`planar_mbs.outputs.plot`) and the rerun
recordings (`planar_mbs.outputs.rerun_log`) both read results through these helpers.

numpy only; the section itself is `planar_mbs.results.section`, the one of the project.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Sequence

import numpy as np

from ..errors import MbsError, did_you_mean
from ..mechanism.model import CP_KIND, PairKind
from .hdf5 import Results
from .. import catalog
from .section import AnalysisError, clock_body, crossings, facts, poincare_section
from .section import slider_body as _slider

if TYPE_CHECKING:  # pragma: no cover
    from ..mechanism.model import Model


JOURNAL_PAIRS = (catalog.PAIRS[PairKind.CIRCLE_IN_CIRCLE].name, catalog.PAIRS[PairKind.LUBRICATED].name)


class PlotError(MbsError):
    """Bad usage of `mbs plot` / `mbs view` (unknown signal, not a results file): exit code 2.  A hint
    line is never empty: one left with nothing after ``hint:`` says where the names are listed."""

    exit_code = 2

    def __init__(self, message: str = ""):
        lines = str(message).split("\n")
        lines = [EMPTY_HINT if line.strip() == "hint:" else line for line in lines]
        super().__init__("\n".join(lines))


EMPTY_HINT = "hint: `mbs plot FILE --list` prints the signals the results hold (BODY.phi: a body's angle)"


def entities(results: "Results") -> dict[str, set[str]]:
    """``{entity: {quantity, ...}}`` of the signals present."""
    out: dict[str, set[str]] = {}
    for name in results.signals:
        entity, _, qty = name.rpartition(".")
        out.setdefault(entity, set()).add(qty)
    return out


def body_names(results: "Results") -> list[str]:
    return sorted(e for e, q in entities(results).items() if {"x", "y", "phi"} <= q)


def driver_names(results: "Results") -> list[str]:
    return sorted(e for e, q in entities(results).items() if "power" in q and ({"torque"} & q or {"force"} & q))


def clearance_names(results: "Results") -> list[str]:
    return sorted(e for e, q in entities(results).items() if {"ex", "ey", "penetration"} <= q)


def is_journal(model, name: str, results: "Results | None" = None) -> bool:
    """Is clearance element `name` a journal in a bearing (whose orbit is a figure), rather than a contact
    between outlines or a corner of a translational clearance joint?  From the model, else from the
    contact geometry the results recorded (`section.mechanism_facts`); True when neither says."""
    if model is not None and name in model.clearance_names:
        kind = int(model.kernel.clearance_param[model.clearance_names.index(name), CP_KIND])
        return kind in (PairKind.CIRCLE_IN_CIRCLE, PairKind.LUBRICATED)
    known = facts(results) if model is None else None
    pair = (known.get("contacts") or {}).get(name) if known else None
    return pair is None or pair in JOURNAL_PAIRS


def check_signals(results: "Results", names: Sequence[str]) -> None:
    """Raise `PlotError` (with a did-you-mean hint) for the first unknown signal."""
    for name in names:
        if name not in results.signals:
            ents = entities(results)
            if name in ents:
                hint = f"`{name}` is an entity; its signals are " + ", ".join(
                    f"`{name}.{q}`" for q in sorted(ents[name]))
            else:
                hint = did_you_mean(name, results.signals)
            raise PlotError(f"error: no signal `{name}` in the results" + (f"\nhint: {hint}" if hint else
                            "\nhint: `mbs plot FILE --list` prints the signal names"))


def slider_body(results: "Results", model: "Model | None" = None) -> str | None:
    """The body shown as "the slider" (`planar_mbs.results.section.slider_body`, the one rule)."""
    return _slider(results, model) if body_names(results) or model is not None else None


def turning_body(results: "Results", model: "Model | None" = None) -> str | None:
    """The body whose revolutions clock the Poincaré section (`planar_mbs.results.section.clock_body`)."""
    return clock_body(results, model)


def revolution_times(time: np.ndarray, phi: np.ndarray, skip: int = 1) -> np.ndarray:
    """Times at which ``phi - phi[0]`` crosses ``±2 pi k``, the first ``skip`` dropped
    (`planar_mbs.results.section.crossings`)."""
    return crossings(time, phi)[skip:]


@dataclass
class PoincareSet:
    x: np.ndarray
    y: np.ndarray
    t: np.ndarray
    x_name: str
    y_name: str
    body: str
    skip: int


def poincare(results: "Results", x: str, y: str, body: str | None = None, skip: int = 1,
             model: "Model | None" = None) -> PoincareSet:
    """Poincaré points ``(x, y)``, one per revolution of `body` after the first `skip`:
    the section of `planar_mbs.results.section.poincare_section` (the one used by sweeps and
    `mbs analyze`)."""
    check_signals(results, [x, y])
    body = body or turning_body(results, model)
    if body is None:
        raise PlotError("error: no body angle in the results to clock the Poincaré section\nhint: keep the "
                        "driven body's angle (`--keep slider,crank`) or name a body with `--clock`")
    if f"{body}.phi" not in results:
        raise PlotError(f"error: {clock_missing(results, body)}")
    try:
        sec = poincare_section(results, (x, y) if x != y else (x,), clock=body, transient=skip, model=model)
    except AnalysisError as err:
        raise PlotError(f"error: {err}") from None
    return PoincareSet(sec.points[x], sec.points[y], sec.time, x, y, body, skip)


def clock_missing(results: "Results", body: str) -> str:
    """Why the section cannot be clocked by `body` in these results, and what to do (never an empty hint)."""
    bodies = body_names(results)
    if body in _model_bodies(results):
        kept = sorted({n.rpartition(".")[0] for n in results.signals})
        return (f"the results keep no angle of `{body}`, the body whose revolutions clock the Poincaré "
                f"section\nhint: keep it too (`--keep {','.join(kept + [body])}`), or draw the sections the "
                "sweep stored (`mbs plot SWEEP.h5` with no signals)")
    hint = did_you_mean(str(body), bodies)
    return (f"no body `{body}` to clock the Poincaré section\nhint: "
            + (hint or (f"bodies with an angle here: {', '.join(bodies)}" if bodies else
                        "these results keep no body angle: keep the driven body (`--keep BODY`)")))


def _model_bodies(results: "Results") -> list[str]:
    """The bodies named in the results' recorded mechanism (the slider, clock and output link)."""
    known = facts(results) or {}
    return [str(known[k]) for k in ("slider", "clock", "output") if known.get(k)]


def clearance_radius(results: "Results", joint: str) -> float:
    """Radial clearance c of a clearance joint: ``e - penetration`` (the same at every sample)."""
    c = results[f"{joint}.e"] - results[f"{joint}.penetration"]
    return float(np.median(c)) if len(c) else float("nan")


def contact_onsets(results: "Results", joint: str) -> np.ndarray:
    """Sample indices where `joint` goes from free flight to contact."""
    flag = results.signals.get(f"{joint}.in_contact")
    if flag is None:
        flag = (results[f"{joint}.penetration"] > 0).astype(float)
    on = flag > 0.5
    return np.nonzero(on[1:] & ~on[:-1])[0] + 1


def stick_changes(results: "Results", element: str) -> tuple[np.ndarray, np.ndarray]:
    """Sample indices where `element`'s friction sticks or slips (its ``stick`` signal changes), and
    the state from there on (True: stuck)."""
    stuck = np.asarray(results[f"{element}.stick"]) > 0.5
    i = np.nonzero(stuck[1:] != stuck[:-1])[0] + 1
    return i, stuck[i]


def sticking_elements(results: "Results") -> list[str]:
    """The elements whose friction can stick (those with a ``stick`` signal), in the file's order."""
    return [name[:-len(".stick")] for name in results.signals if name.endswith(".stick")]


class _WindowSignals(dict):
    """Signals of a results object cut to a time window, read (and cut) on first access."""

    def __init__(self, results: "Results", mask: np.ndarray):
        super().__init__()
        self._results, self._mask = results, mask
        self._names = list(results.signals)

    def __missing__(self, name):
        if name not in self._names:
            raise KeyError(name)
        value = np.asarray(self._results[name])[self._mask]
        self[name] = value
        return value

    def __contains__(self, name) -> bool:
        return name in self._names

    def __iter__(self):
        return iter(self._names)

    def __len__(self) -> int:
        return len(self._names)

    def keys(self):
        return list(self._names)

    def items(self):
        return [(n, self[n]) for n in self._names]

    def values(self):
        return [self[n] for n in self._names]

    def get(self, name, default=None):
        return self[name] if name in self._names else default


def time_window(results: "Results", t_from: float | None = None, t_to: float | None = None) -> "Results":
    """The samples with ``t_from <= t <= t_to`` (either end open when None), as `Results`."""
    if t_from is None and t_to is None:
        return results
    t = np.asarray(results.time)
    lo = -np.inf if t_from is None else t_from
    hi = np.inf if t_to is None else t_to
    if not lo < hi:
        raise PlotError(f"error: the time window is empty (--from {lo:g} s, --to {hi:g} s)\n"
                        "hint: --from must be before --to")
    mask = (t >= lo) & (t <= hi)
    if not mask.any():
        raise PlotError(f"error: no samples between {lo:g} s and {hi:g} s (the run covers "
                        f"{t[0]:g} s to {t[-1]:g} s)\nhint: choose a window inside the run")
    cut = Results(time=t[mask], signals={}, units=dict(results.units), attrs=dict(results.attrs))
    cut.signals = _WindowSignals(results, mask)
    # the window as asked (an open end: the run's first or last sample), for titles
    cut.attrs["window"] = (float(t[mask][0]) if t_from is None else float(t_from),
                           float(t[mask][-1]) if t_to is None else float(t_to))
    return cut
