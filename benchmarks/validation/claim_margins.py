"""How far the study's planned spectra lie from the reference's, in the numbers the claims
read, and which verdicts that leaves unsettled (lfjax.vision.claim_margins).

Computes the alternatives' reduced set (every modelling alternative and the baseline) twice:
on the main study's planned spectra (each layout's Gauss rule, read from a default run's
``results.nc``) and on the reference spectrum of ``--accuracy vsotf`` (20 nm steps, every
peak refined). Prints, per alternative, the largest differences in what the claims read
(the calibration of :class:`~lfjax.vision.claim_margins.Resolution`), the claims each
side leaves unsettled, both sides' verdicts, and the verdicts after settling the planned
side at the reference (:func:`lfjax.reproduce.settling.settle`).

    PYTHONPATH=. .venv/bin/python benchmarks/validation/claim_margins.py \
        --study OUT/results.nc --out benchmarks/validation/claim_margins.log
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

sys.path.insert(1, str(Path(__file__).resolve().parents[1]))  # benchmarks/: _common


def differences(planned, reference) -> dict:
    """Largest |planned − reference| of what the claims read (means over the aberrated eyes
    where a claim reads a mean), and how many grid peaks moved."""
    import numpy as np

    from lfjax.vision.claims import aberrated, average

    same = np.abs(planned.predicted_accommodation - reference.predicted_accommodation) < 1e-9
    fmask = planned.frequency <= 60.0 + 1e-9

    def ratio(ds):  # claim 5: the average eye's mean MTF over the aberrated eyes' mean
        area = ds.mtf_at_peak.where(fmask).mean("frequency").sel(metric="vsotf")
        return average(area) / aberrated(area).mean("eye")

    def mean(ds, var, metric="vsotf"):
        return aberrated(ds)[var].sel(metric=metric).mean("eye")

    vs = same.sel(metric="vsotf") & np.isfinite(planned.predicted_accommodation.sel(metric="vsotf"))
    moved = lambda m: int((~same.sel(metric=m) & np.isfinite(
        planned.predicted_accommodation.sel(metric=m))).sum())  # noqa: E731
    return {
        "vertex_D": float(np.nanmax(np.abs(planned.predicted_accommodation_parabolic
                                           - reference.predicted_accommodation_parabolic)
                                    .sel(metric="vsotf").where(vs).values)),
        "mean_peak_D": float(np.nanmax(np.abs(mean(planned, "predicted_accommodation_continuous")
                                              - mean(reference, "predicted_accommodation_continuous")).values)),
        "mean_strehl_peak_D": float(np.nanmax(np.abs(mean(planned, "predicted_accommodation", "strehl")
                                                     - mean(reference, "predicted_accommodation", "strehl")).values)),
        "mtf_ratio": float(np.nanmax(np.abs(ratio(planned) - ratio(reference)).values)),
        "mean_cutoff_cpd": float(np.nanmax(np.abs(mean(planned, "cutoff_frequency")
                                                  - mean(reference, "cutoff_frequency")).values)),
        "vsotf_grid_peaks_moved": moved("vsotf"),
        "strehl_grid_peaks_moved": moved("strehl"),
    }


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--study", type=Path, required=True,
                   help="results.nc of a default `lfjax reproduce` run (its planned spectra)")
    p.add_argument("--out", type=Path, default=None, help="also write the log here")
    args = p.parse_args()
    from _common import header

    lines = []

    def say(text=""):
        print(text, flush=True)
        lines.append(text)

    header("claim margins: the planned spectra against the reference, in what the claims read")
    import xarray as xr

    from lfjax.cli.cache import enable_compilation_cache
    from lfjax.reproduce.alternatives import ALTERNATIVES, BASELINE
    from lfjax.reproduce.config import StudyConfig
    from lfjax.reproduce.settling import mark_unsettled, settle
    from lfjax.reproduce.study import run_study_variants, study_wavelength_rules
    from lfjax.vision.claim_margins import Resolution
    from lfjax.vision.claims import evaluate_claims

    enable_compilation_cache()
    rules = study_wavelength_rules(xr.open_dataset(args.study, engine="h5netcdf"))
    config = StudyConfig()
    options = {name: config.options.replace(**change)
               for name, change in ({BASELINE: {}} | ALTERNATIVES).items()}
    t0 = time.perf_counter()
    planned = run_study_variants(config.reduced(rules), options)
    t_planned = time.perf_counter() - t0
    t0 = time.perf_counter()
    reference = run_study_variants(config.reference().reduced(), options)
    t_reference = time.perf_counter() - t0
    say(f"planned spectra {rules}: {t_planned:.0f} s; reference (20 nm): {t_reference:.0f} s")
    say(f"resolution (lfjax.vision.claim_margins.Resolution()): {Resolution()}")
    say()
    diffs = {name: differences(planned[name], reference[name]) for name in options}
    keys = list(next(iter(diffs.values())))
    worst = {}
    say("| alternative | " + " | ".join(keys) + " |")
    say("|---|" + "---|" * len(keys))
    for name, diff in diffs.items():
        say(f"| {name} | " + " | ".join(f"{diff[k]:.4g}" for k in keys) + " |")
        for k, v in diff.items():
            worst[k] = max(worst.get(k, 0.0), v)
    say("| **largest** | " + " | ".join(f"**{worst[k]:.4g}**" for k in keys) + " |")
    say()
    t0 = time.perf_counter()
    settled, settled_claims = settle(planned, options, config.reference().reduced(),
                                     config.dof_fraction)
    t_settle = time.perf_counter() - t0
    say("| alternative | planned: verdicts | unsettled (claim: layouts) | reference: verdicts "
        "| unsettled | settled: verdicts | = reference |")
    say("|---|---|---|---|---|---|---|")
    same_planned = same_settled = total = 0
    for name in options:
        p_claims = mark_unsettled(evaluate_claims(planned[name]), planned[name])
        r_claims = evaluate_claims(reference[name])
        r_marks = mark_unsettled(evaluate_claims(reference[name]),
                                 reference[name].assign_attrs(accuracy_plan="claims"))
        s_claims = settled_claims[name]

        def verdicts(claims):
            return " ".join(c.verdict for c in claims)

        def marks(claims):
            return ", ".join(f"{c.id}: {' '.join(c.unsettled)}" for c in claims if c.unsettled) or "—"

        total += len(r_claims)
        same_planned += sum(a.verdict == b.verdict for a, b in zip(p_claims, r_claims))
        same_settled += sum(a.verdict == b.verdict for a, b in zip(s_claims, r_claims))
        say(f"| {name} | {verdicts(p_claims)} | {marks(p_claims)} | {verdicts(r_claims)} | "
            f"{marks(r_marks)} | {verdicts(s_claims)} | "
            f"{sum(a.verdict == b.verdict for a, b in zip(s_claims, r_claims))}/{len(r_claims)} |")
    say()
    say(f"verdicts equal to the reference's: planned {same_planned}/{total}, settled "
        f"{same_settled}/{total}; settling took {t_settle:.0f} s "
        f"(layouts: {sorted({n for cl in settled_claims.values() for c in cl for n in c.reference_layouts})})")
    if args.out is not None:
        args.out.write_text("\n".join(lines) + "\n")


if __name__ == "__main__":
    main()
