"""Layout optimisation, honestly generalised: fit on 10 training eyes, report on held-out eyes.

Run:  .venv/bin/python benchmarks/layout_optimisation.py            (defaults below)
      .venv/bin/python benchmarks/layout_optimisation.py --quick    (smoke test, minutes)

What it does
1. The reference check (lfjax.layout_opt's docstring): 2×2 views at 1.5 mm pitch, 4 seeded
   eyes (sample_eyes(0, 4)), correct accommodation at 0–4 D, mean VSOTF for subaperture
   diameters 0.5–1.5 mm under the paper's reference (same layout, aberration-free: rises
   without bound as the views shrink) and the open-pupil reference (interior optimum).
2. The fit: square 2×2 lattice (pitch, diameter, rotation) from the paper's tangent grid,
   objective = population-mean VSOTF at the correct accommodation over the depths (open-pupil
   reference), jaxopt L-BFGS-B; training eyes sample_eyes(seed, n_train); held-out eyes
   sample_eyes(seed + 1, n_test), never seen by the fit. Constraints: centres inside the
   3 mm pupil, diameters 0.5–2 mm; with and without the non-overlap constraint.
3. Gains over the tangent grid on train and held-out eyes; the held-out accommodation error
   (continuous VSOTF peak within ±0.3 D) before/after on the first --accommodation-eyes
   held-out eyes; figures benchmarks/layout_optimisation_*.png; results
   benchmarks/layout_optimisation.json.

Sampling: the planner's aliasing guard (plan_sampling(..., estimate_accuracy=False)) for the
worst case of the feasible set (lfjax.layout_opt.guard_sampling) and 3 wavelengths
(450/550/650 nm, V(λ)-weighted), to keep it affordable on 2 CPU cores.

Results (2 CPU cores shared with other jobs, float32; see the JSON for every number):
RESULTS_PLACEHOLDER
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))


def parse(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--train-eyes", type=int, default=10)
    p.add_argument("--test-eyes", type=int, default=200)
    p.add_argument("--accommodation-eyes", type=int, default=40,
                   help="held-out eyes whose accommodation error is evaluated (0: none)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--steps", type=int, default=30)
    p.add_argument("--wavelengths", type=float, nargs="+", default=[450.0, 550.0, 650.0])
    p.add_argument("--quick", action="store_true", help="2 train, 10 test eyes, 5 steps")
    p.add_argument("--skip-overlap-run", action="store_true",
                   help="only the non-overlapping fit")
    args = p.parse_args(argv)
    if args.quick:
        args.train_eyes, args.test_eyes, args.steps, args.accommodation_eyes = 2, 10, 5, 4
    return args


def reference_scan(wavelengths):
    import lfjax
    from lfjax import layout_opt as lo

    eyes = lfjax.sample_eyes(0, 4)
    diameters = [0.5, 0.75, 1.0, 1.25, 1.5]
    depths = np.linspace(0.0, 4.0, 5)
    out = {"diameters_mm": diameters, "depths_D": depths.tolist()}
    for ref in ("paper", "open_pupil"):
        t0 = time.perf_counter()
        v = lo.diameter_scan(eyes, 2, 1.5, diameters, depths, ref, wavelengths_nm=wavelengths)
        out[ref] = {"mean": v.mean(axis=1).tolist(), "worst_depth": v.min(axis=1).tolist(),
                    "by_depth": v.tolist(), "time_s": time.perf_counter() - t0}
    return out


def fig_scan(scan):
    from matplotlib.figure import Figure

    fig = Figure(figsize=(6.5, 3.2), layout="constrained")
    for i, ref in enumerate(("paper", "open_pupil")):
        ax = fig.add_subplot(1, 2, i + 1)
        d = scan["diameters_mm"]
        ax.plot(d, scan[ref]["mean"], "o-", color="tab:red", label="mean over depths")
        ax.plot(d, scan[ref]["worst_depth"], "s--", color="tab:blue", label="worst depth")
        ax.set_xlabel("subaperture diameter (mm), 2×2 at 1.5 mm pitch")
        ax.set_title(f"VSOTF reference: {ref}", fontsize=9)
        if i == 0:
            ax.set_ylabel("VSOTF at correct accommodation")
            ax.legend(fontsize=7)
    return fig


def run_fit(args, train, test, non_overlap: bool, tag: str):
    import lfjax  # noqa: F401
    from lfjax import layout_opt as lo
    from lfjax import layout_plots
    from lfjax.eyes import Eyes

    constraints = lo.Constraints(3.0, max_diameter_mm=2.0, min_diameter_mm=0.5,
                                 non_overlap=non_overlap)
    depths = np.linspace(0.0, 4.0, 5)
    both = Eyes(np.concatenate([np.asarray(train.zernike_um), np.asarray(test.zernike_um)]),
                train.measured_pupil_mm)
    t0 = time.perf_counter()
    problem = lo.make_problem(train, depths, constraints, "depth_of_field",
                              wavelengths_nm=args.wavelengths, planning_eyes=both)
    t_problem = time.perf_counter() - t0
    start = lo.initial_lattice("square", 4, constraints)
    fit = lo.optimise_layout(start, problem, method="lbfgsb", max_steps=args.steps,
                             test_eyes=test, progress=True)
    result = {
        "tag": tag, "constraints": constraints.as_dict(),
        "freq_step_cpd": problem.config.freq_step_cpd, "bands": problem.config.bands,
        "problem_s": t_problem, "fit_s": fit.time_s, "steps": fit.n_steps,
        "converged": fit.converged, "history": fit.history.tolist(),
        "initial": lo.params_to_dict(fit.initial_params), "fitted": lo.params_to_dict(fit.params),
        "train": {k: {m: v for m, v in fit.train[k].items() if m != "values"} for k in fit.train},
        "test": {k: {m: v for m, v in fit.test[k].items() if m != "values"} for k in fit.test},
    }
    if args.accommodation_eyes > 0:
        sub = test[: args.accommodation_eyes]
        acc_problem = problem.with_objective("accommodation")
        t0 = time.perf_counter()
        result["accommodation"] = {
            k: {m: v for m, v in lo.evaluate_layout(p, acc_problem, sub, terms=("accommodation",),
                                                    chunk=args.train_eyes).items() if m != "values"}
            for k, p in (("before", fit.initial_params), ("after", fit.params))}
        result["accommodation_s"] = time.perf_counter() - t0
    shown = test[: min(test.n_eyes, 50)]
    curves = {"tangent 2x2": lo.through_focus_curves(fit.initial_params, problem, eyes=shown,
                                                      chunk=args.train_eyes),
              "fitted": lo.through_focus_curves(fit.params, problem, eyes=shown,
                                                chunk=args.train_eyes)}
    figs = {
        f"layout_optimisation_{tag}_layouts.png": layout_plots.fig_layouts(
            {"tangent 2x2": fit.initial_layout, "fitted": fit.layout}, 3.0),
        f"layout_optimisation_{tag}_through_focus.png": layout_plots.fig_through_focus(
            curves, depths, f"held-out eyes ({shown.n_eyes}), {tag}"),
    }
    for name, fig in figs.items():
        fig.savefig(HERE / name, dpi=110)
    lo.save_layout_json(HERE / f"layout_optimisation_{tag}.json", fit.layout, 3.0,
                        objective=dict(name=fit.objective.name, train=result["train"],
                                       test=result["test"]),
                        provenance=dict(script="benchmarks/layout_optimisation.py",
                                        seed_train=args.seed, seed_test=args.seed + 1,
                                        n_train=train.n_eyes, n_test=test.n_eyes),
                        parameters=fit.params)
    return result


def summary_lines(scan, fits):
    lines = ["reference check, 2x2 at 1.5 mm pitch, 4 eyes, correct accommodation 0-4 D:",
             "  d (mm)              " + " ".join(f"{d:6.2f}" for d in scan["diameters_mm"])]
    for ref in ("paper", "open_pupil"):
        lines.append(f"  mean, {ref:12s} " + " ".join(f"{v:6.3f}" for v in scan[ref]["mean"]))
        lines.append(f"  worst, {ref:11s} " + " ".join(f"{v:6.3f}" for v in scan[ref]["worst_depth"]))
    for r in fits:
        f = r["fitted"]
        lines.append(f"fit [{r['tag']}]: df {r['freq_step_cpd']:.3f} cpd, {r['steps']} steps in "
                     f"{r['fit_s']:.0f} s ({'converged' if r['converged'] else 'step limit'}); "
                     f"pitch {f['pitch_mm']:.3f} mm, d {f['diameter_mm']:.3f} mm, rotation "
                     f"{f['rotation_rad']:.3f} rad")
        for split in ("train", "test"):
            b, a = r[split]["before"], r[split]["after"]
            lines.append(
                f"  {split:5s} ({b['n_eyes']:3d} eyes): mean VSOTF {b['depth_of_field']:.4f} -> "
                f"{a['depth_of_field']:.4f} ({a['depth_of_field'] / b['depth_of_field'] - 1:+.1%}), "
                f"worst depth {b['worst_depth_vsotf']:.4f} -> {a['worst_depth_vsotf']:.4f}, "
                f"cut-off {b['resolution']:.1f} -> {a['resolution']:.1f} cpd")
        if "accommodation" in r:
            b, a = r["accommodation"]["before"], r["accommodation"]["after"]
            lines.append(f"  held-out accommodation RMSE ({b['n_eyes']} eyes): "
                         f"{b['accommodation_rmse_D']:.3f} -> {a['accommodation_rmse_D']:.3f} D "
                         f"(peaks found {b['peak_success_fraction']:.0%} / "
                         f"{a['peak_success_fraction']:.0%}; {r['accommodation_s']:.0f} s)")
    return lines


def main(argv=None):
    args = parse(argv)
    import lfjax
    from lfjax.cli import enable_compilation_cache

    enable_compilation_cache()
    t_all = time.perf_counter()
    command = "python benchmarks/layout_optimisation.py " + " ".join(sys.argv[1:] if argv is None else argv)
    print(f"$ {command}")
    scan = reference_scan(args.wavelengths)
    fig_scan(scan).savefig(HERE / "layout_optimisation_reference_scan.png", dpi=110)
    train = lfjax.sample_eyes(args.seed, args.train_eyes)
    test = lfjax.sample_eyes(args.seed + 1, args.test_eyes)
    fits = [run_fit(args, train, test, True, "non_overlap")]
    if not args.skip_overlap_run:
        fits.append(run_fit(args, train, test, False, "overlap_allowed"))
    lines = summary_lines(scan, fits)
    lines.append(f"total {time.perf_counter() - t_all:.0f} s")
    print("\n".join(lines))
    (HERE / "layout_optimisation.json").write_text(json.dumps(
        {"command": command, "scan": scan, "fits": fits, "summary": lines}, indent=1, default=str))
    return 0


if __name__ == "__main__":
    sys.exit(main())
