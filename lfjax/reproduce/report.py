"""The report: CSV tables and ``REPORT.md`` from the study, its claims and the alternatives.

``TABLES`` names the CSV files; :func:`prediction_table`, :func:`summary_table`,
:func:`cutoff_table`, :func:`claims_table` and :func:`alternatives_table` build them as
pandas DataFrames; :func:`write_report` writes the markdown report.

Imports :mod:`~lfjax.reproduce.config` and :mod:`~lfjax.reproduce.study` from the package,
and the claims from :mod:`lfjax.vision.claims`.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from lfjax.vision.claim_core import Claim
from lfjax.vision.claims import aberrated, average
from lfjax.reproduce.config import METRICS, StudyConfig

TABLES = {
    "predictions": "accommodation_predictions.csv",
    "summary": "accommodation_summary.csv",
    "cutoff": "cutoff_frequencies.csv",
    "claims": "claims.csv",
    "alternatives": "alternatives.csv",
}


# ----------------------------------------------------------------------------- tables


def prediction_table(ds):
    """Per eye × layout × depth × metric predictions (a pandas DataFrame, all finite)."""
    import pandas as pd

    columns = dict(predicted_accommodation_D="predicted_accommodation",
                   accommodation_error_D="accommodation_error",
                   predicted_accommodation_parabolic_D="predicted_accommodation_parabolic",
                   predicted_accommodation_continuous_D="predicted_accommodation_continuous",
                   peak_value="peak_value", cutoff_cpd="cutoff_frequency")
    # NumPy arrays (layout, eye, depth, metric): one xarray selection per cell took a second
    values = {col: ds[var].transpose("layout", "eye", "depth", "metric").values
              for col, var in columns.items()}
    pred = values["predicted_accommodation_D"]
    metric_index = [list(ds.metric.values).index(m) for m in METRICS]
    eyes, is_avg = [str(e) for e in ds.eye.values], ds.is_average.values
    depths, rel = ds.depth.values, ds.depth_rel_cdp.values
    rows = []
    for li, layout in enumerate(ds.layout.values):
        for di in range(ds.depth.size):
            if not np.all(np.isfinite(pred[li, :, di])):
                continue  # natural view: the CDP only
            for ei, eye in enumerate(eyes):
                for metric, mi in zip(METRICS, metric_index):
                    rows.append(dict(
                        eye=eye, is_average=bool(is_avg[ei]), layout=str(layout),
                        depth_D=float(depths[di]), depth_rel_cdp_D=float(rel[di]),
                        metric=metric,
                        **{col: float(v[li, ei, di, mi]) for col, v in values.items()}))
    return pd.DataFrame(rows)


def summary_table(ds):
    """Per layout × depth × metric: mean, SD, min, max of the aberrated eyes' errors and the
    average eye's error (D)."""
    import pandas as pd

    ab, av = aberrated(ds), average(ds)
    rows = []
    for layout in ds.layout.values:
        for di in range(ds.depth.size):
            for metric in METRICS:
                e = ab.sel(layout=layout, metric=metric).accommodation_error.isel(depth=di).values
                if not np.all(np.isfinite(e)):
                    continue
                p = (ab.sel(layout=layout, metric=metric).predicted_accommodation
                     .isel(depth=di).values)
                a = av.sel(layout=layout, metric=metric).isel(depth=di)
                rows.append(dict(
                    layout=str(layout), depth_D=float(ds.depth[di]),
                    depth_rel_cdp_D=float(ds.depth_rel_cdp[di]), metric=metric,
                    n_eyes=int(e.size),
                    mean_predicted_accommodation_D=float(np.mean(p)),
                    mean_error_D=float(np.mean(e)),
                    sd_error_D=float(np.std(e, ddof=1)) if e.size > 1 else 0.0,
                    min_error_D=float(np.min(e)), max_error_D=float(np.max(e)),
                    average_eye_predicted_accommodation_D=float(a.predicted_accommodation),
                    average_eye_error_D=float(a.accommodation_error),
                ))
    return pd.DataFrame(rows)


def cutoff_table(ds):
    """Per layout × depth: cut-off frequency (MTF threshold) at the VSOTF-predicted
    accommodation, mean ± SD of the aberrated eyes and the average eye (cpd)."""
    import pandas as pd

    ab, av = aberrated(ds), average(ds)
    rows = []
    for layout in ds.layout.values:
        for di in range(ds.depth.size):
            c = ab.sel(layout=layout, metric="vsotf").cutoff_frequency.isel(depth=di).values
            if not np.all(np.isfinite(c)):
                continue
            a = float(av.sel(layout=layout, metric="vsotf").cutoff_frequency.isel(depth=di))
            rows.append(dict(
                layout=str(layout), depth_D=float(ds.depth[di]),
                depth_rel_cdp_D=float(ds.depth_rel_cdp[di]), n_eyes=int(c.size),
                mean_cutoff_cpd=float(np.mean(c)),
                sd_cutoff_cpd=float(np.std(c, ddof=1)) if c.size > 1 else 0.0,
                min_cutoff_cpd=float(np.min(c)), max_cutoff_cpd=float(np.max(c)),
                average_eye_cutoff_cpd=a,
                threshold=float(ds.attrs.get("config_cutoff_threshold", 0.05)),
            ))
    return pd.DataFrame(rows)


def claims_table(claims: list[Claim]):
    import pandas as pd

    return pd.DataFrame([dict(id=c.id, finding=c.finding, criterion=c.criterion, result=c.result,
                              verdict=c.verdict, **_settling(c)) for c in claims])


def _settling(claim: Claim) -> dict:
    """The table columns saying whether the numbers settle a verdict: the layouts it turns
    on within the planned spectrum's error (``unsettled_layouts``) and those computed
    again at the reference spectrum to settle it (``reference_layouts``), space-separated."""
    return dict(unsettled_layouts=" ".join(claim.unsettled),
                reference_layouts=" ".join(claim.reference_layouts))


def _marked(claim: Claim, text: str) -> str:
    """``text`` (a verdict) marked † when the planned spectrum leaves it unsettled and ‡
    when it was settled at the reference spectrum."""
    return text + ("†" if claim.unsettled else "‡" if claim.reference_layouts else "")


def alternatives_table(baseline: list[Claim], alternatives: dict):
    """Verdict per claim and variant, with ``flips`` against the reduced baseline."""
    import pandas as pd

    rows = []
    ref = {c.id: c.verdict for c in alternatives.get("baseline (reduced)", baseline)}
    full = {c.id: c.verdict for c in baseline}
    for variant, claims in alternatives.items():
        for c in claims:
            rows.append(dict(variant=variant, claim=c.id, verdict=c.verdict,
                             flips_vs_reduced_baseline=c.verdict != ref.get(c.id),
                             full_study_verdict=full.get(c.id), result=c.result,
                             **_settling(c)))
    return pd.DataFrame(rows)


# ----------------------------------------------------------------------------- report


def _md_escape(text: str) -> str:
    return str(text).replace("|", "\\|").replace("\n", " ")


def _spectral_rule_text(layout_ds) -> str:
    """A layout's spectral rule in words: "uniform, 20 nm steps (16 λ)", "V(λ)-weighted
    Gauss rule (8 λ)", or "not recorded"."""
    rule = str(layout_ds.spectral_rule.values) if "spectral_rule" in layout_ds else "uniform"
    count = int(layout_ds.n_wavelengths) if "n_wavelengths" in layout_ds else None
    nodes = f" ({count} λ)" if count is not None else ""
    if rule == "gauss":  # a Gauss rule has no step: its nodes are not evenly spaced
        return f"V(λ)-weighted Gauss rule{nodes}"
    if "wavelength_step_nm" not in layout_ds or not np.isfinite(
            float(layout_ds.wavelength_step_nm)):
        return "not recorded"
    return f"uniform, {float(layout_ds.wavelength_step_nm):g} nm steps{nodes}"


def _settling_note(claims: list[Claim], alternatives: dict) -> str:
    """The paragraph under the claims explaining † and ‡ (see :mod:`lfjax.reproduce.settling`)."""
    where = [("the study", claims)] + [(f"`{v}`", found) for v, found in alternatives.items()]
    unsettled = [f"claim {c.id} in {name} (turns on {', '.join(c.unsettled)})"
                 for name, found in where for c in found if c.unsettled]
    settled = [f"claim {c.id} in {name} ({', '.join(c.reference_layouts)})"
               for name, found in where for c in found if c.reference_layouts and not c.unsettled]
    text = ("Each layout's spectrum is planned for the peaks and cut-offs the claims read. A "
            "verdict whose numbers lie closer to its threshold than that spectrum's error "
            "(lfjax.vision.claim_margins) is the spectrum's, not the model's.")
    if unsettled:
        text += (" † Unsettled: " + "; ".join(unsettled) + ". The reference spectrum "
                 "(`--accuracy vsotf`) may give the other verdict; `--settle-verdicts` computes "
                 "the layouts named at the reference spectrum and reports its verdict.")
    if settled:
        text += (" ‡ Settled at the reference spectrum (`--settle-verdicts`): "
                 + "; ".join(settled) + ": those layouts' numbers are the reference's.")
    return text


def write_report(path: Path, ds, claims, alternatives, config: StudyConfig, timings: dict,
                 files: list[str], population_markdown: str | None = None,
                 display_markdown: str | None = None) -> None:
    """REPORT.md: claims with numbers and verdicts, modelling-choice flips, settings.

    ``population_markdown``: body of the section "What ten eyes cannot tell" (from a
    population sweep, :func:`lfjax.reproduce.population_section`); None leaves it out."""
    lines = (_study_section(ds, config) + _claims_section(claims, alternatives)
             + _modelling_section(claims, alternatives, config)
             + _added_sections(display_markdown, population_markdown)
             + _method_notes(config) + _settings_section(ds, config, timings)
             + _files_section(files))
    path.write_text("\n".join(lines) + "\n")


def _study_section(ds, config: StudyConfig) -> list[str]:
    """The title and the study in one paragraph (eyes, pupil, CDP, layouts, depths, the
    accommodation grid, the spectrum)."""
    lines: list[str] = []
    add = lines.append
    add("# Reproduction of Miyanishi, Sahin & Gotchev with lfjax")
    add("")
    n_ab = int((~ds.is_average).sum())
    add(f"Study: {n_ab} virtual eyes (Thibos et al. 2002, seed {config.seed}) plus the average "
        f"eye; {config.pupil_diameter_mm:g} mm pupil; CDP at {config.cdp_D:g} D; layouts "
        f"{', '.join(ds.layout.values)}; rendered depths "
        f"{', '.join(f'{d:+.1f}' for d in ds.depth_rel_cdp.values)} D relative to the CDP; "
        f"accommodation grid 0–{config.accommodation_max_D:g} D in "
        f"{config.accommodation_step_D:g} D steps, each depth evaluated within "
        f"±{config.window_D:g} D (and ≥ 0 D); "
        f"{config.wavelengths_nm[0]:g}–{config.wavelengths_nm[1]:g} nm "
        + (f"in {config.wavelengths_nm[2]:g} nm steps (`--accuracy vsotf`)"
           if config.accuracy == "vsotf" else
           f"with each layout's wavelength step planned for peaks to "
           f"{config.peak_tolerance_D:g} D and cut-offs to {config.cutoff_tolerance_cpd:g} cpd "
           f"(`--accuracy claims`; steps under Settings)")
        + f", λ_ref {config.options.lca_reference_nm:g} nm. Configuration: `{config.label}`.")
    if config.label == "quick":
        add("")
        add("**This is the `--quick` run**: few eyes, depths, wavelengths and a coarse "
            "accommodation grid. Its numbers test the pipeline, not the paper; run "
            "`lfjax reproduce` without `--quick` for the reproduction.")
    add("")
    return lines


def _claims_section(claims, alternatives) -> list[str]:
    """"Claims": each finding with its criterion, the number reproduced and the verdict."""
    lines: list[str] = []
    add = lines.append
    add("## Claims")
    add("")
    add("Each finding of the paper is restated as a claim with an explicit criterion, checked "
        "on this run. Predicted accommodation is the grid peak of the metric (as in the paper); "
        "errors are predicted accommodation minus rendered depth (negative: focused farther).")
    add("")
    add("| # | finding | criterion | reproduced | verdict |")
    add("|---|---|---|---|---|")
    for c in claims:
        add(f"| {c.id} | {_md_escape(c.finding)} | {_md_escape(c.criterion)} | "
            f"{_md_escape(c.result)} | **{_marked(c, c.verdict)}** |")
    add("")
    everything = list(claims) + [c for found in alternatives.values() for c in found]
    if any(c.unsettled or c.reference_layouts for c in everything):
        add(_settling_note(claims, alternatives))
        add("")
    return lines


def _modelling_section(claims, alternatives, config: StudyConfig) -> list[str]:
    """"Modelling choices": the claims under each alternative, and the verdicts that flip
    against the reduced baseline."""
    lines: list[str] = []
    add = lines.append
    add("## Modelling choices")
    add("")
    if alternatives:
        red = config.reduced()
        add("The paper leaves some modelling choices open (lfjax's design notes: "
            "docs/design.md#modelling-choices in the lfjax project). Each alternative was "
            "run on a reduced set — the same eyes and accommodation grid, rendered depths "
            f"{', '.join(f'{d:+.0f}' for d in red.depth_offsets_D)} D relative to the CDP, "
            + (f"{red.wavelengths_nm[2]:g} nm wavelength steps" if config.accuracy == "vsotf"
               else "each layout's planned wavelengths")
            + " — next to a baseline on the same "
            "set; a verdict in bold differs from that baseline (the choice changes the "
            "conclusion).")
        add("")
        variants = list(alternatives)
        add("| claim | full study | " + " | ".join(variants) + " |")
        add("|---|---|" + "---|" * len(variants))
        base = {c.id: c.verdict for c in alternatives.get("baseline (reduced)", claims)}
        for c in claims:
            cells = []
            for v in variants:
                other = next(x for x in alternatives[v] if x.id == c.id)
                verdict = _marked(other, other.verdict)
                cells.append(f"**{verdict}**" if other.verdict != base.get(c.id) else verdict)
            add(f"| {c.id} | {_marked(c, c.verdict)} | " + " | ".join(cells) + " |")
        add("")
        flips = [(v, x.id) for v in variants for x in alternatives[v]
                 if x.verdict != base.get(x.id)]
        if flips:
            add("Conclusions that change with a modelling choice: "
                + "; ".join(f"claim {cid} under `{v}`" for v, cid in flips) + ".")
        else:
            add("No conclusion changes with these modelling choices on the reduced set.")
        red_vs_full = [c.id for c in claims if base.get(c.id) != c.verdict]
        if red_vs_full:
            add("")
            add("The reduced baseline itself differs from the full study for claim(s) "
                f"{', '.join(red_vs_full)}: those verdicts depend on the sampling of depths or "
                "wavelengths, so read their flips with care.")
        add("")
        add("Numbers behind each verdict: `alternatives.csv`.")
    else:
        add("Not run (`--quick` or `--no-alternatives`). The full run checks the claims under "
            "`ModelOptions(sce=\"intensity\")`, `accommodation_sa=\"wavefront_5mm\"`, "
            "`accommodation_sa=\"unscaled\"`, `lca_A=633.46` and "
            "`wavelength_normalisation=\"unit_sum\"` (ISETBio's per-wavelength PSF "
            "normalisation).")
    add("")
    return lines


def _added_sections(display_markdown: str | None, population_markdown: str | None) -> list[str]:
    """"Beyond the ideal display" and "What ten eyes cannot tell", when given."""
    lines: list[str] = []
    add = lines.append
    if display_markdown:
        add("## Beyond the ideal display")
        add("")
        add(display_markdown.rstrip())
        add("")
        add("Figures: `display_effects.png`, `display_lenslet_sweep.png`; numbers: "
            "`display_effects.csv`, `display_lenslet_sweep.csv`.")
        add("")
    if population_markdown:
        add("## What ten eyes cannot tell")
        add("")
        add(population_markdown.rstrip())
        add("")
    return lines


def _method_notes(config: StudyConfig) -> list[str]:
    """"Notes on the method": the window, the grid, the references and the cut-off."""
    lines: list[str] = []
    add = lines.append
    add("## Notes on the method")
    add("")
    add(f"- Accommodation window: the paper does not state its through-focus range. Here each "
        f"rendered depth sees the states within ±{config.window_D:g} D of it, which contains "
        "the CDP for every rendered depth, so the Strehl ratio can peak at the CDP (claim 3). "
        "States below 0 D are excluded (hyperopic limit), so at the 0 D depth no error can be "
        "negative; the shared grid stops at "
        f"{config.accommodation_max_D:g} D, which clips the range of the nearest depths.")
    add("- The accommodation grid is absolute (0, 0.2, 0.4 … D): rendered depths at half "
        "dioptres fall between grid states, so their errors are odd multiples of 0.1 D. "
        "The sub-grid (parabolic) peak is in `accommodation_predictions.csv` for reference.")
    add("- VSOTF and Strehl reference: the same layout, aberration-free, focused and rendered on "
        "the CDP, accommodation SA and LCA kept "
        f"(`vsotf_reference={config.options.vsotf_reference!r}`).")
    add(f"- Cut-off frequency: first frequency where the radial MTF at the VSOTF-predicted "
        f"accommodation falls to {config.cutoff_threshold:g}, on each layout's own frequency grid.")
    add("")
    return lines


def _settings_section(ds, config: StudyConfig, timings: dict) -> list[str]:
    """"Settings": each layout's sampling and spectrum, the model options and the timings."""
    lines: list[str] = []
    add = lines.append
    add("## Settings")
    add("")
    add("| layout | subapertures | frequency step (cpd) | PSF field (arcmin) | FFT size | "
        "PSF transform | wavelengths | time (s) |")
    add("|---|---|---|---|---|---|---|---|")
    # a Dataset assembled elsewhere (the sweep's study view) may record no sampling per layout
    samplings = json.loads(ds.attrs.get("sampling_json", "{}"))
    for name in ds.layout.values:
        s = ds.sel(layout=name)
        sampling = samplings.get(str(name))
        transform = ("not recorded" if sampling is None
                     else "FFT (pupil step λ·Δf)" if sampling.get("transform", "fft") == "fft"
                     else f"MFT ({sampling.get('mft_pupil_samples')} pupil samples)")
        add(f"| {name} | {int(s.n_subapertures)} | {float(s.freq_step_cpd):g} | "
            f"{60.0 / float(s.freq_step_cpd):.1f} | {int(s.n_fft)} | {transform} | "
            f"{_spectral_rule_text(s)} | {float(s.compute_seconds):.1f} |")
    add("")
    add("Model options (`lfjax.ModelOptions`):")
    add("")
    add("```")
    for key, value in config.options.as_dict().items():
        add(f"{key} = {value!r}")
    add("```")
    add("")
    add("Timings (s, wall clock, including compilation): "
        + ", ".join(f"{k} {v:.1f}" for k, v in timings.items()) + ".")
    add("")
    return lines


def _files_section(files: list[str]) -> list[str]:
    """"Files": every file written."""
    lines: list[str] = []
    add = lines.append
    add("## Files")
    add("")
    for f in files:
        add(f"- `{f}`")
    return lines



__all__ = [
    "TABLES",
    "alternatives_table",
    "claims_table",
    "cutoff_table",
    "prediction_table",
    "summary_table",
    "write_report",
]
