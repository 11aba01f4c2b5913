"""The modelling alternatives: choices the paper leaves open, and the claims under each.

``ALTERNATIVES`` names each choice as a :class:`~lfjax.ModelOptions` change;
:func:`run_alternatives` reruns the study on :meth:`StudyConfig.reduced
<lfjax.reproduce.config.StudyConfig.reduced>` under each of them (and a baseline on the
same reduced set) and evaluates the claims.

Imports :mod:`~lfjax.reproduce.config` and :mod:`~lfjax.reproduce.study` from the package,
and the claims from :mod:`lfjax.claims`.
"""

from __future__ import annotations

from ..claims import evaluate_claims
from .config import StudyConfig
from .study import run_study

ALTERNATIVES: dict[str, dict] = {
    "sce=intensity": {"sce": "intensity"},
    "accommodation_sa=wavefront_5mm": {"accommodation_sa": "wavefront_5mm"},
    "accommodation_sa=unscaled": {"accommodation_sa": "unscaled"},
    "lca_A=633.46": {"lca_A": 633.46},
    "wavelength_normalisation=unit_sum": {"wavelength_normalisation": "unit_sum"},
}
"""Modelling choices the paper leaves open (docs/design.md#modelling-choices), as ``ModelOptions`` changes."""


def run_alternatives(config: StudyConfig, stage=None) -> dict:
    """Claims under each modelling-choice alternative on :meth:`StudyConfig.reduced`.

    Returns {variant: list[Claim]} with a ``"baseline (reduced)"`` entry computed on the
    same reduced set first.
    """
    reduced = config.reduced()
    results = {}
    variants = {"baseline (reduced)": {}} | ALTERNATIVES
    for name, change in variants.items():
        options = config.options.replace(**change)

        def sub_stage(layout, _name=name):
            if stage is not None:
                stage(f"alternative {_name}: {layout}")

        ds = run_study(reduced.replace(options=options), options, stage=sub_stage)
        results[name] = evaluate_claims(ds, config.dof_fraction)
    return results


__all__ = [
    "ALTERNATIVES",
    "run_alternatives",
]
