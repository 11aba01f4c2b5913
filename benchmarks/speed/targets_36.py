"""Issue #36's targets, measured side by side: `lfjax reproduce` cold and warm and the default
sweep's seconds per eye, for two checkouts of lfjax on the same machine in one run.

Each command runs as a user runs it (a fresh process, ``python -m lfjax.cli``), with the
checkout first on PYTHONPATH; "cold" uses empty JAX compilation and lfjax plan caches in a
temporary folder, "warm" the same caches again. The two checkouts alternate (A B A B …) so
they share the machine's background load. Wall time and peak resident memory come from
``/usr/bin/time -v``. The sweep is the default configuration (``lfjax sweep --template``)
with ``n_eyes`` eyes, run once to compile and once timed (warm); its seconds per eye are
the timed run's wall time over its eyes (plan and store creation included).

    .venv/bin/python benchmarks/speed/targets_36.py --before /work/wt-old --after . \
        --sweep-eyes 47 --out benchmarks/speed/targets_36.log
"""

from __future__ import annotations

import argparse
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


def run(checkout: Path, args: list[str], caches: Path, cwd: Path, log) -> tuple[float, float, int]:
    env = dict(os.environ, PYTHONPATH=str(checkout.resolve()),
               JAX_COMPILATION_CACHE_DIR=str(caches / "jax"), LFJAX_CACHE_DIR=str(caches / "lfjax"),
               PYTHONUNBUFFERED="1")
    cmd = ["/usr/bin/time", "-v", sys.executable, "-m", "lfjax.cli", *args]
    t0 = time.perf_counter()
    proc = subprocess.run(cmd, cwd=cwd, env=env, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    rss = re.search(r"Maximum resident set size \(kbytes\): (\d+)", proc.stderr)
    log.write(f"$ PYTHONPATH={checkout} {' '.join(args)}\n{proc.stdout[-3000:]}\n{proc.stderr[-1500:]}\n")
    return wall, (int(rss.group(1)) / 2**20 if rss else float("nan")), proc.returncode


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--before", type=Path, required=True, help="checkout measured first (A)")
    p.add_argument("--after", type=Path, required=True, help="checkout measured second (B)")
    p.add_argument("--sweep-eyes", type=int, default=47, help="eyes of the sweep (plus the average eye)")
    p.add_argument("--skip-reproduce", action="store_true")
    p.add_argument("--warm-runs", type=int, default=1,
                   help="warm runs of each checkout, alternating (their median is printed too)")
    p.add_argument("--skip-sweep", action="store_true")
    p.add_argument("--keep", type=Path, default=None,
                   help="copy the after checkout's warm reproduce output here (to compare)")
    p.add_argument("--out", type=Path, default=None, help="full log of every command")
    args = p.parse_args()
    from _common import header

    header("Issue #36 targets: reproduce cold/warm, sweep s/eye, before and after")
    log = open(args.out, "w") if args.out else open(os.devnull, "w")
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        checkouts = {"before": args.before.resolve(), "after": args.after.resolve()}
        for name in checkouts:
            (tmp / name).mkdir()
        if not args.skip_reproduce:
            phases = ["cold"] + ["warm" if k == 0 else f"warm {k + 1}" for k in range(args.warm_runs)]
            for phase in phases:
                for name, checkout in checkouts.items():
                    out = tmp / name / f"reproduce_{phase.replace(' ', '_')}"
                    wall, rss, rc = run(checkout, ["reproduce", "--out", str(out)], tmp / name / "caches",
                                        tmp / name, log)
                    rows.append((f"reproduce {phase}", name, wall, rss, rc, None))
                    print(f"reproduce {phase:4s} {name:6s}: {wall:7.1f} s, peak {rss:.2f} GiB, exit {rc}", flush=True)
            if args.keep is not None:
                shutil.copytree(tmp / "after" / "reproduce_warm", args.keep, dirs_exist_ok=True)
        for name, checkout in ({} if args.skip_sweep else checkouts).items():
            config = tmp / name / "sweep.toml"
            run(checkout, ["sweep", "--template", str(config)], tmp / name / "caches", tmp / name, log)
            text = config.read_text()
            text, n = re.subn(r"(?m)^n_eyes\s*=.*$", f"n_eyes = {args.sweep_eyes}", text)
            assert n == 1, "the template names n_eyes once"
            config.write_text(text)
        for phase in () if args.skip_sweep else ("compile", "timed"):
            for name, checkout in checkouts.items():
                store = tmp / name / f"sweep_{phase}.zarr"
                wall, rss, rc = run(checkout, ["sweep", str(tmp / name / "sweep.toml"), "--out", str(store),
                                               "--no-progress"], tmp / name / "caches", tmp / name, log)
                per_eye = wall / (args.sweep_eyes + 1)
                rows.append((f"sweep {phase}", name, wall, rss, rc, per_eye))
                print(f"sweep {phase:7s} {name:6s}: {wall:7.1f} s, {per_eye:.2f} s/eye "
                      f"(1,000 eyes ~ {per_eye * 1001 / 60:.0f} min), peak {rss:.2f} GiB, exit {rc}", flush=True)
                shutil.rmtree(store, ignore_errors=True)
    print("\n| step | before | after | after / before |\n|---|---|---|---|")
    steps = dict.fromkeys(r[0] for r in rows)
    for step in steps:
        b = next(r for r in rows if r[0] == step and r[1] == "before")
        a = next(r for r in rows if r[0] == step and r[1] == "after")
        print(f"| {step} | {b[2]:.1f} s ({b[3]:.2f} GiB) | {a[2]:.1f} s ({a[3]:.2f} GiB) | {a[2] / b[2]:.2f} |")
    warm = {name: sorted(r[2] for r in rows if r[0].startswith("reproduce warm") and r[1] == name)
            for name in ("before", "after")}
    if len(warm["after"]) > 1:
        median = {name: float(np.median(w)) for name, w in warm.items()}
        print(f"| reproduce warm, median of {len(warm['after'])} | {median['before']:.1f} s | "
              f"{median['after']:.1f} s | {median['after'] / median['before']:.2f} |")


if __name__ == "__main__":
    main()
