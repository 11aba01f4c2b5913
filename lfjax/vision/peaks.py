"""Continuous accommodation peaks: bracket on a grid, refine with a solver, differentiate.

The predicted accommodation is the state that maximises a through-focus metric (VSOTF by
default). :func:`accommodation_peaks` evaluates the metric on a coarse grid (states shared
by all rendered depths, as :func:`lfjax.vision.focus.through_focus` does), brackets the
global grid maximum and every other local grid maximum worth refining, and refines them
with one of:

``"auto"`` (default)
    ``"newton"`` for VSOTF (smooth in accommodation) and ``"golden"`` for the Strehl ratio:
    the sampled PSF's peak is the largest of its pixels, piecewise smooth in accommodation,
    and Newton's derivatives jump between pieces (tests/vision/test_peaks.py pins the case).
``"newton"``
    optimistix ``Newton`` root find of dV/da = 0 inside the bracket; dV/da and d²V/da² by
    forward-mode differentiation of the pipeline in the scalar accommodation (cheap: one
    state per step). Derivatives of the peak with respect to every other input follow from
    the implicit function theorem (optimistix ``ImplicitAdjoint``).
``"golden"``
    optimistix ``GoldenSearch`` of −V inside the bracket, searched as the offset from the
    bracket centre (optimistix 0.1.0 places its first midpoint at (upper − lower)/(φ + 1)
    instead of lower + …, so brackets not straddling 0 diverge; upstream issue #236).
``"bfgs"``
    optimistix ``BFGS`` of −V from the grid peak, unconstrained; a result leaving the
    bracket is reported as failed.
``"local"``
    no solver loop: the grid parabola's vertex v, then the metric at v and v ± 0.02 D
    (``LOCAL_OFFSETS_D``; one batched evaluation, compiled like the grid: a solver's while
    loop around the pipeline's derivatives compiles 3–4× longer), and the vertex of the
    parabola through those points, clipped to the bracket. Near the hyperopic limit or the
    window's end the stencil moves inside the bracket instead of being clipped. Its
    derivative is that of the fitted vertex (a finite-difference estimate of the implicit
    one). Success: the fit is concave and its vertex lies within ``LOCAL_TRUST_D`` =
    0.05 D of the stencil's centre (or the peak is held at the hyperopic limit). On
    10 eyes × 2 layouts × 9 depths: 2–3e-5 D from Newton at the median, 4–9e-5 D at p95
    (five points out to ±0.05 D: 0.9–1.9e-4 and 2.8–5.7e-4; the curvature's cubic bias
    grows with the stencil's width), with three states per peak instead of five.
``"parabola"``
    the vertex of the parabola through the grid maximum and its neighbours (no solver),
    the metric evaluated there.
``"vertex"``
    the same vertex, and the parabola's own value there: no pipeline evaluation at all
    beyond the grid (what population sweeps use when every second counts; the location is
    the parabola's, RESULTS §10).
``"grid"``
    the grid maximum itself.
``"adaptive"``
    ``"local"`` only where the grid cannot answer: every grid peak's location is first
    estimated from the grid alone (:func:`grid_peak_estimate`: the maximum of the quartic
    through the five grid values around it, with the distance to the three-point parabola's
    vertex as its error estimate), and the local stencil is spent only on the (eye, depth)
    pairs whose estimate exceeds ``tolerance_D`` or which the estimate cannot serve (a
    neighbour missing at the window's end or the hyperopic limit, a curve not concave
    there, and, when both candidates are refined, a second peak whose choice reads the
    refined values). Those pairs are gathered first and refined in batches of a fixed size
    inside one ``lax.map``; a batch holding none is skipped (``lax.cond``), so the
    arithmetic follows the number of pairs refined (under an outer ``jax.vmap`` the skip
    becomes a select and every batch is computed: the values are the same).

Every result carries a success flag and, for the optimistix methods, the solver's result
code; the pipeline never raises inside the batch (``throw=False``).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import NamedTuple

import equinox as eqx
import jax
import jax.numpy as jnp
from jaxtyping import Array, ArrayLike, Bool

from lfjax.base.errors import ParameterError
from lfjax.base.parabola import parabola_vertex
from lfjax.base.types import shape_checked
from lfjax.display.lenticular import check_display_for_layout
from lfjax.kernel.pipeline import (
    Accommodation,
    PipelineConfig,
    Scene,
    eye_coefficients,
    pair_metric,
    reference_normalisers,
    retinal_metrics,
)
from lfjax.model.eyes import Eyes
from lfjax.model.spectral import Spectrum
from lfjax.vision.peak_options import METRICS, PeakOptions, resolved_method
from lfjax.vision.peak_refinement import (
    ADAPTIVE_BATCHES,
    Peak,
    adaptive_refinement,
    grid_peak_estimate,
    local_refinement,
    map_pairs,
    pairs_per_batch,
    parabola_value,
    refine_peak,
)

class Peaks(eqx.Module):
    """Predicted accommodation of every (eye, rendered depth): the global maximum and, where
    the curve has one, a second peak.

    Attributes (each (n_eyes, n_depth))
    ----------
    accommodation_D : continuous predicted accommodation (global maximum), D
    value : metric at it
    success : bool — the solver converged inside its bracket, and the peak is not on the
        grid's far end (where the true maximum may lie beyond the grid)
    result : optimistix result code of that refinement (0 successful, −1 no solver)
    n_steps : solver steps
    grid_accommodation_D, grid_value : the grid maximum, D
    second_accommodation_D, second_value : the other local maximum (NaN where there is none)
    at_hyperopic_limit : bool — the maximum is at 0 D (the eye cannot relax further)
    at_grid_edge : bool — the grid maximum is the last (or first, above 0 D) state
    grid_error_D : the grid's own estimate of how far its interpolated peak lies from the
        true maximum (:func:`grid_peak_estimate`), D; ``inf`` where it cannot tell. The
        ``"adaptive"`` method refines exactly the peaks where it exceeds ``tolerance_D``.
    """

    accommodation_D: Array
    value: Array
    success: Array
    result: Array
    n_steps: Array
    grid_accommodation_D: Array
    grid_value: Array
    second_accommodation_D: Array
    second_value: Array
    at_hyperopic_limit: Array
    at_grid_edge: Array
    grid_error_D: Array

    @property
    def has_second_peak(self):
        return jnp.isfinite(self.second_accommodation_D)


def _local_maxima(values, allowed, prominence: float):
    """Indices of the global and of the highest other local grid maximum (…, n).

    A second maximum counts when it is a strict local maximum of the allowed states, at
    least ``prominence`` (relative) above the lowest value between it and the global one.
    Returns (global index, second index or −1).
    """
    v = jnp.where(allowed, values, -jnp.inf)
    n = v.shape[-1]
    best = jnp.argmax(v, axis=-1)
    left = jnp.concatenate([jnp.full(v.shape[:-1] + (1,), -jnp.inf), v[..., :-1]], axis=-1)
    right = jnp.concatenate([v[..., 1:], jnp.full(v.shape[:-1] + (1,), -jnp.inf)], axis=-1)
    local = (v > left) & (v >= right) & jnp.isfinite(v)
    k = jnp.arange(n)
    # lowest value between each candidate and the global maximum
    lo = jnp.minimum(k, best[..., None])
    hi = jnp.maximum(k, best[..., None])
    inside = (k[..., None, :] >= lo[..., :, None]) & (k[..., None, :] <= hi[..., :, None])
    valley = jnp.min(jnp.where(inside, v[..., None, :], jnp.inf), axis=-1)  # (…, n)
    prominent = v - valley >= prominence * jnp.abs(v)
    candidate = local & prominent & (k != best[..., None])
    second = jnp.where(jnp.any(candidate, axis=-1),
                       jnp.argmax(jnp.where(candidate, v, -jnp.inf), axis=-1), -1)
    return best, second


def _bracket(states_D, index):
    n = states_D.shape[-1]
    lo = jnp.take_along_axis(states_D, jnp.clip(index - 1, 0, n - 1)[..., None], -1)[..., 0]
    hi = jnp.take_along_axis(states_D, jnp.clip(index + 1, 0, n - 1)[..., None], -1)[..., 0]
    return lo, hi


@eqx.filter_jit
@shape_checked
def accommodation_peaks(
    eyes: Eyes, scene: Scene, spectrum: Spectrum, grid: Accommodation, config: PipelineConfig,
    metric: str = "vsotf", peaks: PeakOptions = PeakOptions(),  # noqa: B008 - frozen
    allowed: Bool[ArrayLike, "n_depth n_k"] | None = None,
) -> Peaks:
    """Continuous predicted accommodation of every eye and rendered depth.

    Compiled here (``eqx.filter_jit``: strings, numbers and ``config`` static, arrays
    traced); pure, so ``jax.vmap`` and ``jax.grad`` apply from outside, and inside an outer
    ``jax.jit`` it is inlined.

    Parameters
    ----------
    eyes, scene, spectrum, config : as :func:`lfjax.kernel.pipeline.retinal_metrics`
    grid : Accommodation whose ``pair_index`` (n_depth, n_k) lists each depth's grid states
        in increasing accommodation (through_focus's grid)
    metric : "vsotf" or "strehl"
    peaks : :class:`PeakOptions`: the method (module docstring; "auto" by default), the
        second-peak prominence, the solvers' tolerance and step limit, and whether second
        peaks are refined — with ``second_peaks`` (default) both candidates run in one
        batched solve and the higher refined value is returned as the peak (a second peak
        that refines higher wins); without, the solver's work halves: the second peak is
        located by the grid parabola and valued on the grid. ``"adaptive"`` refines only the
        peaks whose grid estimate's error (:func:`grid_peak_estimate`) may exceed
        ``peaks.tolerance_D``; the others keep the estimate. (``peaks.metrics`` is not read:
        this function finds the peaks of ``metric``.)
    allowed : (n_depth, n_k) bool, grid states to consider (default all)
    """
    if metric not in METRICS:
        raise ParameterError("metric", "{metric} must be one of {allowed}, got {got!r}",
                             allowed=METRICS, got=metric)
    check_display_for_layout(scene.display, scene, parameter="scene", path=".display")
    reference = reference_normalisers(scene, spectrum, grid, config)
    on_grid = retinal_metrics(eyes, scene, spectrum, grid, config, reference)
    return peaks_from_grid(getattr(on_grid, metric), eyes, scene, spectrum, grid, config,
                           reference, metric, peaks, allowed)


def single_state_metric(measured_pupil_mm: float, scene: Scene, spectrum: Spectrum,
                        grid: Accommodation, config: PipelineConfig, reference,
                        metric: str = "vsotf"):
    """The function solvers maximise: ``value_fn(a, (zernike_um, depth_D))`` → the metric
    (scalar) of one eye (coefficients as the pipeline uses them, piston and tilt dropped)
    accommodated at ``a`` (D) on the scene's point rendered at ``depth_D`` (D), with the
    accommodation SA of ``grid`` and the scene's ``reference`` normalisers."""

    def value_fn(a, args):
        zernike_um, depth = args
        one = Scene(scene.centres_mm, scene.diameters_mm, scene.cdp_D, depth[None],
                    scene.pupil_diameter_mm, scene.display)
        state = Accommodation(a[None], jnp.zeros((1, 1), jnp.int32), grid.sa_c40_um_per_D,
                              grid.sa_radius_mm)
        return pair_metric(zernike_um, measured_pupil_mm, one, spectrum, state, config,
                           reference, metric)[0, 0]

    return value_fn


class _Curves(NamedTuple):
    """One grid of through-focus curves and what refining their peaks needs (host-static
    choices and traced arrays, all (n_eyes, n_depth, n_k) or (n_eyes, n_depth))."""

    values: jnp.ndarray  # the metric on the grid
    states: jnp.ndarray  # each curve's states, D
    allowed: jnp.ndarray  # the states a peak may sit on
    usable: jnp.ndarray  # allowed states, NaN elsewhere
    value_fn: Callable  # the metric of one (eye, depth) at one state
    args: tuple  # (coefficients, depths) of every (eye, depth)
    method: str  # resolved refinement
    batch: int  # pairs refined together
    peaks: PeakOptions

    @property
    def masked(self):
        return jnp.where(self.allowed, self.values, -jnp.inf)


def _take(x, i):
    return jnp.take_along_axis(x, jnp.maximum(i, 0)[..., None], -1)[..., 0]


def _bracket_of(c: _Curves, index):
    """The bracket of the grid maximum at ``index``: its neighbours among the allowed states
    (disallowed ones lie below 0 D or outside the window, both ends of the usable grid)."""
    n = c.states.shape[-1]
    lo, hi = _bracket(c.states, jnp.maximum(index, 0))
    lo = jnp.where(jnp.isfinite(_take(c.usable, jnp.maximum(index - 1, 0))) & (index > 0), lo,
                   _take(c.states, index))
    hi = jnp.where(jnp.isfinite(_take(c.usable, jnp.minimum(index + 1, n - 1)))
                   & (index < n - 1), hi, _take(c.states, index))
    return jnp.maximum(lo, 0.0), hi


def _unrefined(location, value) -> Peak:
    """A peak located without a solver (no steps, result −1, success)."""
    return Peak(location, value, jnp.ones(location.shape, bool),
                jnp.full(location.shape, -1, jnp.int32), jnp.zeros(location.shape, jnp.int32))


def _grid_located(c: _Curves, index) -> Peak:
    """The grid parabola's vertex of the maximum at ``index``, valued on the grid."""
    located = jnp.clip(parabola_vertex(c.states, c.masked, index), *_bracket_of(c, index))
    return _unrefined(located, _take(c.values, index))


def _refine(c: _Curves, index) -> Peak:
    """The maximum at grid ``index`` (n_eyes, n_depth) refined by ``c.method``."""
    lo, hi = _bracket_of(c, index)
    start = _take(c.states, index)
    if c.method == "grid":
        return _unrefined(start, _take(c.values, index))
    if c.method == "parabola":
        a = jnp.clip(parabola_vertex(c.states, c.masked, index), lo, hi)
        return _unrefined(a, map_pairs(c.value_fn, c.batch, a, c.args))
    if c.method == "vertex":
        a = jnp.clip(parabola_vertex(c.states, c.masked, index), lo, hi)
        return _unrefined(a, parabola_value(c.states, c.masked, index, a))
    if c.method == "local":
        return local_refinement(c.value_fn, parabola_vertex(c.states, c.masked, index), lo, hi,
                                c.args, c.batch)
    if c.method == "newton":  # start from the grid parabola's vertex: fewer steps
        start = jnp.clip(parabola_vertex(c.states, c.masked, index), lo, hi)
    solve = lambda lo_, hi_, s_, z_, d_: refine_peak(  # noqa: E731
        c.value_fn, lo_, hi_, s_, (z_, d_), c.method, c.peaks.atol_D, c.peaks.max_steps)
    return map_pairs(solve, c.batch, lo, hi, start, *c.args)


def _adaptive(c: _Curves, best, second_index, has_second) -> tuple[Peak, Peak]:
    """``"adaptive"``: (global, second) candidates, refined only where the grid's own
    estimate cannot answer. The candidates go side by side along the eye axis (not vmapped:
    under vmap the skipped batches would be computed); a pair with a second peak refines
    both, since the choice between them reads their refined values."""
    second_peaks = c.peaks.second_peaks
    n_cand = 2 if second_peaks else 1
    index = jnp.concatenate([best, second_index][:n_cand])
    bounds = [_bracket_of(c, i) for i in (best, second_index)[:n_cand]]
    lo = jnp.concatenate([b[0] for b in bounds])
    hi = jnp.concatenate([b[1] for b in bounds])
    tile = lambda x: jnp.concatenate([x] * n_cand)  # noqa: E731
    estimate = grid_peak_estimate(tile(c.states), tile(c.masked), index)
    vertex = parabola_vertex(tile(c.states), tile(c.masked), index)
    force = tile(has_second) if second_peaks else jnp.zeros(index.shape, bool)
    n_pairs = index.shape[0] * index.shape[1]
    adaptive_batch = max(1, min(c.batch, -(-n_pairs // ADAPTIVE_BATCHES)))
    both = adaptive_refinement(c.value_fn, estimate, vertex, lo, hi,
                               tuple(tile(a) for a in c.args), c.peaks.tolerance_D, force,
                               adaptive_batch)
    n_eyes = c.values.shape[0]
    main = jax.tree_util.tree_map(lambda x: x[:n_eyes], both)
    if second_peaks:
        return main, jax.tree_util.tree_map(lambda x: x[n_eyes:], both)
    return main, _grid_located(c, second_index)


def _candidates(c: _Curves, best, second_index, has_second) -> tuple[Peak, Peak]:
    """The global and the second candidate, each refined as ``c.peaks`` says."""
    if c.method == "adaptive":
        return _adaptive(c, best, second_index, has_second)
    if c.peaks.second_peaks:
        # Both candidates in one batched solve: one compiled solver (a lax.cond between two
        # solves compiled the pipeline's derivatives twice).
        both = jax.vmap(lambda i: _refine(c, i))(jnp.stack([best, second_index]))
        return (jax.tree_util.tree_map(lambda x: x[0], both),
                jax.tree_util.tree_map(lambda x: x[1], both))
    return _refine(c, best), _grid_located(c, second_index)


def peaks_from_grid(
    values, eyes: Eyes, scene: Scene, spectrum: Spectrum, grid: Accommodation,
    config: PipelineConfig, reference, metric: str = "vsotf",
    peaks: PeakOptions = PeakOptions(),  # noqa: B008 - frozen, checked once
    allowed=None,
) -> Peaks:
    """:func:`accommodation_peaks` from metric values already computed on the grid,
    ``values`` (n_eyes, n_depth, n_k); ``reference`` = the scene's
    :func:`lfjax.kernel.pipeline.reference_normalisers`; ``peaks``: see
    :func:`accommodation_peaks`."""
    if not isinstance(peaks, PeakOptions):
        raise ParameterError("peaks", "{peaks} must be lfjax.PeakOptions, got {got}",
                             got=type(peaks).__name__)
    method = resolved_method(metric, peaks.method)
    if grid.pair_index.shape[-1] < 2:
        raise ValueError(
            f"a peak needs a grid of >= 2 accommodation states per depth to bracket it, got "
            f"{grid.pair_index.shape[-1]}"
        )
    states = grid.states_D[grid.pair_index]  # (n_depth, n_k)
    allowed = jnp.ones(states.shape, bool) if allowed is None else jnp.asarray(allowed, bool)
    states_b = jnp.broadcast_to(states, values.shape)
    allowed_b = jnp.broadcast_to(allowed, values.shape)
    best, second = _local_maxima(values, allowed_b, peaks.prominence)
    usable = jnp.where(allowed_b, states_b, jnp.nan)
    coefficients = eye_coefficients(eyes, config)
    curves = _Curves(
        values, states_b, allowed_b, usable,
        single_state_metric(eyes.measured_pupil_mm, scene, spectrum, grid, config, reference,
                            metric),
        (jnp.broadcast_to(coefficients[:, None, :], values.shape[:2] + coefficients.shape[-1:]),
         jnp.broadcast_to(scene.depths_D[None, :], values.shape[:2])),
        method, pairs_per_batch(scene, config, method, 2 if peaks.second_peaks else 1), peaks)
    has_second = second >= 0
    main, other = _candidates(curves, best, jnp.where(has_second, second, best), has_second)
    return _chosen(curves, main, other, best, second, has_second)


def _chosen(c: _Curves, main: Peak, other: Peak, best, second, has_second) -> Peaks:
    """The higher refined candidate as the peak, the other as the second peak where it is
    distinct, with the flags of the grid's ends."""
    swap = has_second & (other.value > main.value)
    pick = lambda a, b: jnp.where(swap, b, a)  # noqa: E731
    peak = jax.tree_util.tree_map(pick, main, other)
    alt = jax.tree_util.tree_map(pick, other, main)
    distinct = has_second & (jnp.abs(alt.accommodation_D - peak.accommodation_D) > 1e-3)
    at_limit = peak.accommodation_D <= 10 * c.peaks.atol_D
    edge_index = jnp.where(swap, second, best)
    edge_state = _take(c.states, edge_index)
    first = jnp.nanmin(c.usable, axis=-1)
    last = jnp.nanmax(c.usable, axis=-1)
    at_edge = ((edge_state >= last - 1e-9) | ((edge_state <= first + 1e-9) & (first > 1e-9)))
    return Peaks(
        accommodation_D=peak.accommodation_D, value=peak.value,
        success=peak.success & ~at_edge, result=peak.result, n_steps=peak.n_steps,
        grid_accommodation_D=_take(c.states, best), grid_value=_take(c.values, best),
        second_accommodation_D=jnp.where(distinct, alt.accommodation_D, jnp.nan),
        second_value=jnp.where(distinct, alt.value, jnp.nan),
        at_hyperopic_limit=at_limit, at_grid_edge=at_edge,
        grid_error_D=grid_peak_estimate(c.states, c.masked, edge_index).error_D,
    )


__all__ = ["Peaks", "accommodation_peaks", "peaks_from_grid", "single_state_metric"]
