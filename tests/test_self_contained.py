"""The repository explains itself: it names no file users do not have.

Every tracked text file is searched for references to private notes and for nicknames of
the paper; the paper is cited by authors and title instead
(Muvengei, Kihiu and Ikua, "Effects of input speed on the dynamic response of planar
multi-body systems with differently located frictionless revolute clearance joints").
The patterns are assembled from pieces so that this file does not match itself.
"""
import re
import subprocess
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
SKIP_DIRS = {".git", ".venv", "__pycache__", ".pytest_cache", ".hypothesis", "results", "build", "dist"}
TEXT = (".py", ".md", ".mbs", ".toml", ".lark", ".txt", ".json", ".cfg", ".ini", ".yml", ".yaml", "")

DESIGN_NOTE = re.compile("design" + r"\.md", re.I)
# prose references to the paper as "the seed" (a random generator's `seed=` stays allowed)
SEED_PROSE = re.compile(r"\bthe\s+" + "seed" + r"\b|\b" + "seed" + r"(?:'s|\s+(?:eqs?\b|§|paper|model|study|case|slider))",
                        re.I)
SEED_WORD = re.compile(r"\b" + "seed" + r"\b", re.I)  # any use at all, in docs and models


def tracked_files():
    try:
        out = subprocess.run(["git", "ls-files"], cwd=ROOT, capture_output=True, text=True, check=True).stdout
        paths = [ROOT / line for line in out.splitlines()]
    except (OSError, subprocess.CalledProcessError):  # not a git checkout: walk the tree
        paths = [p for p in ROOT.rglob("*") if not SKIP_DIRS & set(p.relative_to(ROOT).parts)]
    return [p for p in paths if p.is_file() and p.suffix in TEXT and p.name != Path(__file__).name]


def offences():
    found = []
    for path in tracked_files():
        try:
            text = path.read_text(encoding="utf-8")
        except UnicodeDecodeError:
            continue  # deliberately broken test inputs
        prose = path.suffix in (".md", ".mbs", ".toml", ".txt")
        for n, line in enumerate(text.splitlines(), 1):
            if DESIGN_NOTE.search(line) or SEED_PROSE.search(line) or (prose and SEED_WORD.search(line)):
                found.append(f"{path.relative_to(ROOT)}:{n}: {line.strip()}")
    return found


def test_no_reference_to_files_users_do_not_have():
    assert offences() == []


def test_the_search_finds_what_it_looks_for(tmp_path):
    """The patterns catch the forms that were once in the repository and spare a random seed."""
    bad = ["see " + "design" + ".md §6", "as in " + "the " + "seed", "(" + "seed" + " eq. 18)", "the " + "seed" + "'s figures",
           "Seed" + " paper §III"]
    good = ["rng = np.random.default_rng(" + "seed" + ")", "def f(x, " + "seed" + ": int = 0)", "Muvengei et al. eq. 18"]
    assert all(DESIGN_NOTE.search(b) or SEED_PROSE.search(b) for b in bad)
    assert not any(DESIGN_NOTE.search(g) or SEED_PROSE.search(g) for g in good)
    assert tracked_files(), "found no files to search"


def test_architecture_page_names_only_files_that_exist():
    """docs/architecture.md: every module and file it names is in the repository, and every
    module of the package has its paragraph."""
    text = (ROOT / "docs" / "architecture.md").read_text(encoding="utf-8")
    named = set(re.findall(r"`([\w/]+\.(?:py|md|lark))`", text))
    files = [p.relative_to(ROOT).as_posix() for p in tracked_files()]
    assert [n for n in named if not any(f == n or f.endswith("/" + n) for f in files)] == []
    modules = [p.name for p in (ROOT / "planar_mbs").glob("*.py") if p.name != "__init__.py"]
    assert [m for m in modules if f"`{m}`" not in text] == []
    assert "Effects of input speed on the dynamic response of planar" in " ".join(text.split())
