"""Display-effects study (issue #13): lenslet diffraction, pixels and an OLED-like spectrum
switched on one by one for 2×2, 3×3 and 4×4, and the 2×2 lenslet-size sweep.

Run:  python benchmarks/studies/display_effects.py [--eyes N]
          [--out benchmarks/studies/display_effects]

Eyes: the Thibos average eye and the first N virtual eyes of seed 0 (the reproduction's
eyes). Writes display_effects.csv, display_lenslet_sweep.csv, study.nc and sweep.nc (the
xarray Datasets), REPORT.md (the section `lfjax reproduce --display-effects` adds) and the
two figures into --out.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from lfjax.studies import display_effects as de
from lfjax.cli import enable_compilation_cache
from lfjax.model.eyes import append_average_eye, sample_eyes


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--eyes", type=int, default=2)
    parser.add_argument("--out", default=str(Path(__file__).with_name("display_effects")))
    parser.add_argument("--sweep-only", action="store_true",
                        help="reuse --out/study.nc and recompute the 2x2 lenslet sweep only")
    parser.add_argument("--report-only", action="store_true",
                        help="reuse --out/study.nc and --out/sweep.nc: tables, figures, REPORT.md")
    args = parser.parse_args(argv)
    enable_compilation_cache()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    eyes = append_average_eye(sample_eyes(0, args.eyes))
    names = [f"eye{i + 1:02d}" for i in range(args.eyes)] + ["average"]
    config = de.DisplayStudyConfig()
    t0 = time.perf_counter()
    import xarray as xr

    if args.sweep_only or args.report_only:
        study = xr.load_dataset(out / "study.nc", engine="h5netcdf")
    else:
        study = de.run_display_study(eyes, names, config)
        study.to_netcdf(out / "study.nc", engine="h5netcdf")
    t1 = time.perf_counter()
    if args.report_only:
        sweep = xr.load_dataset(out / "sweep.nc", engine="h5netcdf")
    else:
        sweep = de.lenslet_sweep(eyes, names, config)
        sweep.to_netcdf(out / "sweep.nc", engine="h5netcdf")
    t2 = time.perf_counter()
    de.effects_table(study).to_csv(out / "display_effects.csv", index=False, float_format="%.6g")
    de.sweep_table(sweep).to_csv(out / "display_lenslet_sweep.csv", index=False, float_format="%.6g")
    de.save_display_figures(study, sweep, out)
    command = "python benchmarks/studies/display_effects.py " + " ".join(
        argv if argv is not None else sys.argv[1:])
    seconds = "\n".join(
        f"| {layout} | {step} | {float(study.seconds.sel(step=step, layout=layout)):.1f} | "
        f"{float(study.freq_step_cpd.sel(step=step, layout=layout)):.3g} |"
        for layout in study.layout.values for step in study.step.values)
    (out / "REPORT.md").write_text(
        f"# Beyond the ideal display\n\n`{command.strip()}` — {len(names)} eyes "
        f"({', '.join(names)}); study {float(study.seconds.sum()):.0f} s of pipeline time, "
        f"sweep {'(from sweep.nc)' if args.report_only else f'{t2 - t1:.0f} s'}.\n\n"
        + de.display_effects_markdown(study, sweep)
        + "\n\n| layout | step | seconds | planned df (cpd) |\n|---|---|---|---|\n" + seconds + "\n")
    print((out / "REPORT.md").read_text())
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
