"""The kernels name every status code, workspace slot and contact-state column: no bare
literals that a new code or slot could silently shift (scanned from the sources with `ast`).

Flagged: a ``return`` of a nonzero integer literal (a status code), a status variable compared
with a nonzero integer literal, anything compared with 0.5 (a float used as a flag),
``ws.flags[<literal>]`` / ``ws.dense[<literal>]``, ``contact[k, <literal>]``, and an observation
row written at ``row[col + <literal>]`` (its columns are named in `model`)."""
from __future__ import annotations

import ast
from pathlib import Path

import pytest

KERNEL = Path(__file__).resolve().parents[1] / "planar_mbs" / "kernel"


def _int(node) -> bool:
    return isinstance(node, ast.Constant) and type(node.value) is int


def findings(source: str) -> list[tuple[int, str]]:
    bad = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Return) and node.value is not None:
            values = node.value.elts if isinstance(node.value, ast.Tuple) else [node.value]
            bad += [(node.lineno, "bare status literal") for v in values if _int(v) and v.value != 0]
        elif isinstance(node, ast.Compare):
            sides = [node.left, *node.comparators]
            if any(isinstance(n, ast.Name) and n.id in ("st", "status") for n in sides) and \
                    any(_int(n) and n.value != 0 for n in sides):
                bad.append((node.lineno, "status compared with a literal"))
            if any(isinstance(n, ast.Constant) and n.value == 0.5 for n in sides):
                bad.append((node.lineno, "a float compared with 0.5 as a flag"))
        elif isinstance(node, ast.Subscript):
            base, index = node.value, node.slice
            if isinstance(base, ast.Attribute) and base.attr in ("flags", "dense") and _int(index):
                bad.append((node.lineno, f"ws.{base.attr}[{index.value}]"))
            if isinstance(base, ast.Name) and base.id == "contact" and isinstance(index, ast.Tuple) \
                    and _int(index.elts[-1]):
                bad.append((node.lineno, f"contact[.., {index.elts[-1].value}]"))
            if isinstance(base, ast.Name) and base.id == "row" and isinstance(index, ast.BinOp) \
                    and _int(index.right) and index.right.value != 0:
                bad.append((node.lineno, f"row[.. + {index.right.value}]"))
    return sorted(bad)


def test_the_scanner_finds_what_it_should():
    src = ("def f(ws, contact, row, col, st):\n"
           "    ws.flags[2] = 1\n    x = ws.dense[0]\n    if contact[k, 0] < 0.5:\n        return 7\n"
           "    if st == 6:\n        return 1.0, 3\n    row[col + 4] = x\n    return 0\n")
    assert [line for line, _ in findings(src)] == [2, 3, 4, 4, 5, 6, 7, 8]
    ok = ("def f(ws, contact, row, col, st):\n    ws.flags[FL_DENSE_READY] = 1\n"
          "    if contact_mode(contact, k) == FREE:\n        return BAD_INPUT\n    row[col + CS_FN] = 0.0\n"
          "    return 0\n")
    assert findings(ok) == []


@pytest.mark.parametrize("path", sorted(KERNEL.glob("*.py")), ids=lambda p: p.name)
def test_no_bare_status_literals_or_positional_slots_in_the_kernels(path):
    bad = findings(path.read_text(encoding="utf-8"))
    assert not bad, "\n".join(f"{path.name}:{line}: {what}" for line, what in bad)
