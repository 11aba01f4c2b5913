"""Population sweep throughput: eyes per second, compile time and memory, per configuration.

Two parts:

* ``variants`` (in one process, side by side): the paper's scene (4 layouts × 9 depths,
  0.2 D grid within ±2 D) under the settings that trade accuracy for speed — wavelength
  step (10 nm, the paper's; 20 nm, which moved no prediction on the paper's grid, RESULTS
  §6) and the continuous peak (``local`` five-point refinement, ``parabola``: the grid
  parabola plus one evaluation, ``vertex``: the grid parabola alone, ``none``: grid peaks
  only). Steady-state seconds per eye
  come from chunks after the first (the first includes compilation).
* ``scaling``: ``lfjax sweep`` run as a user runs it (a fresh process with an empty
  compilation cache, so every run compiles) for N eyes; wall time, eyes/s and peak resident memory from its
  own report. Times for 100 → 1,000 eyes are measured; 10,000 is extrapolated from the
  measured slope (stated as such).

Usage::

    .venv/bin/python benchmarks/speed/bench_sweep.py variants --eyes 11 --chunk-size 4
    .venv/bin/python benchmarks/speed/bench_sweep.py scaling --eyes 100 1000 --wavelength-step 20 \
        --peak vertex --chunk-size 8 --keep benchmarks/_cache/sweep/paper_1000.zarr
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(1, str(Path(__file__).resolve().parents[1]))  # benchmarks/: _common
from _common import BENCH_DATE, header  # noqa: E402

HERE = Path(__file__).resolve().parent


def paper_config(n_eyes: int, wavelength_step: float, peak: str, chunk_size: int, seed: int = 0):
    from lfjax.sweep import config_from_dict

    metrics = {"continuous_peaks": [] if peak == "none" else ["vsotf"],
               "peak_method": "local" if peak == "none" else peak}
    return config_from_dict({
        "population": {"n_eyes": n_eyes, "seed": seed},
        "spectrum": {"wavelengths_nm": [400.0, 700.0, float(wavelength_step)]},
        "metrics": metrics,
        "run": {"chunk_size": chunk_size},
    })


def variants(args) -> None:
    from lfjax.sweep import run_sweep

    header("lfjax population sweep: variants side by side (steady state per eye)")
    rows = []
    tmp = Path(tempfile.mkdtemp(prefix="bench_sweep_"))
    try:
        for step in args.wavelength_steps:
            for peak in args.peaks:
                config = paper_config(args.eyes, step, peak, args.chunk_size)
                t0 = time.perf_counter()
                run = run_sweep(config, tmp / f"w{step:g}_{peak}.zarr", progress=False)
                total = time.perf_counter() - t0
                steady = run.chunk_seconds[1:]
                per_eye = float(np.median(steady)) / args.chunk_size if steady else float("nan")
                row = dict(wavelength_step_nm=step, peak=peak, eyes=config.n_total_eyes,
                           chunk_size=args.chunk_size, setup_s=round(run.setup_seconds, 2),
                           first_chunk_s=round(run.chunk_seconds[0], 2),
                           steady_s_per_eye=round(per_eye, 3), total_s=round(total, 1),
                           eyes_1000_min=round((1000 * per_eye + run.chunk_seconds[0]) / 60, 1))
                rows.append(row)
                print(json.dumps(row), flush=True)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    base = rows[0]["steady_s_per_eye"]
    print("\nwavelength_step peak      s/eye  ratio  first chunk (compile) s  1,000 eyes (min)")
    for r in rows:
        print(f"{r['wavelength_step_nm']:>8g} nm  {r['peak']:<9} {r['steady_s_per_eye']:6.3f}  "
              f"{r['steady_s_per_eye'] / base:5.2f}  {r['first_chunk_s']:10.1f}"
              f"              {r['eyes_1000_min']:6.1f}")
    _write_csv(HERE / "sweep_variants.csv", rows)


def scaling(args) -> None:
    header("lfjax population sweep: scaling with the number of eyes (fresh processes)")
    rows = []
    tmp = Path(tempfile.mkdtemp(prefix="bench_sweep_scaling_"))
    env = dict(os.environ)
    env["LFJAX_CACHE_DIR"] = str(tmp / "cache")  # a cold cache per run: compile included
    try:
        for n in args.eyes:
            shutil.rmtree(tmp / "cache", ignore_errors=True)
            config = paper_config(n, args.wavelength_step, args.peak, args.chunk_size)
            from lfjax.sweep import config_to_toml

            toml = tmp / f"sweep_{n}.toml"
            toml.write_text(config_to_toml(config))
            store = tmp / f"sweep_{n}.zarr"
            cmd = [str(Path(sys.executable).parent / "lfjax"), "sweep", str(toml), "--out",
                   str(store), "--no-progress"]
            t0 = time.perf_counter()
            proc = subprocess.run(cmd, capture_output=True, text=True, env=env)
            wall = time.perf_counter() - t0
            if proc.returncode != 0:
                raise RuntimeError(proc.stderr[-2000:])
            report = proc.stdout
            rate = float(re.search(r"([0-9.]+) eyes/s", report).group(1))
            rss = float(re.search(r"peak memory ([0-9.]+) MiB", report).group(1))
            row = dict(eyes=config.n_total_eyes, wall_s=round(wall, 1), eyes_per_s=rate,
                       peak_rss_mib=rss, chunk_size=args.chunk_size,
                       wavelength_step_nm=args.wavelength_step, peak=args.peak,
                       command=" ".join(cmd[1:3]) + " --out STORE")
            rows.append(row)
            print(json.dumps(row), flush=True)
            if args.keep is not None and n == max(args.eyes):
                # the largest store feeds the ten-eye analysis (lfjax sweep-report)
                keep = Path(args.keep)
                shutil.rmtree(keep, ignore_errors=True)
                keep.parent.mkdir(parents=True, exist_ok=True)
                shutil.move(str(store), str(keep))
                (keep.parent / (keep.stem + ".toml")).write_text(toml.read_text())
                print(f"kept the {n}-eye store in {keep}")
            shutil.rmtree(store, ignore_errors=True)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    if len(rows) >= 2:
        n = np.array([r["eyes"] for r in rows], float)
        t = np.array([r["wall_s"] for r in rows], float)
        slope, intercept = np.polyfit(n, t, 1)
        print(f"\nwall time ≈ {intercept:.1f} s + {slope:.3f} s/eye × N (fit over N = "
              f"{n.astype(int).tolist()}); 10,000 eyes extrapolated: "
              f"{(intercept + slope * 10001) / 60:.1f} min")
    _write_csv(HERE / "sweep_scaling.csv", rows)


def _write_csv(path: Path, rows: list[dict]) -> None:
    with path.open("w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    print(f"wrote {path.relative_to(HERE.parents[1])} ({BENCH_DATE})")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    sub = parser.add_subparsers(dest="part", required=True)
    v = sub.add_parser("variants")
    v.add_argument("--eyes", type=int, default=11)
    v.add_argument("--chunk-size", type=int, default=4)
    v.add_argument("--wavelength-steps", type=float, nargs="+", default=[10.0, 20.0])
    v.add_argument("--peaks", nargs="+", default=["local", "parabola", "vertex", "none"])
    s = sub.add_parser("scaling")
    s.add_argument("--eyes", type=int, nargs="+", default=[100, 1000])
    s.add_argument("--chunk-size", type=int, default=8)
    s.add_argument("--wavelength-step", type=float, default=20.0)
    s.add_argument("--peak", default="vertex")
    s.add_argument("--keep", default=None, metavar="STORE",
                   help="move the largest run's store here (e.g. benchmarks/_cache/sweep/paper_1000.zarr)")
    args = parser.parse_args()
    variants(args) if args.part == "variants" else scaling(args)


if __name__ == "__main__":
    main()
