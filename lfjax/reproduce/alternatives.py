"""The modelling alternatives: choices the paper leaves open, and the claims under each.

``ALTERNATIVES`` names each choice as a :class:`~lfjax.ModelOptions` change;
:func:`run_alternatives` reruns the study on :meth:`StudyConfig.reduced
<lfjax.reproduce.config.StudyConfig.reduced>` under each of them (and a baseline on the
same reduced set) and evaluates the claims. Every alternative changes only numbers of the
model (:class:`~lfjax.model.options.ModelParameters`), so each layout's baseline and
alternatives run as one compiled program over their stacked parameters
(:func:`~lfjax.reproduce.study.run_study_variants`). The baseline is the main study's
own numbers on the reduced depths when the main study is given.

Imports :mod:`~lfjax.reproduce.config` and :mod:`~lfjax.reproduce.study` from the package,
and the claims from :mod:`lfjax.vision.claims`.
"""

from __future__ import annotations

import json

from lfjax.vision.claims import evaluate_claims
from lfjax.reproduce.config import StudyConfig
from lfjax.reproduce.settling import mark_unsettled, settle
from lfjax.reproduce.study import run_study_variants, study_wavelength_rules

ALTERNATIVES: dict[str, dict] = {
    "sce=intensity": {"sce": "intensity"},
    "accommodation_sa=wavefront_5mm": {"accommodation_sa": "wavefront_5mm"},
    "accommodation_sa=unscaled": {"accommodation_sa": "unscaled"},
    "lca_A=633.46": {"lca_A": 633.46},
    "wavelength_normalisation=unit_sum": {"wavelength_normalisation": "unit_sum"},
}
"""Modelling choices the paper leaves open (docs/design.md#modelling-choices), as ``ModelOptions`` changes."""

BASELINE = "baseline (reduced)"
"""Name of the baseline rerun on the reduced set, the first entry of :func:`run_alternatives`."""


def run_alternatives(config: StudyConfig, stage=None, wavelength_rules=None,
                     study=None, settle_stage=None) -> dict:
    """Claims under each modelling-choice alternative on :meth:`StudyConfig.reduced`.

    ``wavelength_rules``: {layout: (rule, value)} to reuse (the main study's plan,
    :func:`~lfjax.reproduce.study.study_wavelength_rules`); else each layout's is planned.
    ``study``: the main study's Dataset under ``config``. When it holds the reduced set
    (its depths include the reduced depths, with the same eyes, states, options and
    spectra), the baseline is read from it instead of computed again: each (eye, depth)'s
    numbers do not depend on which other depths are evaluated beside it.
    Each claim records the layouts its verdict turns on within the planned spectrum's
    error (:attr:`~lfjax.vision.claim_core.Claim.unsettled`); with
    ``config.settle_verdicts`` those layouts are computed again at the reference spectrum
    (:func:`~lfjax.reproduce.settling.settle`; ``settle_stage(name)`` is called as each
    starts) and the verdicts are the reference's.
    Returns {variant: list[Claim]} with a ``"baseline (reduced)"`` entry first.
    """
    reduced = config.reduced(wavelength_rules)
    baseline = _baseline_from_study(study, config, reduced, wavelength_rules)
    changes = ({} if baseline is not None else {BASELINE: {}}) | ALTERNATIVES
    variants = {name: config.options.replace(**change) for name, change in changes.items()}

    def sub_stage(layout):
        if stage is not None:
            stage(f"alternatives: {layout}")

    datasets = run_study_variants(reduced, variants, stage=sub_stage)
    if baseline is not None:
        datasets = {BASELINE: baseline} | datasets
    claims = {name: evaluate_claims(ds, config.dof_fraction) for name, ds in datasets.items()}
    if config.settle_verdicts and config.accuracy != "vsotf":
        options = {BASELINE: config.options} | variants
        datasets, claims = settle(datasets, options, config.reference().reduced(),
                                  config.dof_fraction, claims, stage=settle_stage)
        return claims
    return {name: mark_unsettled(found, datasets[name]) for name, found in claims.items()}


def _baseline_from_study(study, config: StudyConfig, reduced: StudyConfig, wavelength_rules):
    """The reduced set's baseline as a selection of the main ``study`` Dataset, or None when
    the study cannot stand for it (no study, or a depth, layout or spectrum the reduced set
    would compute differently)."""
    if study is None:
        return None
    if config.accuracy == "vsotf":
        same_spectra = reduced.wavelengths_nm == config.wavelengths_nm
    else:
        same_spectra = bool(wavelength_rules) and study_wavelength_rules(study) == {
            name: (rule, value) for name, rule, value in reduced.wavelength_rules}
    depths = {round(float(d), 9) for d in study.depth.values}
    wanted = {round(float(d), 9) for d in reduced.depths_D}
    if (not same_spectra or not wanted <= depths
            or list(study.layout.values) != list(reduced.layouts)
            or study.attrs.get("model_options_json") != json.dumps(config.options.as_dict())):
        return None
    return study.sel(depth=[float(d) for d in study.depth.values if round(float(d), 9) in wanted])


__all__ = [
    "ALTERNATIVES",
    "BASELINE",
    "run_alternatives",
]
