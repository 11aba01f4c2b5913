"""Which claims a study's numbers decide, and which they leave to the spectrum's error.

A study computed on a planned spectrum (a Gauss rule for V(λ) with few nodes) differs from
the reference spectrum by small amounts: continuous peaks by up to the plan's peak target,
cut-offs by up to its cut-off target, the MTF by a fraction of a percent. A claim whose
criterion sits further than that from every threshold has the same verdict on either
spectrum. One that sits closer does not: its verdict is the spectrum's, not the model's.

:func:`undecided_layouts` finds those claims. For each claim it lets every number the claim
reads take any value within :class:`Resolution` of the computed one (and a grid peak move to
a neighbouring state where the plan's error could move it there), and asks whether the
verdict can change. It returns, per claim whose verdict can, the layouts whose numbers can
change it: computing those layouts again at the reference spectrum decides the claim as
the reference would (:func:`lfjax.reproduce.alternatives.run_alternatives` does).

Host-side NumPy on the study Dataset (:func:`lfjax.reproduce.study.run_study`'s variables);
milliseconds. Imports :mod:`lfjax.vision.claims` only.
"""

from __future__ import annotations

import dataclasses
import itertools
from dataclasses import dataclass

import numpy as np

from lfjax.model.layouts import LF_LAYOUTS
from lfjax.vision.claims import all_of, compare_bounds, dof_D


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


class _Study:
    """The Dataset's numbers the claims read, as NumPy arrays (layout, eye, depth, ...)."""

    def __init__(self, ds, resolution: Resolution):
        self.r = resolution
        self.layouts = [str(n) for n in ds.layout.values]
        self.lf = [n for n in LF_LAYOUTS if n in self.layouts]
        self.rel = np.asarray(ds.depth_rel_cdp.values, float)
        self.depths = np.asarray(ds.depth.values, float)
        self.acc = np.asarray(ds.accommodation.values, float)
        self.step = float(self.acc[1] - self.acc[0]) if self.acc.size > 1 else 0.0
        is_avg = np.asarray(ds.is_average.values, bool)
        self.eyes = np.flatnonzero(~is_avg)
        self.avg = int(np.flatnonzero(is_avg)[0]) if np.any(is_avg) else None
        self.pred = np.asarray(ds.predicted_accommodation.values, float)
        # a Dataset without the through-focus curves (a sweep's study view) cannot say which
        # grid peaks may move: only the numbers themselves are moved then
        self.strehl = np.asarray(ds.strehl.values, float) if "strehl" in ds else None
        self.vertex = (np.asarray(ds.predicted_accommodation_parabolic.values, float)[..., 0]
                       if "predicted_accommodation_parabolic" in ds
                       else np.full(self.pred.shape[:-1], np.nan))
        self.cont = np.asarray(ds.predicted_accommodation_continuous.values, float)[..., 0]
        self.cutoff = np.asarray(ds.cutoff_frequency.values, float)[..., 0]
        fmask = np.asarray(ds.frequency.values, float) <= 60.0 + 1e-9
        self.area = np.mean(np.asarray(ds.mtf_at_peak.values, float)[..., 0, fmask], axis=-1)

    def li(self, name: str) -> int:
        return self.layouts.index(name)

    def vsotf_peaks(self, li: int, eye: int, di: int) -> list[float]:
        """The states (D) the reference's VSOTF grid peak may take: the plan's, and its
        neighbour when the parabola's vertex lies within ``vertex_D`` of their mid-point."""
        p = self.pred[li, eye, di, 0]
        if not np.isfinite(p):
            return []
        out = [float(p)]
        offset = self.vertex[li, eye, di] - p
        if np.isfinite(offset) and abs(offset) > 0.5 * self.step - self.r.vertex_D:
            i = int(np.argmin(np.abs(self.acc - p))) + (1 if offset > 0 else -1)
            if 0 <= i < self.acc.size and (self.strehl is None
                                             or np.isfinite(self.strehl[li, eye, di, i])):
                out.append(float(self.acc[i]))
        return out

    def strehl_peaks(self, li: int, eye: int, di: int) -> list[float]:
        """The states (D) the reference's Strehl grid peak may take: the plan's, and any
        state within two steps whose value is within ``strehl_gap`` of the peak's."""
        p = self.pred[li, eye, di, 1]
        if not np.isfinite(p):
            return []
        if self.strehl is None:
            return [float(p)]
        v = self.strehl[li, eye, di]
        i = int(np.argmin(np.abs(self.acc - p)))
        near = range(max(0, i - 2), min(v.size, i + 3))
        return [float(p)] + [float(self.acc[j]) for j in near
                             if j != i and np.isfinite(v[j]) and v[j] >= v[i] - self.r.strehl_gap]


def _mean_range(per_eye_options) -> tuple[float, float]:
    """Smallest and largest mean over eyes, each eye taking any of its values."""
    return (float(np.mean([min(o) for o in per_eye_options])),
            float(np.mean([max(o) for o in per_eye_options])))


def _deciding(possible: dict, verdict) -> set[str]:
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


def _counted(cells: list, fraction: float) -> set[str]:
    """Claims that hold when at least ``fraction`` of their cells do. ``cells``: (layout,
    possible outcomes of the cell). The layouts of the undecided cells when those decide."""
    total = len(cells)
    if not total:
        return set()
    sure = sum(1 for _, o in cells if o == {True})
    unsure = [name for name, o in cells if len(o) > 1]
    verdicts = {(sure + k) / total >= fraction for k in (0, len(unsure))}
    return set(unsure) if len(verdicts) > 1 else set()


# ----------------------------------------------------------------------------- the claims


def _claim1(s: _Study) -> set[str]:
    if "natural" not in s.layouts or not np.any(np.isclose(s.rel, 0.0)):
        return set()
    li, di = s.li("natural"), int(np.argmin(np.abs(s.rel)))
    options = [[p - s.depths[di] for p in s.vsotf_peaks(li, e, di)] for e in s.eyes]
    if any(not o for o in options):
        return set()
    # max |error| <= 0.2 D and -0.25 <= mean < 0 D, each eye's error any of its options:
    # the ranges of the largest |error| and of the mean bound both verdicts, for any number
    # of eyes (each eye's choice moves both, so this may flag a verdict only a choice
    # moving them apart could change: a flag too many, never one too few)
    largest = (max(min(abs(o) for o in opts) for opts in options),
               max(max(abs(o) for o in opts) for opts in options))
    mean_lo, mean_hi = _mean_range(options)
    can_hold = largest[0] <= 0.2 + 1e-6 and mean_hi >= -0.25 and mean_lo < 0
    can_fail = largest[1] > 0.2 + 1e-6 or mean_lo < -0.25 or mean_hi >= 0
    return {"natural"} if can_hold and can_fail else set()


def _claim2(s: _Study) -> set[str]:
    check = s.depths > 1e-9
    possible = {}
    for name in s.lf:
        e = np.mean(s.cont[s.li(name)][s.eyes], axis=0) - s.depths
        if not np.all(np.isfinite(e)):
            possible[name] = {None}
            continue
        p = s.r.mean_peak_D
        options = set()
        for shift in (-p, 0.0, p):  # the means move by up to p, their range by up to 2p
            for spread in (-2 * p, 0.0, 2 * p):
                small = np.max(np.abs(e)) + shift <= 0.25 + 1e-9
                constant = np.ptp(e) + spread <= 0.2 + 1e-9
                negative = bool(np.all(e[check] + shift < 0)) if np.any(check) else False
                if not (small and constant) or (np.any(check) and not negative):
                    options.add(False)
                else:
                    options.add(True if np.any(check) else None)
        possible[name] = options
    # a density the data lack leaves the claim at best undecided (evaluate_claims' rule)
    missing = [None] if any(n not in s.layouts for n in LF_LAYOUTS) else []
    return _deciding(possible, lambda combo: all_of(list(combo) + missing)) if possible else set()


def _claim3(s: _Study) -> set[str]:
    possible = {}
    for name in s.lf:
        li = s.li(name)
        cells = []
        for di, r in enumerate(s.rel):
            if name == "2x2" and abs(r) > 1.0 + 1e-9:
                continue
            vs = [s.vsotf_peaks(li, e, di) for e in s.eyes]
            if any(not o for o in vs):
                continue
            s_lo, s_hi = _mean_range([s.strehl_peaks(li, e, di) for e in s.eyes])
            v_lo, v_hi = _mean_range(vs)
            d_min = max(0.0, s_lo - v_hi, v_lo - s_hi)
            d_max = max(abs(s_hi - v_lo), abs(v_hi - s_lo))
            cells.append({d_min <= 0.2 + 1e-9, d_max <= 0.2 + 1e-9})
        agree = {all(c) for c in itertools.product(*cells)} if cells else {True}
        far_part = {None}
        if name == "2x2":
            cdp = float(s.depths[int(np.argmin(np.abs(s.rel)))])
            per_depth = []
            for di in [d for d, r in enumerate(s.rel) if abs(r) > 1.0 + 1e-9]:
                closer = [{abs(p - cdp) < abs(p - s.depths[di]) for p in s.strehl_peaks(li, e, di)}
                          for e in s.eyes]
                sure = sum(1 for c in closer if c == {True})
                unsure = sum(1 for c in closer if len(c) > 1)
                per_depth.append({(sure + k) / len(closer) >= 0.5 for k in (0, unsure)})
            if per_depth:
                far_part = {all(c) for c in itertools.product(*per_depth)}
        possible[name] = {(a, f) for a in agree for f in far_part}
    if not possible:
        return set()
    lf = list(possible)

    def verdict(combo):
        parts = dict(zip(lf, combo))
        agree = all(a for a, _ in combo)
        far = parts["2x2"][1] if "2x2" in parts else None
        return all_of([agree, far])

    return _deciding(possible, verdict)


def _cells(s: _Study, outcomes) -> list:
    """(layout, possible outcomes) of every (layout, depth) cell of a claim counted over
    cells; ``outcomes(li, di)`` gives a cell's set of possible outcomes, or None to skip it."""
    cells = []
    for name in s.layouts:
        for di in range(s.rel.size):
            found = outcomes(s.li(name), di)
            if found is not None:
                cells.append((name, found))
    return cells


def _claim4(s: _Study) -> set[str]:
    def within(li, di):  # |average eye's peak - mean of the eyes' peaks| <= 0.2 D
        av = s.vsotf_peaks(li, s.avg, di)
        ab = [s.vsotf_peaks(li, e, di) for e in s.eyes]
        if not av or any(not o for o in ab):
            return None
        m_lo, m_hi = _mean_range(ab)
        d_min = max(0.0, min(av) - m_hi, m_lo - max(av))
        d_max = max(abs(max(av) - m_lo), abs(m_hi - min(av)))
        return {d_min <= 0.2 + 1e-9, d_max <= 0.2 + 1e-9}

    return set() if s.avg is None else _counted(_cells(s, within), 0.9)


def _claim5(s: _Study) -> set[str]:
    def better(li, di):  # the average eye's mean MTF above the eyes' mean
        a = s.area[li, s.avg, di]
        if not np.isfinite(a):
            return None
        ratio = a / float(np.mean(s.area[li, s.eyes, di]))
        return {ratio - s.r.mtf_ratio > 1.0, ratio + s.r.mtf_ratio > 1.0}

    return set() if s.avg is None else _counted(_cells(s, better), 0.9)


MAX_CORNER_DEPTHS = 10
"""Claim 6's box of mean cut-offs is searched at every corner (2^n) up to this many depths
(the paper's study has 9); beyond it, at its two uniform corners only."""


def _mean_cutoffs(s: _Study, name: str) -> np.ndarray:
    return np.mean(s.cutoff[s.li(name)][s.eyes], axis=0)


def _claim6(s: _Study, fraction: float) -> set[str]:
    if len(s.lf) < 2 or s.rel.size < 3:
        return set()
    w = s.r.mean_cutoff_cpd
    possible = {}
    for name in s.lf:
        c = _mean_cutoffs(s, name)
        if not np.all(np.isfinite(c)):
            possible[name] = {(float("nan"), True)}
            continue
        # each depth's mean cut-off anywhere within ±w: the extremes of the DOF (for each
        # censoring) among the corners of that box. Beyond MAX_CORNER_DEPTHS depths (2^n
        # corners) only the box's two uniform corners: cheaper, and it may miss a flag
        corners = (itertools.product(*[(x - w, x + w) for x in c])
                   if c.size <= MAX_CORNER_DEPTHS else (c - w, c + w))
        spans: dict = {}
        for corner in itertools.chain([c], corners):
            d, cens = dof_D(s.rel, np.asarray(corner), fraction)
            lo, hi = spans.get(cens, (d, d))
            spans[cens] = (min(lo, d), max(hi, d))
        possible[name] = ({dof_D(s.rel, c, fraction)}
                          | {(d, cens) for cens, span in spans.items() for d in span})

    def verdict(combo):
        dofs = dict(zip(s.lf, combo))
        steps = [compare_bounds(*dofs[a], *dofs[b], 1e-9, strict=False)
                 for a, b in zip(s.lf, s.lf[1:])]
        steps.append(compare_bounds(*dofs[s.lf[0]], *dofs[s.lf[-1]], 1e-9, strict=True))
        return all_of(steps)

    return _deciding(possible, verdict)


def _claim7(s: _Study) -> set[str]:
    if len(s.lf) < 2 or not np.any(np.isclose(s.rel, 0.0)):
        return set()
    i0 = int(np.argmin(np.abs(s.rel)))
    w = s.r.mean_cutoff_cpd
    possible = {}
    for name in s.lf:
        c = _mean_cutoffs(s, name)
        if not np.all(np.isfinite(c)):
            possible[name] = {(float("nan"), None)}
            continue
        others = np.delete(c, i0)
        options = {(float(c[i0]), bool(c[i0] >= 0.98 * np.max(c)))}  # the computed value
        for at_cdp in (c[i0] - w, c[i0] + w):
            for best_other in ((others - w).max(initial=-np.inf), (others + w).max(initial=-np.inf)):
                options.add((float(at_cdp), bool(at_cdp >= 0.98 * max(best_other, at_cdp))))
        possible[name] = options

    def verdict(combo):
        if any(flag is None for _, flag in combo):
            return None
        values = [v for v, _ in combo]
        return bool(all(b < a for a, b in zip(values, values[1:])) and all(f for _, f in combo))

    return _deciding(possible, verdict)


def undecided_layouts(ds, resolution: Resolution = Resolution(),  # noqa: B008 (frozen)
                      dof_fraction: float | None = None) -> dict[str, tuple[str, ...]]:
    """{claim id: layouts} for each claim of :func:`lfjax.vision.claims.evaluate_claims`
    whose verdict on ``ds`` could change if the numbers it reads moved within
    ``resolution``: the layouts whose numbers can change it (computed again at the
    reference spectrum, they decide the claim as the reference would). Claims the numbers
    decide are absent.

    ``ds``: a study Dataset (:func:`lfjax.reproduce.study.run_study`); without its
    through-focus curves (``strehl``, ``predicted_accommodation_parabolic``) no grid peak is
    taken to move. Milliseconds.
    """
    frac = float(ds.attrs.get("config_dof_fraction", 0.8)) if dof_fraction is None else dof_fraction
    s = _Study(ds, resolution)
    found = {"1": _claim1(s), "2": _claim2(s), "3": _claim3(s), "4": _claim4(s),
             "5": _claim5(s), "6": _claim6(s, frac), "7": _claim7(s)}
    return {claim: tuple(n for n in s.layouts if n in names)
            for claim, names in found.items() if names}


__all__ = ["Resolution", "undecided_layouts"]
