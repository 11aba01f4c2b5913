"""The wavelength step (or Gauss rule in V(λ)) a plan needs: proxy through-focus curves at each
candidate against a converged reference, within half of each target.
"""

from __future__ import annotations

import numpy as np

from lfjax.base.units import DEGREES_PER_RADIAN
from lfjax.model.spectral import gauss_rule, make_spectrum
from lfjax.planner.ladder import ladder_floor
from lfjax.planner.proxy import Proxy, grid_peaks, peak_shift_D
from lfjax.planner.state import PlanningState

WAVELENGTH_STEPS_NM = (50.0, 30.0, 25.0, 20.0, 10.0, 5.0)
"""Wavelength steps the planner chooses from (coarsest first)."""

GAUSS_NODE_CANDIDATES = tuple(range(4, 17))
"""Node counts of the Gauss rule in V(λ) the planner tries (fewest first), each only while
it is fewer than the uniform step's wavelengths."""

SPECTRAL_REFERENCE_STEP_NM = 5.0
"""Wavelength step of the proxy's converged spectrum, against which candidate steps are
measured. The V(λ)-weighted sum is a trapezoid rule on an integrand that vanishes at both
ends of 400–700 nm, so it converges fast: on the study's eleven eyes 20 and 25 nm agree with
5 nm to 8e-4 D in peaks and 0.06 cpd in natural-view cut-offs (benchmarks/RESULTS.md §18).
(It was 2.5 nm; the 121-wavelength proxy cost 5–10 s per plan.)"""

PEAK_NEIGHBOURHOOD_D = np.round(np.arange(-3, 4) * 0.1, 9)
"""States (D from each rendered depth) where the wavelength step's proxy reads peaks and
cut-offs: fine enough for a parabola vertex whatever the scene's accommodation grid (on a
0.5 D grid the scene's own states near a depth would be one), wide enough to hold the
aberration-free proxy's peak."""


def peak_neighbourhood(pair_depth) -> tuple[np.ndarray, np.ndarray]:
    """(accommodation, depth) pairs: every rendered depth ± :data:`PEAK_NEIGHBOURHOOD_D`,
    states ≥ 0 D (the hyperopic limit)."""
    depths = np.unique(np.asarray(pair_depth, float))
    acc = depths[:, None] + PEAK_NEIGHBOURHOOD_D[None, :]
    dep = np.broadcast_to(depths[:, None], acc.shape)
    keep = acc >= -1e-9
    return np.clip(acc[keep], 0.0, None), dep[keep]


def choose_wavelength_step(p: PlanningState) -> None:
    """The coarsest candidate step whose proxy curves keep within half of each target against
    a 5 nm reference (or the given step); with ``Overrides.spectral_rule="auto"`` also the
    Gauss rule for V(λ) with the fewest nodes that does the same, taken when it has fewer
    wavelengths than that step. Then the guard again on the chosen wavelengths. A given
    spectrum is kept (with a warning for steps over 20 nm)."""
    s, t = p.scene, p.targets
    if p.wl is not None:
        p.errors["spectral"] = float("nan")
        if p.wl.size > 1 and np.any(np.diff(p.wl) > 20.0):
            p.reasons.append("warning: wavelength steps over 20 nm under-sample LCA blur (Ravikumar et al. 2008; "
                             "benchmarks/speed/speed_accuracy.py: 50 nm moves a prediction by 0.2 D)")
        return
    step_choice = p.overrides.wavelength_step_nm
    spec_proxy_df = ladder_floor(min(p.df_top, s.smallest_diameter_mm
                                     / (float(p.guard_wl.max()) * 1e-6 * 24) / DEGREES_PER_RADIAN))
    peak = peak_neighbourhood(s.pair_depth)
    lo, hi = map(float, s.wavelength_range_nm)

    def curves(wavelengths, weights=None):
        proxy = Proxy(s, make_spectrum(wavelengths, s.options, weights=weights),
                      p.overrides.edge_width_samples, n_wavelengths=wavelengths.size)
        if t.cutoff_cpd is None:
            return proxy.vsotf(spec_proxy_df, peak), None
        return proxy.vsotf_and_cutoffs(spec_proxy_df, peak, t.cutoff_threshold)

    ref, ref_cut = curves(np.arange(lo, hi + 1e-6, SPECTRAL_REFERENCE_STEP_NM))
    ref_peak = grid_peaks(ref, peak)
    # Cut-offs at each depth's peak state and its neighbours 0.1 D away, not the peak
    # alone: a real eye's aberrations blur it like a little defocus, and a blurred MTF
    # crosses the threshold with a shallower slope, where a spectral error moves it
    # more. Farther out the defocused MTF oscillates about the threshold and its first
    # crossing jumps between lobes: no predicted accommodation sits there.
    near_peak = np.abs(peak[0] - np.asarray(ref_peak)[
        np.searchsorted(np.unique(peak[1]), peak[1])]) <= 0.1 + 1e-9
    budget = p.budget

    def measure(wavelengths, weights=None):
        """(meets every target, errors, what they are against their budgets) of one spectrum
        on the proxy against the reference."""
        v, cuts = curves(wavelengths, weights)
        err = float(np.max(np.abs(v - ref)))
        same_peak = grid_peaks(v, peak) == ref_peak
        shift = peak_shift_D(v, ref, peak)
        cut = (float(np.max(np.abs(cuts - ref_cut)[near_peak])) if cuts is not None
               else float("nan"))
        ok = err <= 0.5 * budget
        ok &= shift <= 0.5 * t.peak_D if t.peak_D is not None else same_peak
        ok &= t.cutoff_cpd is None or cut <= 0.5 * t.cutoff_cpd
        text = (f"VSOTF error {err:.2g} (budget {0.5 * budget:.2g}), peaks "
                + (f"moved ≤ {shift:.2g} D (budget {0.5 * t.peak_D:.2g})"
                   if t.peak_D is not None else ('unchanged' if same_peak else 'MOVED'))
                + (f", cut-offs moved ≤ {cut:.2g} cpd (budget {0.5 * t.cutoff_cpd:.2g})"
                   if t.cutoff_cpd is not None else ""))
        return bool(ok), (err, shift, cut), text

    candidates = [step_choice] if step_choice is not None else [
        step for step in WAVELENGTH_STEPS_NM
        if abs((hi - lo) / step - round((hi - lo) / step)) < 1e-9
        and step > SPECTRAL_REFERENCE_STEP_NM]
    chosen = None
    for step in candidates:
        ok, errors, text = measure(np.arange(lo, hi + 1e-6, step))
        if step_choice is not None or ok:
            chosen = step
            p.errors["spectral"], p.errors["spectral_peak_D"], p.errors["spectral_cutoff_cpd"] = errors
            p.reasons.append(
                f"wavelength step {step:g} nm against {SPECTRAL_REFERENCE_STEP_NM:g} nm on the proxy: "
                + text + (" (user's step)" if step_choice is not None else ""))
            break
    if chosen is None:  # no coarser step meets the targets: the reference's own step
        chosen = SPECTRAL_REFERENCE_STEP_NM
        p.errors["spectral"] = 0.0
        p.errors["spectral_peak_D"] = p.errors["spectral_cutoff_cpd"] = 0.0
        p.reasons.append(f"wavelength step {chosen:g} nm: the reference step (no coarser "
                         f"candidate met the targets)")
    p.wl, p.weights, p.rule = np.arange(lo, hi + 1e-6, chosen), None, "uniform"
    if step_choice is None and p.overrides.spectral_rule == "auto":
        _try_gauss_rule(p, measure, lo, hi)
    # The guard ran on a 5 nm grid; on the chosen, coarser grid each wavelength carries
    # more of the weight, so the blue and red ends may no longer be light enough to let
    # wrap. The field must hold the spectrum the pipeline will sum.
    p.radius = max(p.radius, p.field_radius(make_spectrum(p.wl, s.options, weights=p.weights)))
    if 30.0 / (p.radius * p.guard.margin) < p.df_guard:
        p.df_guard = 30.0 / (p.radius * p.guard.margin)
        p.df_top = ladder_floor(min(p.df_guard, p.df_floor_samples))
        what = (f"{p.wl.size}-node Gauss rule" if p.rule == "gauss" else f"{chosen:g} nm grid")
        p.reasons.append(f"field guard on the chosen {what}: blur reaches "
                         f"{p.radius:.1f} arcmin → df ≤ {p.df_guard:.3g} cpd")
    if np.isfinite(p.errors["spectral"]):
        p.budget -= p.errors["spectral"]


def _try_gauss_rule(p: PlanningState, measure, lo: float, hi: float) -> None:
    """The Gauss rule for V(λ) on [lo, hi] with the fewest nodes (of
    :data:`GAUSS_NODE_CANDIDATES`, each fewer than the uniform step's wavelengths) that
    meets the same criteria on the proxy as the step (``measure``); it replaces the step
    when found. Either way the reasons say which rule and why."""
    n_uniform = p.wl.size
    rejected = None
    for n in GAUSS_NODE_CANDIDATES:
        if n >= n_uniform:
            break
        nodes, weights = gauss_rule(n, lo, hi)
        ok, errors, text = measure(nodes, weights)
        if not ok:
            rejected = (n, text)
            continue
        p.wl, p.weights, p.rule = nodes, weights, "gauss"
        p.errors["spectral"], p.errors["spectral_peak_D"], p.errors["spectral_cutoff_cpd"] = errors
        p.reasons.append(
            f"wavelengths: Gauss rule in V(λ), {n} nodes ({nodes[0]:.1f}–{nodes[-1]:.1f} nm) "
            f"against {SPECTRAL_REFERENCE_STEP_NM:g} nm on the proxy: {text}; {n} wavelengths "
            f"instead of the uniform step's {n_uniform}"
            + (f" ({rejected[0]} nodes: {rejected[1]})" if rejected is not None else ""))
        return
    p.reasons.append(
        f"wavelengths: the uniform step kept ({n_uniform} wavelengths): "
        + (f"no Gauss rule in V(λ) with fewer nodes met the targets ({rejected[0]} nodes: "
           f"{rejected[1]})" if rejected is not None
           else "no Gauss rule candidate has fewer nodes"))



__all__ = ["choose_wavelength_step", "peak_neighbourhood", "WAVELENGTH_STEPS_NM",
           "GAUSS_NODE_CANDIDATES", "SPECTRAL_REFERENCE_STEP_NM", "PEAK_NEIGHBOURHOOD_D"]
