"""The question's plan against the VSOTF plan: `lfjax reproduce` under both, side by side.

``--accuracy claims`` (the default) plans each layout's wavelength step for the claims'
needs (peaks to 0.01 D, cut-offs to 0.25 cpd); ``--accuracy vsotf`` is the earlier fixed
10 nm grid (made for a VSOTF error of 1e-3). This script runs the full default study under
both, one after the other, each in a fresh process with a new empty compilation cache
(cold) and then again on that cache (warm), counting compiled programs
(``benchmarks/speed/count_compiles.py``), and compares what the claims read:

* every verdict, in ``claims.csv`` and in ``alternatives.csv``;
* every continuous VSOTF peak (``results.nc``), against ``--peak-target`` (D);
* every cut-off frequency at the same grid state, against ``--cutoff-target`` (cpd);
  cells whose 0.2 D grid peak differs between the runs (a near-tie of two grid states
  decided the other way) are counted and reported apart, since their cut-offs are read at
  different accommodation states.

Run:  PYTHONPATH=. .venv/bin/python benchmarks/validation/accuracy_plans.py --work DIR
      (or --compare-only with the two output folders already in DIR)
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[1]
PLANS = ("vsotf", "claims")


def _run(plan: str, work: Path, warm: bool) -> dict:
    cache, out = work / f"cache-{plan}", work / f"out-{plan}"
    cmd = [sys.executable, str(ROOT / "benchmarks" / "speed" / "count_compiles.py"), "--full",
           "--accuracy", plan,
           "--cache", str(cache), "--out", str(out)]
    print("$", " ".join(cmd), flush=True)
    done = subprocess.run(cmd, capture_output=True, text=True, check=True,
                          env=dict(os.environ, PYTHONPATH=str(ROOT)))
    result = json.loads(done.stdout.strip().splitlines()[-1])
    report = (out / "REPORT.md").read_text()
    result["stages"] = next(line for line in report.splitlines() if line.startswith("Timings"))
    result["warm" if warm else "cold"] = True
    return result


def compare(work: Path, peak_target: float, cutoff_target: float) -> dict:
    import pandas as pd
    import xarray as xr

    out = {}
    old, new = work / "out-vsotf", work / "out-claims"
    verdicts = {}
    for table, keys in (("claims.csv", ["id"]), ("alternatives.csv", ["variant", "claim"])):
        a, b = pd.read_csv(old / table), pd.read_csv(new / table)
        column = "verdict"
        merged = a.merge(b, on=keys, suffixes=("_vsotf", "_claims"))
        assert len(merged) == len(a) == len(b), table
        changed = merged[merged[f"{column}_vsotf"] != merged[f"{column}_claims"]]
        verdicts[table] = {"compared": len(merged), "different": len(changed),
                           "which": [" ".join(map(str, row)) for row in
                                     changed[keys].itertuples(index=False)]}
    out["verdicts"] = verdicts
    with xr.open_dataset(old / "results.nc", engine="h5netcdf") as a, \
            xr.open_dataset(new / "results.nc", engine="h5netcdf") as b:
        per_layout = {}
        for layout in a.layout.values:
            x, y = a.sel(layout=layout), b.sel(layout=layout)
            cont = np.abs(x.predicted_accommodation_continuous.sel(metric="vsotf").values
                          - y.predicted_accommodation_continuous.sel(metric="vsotf").values)
            grid_a, grid_b = x.predicted_accommodation.values, y.predicted_accommodation.values
            cells = np.isfinite(grid_a)
            flipped = cells & (np.abs(grid_a - grid_b) > 1e-9)
            cut = np.abs(x.cutoff_frequency.values - y.cutoff_frequency.values)
            same = cells & ~flipped
            per_layout[str(layout)] = {
                "wavelength_step_nm": [float(d["wavelength_step_nm"]) if "wavelength_step_nm" in d
                                       else 10.0 for d in (x, y)],
                "freq_step_cpd": [float(x.freq_step_cpd), float(y.freq_step_cpd)],
                "continuous_peak_max_D": float(np.nanmax(cont)),
                "grid_peaks_flipped": f"{int(flipped.sum())}/{int(cells.sum())}",
                "grid_flip_D": float(np.max(np.abs(grid_a - grid_b)[cells])),
                "cutoff_same_state_max_cpd": float(np.max(cut[same])),
                "cutoff_same_state_p95_cpd": float(np.percentile(cut[same], 95)),
                "cutoff_flipped_max_cpd": float(np.max(cut[flipped])) if flipped.any() else 0.0,
            }
        out["layouts"] = per_layout
    worst_peak = max(v["continuous_peak_max_D"] for v in out["layouts"].values())
    worst_cut = max(v["cutoff_same_state_max_cpd"] for v in out["layouts"].values())
    out["peaks_within_target"] = bool(worst_peak <= peak_target)
    out["cutoffs_within_target"] = bool(worst_cut <= cutoff_target)
    out["targets"] = {"peak_D": peak_target, "cutoff_cpd": cutoff_target}
    return out


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--work", required=True, help="folder for caches and outputs")
    parser.add_argument("--compare-only", action="store_true")
    parser.add_argument("--peak-target", type=float, default=0.01)
    parser.add_argument("--cutoff-target", type=float, default=0.25)
    args = parser.parse_args(argv)
    work = Path(args.work)
    work.mkdir(parents=True, exist_ok=True)
    print("$", " ".join([Path(sys.executable).name, *sys.argv]), flush=True)
    runs = []
    if not args.compare_only:
        for plan in PLANS:  # cold, then warm on the same cache
            for warm in (False, True):
                result = _run(plan, work, warm)
                print(json.dumps(result), flush=True)
                runs.append(result)
    summary = {"runs": runs, "comparison": compare(work, args.peak_target, args.cutoff_target)}
    (work / "accuracy_plans.json").write_text(json.dumps(summary, indent=1))
    print(json.dumps(summary["comparison"], indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
