"""The paper's findings (1)–(7) as claims: the registry, and the readings derived from it.

Each claim is declared once, as a frozen :class:`~lfjax.vision.claim_core.ClaimRule` in
:mod:`lfjax.vision.claims_accommodation` (1–4) or :mod:`lfjax.vision.claims_resolution`
(5–7), with its finding, criterion and thresholds. :data:`CLAIMS` lists the seven; from it

* :func:`evaluate_claims` gives every claim's verdict on a study Dataset (written by
  :func:`lfjax.reproduce.study.run_study`, or read from a sweep store by
  :func:`lfjax.sweep.store.study_view`);
* :func:`undecided_layouts` gives the claims whose verdict the spectrum's error could
  change (:mod:`lfjax.vision.claim_margins` holds the ranges);
* the population sweep's ten-eye check (:mod:`lfjax.sweep.ten_eyes`) evaluates them on
  samples of eyes (:meth:`~lfjax.vision.claim_core.StudyNumbers.take_eyes`).

:func:`aberrated` and :func:`average` select the sampled eyes and the average eye of a
Dataset. Shared by the reproduction (:mod:`lfjax.reproduce`) and the sweep, so it lives
below both: it reads the Dataset only, and imports nothing of either.
"""

from __future__ import annotations

from lfjax.vision.claim_core import Claim, ClaimRule, StudyNumbers
from lfjax.vision.claim_margins import Resolution
from lfjax.vision.claims_accommodation import (AverageEyePredictsMean, NaturalView,
                                               SmallNegativeConstant, StrehlAgrees)
from lfjax.vision.claims_resolution import AverageEyeSharper, CutoffFalls, DepthOfFieldGrows

CLAIMS: tuple[ClaimRule, ...] = (
    NaturalView(),
    SmallNegativeConstant(),
    StrehlAgrees(),
    AverageEyePredictsMean(),
    AverageEyeSharper(),
    DepthOfFieldGrows(),
    CutoffFalls(),
)
"""The paper's seven claims, in the paper's order (ids "1"–"7")."""


def aberrated(ds):
    """The sampled (aberrated) eyes of a study Dataset: every eye but the average eye."""
    return ds.sel(eye=~ds.is_average.values)


def average(ds):
    """The average eye of a study Dataset (its eye axis dropped)."""
    return ds.sel(eye=ds.is_average.values).isel(eye=0)


def _numbers(ds_or_numbers) -> StudyNumbers:
    s = (ds_or_numbers if isinstance(ds_or_numbers, StudyNumbers)
         else StudyNumbers.from_dataset(ds_or_numbers))
    if s.avg is None:
        raise ValueError("ds: the study has no average eye (is_average all False); claims 1, "
                         "4, 5 and 7 compare against it")
    return s


def evaluate_claims(ds, dof_fraction: float | None = None) -> list[Claim]:
    """The paper's findings (1)–(7) checked on a study Dataset (or its
    :class:`~lfjax.vision.claim_core.StudyNumbers`), each with its criterion.

    ``dof_fraction``: claim 6's fraction of the best cut-off (default: the Dataset's
    ``config_dof_fraction`` attribute, else 0.8).

    A claim's ``holds`` is None (verdict "n/a") when the Dataset cannot decide it: a part
    of its criterion needs data that are absent (no natural view, no LF layouts, no 2x2
    depth beyond +-1 D, no depth > 0 D, fewer than 2 LF layouts or 3 depths, no cell with
    an average-eye value) or not finite, or a depth of field reaching the end of the
    sampled depths (a lower bound) would have to win a comparison. A part that fails
    still makes the claim fail."""
    s = _numbers(ds)
    frac = s.dof_fraction(dof_fraction)
    return [rule.evaluate(s, frac) for rule in CLAIMS]


def undecided_layouts(ds, resolution: Resolution = Resolution(),  # noqa: B008 (frozen)
                      dof_fraction: float | None = None) -> dict[str, tuple[str, ...]]:
    """{claim id: layouts} for each claim of :data:`CLAIMS` whose verdict on ``ds`` could
    change if the numbers it reads moved within ``resolution``: the layouts whose numbers
    can change it (computed again at the reference spectrum, they decide the claim as the
    reference would). Claims the numbers decide are absent.

    ``ds``: a study Dataset (:func:`lfjax.reproduce.study.run_study`); without its
    through-focus curves (``strehl``, ``predicted_accommodation_parabolic``) no grid peak is
    taken to move. Milliseconds.
    """
    s = StudyNumbers.from_dataset(ds)
    frac = s.dof_fraction(dof_fraction)
    found = {rule.id: rule.undecided(s, resolution, frac) for rule in CLAIMS}
    return {claim: tuple(n for n in s.layouts if n in names)
            for claim, names in found.items() if names}


__all__ = [
    "CLAIMS",
    "aberrated",
    "average",
    "evaluate_claims",
    "undecided_layouts",
]
