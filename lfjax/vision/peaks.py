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

Every result carries a success flag and, for the optimistix methods, the solver's result
code; the pipeline never raises inside the batch (``throw=False``).
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optimistix as optx
from jaxtyping import Array, ArrayLike, Bool, Float, Int

from lfjax.base.parabola import parabola_vertex
from lfjax.base.types import FULL, shape_checked
from lfjax.base.types import is_concrete as _is_concrete
from lfjax.model.eyes import Eyes
from lfjax.kernel.pipeline import (
    Accommodation,
    PipelineConfig,
    Scene,
    eye_coefficients,
    pair_metric,
    reference_normalisers,
    retinal_metrics,
)
from lfjax.kernel.optics import state_chunk
from lfjax.model.spectral import Spectrum

PEAK_METHODS = ("auto", "newton", "golden", "bfgs", "local", "parabola", "vertex", "grid")
METRICS = ("vsotf", "strehl")


def result_name(code: int) -> str:
    """Name of an optimistix result code (``Peaks.result``); −1 means no solver ran."""
    if int(code) < 0:
        return "no solver"
    for name, item in optx.RESULTS._name_to_item.items():  # noqa: SLF001 (no public lookup)
        if int(item._value) == int(code):  # noqa: SLF001
            return name
    return f"unknown ({code})"


class Peak(eqx.Module):
    """One refined maximum of a scalar function on a bracket.

    Attributes
    ----------
    accommodation_D : (…) location of the maximum, D
    value : (…) function value there
    success : (…) bool, the solver converged inside the bracket
    result : (…) int, optimistix result code (0 successful; −1 no solver ran)
    n_steps : (…) int, solver steps (function evaluations for golden section)
    """

    accommodation_D: Float[Array, "..."]
    value: Float[Array, "..."]
    success: Bool[Array, "..."]
    result: Int[Array, "..."]
    n_steps: Int[Array, "..."]


def _check_method(method: str):
    if method not in PEAK_METHODS:
        raise ValueError(f"method must be one of {PEAK_METHODS}, got {method!r}")


def refine_peak(value_fn, lower_D, upper_D, start_D, args, method: str = "newton",
                atol_D: float = 1e-5, max_steps: int = 64) -> Peak:
    """Maximise ``value_fn(a, args)`` (scalar a in D) on the bracket [lower_D, upper_D].

    Scalars in, :class:`Peak` out: vmap it over brackets. Pure and differentiable: the peak
    location's derivative with respect to ``args`` comes from the implicit function theorem
    on the optimality condition (optimistix ``ImplicitAdjoint``); the bracket is treated as
    a constant. Where the maximum sits on a bracket end (the hyperopic limit), the
    location's derivative is zero (the constraint is active).

    Parameters
    ----------
    value_fn : callable (a, args) -> scalar, smooth in a near the peak
    lower_D, upper_D : bracket, D (lower < upper)
    start_D : first iterate (Newton, BFGS), D
    method : "newton", "golden" or "bfgs" (see module docstring)
    atol_D : tolerance on the location, D
    """
    _check_method(method)
    if method in ("parabola", "vertex", "local", "grid", "auto"):
        raise ValueError(f"refine_peak needs a solver method (newton, golden, bfgs), got {method!r}")
    bracket = (lower_D, upper_D, start_D)
    if _is_concrete(*bracket):
        lo, hi, start = (np.asarray(x, float) for x in bracket)
        if not (np.all(np.isfinite(lo)) and np.all(np.isfinite(hi)) and np.all(np.isfinite(start))):
            raise ValueError("the bracket (lower_D, upper_D, start_D) must be finite")
        if np.any(lo >= hi):
            raise ValueError(
                f"empty or one-point bracket: need lower_D < upper_D, got [{lo}, {hi}] D"
            )
    lower_D, upper_D, start_D = (jax.lax.stop_gradient(jnp.asarray(x, float)) for x in bracket)
    lower_D = eqx.error_if(lower_D, ~(lower_D < upper_D),
                           "empty or one-point bracket: need lower_D < upper_D")
    tolerances = dict(rtol=1e-7, atol=atol_D)
    if method == "newton":
        def slope(a, args):
            return jax.jvp(lambda x: value_fn(x, args), (a,), (jnp.ones_like(a),))[1]

        # A maximum on a bracket end (the hyperopic limit) has no root inside: Newton's
        # clipped iterates would stall there until max_steps (and, under vmap, hold up the
        # whole batch). Such an end is pinned: the root of a − end, found in one step.
        pinned_low = slope(lower_D, args) < 0
        pinned_high = slope(upper_D, args) > 0
        end = jnp.where(pinned_low, lower_D, upper_D)
        pinned = pinned_low | pinned_high

        def condition(a, args):
            return jnp.where(pinned, a - end, slope(a, args))

        sol = optx.root_find(condition, optx.Newton(**tolerances),
                             jnp.where(pinned, end, start_D), args,
                             options=dict(lower=lower_D, upper=upper_D), throw=False,
                             max_steps=max_steps)
        location = sol.value
    elif method == "golden":
        centre = 0.5 * (lower_D + upper_D)
        half = 0.5 * (upper_D - lower_D)
        sol = optx.minimise(lambda off, args: -value_fn(centre + off, args),
                            optx.GoldenSearch(**tolerances), jnp.zeros_like(centre), args,
                            options=dict(lower=-half, upper=half), throw=False,
                            max_steps=max_steps)
        location = centre + sol.value
    else:
        sol = optx.minimise(lambda a, args: -value_fn(a[0], args), optx.BFGS(**tolerances),
                            start_D[None], args, throw=False, max_steps=max_steps)
        location = sol.value[0]
    solved = sol.result == optx.RESULTS.successful
    if method == "golden":
        # The golden section's bracket after n steps is known: (upper − lower)·0.618ⁿ. Its
        # Cauchy test also asks the values to settle, which float32 noise on a flat top can
        # keep from happening until max_steps (benchmarks/validation/peak_finding.py: 90 of 720 VSOTF
        # and 79 of 720 Strehl peaks, located to a median 1e-4 D, were flagged as failures
        # after 32 steps); a bracket already narrower than atol_D has converged.
        shrink = jnp.power(0.5 * (jnp.sqrt(5.0) - 1.0), sol.stats["num_steps"])
        solved = solved | ((upper_D - lower_D) * shrink <= atol_D)
    tol = 10 * atol_D
    inside = (location >= lower_D - tol) & (location <= upper_D + tol)
    on_end = (location <= lower_D + tol) | (location >= upper_D - tol)
    location = jnp.where(on_end, jax.lax.stop_gradient(location), location)
    value = value_fn(location, args)
    return Peak(location, value, solved & inside, sol.result._value.astype(jnp.int32),  # noqa: SLF001
                sol.stats["num_steps"].astype(jnp.int32))


LOCAL_OFFSETS_D = (-0.02, 0.0, 0.02)
"""Offsets (D) from the grid parabola's vertex at which ``"local"`` evaluates the metric."""

LOCAL_TRUST_D = 0.05
"""``"local"`` trusts its fitted vertex this far (D) from the stencil's centre."""


# Kernel evaluations one refinement step holds at once, per (eye, depth) pair and state it
# evaluates: the local stencil's points; Newton's location is a root of the metric's slope,
# so each step carries the value with its first and second forward derivatives.
STATE_COST = {"local": len(LOCAL_OFFSETS_D), "newton": 4, "golden": 1, "bfgs": 3, "parabola": 1}


def resolved_method(metric: str, method: str) -> str:
    """The refinement ``method`` runs for ``metric``: ``"auto"`` is Newton for VSOTF (smooth
    in accommodation) and golden section for the Strehl ratio; any other name is itself."""
    if method == "auto":
        return "newton" if metric == "vsotf" else "golden"
    return method


def _pairs_per_batch(scene: Scene, config: PipelineConfig, method: str, n_candidates: int) -> int:
    """(eye, depth) pairs refined together: as many as the kernel's working memory holds
    (:func:`lfjax.kernel.optics.state_chunk`), counting each pair's states, their derivatives
    and the candidates refined side by side."""
    n_views = scene.centres_mm.shape[0]
    states = state_chunk(2**31, n_views, config.n_fft)
    return max(1, states // (STATE_COST.get(method, 1) * n_candidates))


def _map_pairs(fn, batch: int, *args):
    """``jax.vmap(jax.vmap(fn))(*args)`` over the leading (n_eyes, n_depth) axes of every
    argument, in batches of ``batch`` pairs one after another (``lax.map``) when there are
    more: the pairs are independent, so the values are those of one vmap over all."""
    lead = jax.tree_util.tree_leaves(args)[0].shape[:2]
    n_pairs = lead[0] * lead[1]
    if batch >= n_pairs:
        return jax.vmap(jax.vmap(fn))(*args)
    flat = jax.tree_util.tree_map(lambda x: x.reshape((n_pairs,) + x.shape[2:]), args)
    out = jax.lax.map(lambda xs: fn(*xs), flat, batch_size=batch)
    return jax.tree_util.tree_map(lambda x: x.reshape(lead + x.shape[1:]), out)


def _local_refinement(value_fn, vertex_D, lower_D, upper_D, args, batch: int) -> Peak:
    offsets = jnp.asarray(LOCAL_OFFSETS_D, vertex_D.dtype)
    # The stencil is moved inside the usable bracket rather than clipped at its ends: clipped
    # points would coincide at the hyperopic limit and leave the fit singular.
    low = jnp.maximum(lower_D, 0.0)
    centre = jnp.clip(vertex_D, low - offsets[0], upper_D - offsets[-1])
    centre = jax.lax.stop_gradient(jnp.where(upper_D - low < offsets[-1] - offsets[0],
                                             0.5 * (low + upper_D), centre))
    points = centre[..., None] + offsets
    batched = jax.vmap(value_fn, in_axes=(0, None))  # over the stencil's points
    values = _map_pairs(batched, batch, points, args)  # (n_eyes, n_depth, n_points)
    # least-squares parabola in x = point − centre: minimise Σ (c0 + c1 x + c2 x² − v)²
    x = points - centre[..., None]
    design = jnp.stack([jnp.ones_like(x), x, x * x], axis=-1)
    normal = jnp.einsum("...ki,...kj->...ij", design, design, precision=FULL)
    rhs = jnp.einsum("...ki,...k->...i", design, values, precision=FULL)
    c0, c1, c2 = jnp.moveaxis(jnp.linalg.solve(normal, rhs[..., None])[..., 0], -1, 0)
    concave = c2 < 0
    shift = jnp.where(concave, -c1 / (2.0 * jnp.where(concave, c2, -1.0)), 0.0)
    # a vertex far beyond the stencil (a coarse grid's parabola far off) is not trusted
    within = jnp.abs(shift) <= LOCAL_TRUST_D
    location = jnp.clip(centre + jnp.clip(shift, -LOCAL_TRUST_D, LOCAL_TRUST_D), low, upper_D)
    # Held at the hyperopic limit: the bracket reaches 0 D and the fit falls from there (a
    # peak beyond the limit, where the fit may be convex: the curve's far flank).
    on_limit = (low <= 0.0) & (c1 - 2.0 * c2 * centre < 0)
    location = jnp.where(on_limit, low, location)
    peak_value = c0 + c1 * (location - centre) + c2 * (location - centre) ** 2
    n = jnp.full(location.shape, len(LOCAL_OFFSETS_D), jnp.int32)
    return Peak(location, peak_value, (concave & within) | on_limit,
                jnp.full(location.shape, -1, jnp.int32), n)


def _parabola_value(states_D, values, index, at_D):
    """Value at ``at_D`` (D) of the parabola through grid points index−1, index, index+1;
    the grid value where :func:`lfjax.base.parabola.parabola_vertex` falls back to the grid point."""
    n = states_D.shape[-1]
    lo, hi = jnp.clip(index - 1, 0, n - 1), jnp.clip(index + 1, 0, n - 1)
    take = lambda x, i: jnp.take_along_axis(x, i[..., None], axis=-1)[..., 0]  # noqa: E731
    y0, y1, y2 = take(values, lo), take(values, index), take(values, hi)
    a1 = take(states_D, index)
    h = 0.5 * (take(states_D, hi) - take(states_D, lo))
    denom = y0 - 2 * y1 + y2
    ok = (lo != index) & (hi != index) & (denom < 0) & jnp.isfinite(y0 + y2)
    y0, y2, h = (jnp.where(ok, y0, y1), jnp.where(ok, y2, y1), jnp.where(ok, h, 1.0))
    x = at_D - a1
    return y1 + x * (y2 - y0) / (2 * h) + x * x * (y0 - 2 * y1 + y2) / (2 * h * h)


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
    metric: str = "vsotf", method: str = "auto",
    allowed: Bool[ArrayLike, "n_depth n_k"] | None = None, prominence: float = 0.05,
    atol_D: float = 1e-5, max_steps: int = 32, refine_second: bool = True,
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
    method : see the module docstring; "auto" by default
    allowed : (n_depth, n_k) bool, grid states to consider (default all)
    prominence : a second local maximum is reported when it stands this fraction of its
        value above the valley between it and the global one
    atol_D : location tolerance, D
    refine_second : refine the second local maximum too (default). Both candidates then
        run in one batched solve and the higher refined value is returned as the peak (a
        second peak that refines higher wins). False halves the solver's work: the second
        peak is located by the grid parabola and valued on the grid.
    """
    _check_method(method)
    if metric not in METRICS:
        raise ValueError(f"metric must be one of {METRICS}, got {metric!r}")
    reference = reference_normalisers(scene, spectrum, grid, config)
    on_grid = retinal_metrics(eyes, scene, spectrum, grid, config, reference)
    return peaks_from_grid(getattr(on_grid, metric), eyes, scene, spectrum, grid, config,
                           reference, metric, method, allowed, prominence, atol_D, max_steps,
                           refine_second)


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


def peaks_from_grid(
    values, eyes: Eyes, scene: Scene, spectrum: Spectrum, grid: Accommodation,
    config: PipelineConfig, reference, metric: str = "vsotf", method: str = "auto",
    allowed=None, prominence: float = 0.05, atol_D: float = 1e-5, max_steps: int = 32,
    refine_second: bool = True,
) -> Peaks:
    """:func:`accommodation_peaks` from metric values already computed on the grid,
    ``values`` (n_eyes, n_depth, n_k); ``reference`` = the scene's
    :func:`lfjax.kernel.pipeline.reference_normalisers`."""
    _check_method(method)
    method = resolved_method(metric, method)
    if grid.pair_index.shape[-1] < 2:
        raise ValueError(
            f"a peak needs a grid of >= 2 accommodation states per depth to bracket it, got "
            f"{grid.pair_index.shape[-1]}"
        )
    states = grid.states_D[grid.pair_index]  # (n_depth, n_k)
    allowed = jnp.ones(states.shape, bool) if allowed is None else jnp.asarray(allowed, bool)
    states_b = jnp.broadcast_to(states, values.shape)
    allowed_b = jnp.broadcast_to(allowed, values.shape)
    best, second = _local_maxima(values, allowed_b, prominence)
    take = lambda x, i: jnp.take_along_axis(x, jnp.maximum(i, 0)[..., None], -1)[..., 0]  # noqa: E731
    grid_peak, grid_value = take(states_b, best), take(values, best)
    # Brackets: the neighbours among allowed states (disallowed ones lie below 0 D or
    # outside the window, both ends of the usable grid).
    usable = jnp.where(allowed_b, states_b, jnp.nan)
    first = jnp.nanmin(usable, axis=-1)
    last = jnp.nanmax(usable, axis=-1)

    def bracket_of(index):
        lo, hi = _bracket(states_b, jnp.maximum(index, 0))
        lo = jnp.where(jnp.isfinite(take(usable, jnp.maximum(index - 1, 0))) & (index > 0), lo,
                       take(states_b, index))
        hi = jnp.where(jnp.isfinite(take(usable, jnp.minimum(index + 1, states.shape[-1] - 1)))
                       & (index < states.shape[-1] - 1), hi, take(states_b, index))
        return jnp.maximum(lo, 0.0), hi

    value_fn = single_state_metric(eyes.measured_pupil_mm, scene, spectrum, grid, config,
                                   reference, metric)
    depths_b = jnp.broadcast_to(scene.depths_D[None, :], values.shape[:2])
    coefficients = eye_coefficients(eyes, config)
    z_b = jnp.broadcast_to(coefficients[:, None, :], values.shape[:2] + coefficients.shape[-1:])

    n_candidates = 2 if refine_second else 1
    batch = _pairs_per_batch(scene, config, method, n_candidates)

    def refine(index):  # index (n_eyes, n_depth)
        lo, hi = bracket_of(index)
        start = take(states_b, index)
        if method == "grid":
            return Peak(start, take(values, index), jnp.ones(start.shape, bool),
                        jnp.full(start.shape, -1, jnp.int32), jnp.zeros(start.shape, jnp.int32))
        if method == "parabola":
            a = jnp.clip(parabola_vertex(states_b, jnp.where(allowed_b, values, -jnp.inf), index), lo, hi)
            v = _map_pairs(value_fn, batch, a, (z_b, depths_b))
            return Peak(a, v, jnp.ones(a.shape, bool), jnp.full(a.shape, -1, jnp.int32),
                        jnp.zeros(a.shape, jnp.int32))
        if method == "vertex":
            masked = jnp.where(allowed_b, values, -jnp.inf)
            a = jnp.clip(parabola_vertex(states_b, masked, index), lo, hi)
            v = _parabola_value(states_b, masked, index, a)
            return Peak(a, v, jnp.ones(a.shape, bool), jnp.full(a.shape, -1, jnp.int32),
                        jnp.zeros(a.shape, jnp.int32))
        if method == "local":
            return _local_refinement(value_fn, parabola_vertex(
                states_b, jnp.where(allowed_b, values, -jnp.inf), index), lo, hi, (z_b, depths_b),
                batch)
        if method == "newton":  # start from the grid parabola's vertex: fewer steps
            start = jnp.clip(parabola_vertex(states_b, jnp.where(allowed_b, values, -jnp.inf),
                                             index), lo, hi)
        solve = lambda lo_, hi_, s_, z_, d_: refine_peak(  # noqa: E731
            value_fn, lo_, hi_, s_, (z_, d_), method, atol_D, max_steps)
        return _map_pairs(solve, batch, lo, hi, start, z_b, depths_b)

    has_second = second >= 0
    second_index = jnp.where(has_second, second, best)
    if refine_second:
        # Both candidates in one batched solve: one compiled solver (a lax.cond between two
        # solves compiled the pipeline's derivatives twice).
        both = jax.vmap(refine)(jnp.stack([best, second_index]))
        main = jax.tree_util.tree_map(lambda x: x[0], both)
        other = jax.tree_util.tree_map(lambda x: x[1], both)
    else:
        main = refine(best)
        lo, hi = bracket_of(second_index)
        located = jnp.clip(parabola_vertex(states_b, jnp.where(allowed_b, values, -jnp.inf),
                                           second_index), lo, hi)
        other = Peak(located, take(values, second_index), jnp.ones(located.shape, bool),
                     jnp.full(located.shape, -1, jnp.int32), jnp.zeros(located.shape, jnp.int32))
    swap = has_second & (other.value > main.value)
    pick = lambda a, b: jnp.where(swap, b, a)  # noqa: E731
    peak = jax.tree_util.tree_map(pick, main, other)
    alt = jax.tree_util.tree_map(pick, other, main)
    distinct = has_second & (jnp.abs(alt.accommodation_D - peak.accommodation_D) > 1e-3)
    at_limit = peak.accommodation_D <= 10 * atol_D
    edge_index = jnp.where(swap, second, best)
    edge_state = take(states_b, edge_index)
    at_edge = ((edge_state >= last - 1e-9) | ((edge_state <= first + 1e-9) & (first > 1e-9)))
    return Peaks(
        accommodation_D=peak.accommodation_D, value=peak.value,
        success=peak.success & ~at_edge, result=peak.result, n_steps=peak.n_steps,
        grid_accommodation_D=grid_peak, grid_value=grid_value,
        second_accommodation_D=jnp.where(distinct, alt.accommodation_D, jnp.nan),
        second_value=jnp.where(distinct, alt.value, jnp.nan),
        at_hyperopic_limit=at_limit, at_grid_edge=at_edge,
    )


__all__ = [
    "PEAK_METHODS",
    "single_state_metric",
    "Peak",
    "Peaks",
    "refine_peak",
    "accommodation_peaks",
    "peaks_from_grid",
    "result_name",
    "resolved_method",
]
