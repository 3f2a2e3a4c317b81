"""The grammar and parser: every construct, positions, friendly syntax errors (planar_mbs.language.parse)."""
import pytest

from planar_mbs.errors import ModelError
from planar_mbs.language.parse import parse_expression, parse_model, parse_statements, parser
from planar_mbs.language.spec import BinOp, Call, Name, Neg, Number, Vector


def one(text):
    (st,) = parse_statements(text, "t.mbs")
    return st


def field(st, name):
    return next(f for f in st.fields if f.name == name).value


def test_parser_is_built_once():
    assert parser() is parser()


def test_param_number_with_unit():
    st = one("param speed = 5000 rpm")
    assert (st.kind, st.name) == ("param", "speed")
    assert st.value == Number(st.value.pos, 5000.0, "rpm")


@pytest.mark.parametrize("text, value, unit", [
    ("0.3 mm", 0.3, "mm"), ("2.5e-4 kg*m^2", 2.5e-4, "kg*m^2"), ("9.81 m/s^2", 9.81, "m/s^2"),
    ("5000 rpm", 5000, "rpm"), ("207 GPa", 207, "GPa"), ("10 us", 10, "us"), ("30 deg", 30, "deg"),
    ("2500rpm", 2500, "rpm"), ("1e-8", 1e-8, None), (".5", 0.5, None), ("4e10 N/m^1.5", 4e10, "N/m^1.5"),
    ("10 1/s", 10, "1/s"), ("3", 3, None),
])
def test_quantity_terminal(text, value, unit):
    e = parse_expression(text, "x")
    assert isinstance(e, Number) and e.value == pytest.approx(value) and e.unit == unit


def test_unitless_number_then_next_field():
    st = one("simulate { rtol = 1e-8  output_step = 10 us  t_end = 5 rev / speed }")
    assert [f.name for f in st.fields] == ["rtol", "output_step", "t_end"]
    assert field(st, "rtol") == Number(field(st, "rtol").pos, 1e-8, None)
    assert field(st, "output_step").unit == "us"
    t_end = field(st, "t_end")
    assert isinstance(t_end, BinOp) and t_end.op == "/" and t_end.left.unit == "rev"
    assert t_end.right == Name(t_end.right.pos, "speed")


def test_unit_does_not_swallow_the_next_field_on_a_new_line():
    st = one("body b {\n mass = 3\n inertia = 2 kg*m^2 }")
    assert field(st, "mass").unit is None and field(st, "inertia").unit == "kg*m^2"


def test_unit_is_not_a_keyword():
    sts = parse_statements("param n = 3 material steel { E = 1 Pa nu = 0.3 }")
    assert [s.kind for s in sts] == ["param", "material"] and sts[0].value.unit is None


def test_arithmetic_precedence_and_unary_minus():
    e = parse_expression("-2^2 + 3 * (a - 1) / b", "x")
    assert isinstance(e, BinOp) and e.op == "+"
    assert isinstance(e.left, Neg) and e.left.operand.op == "^"
    assert e.right.op == "/" and e.right.left.op == "*"


def test_vectors_calls_and_keyword_arguments():
    e = parse_expression("box(width = 30 mm, height = 15 mm)", "x")
    assert isinstance(e, Call) and e.name == "box" and [k.name for k in e.kwargs] == ["width", "height"]
    v = parse_expression("(0, -9.81 m/s^2)", "x")
    assert isinstance(v, Vector) and len(v.items) == 2 and isinstance(v.items[1], Neg)
    c = parse_expression("crank (0.025, 0)", "x")
    assert isinstance(c, Call) and c.name == "crank" and len(c.args) == 2
    f = parse_expression("sqrt(a^2 + b^2) * cos(pi / 3) + atan2(1, 2)", "x")
    assert isinstance(f, BinOp)


def test_keywords_may_name_fields_and_kwargs():
    st = one("force f = constant(slider, force = (1 N, 0)) { }")
    assert st.value.kwargs[0].name == "force"
    st = one("joint A = clearance_revolute(a, b) { material = steel }")
    assert st.fields[0].name == "material"


def test_every_statement_kind_and_positions():
    text = '''# comment line
param law = hertz   # trailing comment
material steel { E = 207 GPa  nu = 0.3 }
body crank { mass = 0.3 kg  inertia = 1e-5 kg*m^2 }
joint O = revolute(ground (0, 0), crank (-0.025, 0))
joint A = clearance_revolute(crank (0.025, 0), rod (-0.06, 0)) {
    clearance = 0.3 mm
}
driver d = rotation(crank, speed = 5000 rpm)
force f = torque(crank, 2 N*m)
gravity (0, -9.81 m/s^2)
simulate { t_end = 1 s }
override param law = lankarani_nikravesh
'''
    sts = parse_statements(text, "t.mbs")
    assert [s.kind for s in sts] == ["param", "material", "body", "joint", "joint", "driver", "force",
                                     "gravity", "simulate", "param"]
    assert sts[-1].override and not sts[0].override
    a = sts[4]
    assert (a.pos.line, a.pos.column, a.name_pos.column) == (6, 1, 7)
    clearance = a.fields[0]
    assert (clearance.pos.line, clearance.pos.column) == (7, 5)
    assert clearance.value.pos.text == "0.3 mm" and clearance.value.pos.source_line == "    clearance = 0.3 mm"
    assert sts[0].value == Name(sts[0].value.pos, "hertz")


def test_include_statement(tmp_path):
    (tmp_path / "base.mbs").write_text("param a = 1\n")
    main = tmp_path / "main.mbs"
    main.write_text('include "base.mbs"\nparam b = 2\n')
    spec = parse_model(main.read_text(), str(main))
    assert [s.name for s in spec.statements] == ["a", "b"]
    assert spec.statements[0].pos.file.endswith("base.mbs")


def test_include_cycle(tmp_path):
    (tmp_path / "a.mbs").write_text('include "b.mbs"\n')
    (tmp_path / "b.mbs").write_text('param x = 1\ninclude "a.mbs"\n')
    with pytest.raises(ModelError) as e:
        parse_model((tmp_path / "a.mbs").read_text(), str(tmp_path / "a.mbs"))
    assert "include cycle: a.mbs → b.mbs → a.mbs" in e.value.message
    assert e.value.file.endswith("b.mbs") and e.value.line == 2


def test_syntax_error_in_included_file_points_there(tmp_path):
    (tmp_path / "base.mbs").write_text("param a = 1\nparam b = (2\n")
    with pytest.raises(ModelError) as e:
        parse_model('include "base.mbs"', str(tmp_path / "main.mbs"))
    assert e.value.file.endswith("base.mbs") and e.value.line == 2


def syntax_error(text):
    with pytest.raises(ModelError) as e:
        parse_statements(text, "t.mbs")
    return e.value


def test_comma_between_fields():
    e = syntax_error("body x {\n  mass = 1 kg, inertia = 2 }")
    assert (e.line, e.column) == (2, 14)
    assert "not commas" in e.hint
    assert str(e).splitlines()[1:3] == ["      mass = 1 kg, inertia = 2 }", "                 ^"]


def test_misspelled_keyword():
    e = syntax_error("bodi x { mass = 1 kg }")
    assert (e.line, e.column) == (1, 1) and "did you mean `body`?" in e.hint


def test_missing_equal_sign():
    e = syntax_error("joint A revolute(a, b)")
    assert e.message == "unexpected `revolute`" and "`=`" in e.hint


def test_semicolon():
    e = syntax_error("param x = 3;")
    assert e.column == 12 and "`;`" in e.hint


def test_unexpected_end():
    e = syntax_error("param x = (3\n")
    assert "ends in the middle" in e.message and "`)`" in e.hint


def test_field_without_value():
    e = syntax_error("body x { mass 1 kg }")
    assert "key = value" in e.hint


def test_unit_with_spaces_hint():
    e = syntax_error("param x = 3 kg (2)")
    assert "ModelError" not in e.message and e.line == 1


def test_too_large_number():
    e = syntax_error("param x = 1e999")
    assert "too large" in e.message


def test_override_value_errors_point_at_set():
    with pytest.raises(ModelError) as e:
        parse_expression("3 +", "--set")
    assert e.value.file == "--set" and "ends too early" in e.value.message


def test_a_text_parsed_again_comes_from_the_cache_and_still_takes_each_override():
    """A sweep compiles one model text per case: the parse is kept (planar_mbs.language.parse._parsed), the
    overrides are the compiler's, so each case still gets its own value (a crank period of 60 s / rpm);
    a text that does not parse is not kept and fails again."""
    from pathlib import Path

    from planar_mbs.language import parse
    from planar_mbs.mechanism.compile import compile_text
    from planar_mbs.results.section import driver_period

    text = (Path(__file__).resolve().parents[1] / "models" / "slider_crank.mbs").read_text()
    parse._parsed.clear()
    periods = [driver_period(compile_text(text, "sc.mbs", {"speed": f"{rpm}rpm"}))[0] for rpm in (1000, 3000)]
    assert len(parse._parsed) == 1
    assert periods == pytest.approx([0.06, 0.02], rel=1e-12)
    again = parse_statements(text, "sc.mbs")
    assert again == parse._parsed[(text, "sc.mbs")] and again is not parse._parsed[(text, "sc.mbs")]
    for _ in range(2):
        with pytest.raises(ModelError):
            parse_statements("body b { mass = }", "bad.mbs")
    assert ("body b { mass = }", "bad.mbs") not in parse._parsed
