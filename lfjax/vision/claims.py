"""The paper's findings (1)–(7) as claims, each with an explicit criterion.

:class:`Claim` is one finding with its criterion, the numbers reproduced and a verdict;
:func:`evaluate_claims` checks all seven on a study Dataset (written by
:func:`lfjax.reproduce.study.run_study`, or read from a sweep store by
:func:`lfjax.sweep.store.study_view`); :func:`dof_D` is the depth-of-field definition claim 6
uses; :func:`aberrated` and :func:`average` select the sampled eyes and the average eye.

Shared by two applications, the reproduction (:mod:`lfjax.reproduce`) and the population
sweep's ten-eye check (:mod:`lfjax.sweep.ten_eyes`), so it lives below both: it reads the
Dataset only, and imports nothing of either.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from lfjax.model.layouts import LF_LAYOUTS


def aberrated(ds):
    """The sampled (aberrated) eyes of a study Dataset: every eye but the average eye."""
    return ds.sel(eye=~ds.is_average.values)


def average(ds):
    """The average eye of a study Dataset (its eye axis dropped)."""
    return ds.sel(eye=ds.is_average.values).isel(eye=0)


@dataclass
class Claim:
    """One paper finding as a checkable statement."""

    id: str
    finding: str
    criterion: str
    result: str
    holds: bool | None  # None: could not be evaluated on this data
    unsettled: tuple[str, ...] = ()
    """Layouts whose numbers, moved within the planned spectrum's error, could change the
    verdict (:func:`lfjax.vision.claim_margins.undecided_layouts`); empty when the numbers
    settle it."""
    reference_layouts: tuple[str, ...] = ()
    """Layouts computed again at the reference spectrum to settle the verdict
    (:mod:`lfjax.reproduce.settling`)."""

    @property
    def verdict(self) -> str:
        return {True: "holds", False: "fails", None: "n/a"}[self.holds]



def _fmt(x, digits=2):
    return "nan" if not np.isfinite(x) else f"{x:+.{digits}f}"


def dof_D(rel_depths, cutoffs, fraction: float) -> tuple[float, bool]:
    """Depth of field (D): length of the contiguous depth range around the best depth
    where the cut-off stays ≥ ``fraction`` × best, with linear interpolation of the
    crossings. Returns (dof, censored) where censored means the range reaches the end of
    the sampled depths on some side (the true DOF is at least the value)."""
    x = np.asarray(rel_depths, float)
    c = np.asarray(cutoffs, float)
    order = np.argsort(x)
    x, c = x[order], c[order]
    ib = int(np.nanargmax(c))
    level = fraction * c[ib]
    censored = False
    lo = x[ib]
    i = ib
    while True:
        if i == 0:
            lo, censored = x[0], True
            break
        if c[i - 1] >= level:
            i -= 1
            continue
        lo = x[i - 1] + (level - c[i - 1]) / (c[i] - c[i - 1]) * (x[i] - x[i - 1])
        break
    hi = x[ib]
    i = ib
    while True:
        if i == x.size - 1:
            hi, censored = x[-1], True
            break
        if c[i + 1] >= level:
            i += 1
            continue
        hi = x[i] + (c[i] - level) / (c[i] - c[i + 1]) * (x[i + 1] - x[i])
        break
    return float(hi - lo), censored


def all_of(verdicts) -> bool | None:
    """Conjunction of parts that may be undecided (None): False if any part fails, None if
    none fails but one is undecided, else True."""
    verdicts = list(verdicts)
    if any(v is False for v in verdicts):
        return False
    return None if any(v is None for v in verdicts) else True


def compare_bounds(a, a_censored, b, b_censored, tol, strict) -> bool | None:
    """Is the true value behind b >= a (strict: > a)? a and b are lower bounds where
    censored. True when proven (a exact), False when disproven (b exact), else None."""
    if not (math.isfinite(a) and math.isfinite(b)):
        return None
    ok = b > a + tol if strict else b >= a - tol
    if ok:
        return True if not a_censored else None
    return False if not b_censored else None


def evaluate_claims(ds, dof_fraction: float | None = None) -> list[Claim]:
    """The paper's findings (1)–(7) checked on a study Dataset, each with its criterion.

    A claim's ``holds`` is None (verdict "n/a") when the Dataset cannot decide it: a part
    of its criterion needs data that are absent (no natural view, no LF layouts, no 2x2
    depth beyond +-1 D, no depth > 0 D, fewer than 2 LF layouts or 3 depths, no cell with
    an average-eye value) or not finite, or a depth of field reaching the end of the
    sampled depths (a lower bound) would have to win a comparison. A part that fails
    still makes the claim fail."""
    cdp = float(ds.attrs["cdp_D"])
    frac = float(ds.attrs.get("config_dof_fraction", 0.8)) if dof_fraction is None else dof_fraction
    layouts = list(ds.layout.values)
    lf = [name for name in LF_LAYOUTS if name in layouts]
    ab = aberrated(ds)
    av = average(ds)
    rel = ds.depth_rel_cdp.values
    depths = ds.depth.values
    claims: list[Claim] = []

    # (1) natural view
    if "natural" in layouts and np.any(np.isclose(rel, 0.0)):
        sub = ab.sel(layout="natural").sel(depth=cdp, method="nearest")
        err = sub.accommodation_error.sel(metric="vsotf").values
        avg_err = float(av.sel(layout="natural").sel(depth=cdp, method="nearest")
                        .accommodation_error.sel(metric="vsotf"))
        avg_peak = float(av.sel(layout="natural").sel(depth=cdp, method="nearest")
                         .peak_value.sel(metric="vsotf"))
        max_abs = float(np.max(np.abs(err)))
        mean = float(np.mean(err))
        # an eye without a prediction (NaN) leaves the claim undecided, not failed
        holds = (bool(max_abs <= 0.2 + 1e-6 and -0.25 <= mean < 0)
                 if np.all(np.isfinite(err)) else None)
        sub_grid = (sub.predicted_accommodation_continuous.sel(metric="vsotf").values
                    - float(sub.depth))
        # an eye's own Zernike defocus is a refractive error its accommodation must offset
        pupil = float(ds.attrs.get("measured_pupil_mm", 3.0))
        c20 = sub.zernike_um.sel(zernike_j=4).values
        own_D = c20 * 16.0 * math.sqrt(3.0) / pupil**2
        far = [f"{e} {x:+.1f} D (own defocus c(2,0) = {c:+.3f} um = {d:+.2f} D)"
               for e, x, c, d in zip(sub.eye.values, err, c20, own_D) if abs(x) > 0.2 + 1e-6]
        extra = (f"; beyond 0.2 D: {', '.join(far)}" if far else "")
        extra += (f"; continuous peaks: mean {np.mean(sub_grid):+.3f} D, max |error| "
                  f"{np.max(np.abs(sub_grid)):.2f} D")
        claims.append(Claim(
            "1", "Natural view of a point on the CDP: no eye is predicted to focus more than "
                 "0.2 D from the image depth; the mean prediction is slightly negative "
                 "(farther than the image).",
            "VSOTF grid peak: max |error| over the aberrated eyes <= 0.2 D, and -0.25 D <= mean "
            "error < 0 D.",
            f"errors (D) {', '.join(_fmt(e, 1) for e in err)}; max |error| = {max_abs:.2f} D; "
            f"mean = {mean:+.3f} D; average eye {avg_err:+.1f} D (VSOTF peak {avg_peak:.3f})"
            + extra,
            holds))
    else:
        claims.append(Claim("1", "Natural view predictions within 0.2 D.", "needs natural view",
                            "not evaluated", None))

    # (2) VSOTF errors small, negative, constant for every LF layout
    if lf:
        parts, verdicts = [], []
        for name in lf:
            grid_e = ab.sel(layout=name).accommodation_error.sel(metric="vsotf").mean("eye").values
            sel = ab.sel(layout=name)
            e = (sel.predicted_accommodation_continuous.sel(metric="vsotf").mean("eye").values
                 - depths)
            converged = bool(sel.continuous_peak_success.sel(metric="vsotf").values.all())
            small = bool(np.max(np.abs(e)) <= 0.25 + 1e-9)
            check = depths > 1e-9
            negative = bool(np.all(e[check] < 0)) if np.any(check) else False
            constant = bool(np.ptp(e) <= 0.2 + 1e-9)
            if not np.all(np.isfinite(e)):
                verdicts.append(None)  # a depth without continuous peaks: undecided
            elif not (small and constant) or (np.any(check) and not negative):
                verdicts.append(False)
            else:
                # no depth > 0 D: "negative" cannot be judged (0 D is exempt)
                verdicts.append(True if np.any(check) else None)
            parts.append(
                f"{name}: mean errors {_fmt(np.min(e))}…{_fmt(np.max(e))} D "
                f"(range {np.ptp(e):.2f} D; negative at {int(np.sum(e[check] < 0))}/"
                f"{int(np.sum(check))} depths > 0 D)"
                f"{'' if small else ' [not small]'}{'' if negative else ' [not all negative]'}"
                f"{'' if constant else ' [not constant]'}"
                f"{'' if converged else ' [some continuous peaks did not converge]'}"
                f" (0.2 D grid peaks: {_fmt(np.min(grid_e))}…{_fmt(np.max(grid_e))} D, negative "
                f"at {int(np.sum(grid_e[check] < 0))}/{int(np.sum(check))})")
        # "for every density": a density the data lack cannot confirm it (n/a), though
        # one that is present can refute it
        missing = [name for name in LF_LAYOUTS if name not in lf]
        if missing:
            parts.append(f"n/a unless it fails: no {', '.join(missing)} in the data")
        claims.append(Claim(
            "2", "Rendered points (2x2, 3x3, 4x4): VSOTF predicts small accommodation errors, "
                 "negative and about constant across rendered depths, for every viewpoint "
                 "density.",
            "For every LF layout, mean error of the continuous VSOTF peaks (refined from the "
            "grid, lfjax.vision.peaks) over the aberrated eyes at each depth: |mean| <= 0.25 D at all depths "
            "(small); < 0 D at every depth > 0 D (the 0 D depth is exempt: the hyperopic limit "
            "forbids negative errors there) (negative); max - min over depths <= 0.2 D "
            "(constant). Continuous peaks remove the 0.2 D grid's ±0.1 D alternation between "
            "half-dioptre depths; the grid peaks are shown for reference.",
            "; ".join(parts), all_of(verdicts + ([None] if missing else []))))
    else:
        claims.append(Claim("2", "VSOTF errors small/negative/constant.", "needs LF layouts",
                            "not evaluated", None))

    # (3) Strehl agrees with VSOTF except 2x2 beyond +-1 D, where it predicts the CDP
    if lf:
        agree_cells, agree_ok, parts = 0, 0, []
        disagreements = []
        for name in lf:
            for di, r in enumerate(rel):
                sub = ab.sel(layout=name).isel(depth=di)
                p_vs = sub.predicted_accommodation.sel(metric="vsotf").values
                p_sr = sub.predicted_accommodation.sel(metric="strehl").values
                if name == "2x2" and abs(r) > 1.0 + 1e-9:
                    continue
                agree_cells += 1
                d = abs(float(np.mean(p_sr) - np.mean(p_vs)))
                if d <= 0.2 + 1e-9:
                    agree_ok += 1
                else:
                    disagreements.append(f"{name} {r:+.1f} D ({d:.2f} D)")
        parts.append(f"mean Strehl vs VSOTF predictions within 0.2 D in {agree_ok}/{agree_cells} "
                     f"cells" + (f" (not: {', '.join(disagreements)})" if disagreements else ""))
        cdp_ok = None  # part (b) undecided without 2x2 depths beyond +-1 D
        if "2x2" in lf:
            far = [di for di, r in enumerate(rel) if abs(r) > 1.0 + 1e-9]
            fr = []
            for di in far:
                sub = ab.sel(layout="2x2").isel(depth=di)
                p_sr = sub.predicted_accommodation.sel(metric="strehl").values
                closer = np.abs(p_sr - cdp) < np.abs(p_sr - depths[di])
                fr.append(float(np.mean(closer)))
                parts.append(f"2x2 {rel[di]:+.1f} D: {int(np.sum(closer))}/{closer.size} eyes' "
                             f"Strehl peak closer to the CDP (mean {np.mean(p_sr):.2f} D)")
            cdp_ok = all(f >= 0.5 for f in fr) if far else None
            if not far:
                parts.append("no 2x2 depth beyond +-1 D")
        else:
            parts.append("no 2x2 layout")
        holds = all_of([agree_ok == agree_cells if agree_cells else None, cdp_ok])
        claims.append(Claim(
            "3", "Strehl ratio predicts the same accommodation as VSOTF, except for 2x2 "
                 "viewpoints with points rendered more than 1 D from the CDP, where it predicts "
                 "the CDP.",
            "(a) Mean (over aberrated eyes) Strehl and VSOTF predictions within 0.2 D in every "
            "(layout, depth) cell except 2x2 beyond +-1 D; (b) 2x2 beyond +-1 D: at each depth "
            "at least half the eyes' Strehl peaks are closer to the CDP than to the image.",
            "; ".join(parts), holds))
    else:
        claims.append(Claim("3", "Strehl vs VSOTF.", "needs LF layouts", "not evaluated", None))

    # (4) average eye predicts the mean of the aberrated eyes (VSOTF)
    diffs, cells = [], []
    for name in layouts:
        for di, r in enumerate(rel):
            m = float(ab.sel(layout=name).isel(depth=di).predicted_accommodation
                      .sel(metric="vsotf").mean("eye"))
            a = float(av.sel(layout=name).isel(depth=di).predicted_accommodation
                      .sel(metric="vsotf"))
            if np.isfinite(m) and np.isfinite(a):
                diffs.append(a - m)
                cells.append(f"{name} {r:+.1f}")
    diffs = np.asarray(diffs, float)
    within = np.abs(diffs) <= 0.2 + 1e-9
    result4 = (f"within 0.2 D in {int(within.sum())}/{within.size} cells; mean difference "
               f"{np.mean(diffs):+.3f} D; max |difference| {np.max(np.abs(diffs)):.2f} D"
               if within.size else "no cell with both predictions")
    claims.append(Claim(
        "4", "The average eye is predicted to accommodate where the aberrated eyes do on "
             "average.",
        "VSOTF: |average-eye prediction - mean prediction of the aberrated eyes| <= 0.2 D (one "
        "grid step) in at least 90% of (layout, depth) cells.",
        result4, bool(within.mean() >= 0.9) if within.size else None))

    # (5) average eye's MTF better than the aberrated eyes' mean
    fmask = ds.frequency.values <= 60.0 + 1e-9
    better, total, parts = 0, 0, []
    ratios = []
    for name in layouts:
        for di, r in enumerate(rel):
            m_ab = ab.sel(layout=name).isel(depth=di).mtf_at_peak.sel(metric="vsotf").values
            m_av = av.sel(layout=name).isel(depth=di).mtf_at_peak.sel(metric="vsotf").values
            if not np.all(np.isfinite(m_av)):
                continue
            area_ab = float(np.mean(np.mean(m_ab[:, fmask], axis=1)))
            area_av = float(np.mean(m_av[fmask]))
            total += 1
            better += area_av > area_ab
            ratios.append(area_av / area_ab)
    claims.append(Claim(
        "5", "The average eye's MTF is better than the mean MTF of the aberrated eyes (the "
             "average eye overestimates retinal resolution).",
        "At the VSOTF-predicted accommodation, mean radial MTF over 0-60 cpd of the average eye "
        "> the same for the mean of the aberrated eyes in at least 90% of (layout, depth) cells "
        "('almost all cases').",
        f"better in {better}/{total} cells; ratio average/mean {np.min(ratios):.2f}…"
        f"{np.max(ratios):.2f}" if total else "no cells",
        bool(better / total >= 0.9) if total else None))

    # (6) DOF grows with viewpoint density; (7) best cut-off at the CDP falls with density
    if len(lf) >= 2 and rel.size >= 3:
        threshold = float(ds.attrs.get("config_cutoff_threshold", 0.05))
        dofs, censored, parts = {}, {}, []
        for name in lf:
            c = ab.sel(layout=name).cutoff_frequency.sel(metric="vsotf").mean("eye").values
            if not np.all(np.isfinite(c)):
                dofs[name], censored[name] = float("nan"), True
                parts.append(f"{name}: cut-off not finite at every depth")
                continue
            d, cens = dof_D(rel, c, frac)
            dofs[name], censored[name] = d, cens
            others = []
            for f in (0.7, 0.9):
                d2, c2 = dof_D(rel, c, f)
                others.append(f"{'>=' if c2 else ''}{d2:.2f}")
            parts.append(f"{name}: DOF {'>=' if cens else ''}{d:.2f} D (at 0.7/0.9 of best: "
                         f"{others[0]}/{others[1]} D)")
        # a censored DOF is a lower bound: a comparison it would have to win is undecided
        steps = [compare_bounds(dofs[a], censored[a], dofs[b], censored[b], 1e-9, strict=False)
                 for a, b in zip(lf, lf[1:])]
        steps.append(compare_bounds(dofs[lf[0]], censored[lf[0]], dofs[lf[-1]], censored[lf[-1]],
                              1e-9, strict=True))
        holds6 = all_of(steps)
        claims.append(Claim(
            "6", "Depth of field (rendered-depth range keeping in-focus resolution high) grows "
                 "with viewpoint density.",
            f"DOF = length of the contiguous range of rendered depths around the best depth where "
            f"the mean cut-off frequency (MTF {threshold:g}"
            f" at the VSOTF-predicted accommodation) stays >= {frac:g} x its best, crossings "
            f"linearly interpolated ('>=': reaches the end of the sampled depths, a lower "
            f"bound). Holds if DOF never decreases from 2x2 to 3x3 to 4x4 and 4x4 > 2x2; n/a "
            f"if that needs a lower bound to beat another value.",
            "; ".join(parts), holds6))
    else:
        claims.append(Claim("6", "DOF grows with density.", "needs >= 2 LF layouts and >= 3 depths",
                            "not evaluated", None))
    if len(lf) >= 2 and np.any(np.isclose(rel, 0.0)):
        at_cdp, best_at_cdp, parts, finite = [], [], [], True
        for name in lf:
            c = ab.sel(layout=name).cutoff_frequency.sel(metric="vsotf").mean("eye").values
            finite &= bool(np.all(np.isfinite(c)))
            i0 = int(np.argmin(np.abs(rel)))
            at_cdp.append(c[i0])
            best_at_cdp.append(bool(c[i0] >= 0.98 * np.max(c)))
            a = float(av.sel(layout=name).cutoff_frequency.sel(metric="vsotf").values[i0])
            parts.append(f"{name}: {c[i0]:.1f} cpd at the CDP (best {np.max(c):.1f} cpd at "
                         f"{rel[int(np.argmax(c))]:+.1f} D; average eye {a:.1f} cpd)")
        falling = all(b < a for a, b in zip(at_cdp, at_cdp[1:]))
        claims.append(Claim(
            "7", "The best cut-off frequency, reached for points on the CDP, falls as viewpoint "
                 "density rises.",
            "Mean cut-off frequency of the aberrated eyes at the CDP strictly decreases from "
            "2x2 to 3x3 to 4x4, and for each layout the CDP value is within 2% of the best "
            "over depths.",
            "; ".join(parts), bool(falling and all(best_at_cdp)) if finite else None))
    else:
        claims.append(Claim("7", "Best cut-off falls with density.", "needs >= 2 LF layouts",
                            "not evaluated", None))
    return claims


__all__ = [
    "Claim",
    "all_of",
    "compare_bounds",
    "dof_D",
    "evaluate_claims",
    "aberrated",
    "average",
]
