"""What a layout is scored on: image quality at correct focus, depth of field, resolution, predicted accommodation, and the loss that combines them.

Part of :mod:`lfjax.layout_opt` (its public names are re-exported there)."""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp

from lfjax.base.apertures import safe_sqrt
from lfjax.vision.peak_options import PeakOptions
from lfjax.vision.peaks import Peaks, peaks_from_grid
from lfjax.kernel.pipeline import (
    RetinalMetrics,
    retinal_metrics,
)
from lfjax.layout_opt._problem import MAXIMISED, LayoutProblem, Objective


def correct_focus_metrics(layout, problem: LayoutProblem) -> RetinalMetrics:
    """Pipeline output at the correct accommodation (accommodation = rendered depth):
    RetinalMetrics of shape (n_eyes, n_depth, 1[, L//2+1])."""
    return retinal_metrics(problem.eyes, problem.scene(layout), problem.spectrum,
                           problem.accommodation, problem.config, problem.reference)


def depth_of_field(metrics: RetinalMetrics):
    """Population-mean VSOTF at the correct accommodation over the rendered depths (open-pupil
    reference: 1 = natural viewing of an aberration-free eye). Higher is better."""
    return jnp.mean(metrics.vsotf)


def soft_cutoff_cpd(radial_mtf, freq_step_cpd: float, threshold: float = 0.05, softness: float = 0.02):
    """Smooth MTF cut-off (cpd) of radial MTFs (…, L//2+1) sampled at f = k·df.

    .. math:: f_c ≈ Δf\\left(\\tfrac12 + \\sum_{k≥1} σ\\!\\left(\\frac{M(kΔf) − t}{s}\\right)\\right)

    σ the logistic function, t the threshold and s the softness: the frequency extent over
    which the MTF exceeds t. For a monotone MTF it equals the first crossing of t to within
    Δf/2 (the ½ centres the count on the sample bins); as s → 0 it becomes the hard count.
    """
    above = jax.nn.sigmoid((radial_mtf[..., 1:] - threshold) / softness)
    return freq_step_cpd * (0.5 + jnp.sum(above, axis=-1))


def resolution(metrics: RetinalMetrics, problem: LayoutProblem):
    """Population-mean smooth MTF cut-off (cpd) at the correct accommodation over the depths
    (:func:`soft_cutoff_cpd`). Higher is better."""
    o = problem.objective
    return jnp.mean(soft_cutoff_cpd(metrics.radial_mtf, problem.config.freq_step_cpd,
                                    o.mtf_threshold, o.mtf_softness))


def predicted_peaks(layout, problem: LayoutProblem) -> Peaks:
    """Each (eye, depth)'s predicted accommodation, found as the project's peak finder does
    (:func:`lfjax.vision.peaks.peaks_from_grid`): the global maximum of the through-focus VSOTF
    on the problem's peak grid (:func:`peak_window`: the rendered depth and the CDP both
    inside), refined by ``problem.peak_method``. Never a search capped around the rendered
    depth. Differentiable in the layout (through the refinement's values; the grid
    maximum's index is piecewise constant). Fields (n_eyes, n_depth + 1): the rendered
    depths, then the CDP (``problem.peak_depths_D``); ``success`` is False where the
    maximum lies on a window edge (``at_grid_edge``)."""
    scene = problem.scene(layout, problem.peak_depths_D)
    grid = problem.peak_grid
    values = retinal_metrics(problem.eyes, scene, problem.spectrum, grid, problem.config,
                             problem.reference).vsotf
    return peaks_from_grid(values, problem.eyes, scene, problem.spectrum, grid, problem.config,
                           problem.reference, "vsotf", problem_peak_options(problem), problem.peak_allowed)


def problem_peak_options(problem: LayoutProblem) -> PeakOptions:
    """The problem's refinement; a second peak is refined only where that costs nothing
    (the grid's own methods)."""
    return PeakOptions(method=problem.peak_method,
                       second_peaks=problem.peak_method in ("vertex", "grid"))


def _errors(peak_D, problem: LayoutProblem):
    """(absolute, relative) accommodation errors (n_eyes, n_depth), D, of peaks over
    ``problem.peak_depths_D``: the peak against the rendered depth, and that error less the
    eye's own error on the CDP (the display's share of it)."""
    absolute = peak_D[:, :-1] - problem.depths_D[None, :]
    own = peak_D[:, -1:] - problem.cdp_D
    return absolute, absolute - own


def predicted_accommodation_D(layout, problem: LayoutProblem):
    """(peak_D, success), each (n_eyes, n_depth): :func:`predicted_peaks`' location (D)
    and success flag at the rendered depths."""
    peaks = predicted_peaks(layout, problem)
    return peaks.accommodation_D[:, :-1], peaks.success[:, :-1]


def accommodation_mse(layout, problem: LayoutProblem):
    """Mean squared error (D²) of the predicted accommodation against the rendered depth,
    over eyes and depths (:func:`predicted_peaks`). Lower is better."""
    peak, _ = predicted_accommodation_D(layout, problem)
    return jnp.mean((peak - problem.depths_D[None, :]) ** 2)


def objective_terms(layout, problem: LayoutProblem, terms=None) -> dict:
    """{name: scalar} of the requested objective terms (default: the problem's active ones,
    and the accommodation MSE when the objective constrains it)."""
    if terms is None:
        terms = problem.objective.active
        if problem.objective.accommodation_tolerance_D is not None:
            terms = terms + ("relative_accommodation",)
    terms = tuple(terms)
    out = {}
    if "depth_of_field" in terms or "resolution" in terms:
        m = correct_focus_metrics(layout, problem)
        if "depth_of_field" in terms:
            out["depth_of_field"] = depth_of_field(m)
        if "resolution" in terms:
            out["resolution"] = resolution(m, problem)
    if {"image_at_peak", "accommodation", "relative_accommodation"} & set(terms):
        peaks = predicted_peaks(layout, problem)
        absolute, relative = _errors(peaks.accommodation_D, problem)
        if "image_at_peak" in terms:
            out["image_at_peak"] = jnp.mean(peaks.value[:, :-1])
        if "accommodation" in terms:
            out["accommodation"] = jnp.mean(absolute**2)
        if "relative_accommodation" in terms:
            out["relative_accommodation"] = jnp.mean(relative**2)
    return out


def accommodation_penalty(relative_mse_D2, objective: Objective):
    """``penalty_per_D2``·max(RMSE − tolerance, 0)² (0 without a tolerance), the RMSE of the
    accommodation errors relative to each eye's own error on the CDP (D)."""
    if objective.accommodation_tolerance_D is None:
        return 0.0
    excess = jax.nn.relu(safe_sqrt(relative_mse_D2) - objective.accommodation_tolerance_D)
    return objective.penalty_per_D2 * excess**2


def combine(terms: dict, objective: Objective):
    """Weighted loss of objective terms: Σ ± weight·term (− for maximised terms), plus the
    accommodation penalty when the objective has a tolerance."""
    total = 0.0
    for name in objective.active:
        sign = -1.0 if name in MAXIMISED else 1.0
        total = total + sign * objective.weight(name) * terms[name]
    if objective.accommodation_tolerance_D is not None:
        total = total + accommodation_penalty(terms["relative_accommodation"], objective)
    return total


def layout_loss(layout, problem: LayoutProblem):
    """The problem's weighted objective as a loss to minimise (scalar); non-finite values
    raise (``eqx.error_if``) instead of steering a solver."""
    loss = combine(objective_terms(layout, problem), problem.objective)
    return eqx.error_if(loss, ~jnp.isfinite(loss), "layout objective is not finite (NaN or inf)")
