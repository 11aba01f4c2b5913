"""HPO (lenticular) strips against n×n grids, and cross-talk scans (issue #38 items 1–2).

Run:  python benchmarks/studies/hpo_crosstalk.py [--eyes 100] [--crosstalk-eyes 100]
          [--out benchmarks/studies/hpo_crosstalk] [--report-only]

Writes hpo.json, crosstalk.json, hpo_crosstalk.png and REPORT.md into --out, and prints the
command, the wall time and the peak memory (ru_maxrss) with the tables.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import sys
import time
from pathlib import Path

import numpy as np

from lfjax.cli import enable_compilation_cache
from lfjax.studies import hpo


def tables(study: dict, crosstalk: dict) -> str:
    lines = ["| layout | depth D | peak whole D | peak x (vertical structure) D | peak y (horizontal) D "
             "| VSOTF at peak | cut-off x cpd | cut-off y cpd |", "|---|---|---|---|---|---|---|---|"]
    for name, row in study["rows"].items():
        for i, d in enumerate(row["depths_D"]):
            lines.append(f"| {name} | {d:g} | {row['peak_whole_D'][i]:.2f} ± {row['peak_whole_sd_D'][i]:.2f} "
                         f"| {row['peak_x_D'][i]:.2f} | {row['peak_y_D'][i]:.2f} "
                         f"| {row['vsotf_whole_at_peak'][i]:.3f} | {row['cutoff_x_cpd'][i]:.1f} "
                         f"| {row['cutoff_y_cpd'][i]:.1f} |")
    lines += ["", "| layout | gain whole | gain x | gain y |", "|---|---|---|---|"]
    for name, row in study["rows"].items():
        if "gain_whole" in row:
            lines.append(f"| {name} | {np.mean(row['gain_whole']):.3f} ± {np.std(row['gain_whole'], ddof=1):.3f} "
                         f"| {np.mean(row['gain_x']):.3f} | {np.mean(row['gain_y']):.3f} |")
    lines += ["", "| scan | value | gain whole | gain x | VSOTF at peak (CDP) | cut-off x at CDP cpd "
              "| cut-off x at CDP+1 D cpd |", "|---|---|---|---|---|---|---|"]
    for scan, s in crosstalk["scans"].items():
        for row in s["rows"]:
            lines.append(f"| {scan} | {row['value']:g} | {np.mean(row['gain_whole']):.3f} "
                         f"| {np.mean(row['gain_x']):.3f} | {row['vsotf_whole_at_peak'][1]:.3f} "
                         f"| {row['cutoff_x_cpd'][1]:.1f} | {row['cutoff_x_cpd'][-1]:.1f} |")
        level = crosstalk["config"]["gain_threshold"]
        values = [r["value"] for r in s["rows"]]
        cross = [hpo.threshold_crossing(values, [np.mean(r[f"gain_{b}"]) for r in s["rows"]], level)
                 for b in ("whole", "x")]
        shown = ["none in the scan" if t is None else f"**{t:.3g}**" for t in cross]
        lines.append(f"| {scan} | gain {level:g} reached at | {shown[0]} | {shown[1]} | | | |")
    return "\n".join(lines)


def figure(study: dict, crosstalk: dict, path: Path) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 3, figsize=(15, 4.6))
    ax = axes[0]
    rows = study["rows"]
    mid = study["config"]["views"][len(study["config"]["views"]) // 2]
    palette = iter(["tab:green", "tab:red", "tab:purple", "tab:brown", "tab:pink"])
    for name, row in rows.items():
        if "HPO" in name:
            ax.plot(row["depths_D"], row["peak_whole_D"], "-", marker="o", ms=3, color=next(palette),
                    label=f"{name}: whole")
    for band, colour in (("x", "tab:blue"), ("y", "tab:orange")):
        row = rows[f"1x{mid} HPO"]
        ax.plot(row["depths_D"], row[f"peak_{band}_D"], "--", color=colour,
                label=f"1x{mid} HPO: {band} band")
    grid = rows[f"{mid}x{mid}"]
    ax.plot(grid["depths_D"], grid["peak_whole_D"], ":", color="k", marker="s", ms=3,
            label=f"{mid}x{mid} full parallax: whole")
    d = np.asarray(study["config"]["depths_D"])
    ax.plot(d, d, color="0.7", lw=4, alpha=0.5, label="follows depth")
    ax.set_xlabel("rendered depth (D)")
    ax.set_ylabel("predicted accommodation (D), mean of eyes")
    ax.set_title(f"HPO 1×n strips vs {mid}×{mid} (CDP {study['config']['cdp_D']:g} D)", fontsize=9)
    ax.legend(fontsize=6)
    ax = axes[1]
    names = [n for n in study["rows"] if n != "natural"]
    gx = [np.mean(study["rows"][n]["cutoff_x_cpd"]) for n in names]
    gy = [np.mean(study["rows"][n]["cutoff_y_cpd"]) for n in names]
    pos = np.arange(len(names))
    ax.bar(pos - 0.2, gx, 0.4, label="along x (vertical structure)")
    ax.bar(pos + 0.2, gy, 0.4, label="along y (horizontal structure)")
    nat = study["rows"]["natural"]
    ax.axhline(nat["cutoff_x_cpd"][0], color="tab:blue", ls=":", lw=1)
    ax.axhline(nat["cutoff_y_cpd"][0], color="tab:orange", ls=":", lw=1)
    ax.set_xticks(pos, names, rotation=30, ha="right", fontsize=7)
    ax.set_ylabel("MTF cut-off at the peak (cpd), mean of depths")
    ax.set_title("resolution cost (dotted: natural view)", fontsize=9)
    ax.legend(fontsize=7)
    ax = axes[2]
    for scan, s in crosstalk["scans"].items():
        v = [r["value"] for r in s["rows"]]
        g = [np.mean(r["gain_whole"]) for r in s["rows"]]
        line, = ax.plot(v, g, marker="o", label=f"{scan} (whole)")
        if scan.startswith("strips"):
            ax.plot(v, [np.mean(r["gain_x"]) for r in s["rows"]], "--", marker="^",
                    color=line.get_color(), label=f"{scan} (x band)")
    ax.axhline(crosstalk["config"]["gain_threshold"], color="0.5", ls=":")
    ax.set_xlabel("view width / pitch (width scans) · leakage weight (leakage scans)")
    ax.set_ylabel("accommodative gain (slope of peak vs depth)")
    ax.set_title(f"cross-talk, {crosstalk['config']['crosstalk_views']} views across", fontsize=9)
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--eyes", type=int, default=100)
    parser.add_argument("--crosstalk-eyes", type=int, default=100)
    parser.add_argument("--out", default=str(Path(__file__).with_name("hpo_crosstalk")))
    parser.add_argument("--report-only", action="store_true")
    parser.add_argument("--crosstalk-views", type=int, default=3,
                        help="n of the cross-talk scans' n×n grid and 1×n strips")
    args = parser.parse_args(argv)
    enable_compilation_cache()
    load_start = os.getloadavg()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    if args.report_only:
        study = json.loads((out / "hpo.json").read_text())
        crosstalk = json.loads((out / "crosstalk.json").read_text())
    else:
        study = hpo.run_hpo_study(hpo.HpoConfig(n_eyes=args.eyes))
        (out / "hpo.json").write_text(json.dumps(study))
        crosstalk = hpo.run_crosstalk_study(hpo.HpoConfig(n_eyes=args.crosstalk_eyes,
                                                         crosstalk_views=args.crosstalk_views))
        (out / "crosstalk.json").write_text(json.dumps(crosstalk))
    figure(study, crosstalk, out / "hpo_crosstalk.png")
    command = "python benchmarks/studies/hpo_crosstalk.py " + " ".join(
        argv if argv is not None else sys.argv[1:])
    usage = resource.getrusage(resource.RUSAGE_SELF)
    peak_mib = usage.ru_maxrss / 1024
    cpu_s = usage.ru_utime + usage.ru_stime
    load = f"load average (1 min) {load_start[0]:.1f} at the start, {os.getloadavg()[0]:.1f} at the end"
    text = (f"# HPO strips and cross-talk\n\n`{command.strip()}` — HPO study "
            f"{study['config']['n_eyes']} eyes {study['seconds']:.0f} s, cross-talk "
            f"{crosstalk['config']['n_eyes']} eyes {crosstalk['seconds']:.0f} s; "
            + ("tables and figure rebuilt from the json files" if args.report_only else
               f"this run {time.perf_counter() - t0:.0f} s wall, {cpu_s:.0f} s of CPU (user + "
               f"system), peak memory {peak_mib:.0f} MiB; {load}; {os.cpu_count()} cores") + ".\n\n"
            f"Lenticular phone Δ = {study['y_defocus_phone_D']:.3f} D.\n\n" + tables(study, crosstalk) + "\n")
    (out / "REPORT.md").write_text(text)
    print(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
