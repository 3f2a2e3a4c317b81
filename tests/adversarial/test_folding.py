"""Constant folding and tables at the edge of a float: `exp(1000)`, `10^400`, `1e200 N * 1e200`, a
power that overflows at the initial state, knots 1e-320 apart, values near 1.8e308; a flat
sum of many terms; `param t`.  Each is refused at the expression (exit 2, a caret) or accepted,
never an internal error or a numpy warning."""
from __future__ import annotations

import warnings

import pytest

import planar_mbs as api
from advhelp import assert_clean, mbs
from planar_mbs.errors import ModelError

MODEL = """\
param F0 = 1 N
body mass {{ mass = 2 kg  inertia = 0.5 kg*m^2  position = (1, 0) }}
force push = expression(mass, fx = {load})
simulate {{ t_end = 4 ms  output_step = 1 ms }}
"""


def _check(tmp_path, load: str, csv: str | None = None):
    (tmp_path / "m.mbs").write_text(MODEL.format(load=load))
    if csv is not None:
        (tmp_path / "f.csv").write_text(csv)
    return mbs("check", tmp_path / "m.mbs", cwd=tmp_path)


@pytest.mark.parametrize("load, column", [("F0 * exp(1000)", 41), ("F0 * 10^400", 41),
                                          ("1e200 N * 1e200", 36), ("F0 * (1e300 / 1e-300)", 42),
                                          ("F0 * 1e308 + F0 * 1e308", 36)])
def test_a_constant_that_overflows_is_refused_at_it(tmp_path, load, column):
    assert_clean(_check(tmp_path, load), 2, f"m.mbs:3:{column}", "overflows", "^^^")


def test_a_power_that_overflows_at_the_initial_state_is_refused(tmp_path):
    out = _check(tmp_path, "F0 * (mass.x / 1 mm + 1)^400")
    assert_clean(out, 2, "m.mbs:3:41", "overflows", "at the initial state")


def test_a_motion_that_overflows_is_refused(tmp_path):
    (tmp_path / "m.mbs").write_text(
        "body crank { mass = 0.3 kg  inertia = 1e-4 kg*m^2 }\n"
        "joint O = revolute(ground (0, 0), crank (0, 0))\n"
        "driver d = rotation(crank, motion = 1 rad * exp(1000 * (1 + t / 1 s)))\n"
        "simulate { t_end = 4 ms }\n")
    assert_clean(mbs("check", tmp_path / "m.mbs"), 2, "m.mbs:3:", "overflows")


@pytest.mark.parametrize("terms", [101, 200])
def test_a_flat_sum_is_not_nesting(tmp_path, terms):
    load = " + ".join(f"{k} N * sin({k} * 10 rad/s * t)" for k in range(1, terms + 1))
    assert_clean(_check(tmp_path, load), 0)


def test_param_t_is_refused(tmp_path):
    (tmp_path / "m.mbs").write_text("param t = 1 s\n" + MODEL.format(load="F0 * sin(10 rad/s * t)"))
    assert_clean(mbs("check", tmp_path / "m.mbs"), 2, "m.mbs:1:7", "`t` is reserved (the time)")


# ---------------------------------------------------------------- tables at the edge of a float
TABLE = 'F0 * table("f.csv", x = t, x_unit = "s", y_unit = "1"{extra})'


@pytest.mark.parametrize("csv, extra", [
    ("0, 1\n1e-320, 2\n1, 3\n", ""),  # knots 1e-320 apart: slopes beyond a float
    ("0, 1.7e308\n1, -1.7e308\n2, 1.7e308\n3, 0\n", ", interpolation = cubic"),
    ("0, 1.7e308\n1, -1.7e308\n2, 1.7e308\n3, 0\n", ", interpolation = akima"),
])
def test_a_table_beyond_a_float_is_refused_without_a_warning(tmp_path, csv, extra):
    (tmp_path / "m.mbs").write_text(MODEL.format(load=TABLE.format(extra=extra)))
    (tmp_path / "f.csv").write_text(csv)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(ModelError, match="range of a float") as info:
            api.load_model(tmp_path / "m.mbs")
    assert info.value.line == 3


def test_table_units_scaled_beyond_a_float_are_refused_without_a_warning(tmp_path):
    load = 'F0 * table("f.csv", x = t, x_unit = "s", y_unit = "GN") / 1 N'
    (tmp_path / "m.mbs").write_text(MODEL.format(load=load))
    (tmp_path / "f.csv").write_text("0, 1e300\n1, 2\n")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(ModelError, match="range of a float"):
            api.load_model(tmp_path / "m.mbs")
