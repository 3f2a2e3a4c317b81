"""Output size known before a run: `mbs check` shows the rows and bytes, `mbs run` and `mbs sweep`
refuse (exit 2, before anything runs, no file written) a run beyond 10^8 rows or larger than the free
disk, unless --force.  The estimate is checked against the rows real runs write."""
from __future__ import annotations

import subprocess
import time
from pathlib import Path

import h5py
import pytest
from typer.testing import CliRunner

from planar_mbs import load_model, simulate
from planar_mbs.errors import ModelError
from planar_mbs.run.output_size import MAX_ROWS, estimate
from planar_mbs.run.simulation import run_settings

ROOT = Path(__file__).resolve().parents[2]
MODEL = ROOT / "models" / "slider_crank_clearance_a.mbs"
IDEAL = ROOT / "models" / "slider_crank.mbs"


def _cli(*args):
    from planar_mbs.cli.app import app

    r = CliRunner().invoke(app, [str(a) for a in args])
    assert r.exception is None or isinstance(r.exception, SystemExit), repr(r.exception)
    assert "Traceback" not in r.output
    return r


def _typo_model(tmp_path: Path, output_step: str, t_end: str = "5 rev / speed") -> Path:
    m = tmp_path / "typo.mbs"
    m.write_text(f'include "{MODEL}"\noverride simulate {{ t_end = {t_end}  integrator = dopri5  rtol = 1e-6  '
                 f'output_step = {output_step} }}\n')
    return m


@pytest.mark.parametrize("t_end, step", [(0.01, 1e-4), (0.013, 1e-4), (0.02, 3e-4), (0.0101, 1e-3),
                                         (0.005, 7e-5)])
def test_estimate_is_the_number_of_rows_a_run_writes(t_end, step):
    m = load_model(IDEAL)
    settings = run_settings(m, t_end=t_end, output_step=step)
    res = simulate(m, t_end=t_end, output_step=step)
    est = estimate(m, settings)
    assert est.rows == len(res.time)
    assert est.columns == len(res.signals) + 1


def test_estimated_size_bounds_the_file(tmp_path):
    m = load_model(MODEL)
    out = tmp_path / "a.h5"
    simulate(m, output=out, t_end=0.02)
    est = estimate(m, run_settings(m, t_end=0.02))
    size = out.stat().st_size
    data = 4096 * est.columns * 8  # 2001 rows fill one chunk of 4096 rows per column
    assert data <= size <= est.bytes
    assert est.bytes - size <= est.columns * 4096 + 65536  # beyond the whole chunks: only the metadata allowance


@pytest.mark.parametrize("step", ["1e-6 us", "1e-12 us", "1e-300 us", "1e-9 ms", "1e-10 s"])
def test_typo_in_output_step_is_refused_before_running(tmp_path, step):
    model = _typo_model(tmp_path, step)
    out = tmp_path / "a.h5"
    start = time.monotonic()
    r = _cli("run", model, "-o", out, "-q")
    assert r.exit_code == 2, r.output
    assert "beyond the limit of 100,000,000 rows" in r.output and "--force" in r.output
    assert not out.exists()
    assert time.monotonic() - start < 30  # refused, not run: a bound against a run that grows for minutes


@pytest.mark.parametrize("t_end", ["1e5s", "2 h", "30 min", "1001 s"])
def test_absurd_t_end_is_refused(tmp_path, t_end):
    out = tmp_path / "a.h5"
    r = _cli("run", MODEL, "-o", out, "--t-end", t_end, "-q")
    assert r.exit_code == 2, r.output
    assert "output rows" in r.output and not out.exists()


@pytest.mark.parametrize("step", ["1e-6 us", "1e-300 us"])
def test_check_shows_the_estimate_and_warns(tmp_path, step):
    r = _cli("check", _typo_model(tmp_path, step))
    assert r.exit_code == 0, r.output
    assert "output:" in r.output and "output rows" in r.output and "refuses this without --force" in r.output


def test_check_shows_the_estimate_of_a_sane_model():
    r = _cli("check", MODEL)
    m = load_model(MODEL)
    rows = round(m.settings.t_end / m.settings.output_step) + 1  # 5 revolutions at 5000 rpm every 10 µs
    assert r.exit_code == 0 and f"output: {rows:,} output rows" in r.output
    assert "refuses" not in r.output


def test_library_refuses_too_many_rows_unless_asked():
    m = load_model(IDEAL)
    with pytest.raises(ModelError, match="beyond the limit"):
        simulate(m, t_end=1e6, output_step=1e-6)
    with pytest.raises(ModelError, match="beyond the limit of 10 rows"):
        simulate(m, t_end=0.01, output_step=1e-4, max_rows=10)
    assert len(simulate(m, t_end=0.01, output_step=1e-4, max_rows=101).time) == 101
    assert MAX_ROWS == 10**8


def test_sweep_refuses_a_case_beyond_the_limit(tmp_path):
    out = tmp_path / "s.h5"
    r = _cli("sweep", _typo_model(tmp_path, "1e-9 us"), "-P", "speed=600rpm,800rpm", "-o", out, "-q")
    assert r.exit_code == 2, r.output
    assert "case 0" in r.output and "beyond the limit" in r.output
    assert not out.exists()


@pytest.mark.parametrize("args", [["-q"], ["-q", "--rerun", "x.rrd"], ["-q", "--t-end", "1e5s"]])
def test_a_refused_run_leaves_no_trace(tmp_path, monkeypatch, args):
    """Without -o a run writes to results/ under the working folder; a refusal makes no folder."""
    work = tmp_path / "work"
    work.mkdir()
    monkeypatch.chdir(work)
    r = _cli("run", _typo_model(tmp_path, "1e-6 us"), *args)
    assert r.exit_code == 2, r.output
    assert list(work.iterdir()) == []


def test_existing_output_is_untouched_when_refused(tmp_path):
    out = tmp_path / "a.h5"
    out.write_bytes(b"the user's earlier results")
    r = _cli("run", _typo_model(tmp_path, "1e-6 us"), "-o", out, "-q")
    assert r.exit_code == 2 and out.read_bytes() == b"the user's earlier results"


# ---------------------------------------------------------------- free disk space (a real small tmpfs)
@pytest.fixture
def small_disk(tmp_path):
    where = tmp_path / "disk"
    where.mkdir()
    if subprocess.run(["mount", "-t", "tmpfs", "-o", "size=2m", "tmpfs", str(where)],
                      capture_output=True).returncode != 0:
        pytest.skip("cannot mount a tmpfs here")
    yield where
    subprocess.run(["umount", "-l", str(where)], capture_output=True)


def test_run_larger_than_the_free_disk_is_refused(small_disk):
    out = small_disk / "a.h5"
    r = _cli("run", MODEL, "-o", out, "--t-end", "0.05s", "-q")  # 5001 rows x 54 columns: 2.2 MB > 2 MB
    assert r.exit_code == 2, r.output
    assert "do not fit on the disk" in r.output and not out.exists()


def test_sweep_larger_than_the_free_disk_is_refused(small_disk):
    out = small_disk / "s.h5"
    r = _cli("sweep", MODEL, "-P", "speed=2500rpm,5000rpm", "-n", "10", "-o", out, "-q", "--keep", "all")
    assert r.exit_code == 2, r.output
    assert "free on the disk" in r.output and not out.exists()
    with h5py.File(small_disk / "other.h5", "w"):
        pass  # the disk itself is fine: only the sweep was too large
