"""The spatio-angular trade-off of two real panels (issue #27, item 3): perceivable resolution
and accommodation error against views per pupil, over a population of eyes.

Run:  python benchmarks/studies/spatio_angular_tradeoff.py [--eyes 100] [--panels near-eye phone]
          [--counts 1 2 3 4 5 6] [--wavelengths 550 550 10] [--work DIR] [--out DIR]

For each panel class (lfjax.display.panel's presets: a 0.7-inch OLED microdisplay at 30 mm, a
460 ppi phone panel at 350 mm) and each count n, lfjax.studies.tradeoff.panel_for_views builds the
panel of the same pixels, distance, CDP and eye box with tangent n×n views, and the
population sweep (lfjax.sweep.run_sweep) evaluates it on --eyes Thibos eyes (seed 0) at the
CDP and ±1 D. Stores go to --work (resumable: an interrupted run continues where it
stopped; a finished store is reused; --report-only reads what is there). Writes into --out
tradeoff.csv (every count × depth and the pooled rows), tradeoff.md (the tables, the
settings, machine, command and times) and tradeoff.png (the figure).
"""

from __future__ import annotations

import argparse
import csv
import sys
import time
from pathlib import Path

sys.path.insert(1, str(Path(__file__).resolve().parents[1]))  # benchmarks/: _common

from _common import header  # noqa: E402

from lfjax.studies import tradeoff as to
from lfjax.cli import enable_compilation_cache  # noqa: E402
from lfjax.display.panel import PRESETS  # noqa: E402
from lfjax.sweep.store_checks import completed_chunks, is_store  # noqa: E402

HERE = Path(__file__).resolve().parent


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--eyes", type=int, default=100)
    parser.add_argument("--panels", nargs="+", default=["near-eye", "phone"], choices=sorted(PRESETS))
    parser.add_argument("--counts", nargs="+", type=int, default=[1, 2, 3, 4, 5, 6])
    parser.add_argument("--wavelengths", nargs=3, type=float, default=[550.0, 550.0, 10.0],
                        metavar=("START", "STOP", "STEP"), help="V(λ)-weighted spectrum, nm")
    parser.add_argument("--chunk-size", type=int, default=5)
    parser.add_argument("--work", default=str(HERE.parent / "_cache" / "spatio_angular_tradeoff"),
                        help="folder of the sweep stores and layout files")
    parser.add_argument("--out", default=str(HERE / "spatio_angular_tradeoff"))
    parser.add_argument("--report-only", action="store_true",
                        help="no computing: tables and figure from the finished chunks in --work")
    args = parser.parse_args(argv)
    info = header("spatio-angular trade-off (lfjax.studies.tradeoff)")
    enable_compilation_cache()
    config = to.TradeoffConfig(counts=tuple(args.counts), n_eyes=args.eyes,
                               wavelengths_nm=tuple(args.wavelengths), chunk_size=args.chunk_size)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    results, timing = {}, []
    t_all = time.perf_counter()
    for key in args.panels:
        template = PRESETS[key]()
        work = Path(args.work) / key
        if args.report_only:
            parts = [p for p in to.plan_tradeoff(template, work, config)
                     if is_store(p.store) and completed_chunks(p.store).any()]
        else:
            parts = to.run_tradeoff(template, work, config, progress=True)
        for p in parts:
            timing.append((template.name, p.n_per_side, p.seconds, p.peak_rss_mb,
                           [round(c, 1) for c in p.chunk_seconds]))
        if parts:
            results[template.name] = to.tradeoff_table(parts, template.name)
    total = time.perf_counter() - t_all
    rows = [r for rs in results.values() for r in rs]
    with open(out / "tradeoff.csv", "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0]))
        writer.writeheader()
        for r in rows:
            writer.writerow({k: (f"{v:.6g}" if isinstance(v, float) else v) for k, v in r.items()})
    fig = to.fig_tradeoff(results, config.accommodation_tolerance_D, config.window_D)
    fig.savefig(out / "tradeoff.png", dpi=110)
    command = "python benchmarks/studies/spatio_angular_tradeoff.py " + " ".join(
        argv if argv is not None else sys.argv[1:])
    lines = [f"command: `{command}`",
             f"machine: {info['cpu']}, {info['cores']} cores (shared; load avg at start "
             f"{info['load_avg_1m']}), jax {info['jax']} ({info['backend']}, x64={info['x64']})",
             f"date: {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}; wall time of this "
             f"invocation {total / 60:.1f} min" + (" (report only)" if args.report_only else ""),
             f"settings: {config.n_eyes} eyes (sample_eyes seed {config.seed}), depths CDP "
             f"{', '.join(f'{d:+g}' for d in config.depth_offsets_D)} D, accommodation grid "
             f"{config.accommodation_step_D:g} D within ±{config.window_D:g} D (continuous VSOTF "
             f"peaks), wavelengths {config.wavelengths_nm} nm, sampling planned by the sweep's "
             f"field guard on the population, chunks of {config.chunk_size}", ""]
    for name, part_rows in results.items():
        best = to.optimum(part_rows, config.accommodation_tolerance_D)
        lines += [f"### {name}", "",
                  (f"optimum: {best['views']}" if best else
                   f"optimum: none (no count above 1x1 keeps the display's accommodation RMSE "
                   f"within {config.accommodation_tolerance_D:g} D with most peaks inside their "
                   f"window)"), "",
                  to.markdown_table(part_rows, best), ""]
    if args.report_only:
        lines.append("times: this invocation read the stores and computed nothing (the runs that "
                     "filled them are timed in benchmarks/RESULTS.md)")
    else:
        lines += ["| panel | views | sweep s (0: store already complete) | peak RSS MiB "
                  "| chunk s (first with compilation) |", "|---|---|---|---|---|"]
        lines += [f"| {n} | {k}x{k} | {s:.0f} | {m:.0f} | {c} |" for n, k, s, m, c in timing]
    (out / "tradeoff.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))
    print(f"wrote {out / 'tradeoff.csv'}, {out / 'tradeoff.md'}, {out / 'tradeoff.png'}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
