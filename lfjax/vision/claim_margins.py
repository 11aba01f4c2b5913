"""How far a study's numbers may move, and which verdicts such moves can change.

A study computed on a planned spectrum (a Gauss rule for V(λ) with few nodes) differs from
the reference spectrum by small amounts: continuous peaks by up to the plan's peak target,
cut-offs by up to its cut-off target, the MTF by a fraction of a percent. A claim whose
criterion sits further than that from every threshold has the same verdict on either
spectrum. One that sits closer does not: its verdict is the spectrum's, not the model's.

This module holds the ranges: :class:`Resolution` (how far each number may move), the
values a grid peak may take (:func:`vsotf_peaks`, :func:`strehl_peaks`), and the two ways
a claim's possible outcomes are turned into the layouts that decide it (:func:`deciding`,
:func:`counted`). Each claim (:mod:`lfjax.vision.claims_accommodation`,
:mod:`lfjax.vision.claims_resolution`) applies its own thresholds to these ranges in its
``undecided`` method; :func:`lfjax.vision.claims.undecided_layouts` collects them.

Host-side NumPy on :class:`lfjax.vision.claim_core.StudyNumbers`; milliseconds.
"""

from __future__ import annotations

import dataclasses
import itertools
from dataclasses import dataclass

import numpy as np

from lfjax.vision.claim_core import StudyNumbers


@dataclass(frozen=True)
class Resolution:
    """How far a planned spectrum's numbers may lie from the reference spectrum's, for each
    number the claims read (a claim reads means over the aberrated eyes, or one eye).

    The defaults hold the largest differences measured between the study's Gauss rules and
    the 20 nm reference on the reduced set under every modelling alternative, with a margin
    (benchmarks/RESULTS.md §33); they are measured, not guaranteed, bounds.

    Attributes
    ----------
    vertex_D : float, D
        One eye's parabola vertex through its VSOTF grid peak (measured ≤ 0.013 D): a vertex
        closer than this to the mid-point between two states may put the reference's grid
        peak on the other state.
    mean_peak_D : float, D
        Mean continuous VSOTF peak over the eyes (measured ≤ 0.0032 D).
    strehl_gap : float
        One eye's Strehl ratio: a state within two steps of its Strehl peak whose value is
        within this of the peak's may be the reference's peak (measured: every Strehl peak
        that moved had a gap ≤ 0.016).
    mtf_ratio : float
        Mean MTF over 0–60 cpd of the average eye divided by the aberrated eyes' mean, at
        the VSOTF peaks (measured ≤ 0.0037).
    mean_cutoff_cpd : float, cpd
        Mean cut-off frequency over the eyes at their VSOTF peaks (measured ≤ 0.082 cpd).
    """

    vertex_D: float = 0.02
    mean_peak_D: float = 0.005
    strehl_gap: float = 0.025
    mtf_ratio: float = 0.005
    mean_cutoff_cpd: float = 0.12

    def __post_init__(self):
        for f in dataclasses.fields(self):
            value = getattr(self, f.name)
            if not (isinstance(value, (int, float)) and np.isfinite(value) and value >= 0):
                raise ValueError(f"Resolution.{f.name} must be a finite number >= 0, got {value!r}")


# ----------------------------------------------------------------------------- the numbers


def vsotf_peaks(s: StudyNumbers, r: Resolution, li: int, eye: int, di: int) -> list[float]:
    """The states (D) the reference's VSOTF grid peak may take: the plan's, and its
    neighbour when the parabola's vertex lies within ``r.vertex_D`` of their mid-point.
    A Dataset without the through-focus curves (a sweep's study view) cannot say which grid
    peaks may move: only the plan's state then."""
    p = s.pred[li, eye, di, 0]
    if not np.isfinite(p):
        return []
    out = [float(p)]
    offset = s.vertex[li, eye, di] - p
    if np.isfinite(offset) and abs(offset) > 0.5 * s.step - r.vertex_D:
        i = int(np.argmin(np.abs(s.acc - p))) + (1 if offset > 0 else -1)
        if 0 <= i < s.acc.size and (s.strehl is None or np.isfinite(s.strehl[li, eye, di, i])):
            out.append(float(s.acc[i]))
    return out


def strehl_peaks(s: StudyNumbers, r: Resolution, li: int, eye: int, di: int) -> list[float]:
    """The states (D) the reference's Strehl grid peak may take: the plan's, and any
    state within two steps whose value is within ``r.strehl_gap`` of the peak's."""
    p = s.pred[li, eye, di, 1]
    if not np.isfinite(p):
        return []
    if s.strehl is None:
        return [float(p)]
    v = s.strehl[li, eye, di]
    i = int(np.argmin(np.abs(s.acc - p)))
    near = range(max(0, i - 2), min(v.size, i + 3))
    return [float(p)] + [float(s.acc[j]) for j in near
                         if j != i and np.isfinite(v[j]) and v[j] >= v[i] - r.strehl_gap]


def mean_range(per_eye_options) -> tuple[float, float]:
    """Smallest and largest mean over eyes, each eye taking any of its values."""
    return (float(np.mean([min(o) for o in per_eye_options])),
            float(np.mean([max(o) for o in per_eye_options])))


def plain_mean_cutoffs(s: StudyNumbers, name: str) -> np.ndarray:
    """(depth,) mean VSOTF cut-off of the aberrated eyes (cpd); NaN where any eye is NaN
    (a cut-off missing anywhere leaves the margin undecided, not skipped)."""
    return np.mean(s.cutoff[s.li(name)][s.eyes][..., 0], axis=0)


# ----------------------------------------------------------------------------- outcomes


def deciding(possible: dict, verdict) -> set[str]:
    """Layouts whose possible values change ``verdict`` (a function of one value per
    layout, in ``possible``'s order): empty when every combination gives one verdict."""
    names = list(possible)
    outcomes = {combo: verdict(combo)
                for combo in itertools.product(*(sorted(possible[n], key=repr) for n in names))}
    if len(set(outcomes.values())) <= 1:
        return set()
    out = set()
    for k, name in enumerate(names):
        seen: dict = {}
        for combo, v in outcomes.items():
            seen.setdefault(combo[:k] + combo[k + 1:], set()).add(v)
        if any(len(v) > 1 for v in seen.values()):
            out.add(name)
    # a verdict only a joint move changes: every layout that can move is needed
    return out or {n for n in names if len(possible[n]) > 1}


def counted(cells: list, enough) -> set[str]:
    """Claims that hold when enough of their cells do. ``cells``: (layout, possible
    outcomes of the cell); ``enough(fraction)``: the claim's test of the fraction of cells
    that hold. The layouts of the undecided cells when those decide."""
    total = len(cells)
    if not total:
        return set()
    sure = sum(1 for _, o in cells if o == {True})
    unsure = [name for name, o in cells if len(o) > 1]
    verdicts = {enough((sure + k) / total) for k in (0, len(unsure))}
    return set(unsure) if len(verdicts) > 1 else set()


def cells(s: StudyNumbers, outcomes) -> list:
    """(layout, possible outcomes) of every (layout, depth) cell of a claim counted over
    cells; ``outcomes(li, di)`` gives a cell's set of possible outcomes, or None to skip it."""
    found_cells = []
    for name in s.layouts:
        for di in range(s.rel.size):
            found = outcomes(s.li(name), di)
            if found is not None:
                found_cells.append((name, found))
    return found_cells


__all__ = [
    "Resolution",
    "cells",
    "counted",
    "deciding",
    "mean_range",
    "plain_mean_cutoffs",
    "strehl_peaks",
    "vsotf_peaks",
]
