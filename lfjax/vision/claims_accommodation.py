"""Claims (1)–(4) of the paper's study: where the eyes are predicted to focus.

Each claim is one frozen :class:`~lfjax.vision.claim_core.ClaimRule`: its thresholds are
:class:`~lfjax.vision.claim_core.Interval` fields, read by both its verdict
(:meth:`judge`) and its margin (:meth:`undecided`). Registered in
:data:`lfjax.vision.claims.CLAIMS`.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np

from lfjax.model.layouts import LF_LAYOUTS
from lfjax.vision.claim_core import ClaimRule, Interval, StudyNumbers, all_of, eye_mean, fmt
from lfjax.vision.claim_margins import (Resolution, cells, counted, deciding, mean_range,
                                        strehl_peaks, vsotf_peaks)

GRID_STEP = Interval(hi=0.2 + 1e-9)
"""|difference| of two predictions (D) within one 0.2 D grid step (claims 3 and 4)."""


@dataclass(frozen=True)
class NaturalView(ClaimRule):
    """(1) Natural view of a point on the CDP: every eye within 0.2 D, mean slightly
    negative. Reads the aberrated eyes' VSOTF grid-peak errors at the CDP depth (D)."""

    id: str = "1"
    finding: str = ("Natural view of a point on the CDP: no eye is predicted to focus more "
                    "than 0.2 D from the image depth; the mean prediction is slightly negative "
                    "(farther than the image).")
    criterion: str = ("VSOTF grid peak: max |error| over the aberrated eyes <= 0.2 D, and "
                      "-0.25 D <= mean error < 0 D.")
    short_finding: str = "Natural view predictions within 0.2 D."
    needs: str = "needs natural view"
    largest_error: Interval = Interval(hi=0.2 + 1e-6)
    """max |error| over the eyes (D)."""
    mean_error: Interval = Interval(lo=-0.25, hi=0.0, hi_open=True)
    """Mean error over the eyes (D): negative, and not by more than 0.25 D."""

    def judge(self, s: StudyNumbers, dof_fraction: float):
        if "natural" not in s.layouts or not s.has_cdp_depth():
            return None
        li = s.li("natural")
        di = int(np.argmin(np.abs(s.depths - s.cdp)))
        err = s.error[li, s.eyes, di, 0]
        avg_err = float(s.error[li, s.avg, di, 0])
        avg_peak = float(s.peak_value[li, s.avg, di, 0])
        max_abs = float(np.max(np.abs(err)))
        mean = float(np.mean(err))
        # an eye without a prediction (NaN) leaves the claim undecided, not failed
        holds = (bool(self.largest_error.holds(max_abs) and self.mean_error.holds(mean))
                 if np.all(np.isfinite(err)) else None)
        sub_grid = s.cont[li, s.eyes, di, 0] - float(s.depths[di])
        # an eye's own Zernike defocus is a refractive error its accommodation must offset
        pupil = float(s.attrs.get("measured_pupil_mm", 3.0))
        c20 = s.c20[s.eyes]
        own_D = c20 * 16.0 * math.sqrt(3.0) / pupil**2
        far = [f"{e} {x:+.1f} D (own defocus c(2,0) = {c:+.3f} um = {d:+.2f} D)"
               for e, x, c, d in zip(s.eye_labels[s.eyes], err, c20, own_D)
               if abs(x) > self.largest_error.hi]
        extra = (f"; beyond 0.2 D: {', '.join(far)}" if far else "")
        extra += (f"; continuous peaks: mean {np.mean(sub_grid):+.3f} D, max |error| "
                  f"{np.max(np.abs(sub_grid)):.2f} D")
        result = (f"errors (D) {', '.join(fmt(e, 1) for e in err)}; max |error| = "
                  f"{max_abs:.2f} D; mean = {mean:+.3f} D; average eye {avg_err:+.1f} D "
                  f"(VSOTF peak {avg_peak:.3f})" + extra)
        return result, holds

    def undecided(self, s: StudyNumbers, resolution: Resolution, dof_fraction: float):
        if "natural" not in s.layouts or not s.has_cdp_depth():
            return set()
        li, di = s.li("natural"), s.cdp_index()
        options = [[p - s.depths[di] for p in vsotf_peaks(s, resolution, li, e, di)]
                   for e in s.eyes]
        if any(not o for o in options):
            return set()
        # each eye's error any of its options: the ranges of the largest |error| and of the
        # mean bound both verdicts, for any number of eyes (each eye's choice moves both, so
        # this may flag a verdict only a choice moving them apart could change: a flag too
        # many, never one too few)
        largest = (max(min(abs(o) for o in opts) for opts in options),
                   max(max(abs(o) for o in opts) for opts in options))
        outcomes = {a and b for a in self.largest_error.possible(*largest)
                    for b in self.mean_error.possible(*mean_range(options))}
        return {"natural"} if len(outcomes) > 1 else set()


@dataclass(frozen=True)
class SmallNegativeConstant(ClaimRule):
    """(2) For every LF layout the mean continuous VSOTF error is small, negative and about
    constant over the rendered depths (D)."""

    id: str = "2"
    finding: str = ("Rendered points (2x2, 3x3, 4x4): VSOTF predicts small accommodation "
                    "errors, negative and about constant across rendered depths, for every "
                    "viewpoint density.")
    criterion: str = (
        "For every LF layout, mean error of the continuous VSOTF peaks (refined from the "
        "grid, lfjax.vision.peaks) over the aberrated eyes at each depth: |mean| <= 0.25 D at all depths "
        "(small); < 0 D at every depth > 0 D (the 0 D depth is exempt: the hyperopic limit "
        "forbids negative errors there) (negative); max - min over depths <= 0.2 D "
        "(constant). Continuous peaks remove the 0.2 D grid's ±0.1 D alternation between "
        "half-dioptre depths; the grid peaks are shown for reference.")
    short_finding: str = "VSOTF errors small/negative/constant."
    needs: str = "needs LF layouts"
    small: Interval = Interval(hi=0.25 + 1e-9)
    """max |mean error| over the depths (D)."""
    negative: Interval = Interval(hi=0.0, hi_open=True)
    """The mean error at every depth > 0 D (D)."""
    constant: Interval = Interval(hi=0.2 + 1e-9)
    """max - min of the mean errors over the depths (D)."""

    def parts(self, largest: float, spread: float, checked: np.ndarray) -> tuple[bool, bool, bool]:
        """(small, negative, constant) of one layout: ``largest`` max |mean error|,
        ``spread`` their range, ``checked`` the mean errors at the depths > 0 D."""
        negative = self.negative.holds(checked) if checked.size else False
        return self.small.holds(largest), negative, self.constant.holds(spread)

    def layout_verdict(self, largest: float, spread: float, checked: np.ndarray):
        small, negative, constant = self.parts(largest, spread, checked)
        if not (small and constant) or (checked.size and not negative):
            return False
        # no depth > 0 D: "negative" cannot be judged (0 D is exempt)
        return True if checked.size else None

    def judge(self, s: StudyNumbers, dof_fraction: float):
        lf = s.lf
        if not lf:
            return None
        parts, verdicts = [], []
        check = s.depths > 1e-9
        for name in lf:
            li = s.li(name)
            grid_e = eye_mean(s.error[li][s.eyes][..., 0])
            e = eye_mean(s.cont[li][s.eyes][..., 0]) - s.depths
            converged = bool(s.success[li][s.eyes][..., 0].all())
            small, negative, constant = self.parts(np.max(np.abs(e)), np.ptp(e), e[check])
            if not np.all(np.isfinite(e)):
                verdicts.append(None)  # a depth without continuous peaks: undecided
            else:
                verdicts.append(self.layout_verdict(np.max(np.abs(e)), np.ptp(e), e[check]))
            parts.append(
                f"{name}: mean errors {fmt(np.min(e))}…{fmt(np.max(e))} D "
                f"(range {np.ptp(e):.2f} D; negative at {int(np.sum(e[check] < 0))}/"
                f"{int(np.sum(check))} depths > 0 D)"
                f"{'' if small else ' [not small]'}{'' if negative else ' [not all negative]'}"
                f"{'' if constant else ' [not constant]'}"
                f"{'' if converged else ' [some continuous peaks did not converge]'}"
                f" (0.2 D grid peaks: {fmt(np.min(grid_e))}…{fmt(np.max(grid_e))} D, negative "
                f"at {int(np.sum(grid_e[check] < 0))}/{int(np.sum(check))})")
        # "for every density": a density the data lack cannot confirm it (n/a), though
        # one that is present can refute it
        missing = [name for name in LF_LAYOUTS if name not in lf]
        if missing:
            parts.append(f"n/a unless it fails: no {', '.join(missing)} in the data")
        return "; ".join(parts), all_of(verdicts + ([None] if missing else []))

    def undecided(self, s: StudyNumbers, resolution: Resolution, dof_fraction: float):
        check = s.depths > 1e-9
        possible = {}
        for name in s.lf:
            e = np.mean(s.cont[s.li(name)][s.eyes][..., 0], axis=0) - s.depths
            if not np.all(np.isfinite(e)):
                possible[name] = {None}
                continue
            p = resolution.mean_peak_D
            # the means move by up to p, their range by up to 2p
            possible[name] = {self.layout_verdict(np.max(np.abs(e)) + shift, np.ptp(e) + spread,
                                                  e[check] + shift)
                              for shift in (-p, 0.0, p) for spread in (-2 * p, 0.0, 2 * p)}
        # a density the data lack leaves the claim at best undecided (as in judge)
        missing = [None] if any(n not in s.layouts for n in LF_LAYOUTS) else []
        return (deciding(possible, lambda combo: all_of(list(combo) + missing))
                if possible else set())


@dataclass(frozen=True)
class StrehlAgrees(ClaimRule):
    """(3) Strehl predicts VSOTF's accommodation, except 2x2 beyond ±1 D from the CDP,
    where it predicts the CDP."""

    id: str = "3"
    finding: str = ("Strehl ratio predicts the same accommodation as VSOTF, except for 2x2 "
                    "viewpoints with points rendered more than 1 D from the CDP, where it "
                    "predicts the CDP.")
    criterion: str = (
        "(a) Mean (over aberrated eyes) Strehl and VSOTF predictions within 0.2 D in every "
        "(layout, depth) cell except 2x2 beyond +-1 D; (b) 2x2 beyond +-1 D: at each depth "
        "at least half the eyes' Strehl peaks are closer to the CDP than to the image.")
    short_finding: str = "Strehl vs VSOTF."
    needs: str = "needs LF layouts"
    agree: Interval = GRID_STEP
    """|mean Strehl - mean VSOTF prediction| of a cell (D)."""
    exempt_layout: str = "2x2"
    exempt_beyond_D: float = 1.0
    """Cells of ``exempt_layout`` further than this from the CDP (D) are part (b)'s."""
    picks_cdp: Interval = Interval(lo=0.5)
    """Fraction of the eyes whose Strehl peak is closer to the CDP than to the image."""

    def exempt(self, name: str, rel: float) -> bool:
        return name == self.exempt_layout and abs(rel) > self.exempt_beyond_D + 1e-9

    def judge(self, s: StudyNumbers, dof_fraction: float):
        lf = s.lf
        if not lf:
            return None
        agree_cells, agree_ok, parts, disagreements = 0, 0, [], []
        for name in lf:
            li = s.li(name)
            for di, r in enumerate(s.rel):
                if self.exempt(name, r):
                    continue
                agree_cells += 1
                d = abs(float(np.mean(s.pred[li, s.eyes, di, 1])
                              - np.mean(s.pred[li, s.eyes, di, 0])))
                if self.agree.holds(d):
                    agree_ok += 1
                else:
                    disagreements.append(f"{name} {r:+.1f} D ({d:.2f} D)")
        parts.append(f"mean Strehl vs VSOTF predictions within 0.2 D in {agree_ok}/{agree_cells} "
                     f"cells" + (f" (not: {', '.join(disagreements)})" if disagreements else ""))
        cdp_ok = None  # part (b) undecided without 2x2 depths beyond +-1 D
        if self.exempt_layout in lf:
            li = s.li(self.exempt_layout)
            far = [di for di, r in enumerate(s.rel) if self.exempt(self.exempt_layout, r)]
            fr = []
            for di in far:
                p_sr = s.pred[li, s.eyes, di, 1]
                closer = np.abs(p_sr - s.cdp) < np.abs(p_sr - s.depths[di])
                fr.append(float(np.mean(closer)))
                parts.append(f"2x2 {s.rel[di]:+.1f} D: {int(np.sum(closer))}/{closer.size} eyes' "
                             f"Strehl peak closer to the CDP (mean {np.mean(p_sr):.2f} D)")
            cdp_ok = all(self.picks_cdp.holds(f) for f in fr) if far else None
            if not far:
                parts.append("no 2x2 depth beyond +-1 D")
        else:
            parts.append("no 2x2 layout")
        holds = all_of([agree_ok == agree_cells if agree_cells else None, cdp_ok])
        return "; ".join(parts), holds

    def _agreement(self, s: StudyNumbers, r: Resolution, li: int, name: str) -> set[bool]:
        """Part (a)'s possible outcomes on one layout."""
        found = []
        for di, rel in enumerate(s.rel):
            if self.exempt(name, rel):
                continue
            vs = [vsotf_peaks(s, r, li, e, di) for e in s.eyes]
            if any(not o for o in vs):
                continue
            s_lo, s_hi = mean_range([strehl_peaks(s, r, li, e, di) for e in s.eyes])
            v_lo, v_hi = mean_range(vs)
            d_min = max(0.0, s_lo - v_hi, v_lo - s_hi)
            d_max = max(abs(s_hi - v_lo), abs(v_hi - s_lo))
            found.append({self.agree.holds(d_min), self.agree.holds(d_max)})
        return {all(c) for c in itertools.product(*found)} if found else {True}

    def _picks_cdp(self, s: StudyNumbers, r: Resolution, li: int) -> set:
        """Part (b)'s possible outcomes (on the exempt layout)."""
        cdp = float(s.depths[s.cdp_index()])
        per_depth = []
        for di in [d for d, rel in enumerate(s.rel) if self.exempt(self.exempt_layout, rel)]:
            closer = [{bool(abs(p - cdp) < abs(p - s.depths[di]))
                       for p in strehl_peaks(s, r, li, e, di)} for e in s.eyes]
            sure = sum(1 for c in closer if c == {True})
            unsure = sum(1 for c in closer if len(c) > 1)
            per_depth.append({self.picks_cdp.holds((sure + k) / len(closer))
                              for k in (0, unsure)})
        return {all(c) for c in itertools.product(*per_depth)} if per_depth else {None}

    def undecided(self, s: StudyNumbers, resolution: Resolution, dof_fraction: float):
        possible = {}
        for name in s.lf:
            li = s.li(name)
            far_part = (self._picks_cdp(s, resolution, li) if name == self.exempt_layout
                        else {None})
            possible[name] = {(a, f) for a in self._agreement(s, resolution, li, name)
                              for f in far_part}
        if not possible:
            return set()
        lf = list(possible)

        def verdict(combo):
            parts = dict(zip(lf, combo))
            far = parts[self.exempt_layout][1] if self.exempt_layout in parts else None
            return all_of([all(a for a, _ in combo), far])

        return deciding(possible, verdict)


@dataclass(frozen=True)
class AverageEyePredictsMean(ClaimRule):
    """(4) The average eye's VSOTF prediction is the aberrated eyes' mean prediction, in
    almost every (layout, depth) cell."""

    id: str = "4"
    finding: str = ("The average eye is predicted to accommodate where the aberrated eyes do "
                    "on average.")
    criterion: str = ("VSOTF: |average-eye prediction - mean prediction of the aberrated eyes| "
                      "<= 0.2 D (one grid step) in at least 90% of (layout, depth) cells.")
    short_finding: str = finding
    needs: str = criterion
    within: Interval = GRID_STEP
    """|average-eye prediction - mean prediction| of a cell (D)."""
    enough: Interval = Interval(lo=0.9)
    """Fraction of the cells within."""

    def judge(self, s: StudyNumbers, dof_fraction: float):
        diffs = []
        for li in range(len(s.layouts)):
            for di in range(s.rel.size):
                m = float(eye_mean(s.pred[li][s.eyes][:, di, 0]))
                a = float(s.pred[li, s.avg, di, 0])
                if np.isfinite(m) and np.isfinite(a):
                    diffs.append(a - m)
        diffs = np.asarray(diffs, float)
        within = np.array([self.within.holds(abs(d)) for d in diffs], bool)
        if not within.size:
            return "no cell with both predictions", None
        return (f"within 0.2 D in {int(within.sum())}/{within.size} cells; mean difference "
                f"{np.mean(diffs):+.3f} D; max |difference| {np.max(np.abs(diffs)):.2f} D",
                self.enough.holds(within.mean()))

    def undecided(self, s: StudyNumbers, resolution: Resolution, dof_fraction: float):
        def within(li, di):
            av = vsotf_peaks(s, resolution, li, s.avg, di)
            ab = [vsotf_peaks(s, resolution, li, e, di) for e in s.eyes]
            if not av or any(not o for o in ab):
                return None
            m_lo, m_hi = mean_range(ab)
            d_min = max(0.0, min(av) - m_hi, m_lo - max(av))
            d_max = max(abs(max(av) - m_lo), abs(m_hi - min(av)))
            return {self.within.holds(d_min), self.within.holds(d_max)}

        return set() if s.avg is None else counted(cells(s, within), self.enough.holds)


__all__ = ["AverageEyePredictsMean", "GRID_STEP", "NaturalView", "SmallNegativeConstant",
           "StrehlAgrees"]
