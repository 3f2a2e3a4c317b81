"""Run every shipped model briefly and compare the HDF5 results of two checkouts.

    python benchmarks/compare_results.py run OUTDIR      # the importable planar_mbs -> OUTDIR/*.h5
    python benchmarks/compare_results.py compare DIR_A DIR_B
    python benchmarks/compare_results.py time          # time-loop wall times of DOPRI5 and DOP853 runs

`run` writes one file per shipped model (models/*.mbs, t_end cut short) and a few extra cases that
exercise every integrator's step, events and dense output (RK4 and DOP853 on the clearance
slider-crank).  To compare two versions, run it once with each on the path (e.g.
``PYTHONPATH=/tmp/other python benchmarks/compare_results.py run /tmp/a``), then `compare`: it prints,
per file, whether the time column and every signal both files have are bit-identical (and how many
signals only one of them has), else the largest absolute and
relative difference, and exits 1 when any file differs or is missing.  `time` prints one line of
time-loop wall times (the smallest of 3 runs each; run it alternately with each version on the path,
several times, and compare medians: the machine's load changes between runs).
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

MODELS = Path(__file__).resolve().parents[1] / "models"
SHORT = {"four_bar": "0.2 s", "parallelogram_chain": "0.2 s", "redundant_rails": "0.2 s",
         "single_cylinder_engine": "20 ms"}
EXTRA = {  # name: (model, settings)
    "clearance_a_dop853": ("slider_crank_clearance_a", {"integrator": "dop853", "t_end": "6 ms"}),
    "clearance_a_rk4": ("slider_crank_clearance_a", {"integrator": "rk4", "step": "1 us", "t_end": "3 ms"}),
    "slider_crank_rk4": ("slider_crank", {"integrator": "rk4", "step": "10 us", "t_end": "10 ms"}),
}


def run(outdir: Path) -> None:
    import planar_mbs as mbs
    outdir.mkdir(parents=True, exist_ok=True)
    cases = {p.stem: (p.stem, {"t_end": SHORT.get(p.stem, "6 ms")}) for p in sorted(MODELS.glob("*.mbs"))}
    cases.update(EXTRA)
    for name, (model, settings) in cases.items():
        out = outdir / f"{name}.h5"
        out.unlink(missing_ok=True)
        try:
            res = mbs.simulate(mbs.load_model(MODELS / f"{model}.mbs"), output=out, **settings)
            print(f"{name}: {len(res.time)} rows, {res.attrs['n_steps']} steps")
        except Exception as exc:  # a model that fails fails the same way in both versions
            print(f"{name}: {type(exc).__name__}: {exc}".splitlines()[0])


TIMED = {  # name: (model, settings)
    "dopri5_clearance_a": ("slider_crank_clearance_a", {"t_end": "120 ms"}),
    "dop853_clearance_a": ("slider_crank_clearance_a", {"integrator": "dop853", "t_end": "120 ms"}),
    "dopri5_slider_crank": ("slider_crank", {"t_end": "1 s", "output_step": "10 us"}),
    "dop853_four_bar": ("four_bar", {"t_end": "20 s"}),
}


def timing() -> None:
    import json

    import planar_mbs as mbs
    walls = {}
    for name, (model, settings) in TIMED.items():
        m = mbs.load_model(MODELS / f"{model}.mbs")
        walls[name] = min(mbs.simulate(m, **settings).attrs["wall_time"] for _ in range(3))
    print(json.dumps(walls))


def _datasets(f) -> dict[str, np.ndarray]:
    import h5py
    found = {"time": f["time"][()]}
    def add(name, item):
        if not isinstance(item, h5py.Dataset):
            return
        data = item[()]
        if data.dtype.names:  # one compound dataset per entity: compare its fields one by one
            found.update({f"{name}.{field}": data[field] for field in data.dtype.names})
        else:
            found[name] = data
    f["signals"].visititems(add)
    return found


def compare(a: Path, b: Path) -> int:
    import h5py
    bad = 0
    for fa in sorted(a.glob("*.h5")):
        fb = b / fa.name
        if not fb.exists():
            print(f"{fa.stem}: missing in {b}")
            bad += 1
            continue
        with h5py.File(fa, "r") as ha, h5py.File(fb, "r") as hb:
            da, db = _datasets(ha), _datasets(hb)
        shared = sorted(set(da) & set(db))
        only = f"; only in {a.name}: {len(set(da) - set(db))}, only in {b.name}: {len(set(db) - set(da))}" \
            if set(da) != set(db) else ""
        if any(da[k].shape != db[k].shape for k in shared):
            print(f"{fa.stem}: different row counts ({len(da['time'])} and {len(db['time'])}){only}")
            bad += 1
            continue
        numeric = [k for k in shared if da[k].dtype.kind in "fiu"]
        same = all(np.array_equal(da[k], db[k], equal_nan=k in numeric) for k in shared)
        if same:
            print(f"{fa.stem}: bit-identical ({len(da['time'])} rows, {len(shared)} shared datasets{only})")
            continue
        bad += 1
        dabs = max(float(np.nanmax(np.abs(da[k] - db[k]), initial=0.0)) for k in numeric)
        drel = max(float(np.nanmax(np.abs(da[k] - db[k]) / np.maximum(np.abs(da[k]), 1e-300), initial=0.0))
                   for k in numeric)
        print(f"{fa.stem}: differs, largest absolute {dabs:.3g}, relative {drel:.3g}")
    return 1 if bad else 0


if __name__ == "__main__":
    if sys.argv[1:2] == ["run"] and len(sys.argv) == 3:
        run(Path(sys.argv[2]))
    elif sys.argv[1:2] == ["time"]:
        timing()
    elif sys.argv[1:2] == ["compare"] and len(sys.argv) == 4:
        sys.exit(compare(Path(sys.argv[2]), Path(sys.argv[3])))
    else:
        print(__doc__)
        sys.exit(2)
