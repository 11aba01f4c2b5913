"""The modelling alternatives: choices the paper leaves open, and the claims under each.

``ALTERNATIVES`` names each choice as a :class:`~lfjax.ModelOptions` change;
:func:`run_alternatives` reruns the study on :meth:`StudyConfig.reduced
<lfjax.reproduce.config.StudyConfig.reduced>` under each of them (and a baseline on the
same reduced set) and evaluates the claims. Every alternative changes only numbers of the
model (:class:`~lfjax.model.options.ModelParameters`), so each layout's baseline and
alternatives run as one compiled program over their stacked parameters
(:func:`~lfjax.reproduce.study.run_study_variants`).

Imports :mod:`~lfjax.reproduce.config` and :mod:`~lfjax.reproduce.study` from the package,
and the claims from :mod:`lfjax.vision.claims`.
"""

from __future__ import annotations

from lfjax.vision.claims import evaluate_claims
from lfjax.reproduce.config import StudyConfig
from lfjax.reproduce.study import run_study_variants

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


def run_alternatives(config: StudyConfig, stage=None, wavelength_steps_nm=None) -> dict:
    """Claims under each modelling-choice alternative on :meth:`StudyConfig.reduced`.

    ``wavelength_steps_nm``: {layout: step nm} to reuse (the main study's plan,
    :func:`~lfjax.reproduce.study.study_wavelength_steps`); else each layout's is planned.
    Returns {variant: list[Claim]} with a ``"baseline (reduced)"`` entry computed on the
    same reduced set first.
    """
    reduced = config.reduced(wavelength_steps_nm)
    variants = {name: config.options.replace(**change)
                for name, change in ({BASELINE: {}} | ALTERNATIVES).items()}

    def sub_stage(layout):
        if stage is not None:
            stage(f"alternatives: {layout}")

    datasets = run_study_variants(reduced, variants, stage=sub_stage)
    return {name: evaluate_claims(ds, config.dof_fraction) for name, ds in datasets.items()}


__all__ = [
    "ALTERNATIVES",
    "BASELINE",
    "run_alternatives",
]
