"""Claims (5)–(7) of the paper's study: how sharp the retinal image is, and over which
depths.

Each claim is one frozen :class:`~lfjax.vision.claim_core.ClaimRule`: its thresholds are
fields, read by both its verdict (:meth:`judge`) and its margin (:meth:`undecided`).
Registered in :data:`lfjax.vision.claims.CLAIMS`.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np

from lfjax.vision.claim_core import (ClaimRule, Interval, StudyNumbers, all_of, compare_bounds,
                                     dof_D)
from lfjax.vision.claim_margins import Resolution, cells, counted, deciding, plain_mean_cutoffs

MAX_CORNER_DEPTHS = 10
"""Claim 6's box of mean cut-offs is searched at every corner (2^n) up to this many depths
(the paper's study has 9); beyond it, at its two uniform corners only."""


@dataclass(frozen=True)
class AverageEyeSharper(ClaimRule):
    """(5) The average eye's MTF (mean over 0–60 cpd, at the VSOTF peak) beats the
    aberrated eyes' mean in almost every (layout, depth) cell."""

    id: str = "5"
    finding: str = ("The average eye's MTF is better than the mean MTF of the aberrated eyes "
                    "(the average eye overestimates retinal resolution).")
    criterion: str = (
        "At the VSOTF-predicted accommodation, mean radial MTF over 0-60 cpd of the average eye "
        "> the same for the mean of the aberrated eyes in at least 90% of (layout, depth) cells "
        "('almost all cases').")
    short_finding: str = finding
    needs: str = criterion
    max_frequency_cpd: float = 60.0
    enough: Interval = Interval(lo=0.9)
    """Fraction of the cells where the average eye is better."""

    @staticmethod
    def better(average: float, mean: float) -> bool:
        """The average eye's mean MTF strictly above the eyes' (equal is not better)."""
        return bool(average > mean)

    def judge(self, s: StudyNumbers, dof_fraction: float):
        fmask = s.freq <= self.max_frequency_cpd + 1e-9
        better, total, ratios = 0, 0, []
        for li in range(len(s.layouts)):
            for di in range(s.rel.size):
                m_ab = s.mtf[li, s.eyes, di, 0]
                m_av = s.mtf[li, s.avg, di, 0]
                if not np.all(np.isfinite(m_av)):
                    continue
                area_ab = float(np.mean(np.mean(m_ab[:, fmask], axis=1)))
                area_av = float(np.mean(m_av[fmask]))
                total += 1
                better += self.better(area_av, area_ab)
                ratios.append(area_av / area_ab)
        if not total:
            return "no cells", None
        return (f"better in {better}/{total} cells; ratio average/mean {np.min(ratios):.2f}…"
                f"{np.max(ratios):.2f}", self.enough.holds(better / total))

    def undecided(self, s: StudyNumbers, resolution: Resolution, dof_fraction: float):
        fmask = s.freq <= self.max_frequency_cpd + 1e-9
        area = np.mean(s.mtf[..., 0, fmask], axis=-1)

        def better(li, di):
            a = area[li, s.avg, di]
            if not np.isfinite(a):
                return None
            ratio = a / float(np.mean(area[li, s.eyes, di]))
            return {self.better(ratio - resolution.mtf_ratio, 1.0),
                    self.better(ratio + resolution.mtf_ratio, 1.0)}

        return set() if s.avg is None else counted(cells(s, better), self.enough.holds)


@dataclass(frozen=True)
class DepthOfFieldGrows(ClaimRule):
    """(6) The depth of field (:func:`~lfjax.vision.claim_core.dof_D`, D) of the mean
    cut-off grows with viewpoint density."""

    id: str = "6"
    finding: str = ("Depth of field (rendered-depth range keeping in-focus resolution high) "
                    "grows with viewpoint density.")
    criterion: str = (
        "DOF = length of the contiguous range of rendered depths around the best depth where "
        "the mean cut-off frequency (MTF {threshold:g}"
        " at the VSOTF-predicted accommodation) stays >= {fraction:g} x its best, crossings "
        "linearly interpolated ('>=': reaches the end of the sampled depths, a lower "
        "bound). Holds if DOF never decreases from 2x2 to 3x3 to 4x4 and 4x4 > 2x2; n/a "
        "if that needs a lower bound to beat another value.")
    short_finding: str = "DOF grows with density."
    needs: str = "needs >= 2 LF layouts and >= 3 depths"
    tolerance_D: float = 1e-9
    shown_fractions: tuple[float, ...] = (0.7, 0.9)
    """Other fractions of the best cut-off whose DOF the result shows."""

    def criterion_text(self, s: StudyNumbers, dof_fraction: float) -> str:
        threshold = float(s.attrs.get("config_cutoff_threshold", 0.05))
        return self.criterion.format(threshold=threshold, fraction=dof_fraction)

    def grows(self, lf: list[str], dofs: dict) -> bool | None:
        """The verdict on {layout: (DOF, censored)}: never decreasing with density, and the
        densest above the sparsest; a censored DOF is a lower bound, so a comparison it
        would have to win is undecided."""
        steps = [compare_bounds(*dofs[a], *dofs[b], self.tolerance_D, strict=False)
                 for a, b in zip(lf, lf[1:])]
        steps.append(compare_bounds(*dofs[lf[0]], *dofs[lf[-1]], self.tolerance_D, strict=True))
        return all_of(steps)

    def judge(self, s: StudyNumbers, dof_fraction: float):
        lf = s.lf
        if len(lf) < 2 or s.rel.size < 3:
            return None
        dofs, parts = {}, []
        for name in lf:
            c = s.mean_cutoffs(name)
            if not np.all(np.isfinite(c)):
                dofs[name] = (float("nan"), True)
                parts.append(f"{name}: cut-off not finite at every depth")
                continue
            d, cens = dof_D(s.rel, c, dof_fraction)
            dofs[name] = (d, cens)
            others = []
            for f in self.shown_fractions:
                d2, c2 = dof_D(s.rel, c, f)
                others.append(f"{'>=' if c2 else ''}{d2:.2f}")
            parts.append(f"{name}: DOF {'>=' if cens else ''}{d:.2f} D (at 0.7/0.9 of best: "
                         f"{others[0]}/{others[1]} D)")
        return "; ".join(parts), self.grows(lf, dofs)

    def undecided(self, s: StudyNumbers, resolution: Resolution, dof_fraction: float):
        if len(s.lf) < 2 or s.rel.size < 3:
            return set()
        w = resolution.mean_cutoff_cpd
        possible = {}
        for name in s.lf:
            c = plain_mean_cutoffs(s, name)
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
                d, cens = dof_D(s.rel, np.asarray(corner), dof_fraction)
                lo, hi = spans.get(cens, (d, d))
                spans[cens] = (min(lo, d), max(hi, d))
            possible[name] = ({dof_D(s.rel, c, dof_fraction)}
                              | {(d, cens) for cens, span in spans.items() for d in span})
        return deciding(possible, lambda combo: self.grows(s.lf, dict(zip(s.lf, combo))))


@dataclass(frozen=True)
class CutoffFalls(ClaimRule):
    """(7) The best cut-off (cpd), reached on the CDP, falls as viewpoint density rises."""

    id: str = "7"
    finding: str = ("The best cut-off frequency, reached for points on the CDP, falls as "
                    "viewpoint density rises.")
    criterion: str = (
        "Mean cut-off frequency of the aberrated eyes at the CDP strictly decreases from "
        "2x2 to 3x3 to 4x4, and for each layout the CDP value is within 2% of the best "
        "over depths.")
    short_finding: str = "Best cut-off falls with density."
    needs: str = "needs >= 2 LF layouts"
    best_fraction: float = 0.98
    """The CDP's cut-off at least this fraction of the best over depths."""

    @staticmethod
    def falls(values) -> bool:
        """Strictly decreasing from sparsest to densest layout."""
        return all(b < a for a, b in zip(values, values[1:]))

    def near_best(self, at_cdp: float, best: float) -> bool:
        return bool(at_cdp >= self.best_fraction * best)

    def judge(self, s: StudyNumbers, dof_fraction: float):
        lf = s.lf
        if len(lf) < 2 or not s.has_cdp_depth():
            return None
        at_cdp, best_at_cdp, parts, finite = [], [], [], True
        i0 = s.cdp_index()
        for name in lf:
            c = s.mean_cutoffs(name)
            finite &= bool(np.all(np.isfinite(c)))
            at_cdp.append(c[i0])
            best_at_cdp.append(self.near_best(c[i0], np.max(c)))
            a = float(s.cutoff[s.li(name), s.avg, i0, 0])
            parts.append(f"{name}: {c[i0]:.1f} cpd at the CDP (best {np.max(c):.1f} cpd at "
                         f"{s.rel[int(np.argmax(c))]:+.1f} D; average eye {a:.1f} cpd)")
        holds = bool(self.falls(at_cdp) and all(best_at_cdp)) if finite else None
        return "; ".join(parts), holds

    def undecided(self, s: StudyNumbers, resolution: Resolution, dof_fraction: float):
        if len(s.lf) < 2 or not s.has_cdp_depth():
            return set()
        i0 = s.cdp_index()
        w = resolution.mean_cutoff_cpd
        possible = {}
        for name in s.lf:
            c = plain_mean_cutoffs(s, name)
            if not np.all(np.isfinite(c)):
                possible[name] = {(float("nan"), None)}
                continue
            others = np.delete(c, i0)
            options = {(float(c[i0]), self.near_best(c[i0], np.max(c)))}  # the computed value
            for at_cdp in (c[i0] - w, c[i0] + w):
                for best_other in ((others - w).max(initial=-np.inf),
                                   (others + w).max(initial=-np.inf)):
                    options.add((float(at_cdp), self.near_best(at_cdp, max(best_other, at_cdp))))
            possible[name] = options

        def verdict(combo):
            if any(flag is None for _, flag in combo):
                return None
            return bool(self.falls([v for v, _ in combo]) and all(f for _, f in combo))

        return deciding(possible, verdict)


__all__ = ["AverageEyeSharper", "CutoffFalls", "DepthOfFieldGrows", "MAX_CORNER_DEPTHS"]
