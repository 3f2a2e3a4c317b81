"""Units: conversions to SI, dimension checks, the plain-number-is-SI rule (planar_mbs.language.units)."""
import math

import pytest
from hypothesis import given, strategies as st

from planar_mbs.language import units as U


@pytest.mark.parametrize("value, unit, dim, si", [
    (0.3, "mm", U.LENGTH, 3e-4),
    (2.5e-4, "kg*m^2", U.INERTIA, 2.5e-4),
    (9.81, "m/s^2", U.ACCELERATION, 9.81),
    (5000, "rpm", U.ANGULAR_VELOCITY, 5000 * 2 * math.pi / 60),
    (207, "GPa", U.PRESSURE, 207e9),
    (207, "MPa", U.PRESSURE, 207e6),
    (10, "us", U.TIME, 1e-5),
    (30, "deg", U.ANGLE, math.pi / 6),
    (1, "rev", U.ANGLE, 2 * math.pi),
    (2, "N*m", U.TORQUE, 2.0),
    (4e10, "N/m^1.5", U.contact_stiffness(1.5), 4e10),
    (10, "1/s", U.RATE, 10.0),
    (2, "Hz", U.FREQUENCY, 2.0),
    (7800, "kg/m^3", U.DENSITY, 7800.0),
])
def test_conversion_to_si(value, unit, dim, si):
    assert U.to_si(U.quantity(value, unit), False, dim, "x") == pytest.approx(si, rel=1e-12)


def test_ten_microseconds_is_exactly_1e_5():
    assert U.to_si(U.quantity(10, "us"), False, U.TIME, "10 us") == 1e-5


def test_plain_number_is_taken_in_si():
    assert U.to_si(U.quantity(0.025, None), True, U.LENGTH, "0.025") == 0.025
    assert U.to_si(U.quantity(3, None), True, U.MASS, "3") == 3.0


def test_wrong_dimension_message_and_hint():
    with pytest.raises(U.UnitError) as e:
        U.to_si(U.quantity(3, "m"), False, U.MASS, "3 m", "mass")
    assert e.value.message == "a mass was expected, got a length (3 m)"
    assert "mass = 0.3 kg" in e.value.hint


def test_angle_is_not_a_length():
    with pytest.raises(U.UnitError, match="a length was expected, got a plain number"):
        U.to_si(U.quantity(30, "deg"), False, U.LENGTH, "30 deg")


def test_unknown_unit_did_you_mean():
    with pytest.raises(U.UnitError) as e:
        U.parse_unit("mmm")
    assert e.value.message == "unknown unit `mmm`"
    assert "`mm`" in e.value.hint


def _pint_si(text):
    """(SI scale, {dimension: exponent}) of a unit text according to pint (the authority)."""
    ureg = U.registry()
    base = ureg.Quantity(1.0, ureg.parse_units(text)).to_base_units()
    return base.magnitude, {k: float(v) for k, v in base.dimensionality.items()}


def _ours(unit):
    return unit.scale, {d: e for d, e in zip(U.DIMENSIONS, unit.dimensionality) if e}


@pytest.mark.parametrize("name", sorted(U.TABLE))
def test_every_unit_of_our_table_is_pints(name):
    """Our table resolves units without importing pint; each entry must be what pint says."""
    scale, dims = _pint_si(name)
    got_scale, got_dims = _ours(U.parse_unit(name))
    assert got_scale == pytest.approx(scale, rel=1e-14)
    assert got_dims == dims


@pytest.mark.parametrize("text, pint_text", [
    ("kg*m^2", "kg*m**2"), ("m/s^2", "m/s**2"), ("N*m*s/rad", "N*m*s/rad"), ("1/s", "1/s"),
    ("N/m^1.5", "N/m**1.5"), ("kg/m^3", "kg/m**3"), ("rev/min", "rev/min"), ("mm/ms", "mm/ms"),
])
def test_unit_factors_left_to_right_as_pint(text, pint_text):
    scale, dims = _pint_si(pint_text)
    got_scale, got_dims = _ours(U.parse_unit(text))
    assert got_scale == pytest.approx(scale, rel=1e-14)
    assert got_dims == dims


def test_a_unit_outside_the_table_comes_from_pint():
    assert "inch" not in U.TABLE
    assert U.to_si(U.quantity(2, "inch"), False, U.LENGTH, "2 inch") == pytest.approx(0.0508, rel=1e-14)
    assert U.to_si(U.quantity(1, "lbf"), False, U.FORCE, "1 lbf") == pytest.approx(4.4482216152605, rel=1e-12)


def test_offset_units_are_refused():
    with pytest.raises(U.UnitError):
        U.parse_unit("degC")


def test_arithmetic_keeps_units_and_converts_like_pint():
    ureg = U.registry()
    a, b = U.quantity(1, "m") + U.quantity(5, "mm"), ureg.Quantity(1, "m") + ureg.Quantity(5, "mm")
    assert a.magnitude == pytest.approx(b.magnitude) and U.format_quantity(a) == "1.005 m"
    t = U.quantity(2, "rev") / U.quantity(5000, "rpm")
    assert U.to_si(t, False, U.TIME, "t") == pytest.approx(
        (ureg.Quantity(2, "turn") / ureg.Quantity(5000, "rpm")).to("s").magnitude, rel=1e-14)
    assert (U.quantity(3, "m") ** 2).dimensionality == U.parse_unit("m^2").dimensionality


def test_compiling_a_model_imports_no_pint():
    import subprocess
    import sys

    code = ("import sys, planar_mbs as m; m.load_model('models/slider_crank_clearance_a.mbs', speed='3000 rpm'); "
            "print('pint' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True,
                         cwd=__import__("pathlib").Path(__file__).resolve().parents[1])
    assert out.stdout.strip() == "False"


def test_describe_and_format():
    assert U.describe(U.LENGTH.dimensionality) == "a length"
    assert U.describe(U.INERTIA.dimensionality) == "a moment of inertia"
    assert U.format_quantity(U.quantity(5000, "rpm")) == "5000 rpm"
    assert U.format_quantity(U.quantity(2.5e-4, "kg*m^2")) == "0.00025 kg*m^2"


def test_registry_is_created_once():
    assert U.registry() is U.registry()


@given(st.floats(min_value=-1e6, max_value=1e6, allow_nan=False),
       st.sampled_from([("mm", 1e-3), ("cm", 1e-2), ("km", 1e3), ("um", 1e-6), ("m", 1.0)]))
def test_lengths_scale_linearly(x, unit):
    name, factor = unit
    got = U.to_si(U.quantity(x, name), False, U.LENGTH, "x")
    assert got == pytest.approx(x * factor, rel=1e-12, abs=1e-300)
