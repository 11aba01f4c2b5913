"""Verdicts the planned spectrum cannot settle, and settling them at the reference spectrum.

The study's default spectrum is planned per layout for its peaks and cut-offs
(``accuracy="claims"``: a Gauss rule for V(λ) with few nodes). A claim whose numbers sit
closer to its threshold than that spectrum's error is decided by the spectrum, not the
model: the reference spectrum (``accuracy="vsotf"``'s uniform steps) may give the other
verdict. :func:`mark_unsettled` records such claims (:attr:`Claim.unsettled
<lfjax.vision.claim_core.Claim.unsettled>`, from :func:`lfjax.vision.claims.undecided_layouts`);
:func:`settle` computes the layouts they turn on again at the reference spectrum and puts
them in place (:func:`~lfjax.reproduce.study.replace_layouts`), so that the claim's verdict
is the reference's.

Imports :mod:`~lfjax.reproduce.config` and :mod:`~lfjax.reproduce.study` from the package.
"""

from __future__ import annotations

import json
from concurrent.futures import ThreadPoolExecutor

from lfjax.base.programs import in_callers_jax_context
from lfjax.model.options import ModelOptions
from lfjax.reproduce.config import StudyConfig
from lfjax.reproduce.study import layout_workers, replace_layouts, run_study_variants
from lfjax.vision.claim_core import Claim
from lfjax.vision.claim_margins import Resolution
from lfjax.vision.claims import evaluate_claims, undecided_layouts


def reference_layouts(ds) -> tuple[str, ...]:
    """Layouts of a study Dataset computed at the reference spectrum by :func:`settle`."""
    return tuple(json.loads(ds.attrs.get("reference_layouts_json", "[]")))


def mark_unsettled(claims: list[Claim], ds, resolution: Resolution = Resolution()  # noqa: B008
                   ) -> list[Claim]:
    """``claims`` (of ``ds``) with :attr:`~lfjax.vision.claim_core.Claim.unsettled` (the layouts
    whose numbers, within ``resolution``, could change the verdict, less those already at
    the reference spectrum) and :attr:`~lfjax.vision.claim_core.Claim.reference_layouts` set.
    A study at ``accuracy="vsotf"`` is the reference: nothing is unsettled."""
    if ds.attrs.get("accuracy_plan") == "vsotf":
        return claims
    found = undecided_layouts(ds, resolution)
    done = reference_layouts(ds)
    for claim in claims:
        turns_on = found.get(claim.id, ())
        claim.unsettled = tuple(n for n in turns_on if n not in done)
        claim.reference_layouts = tuple(n for n in turns_on if n in done)
    return claims


def settle(datasets: dict, options: dict[str, ModelOptions], reference: StudyConfig,
           dof_fraction: float, claims: dict | None = None,
           resolution: Resolution = Resolution(), workers: int | None = None,  # noqa: B008
           stage=None) -> tuple[dict, dict]:
    """Settle each Dataset's unsettled claims at the reference spectrum.

    ``datasets``: {name: study Dataset}; ``options``: {name: its ModelOptions};
    ``reference``: the configuration whose numbers are the reference (``accuracy="vsotf"``
    on the same depths, eyes and states); ``claims``: {name: list[Claim]} already evaluated
    (else evaluated here). Each layout some claim turns on is computed for every Dataset
    that needs it, in one batch per layout (layouts in threads, :func:`layout_workers`),
    and put in place; the claims are then evaluated again (a second round if the new
    numbers leave another layout unsettled). Returns ({name: Dataset}, {name: claims}).
    """
    datasets = dict(datasets)
    claims = {name: mark_unsettled(claims[name] if claims and name in claims
                                   else evaluate_claims(ds, dof_fraction), ds, resolution)
              for name, ds in datasets.items()}
    for _ in range(2):
        need: dict[str, list[str]] = {}  # layout → Datasets that need it
        for name, found in claims.items():
            for layout in sorted({n for c in found for n in c.unsettled}):
                need.setdefault(layout, []).append(name)
        if not need:
            break

        def one_layout(layout):
            if stage is not None:
                stage(f"settling: {layout}")
            return layout, run_study_variants(
                reference.replace(layouts=(layout,)),
                {name: options[name] for name in need[layout]}, workers=1)

        order = [n for n in reference.layouts if n in need]
        n_workers = layout_workers(workers, len(order))
        if n_workers == 1:
            results = [one_layout(layout) for layout in order]
        else:
            with ThreadPoolExecutor(n_workers, thread_name_prefix="lfjax-settle") as pool:
                results = list(pool.map(in_callers_jax_context(one_layout), order))
        changed = set()
        for _, computed in results:
            for name, ref in computed.items():
                datasets[name] = replace_layouts(datasets[name], ref)
                changed.add(name)
        for name in changed:
            claims[name] = mark_unsettled(evaluate_claims(datasets[name], dof_fraction),
                                          datasets[name], resolution)
    return datasets, claims


__all__ = ["mark_unsettled", "reference_layouts", "settle"]
