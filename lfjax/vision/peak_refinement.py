"""The solvers and estimates behind :func:`lfjax.vision.peaks.accommodation_peaks`: one
maximum refined on its bracket (:func:`refine_peak`, optimistix), the solver-free local
stencil, the grid's own estimate of a peak and of its error (:func:`grid_peak_estimate`),
and the adaptive refinement that spends solver work only where that estimate is not good
enough. The methods are described in :mod:`lfjax.vision.peaks`.
"""

from __future__ import annotations

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optimistix as optx
from jaxtyping import Array, Bool, Float, Int

from lfjax.base.types import FULL
from lfjax.base.types import is_concrete as _is_concrete
from lfjax.kernel.optics import state_chunk
from lfjax.kernel.pipeline import PipelineConfig, Scene
from lfjax.vision.peak_options import check_method

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
    check_method(method)
    if method in ("parabola", "vertex", "local", "grid", "auto", "adaptive"):
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


TYPICAL_REFINED_FRACTION = 0.15
"""Fraction of peaks ``"adaptive"`` refines at the default tolerance on the paper's scene
(11.5 % with its ±1 D window, rounded up: benchmarks/validation/peak_error_estimate.py);
the sweep's time estimate uses it."""


ADAPTIVE_BATCHES = 16
"""``"adaptive"`` refines its flagged pairs in batches of 1/16 of all pairs (or the
kernel's memory limit, if smaller): the work is rounded up to a batch."""


LOCAL_TRUST_D = 0.05
"""``"local"`` trusts its fitted vertex this far (D) from the stencil's centre."""


# Kernel evaluations one refinement step holds at once, per (eye, depth) pair and state it
# evaluates: the local stencil's points; Newton's location is a root of the metric's slope,
# so each step carries the value with its first and second forward derivatives.
STATE_COST = {"local": len(LOCAL_OFFSETS_D), "newton": 4, "golden": 1, "bfgs": 3, "parabola": 1,
              "adaptive": len(LOCAL_OFFSETS_D)}


def pairs_per_batch(scene: Scene, config: PipelineConfig, method: str, n_candidates: int) -> int:
    """(eye, depth) pairs refined together: as many as the kernel's working memory holds
    (:func:`lfjax.kernel.optics.state_chunk`), counting each pair's states, their derivatives
    and the candidates refined side by side."""
    n_views = scene.centres_mm.shape[0]
    states = state_chunk(2**31, n_views, config.n_fft)
    return max(1, states // (STATE_COST.get(method, 1) * n_candidates))


def map_pairs(fn, batch: int, *args):
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


def _local_stencil(vertex_D, lower_D, upper_D):
    """The ``"local"`` stencil around the grid parabola's ``vertex_D``: (centre, points (…, 3))."""
    offsets = jnp.asarray(LOCAL_OFFSETS_D, vertex_D.dtype)
    # The stencil is moved inside the usable bracket rather than clipped at its ends: clipped
    # points would coincide at the hyperopic limit and leave the fit singular.
    low = jnp.maximum(lower_D, 0.0)
    centre = jnp.clip(vertex_D, low - offsets[0], upper_D - offsets[-1])
    centre = jax.lax.stop_gradient(jnp.where(upper_D - low < offsets[-1] - offsets[0],
                                             0.5 * (low + upper_D), centre))
    return centre, centre[..., None] + offsets


def _local_fit(centre, points, values, lower_D, upper_D) -> Peak:
    """The ``"local"`` answer from the metric ``values`` at the stencil's ``points`` (…, 3)."""
    low = jnp.maximum(lower_D, 0.0)
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


def local_refinement(value_fn, vertex_D, lower_D, upper_D, args, batch: int) -> Peak:
    centre, points = _local_stencil(vertex_D, lower_D, upper_D)
    batched = jax.vmap(value_fn, in_axes=(0, None))  # over the stencil's points
    values = map_pairs(batched, batch, points, args)  # (n_eyes, n_depth, n_points)
    return _local_fit(centre, points, values, lower_D, upper_D)


def adaptive_refinement(value_fn, estimate: GridEstimate, vertex_D, lower_D, upper_D, args,
                         tolerance_D: float, force, batch: int) -> Peak:
    """``"adaptive"``: the grid estimate where its error estimate is within ``tolerance_D``
    (and lies in the bracket), the local stencil elsewhere and where ``force``."""
    low = jnp.maximum(lower_D, 0.0)
    trusted = ((estimate.error_D <= tolerance_D) & (estimate.accommodation_D >= low)
               & (estimate.accommodation_D <= upper_D))
    flagged = ~trusted | force
    shape = estimate.accommodation_D.shape
    fallback = Peak(estimate.accommodation_D, estimate.value, jnp.ones(shape, bool),
                    jnp.full(shape, -1, jnp.int32), jnp.zeros(shape, jnp.int32))

    def one_pair(vertex, lo, hi, pair_args):
        centre, points = _local_stencil(vertex, lo, hi)
        values = jax.vmap(value_fn, in_axes=(0, None))(points, pair_args)
        return _local_fit(centre, points, values, lo, hi)

    return _map_flagged(one_pair, flagged, batch, fallback, vertex_D, lower_D, upper_D, args)


def parabola_value(states_D, values, index, at_D):
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


ESTIMATE_NEWTON_STEPS = 8
"""Newton steps that locate the maximum of :func:`grid_peak_estimate`'s polynomials (from
the lower order's maximum, inside ±one grid step: quadratic convergence, far more than
enough)."""


ESTIMATE_RULES = {7: (3.0, 1e-3), 5: (2.0, 2e-3)}
"""How :func:`grid_peak_estimate` turns the distance between its two interpolants into an
error estimate, by the number of grid points it reads: (safety factor, floor in D). Chosen
on the natural view and 2×2 views, and checked on the 3×3 and 4×4 views they were not
chosen on (benchmarks/validation/peak_error_estimate.py); the floor covers two
interpolants agreeing by chance while both are off by a little (< 1.5 mD there)."""


class GridEstimate(eqx.Module):
    """A peak located from the grid values alone, with an estimate of its own error.

    Attributes (each (…))
    ----------
    accommodation_D : maximum of the polynomial through the logarithms of the seven grid
        values around the grid maximum (five where the grid ends sooner), D
    value : the interpolant's value there
    error_D : estimated distance of ``accommodation_D`` from the true maximum, D
        (:func:`grid_peak_estimate`). ``inf`` where the grid cannot tell: a grid maximum
        without two usable neighbours on each side (at the window's end or the hyperopic
        limit), a value that is not positive, a curve not concave there, or an
        interpolated maximum beyond the grid maximum's neighbours.
    n_points : grid points read (7, 5, or 0 where the grid cannot tell)
    """

    accommodation_D: Array
    value: Array
    error_D: Array
    n_points: Array


def _polynomial_maximum(u, y, start):
    """Maximum near ``start`` of the polynomial through (u, y) (…, k) (degree k − 1), in
    the units of u, kept inside [−1, 1]; returns (location, value, concave there)."""
    half = (u.shape[-1] - 1) / 2  # u/half lies in [−1, 1]: a well-conditioned system
    powers = jnp.arange(u.shape[-1], dtype=u.dtype)
    vandermonde = (u / half)[..., :, None] ** powers
    coefficients = jnp.linalg.solve(vandermonde, y[..., None])[..., 0]
    slope_c = coefficients[..., 1:] * powers[1:]
    curvature_c = slope_c[..., 1:] * powers[1:-1]

    def evaluate(c, x):
        return jnp.sum(c * (x / half)[..., None] ** jnp.arange(c.shape[-1], dtype=x.dtype),
                       axis=-1)

    x = start
    for _ in range(ESTIMATE_NEWTON_STEPS):
        g, h = evaluate(slope_c, x) * half, evaluate(curvature_c, x)
        x = jnp.clip(jnp.where(h < 0, x - g / jnp.where(h < 0, h, -1.0), x), -1.0, 1.0)
    return x, evaluate(coefficients, x), evaluate(curvature_c, x) < 0


def grid_peak_estimate(states_D, values, index) -> GridEstimate:
    """Locate the maximum at grid point ``index`` from the grid values alone, and estimate
    the error of that location (:class:`GridEstimate`).

    states_D (…, n) increasing and evenly spaced around ``index``, D; values (…, n),
    positive, −inf (or NaN) at states not to use; index (…) int, the grid maximum.

    Interpolants of the logarithms of the values (the through-focus curves resemble a
    Gaussian near their maxima, which a parabola in the logarithm fits exactly: on the
    paper's 0.2 D grid the quartic through the logarithms erred half as much as the
    quartic through the values). With three usable points on each side of the maximum,
    the answer is the maximum of the polynomial through all seven (sixth order) and its
    error estimate is a safety factor times its distance from the maximum of the quartic
    through the middle five, plus a floor (:data:`ESTIMATE_RULES`); with two on each side,
    the quartic's maximum and its distance from the parabola through the middle three.
    To leading order the distance is the lower order's error, which bounds the higher
    order's. It is an estimate, not a proof: a feature narrower than the grid step is
    invisible to any rule that reads only the grid. Validated against Newton at float64
    (benchmarks/validation/peak_error_estimate.py).
    """
    n = states_D.shape[-1]
    offsets = jnp.arange(-3, 4)
    points = jnp.clip(index[..., None] + offsets, 0, n - 1)
    take = lambda x: jnp.take_along_axis(x, points, axis=-1)  # noqa: E731
    s, y = take(states_D), take(values)
    inside = (index[..., None] + offsets >= 0) & (index[..., None] + offsets <= n - 1)
    usable = inside & jnp.isfinite(y) & (y > 0)
    five = jnp.all(usable[..., 1:6], axis=-1)
    seven = five & usable[..., 0] & usable[..., 6]
    centre = s[..., 3]
    step = 0.5 * (s[..., 4] - s[..., 2])
    step = jnp.where(five & (step > 0), step, 1.0)
    regular = jnp.arange(-3.0, 4.0, dtype=s.dtype)
    u = jnp.where(usable, (s - centre[..., None]) / step[..., None], regular)
    log_y = jnp.log(jnp.where(usable, y, 1.0))
    l0, l1, l2 = log_y[..., 2], log_y[..., 3], log_y[..., 4]
    curvature = l0 - 2 * l1 + l2
    concave = five & (curvature < 0)
    vertex = jnp.clip(jnp.where(concave, 0.5 * (l0 - l2) / jnp.where(concave, curvature, -1.0),
                                0.0), -1.0, 1.0)
    x5, v5, c5 = _polynomial_maximum(u[..., 1:6], log_y[..., 1:6], vertex)
    x7, v7, c7 = _polynomial_maximum(u, log_y, x5)
    safety7, floor7 = ESTIMATE_RULES[7]
    safety5, floor5 = ESTIMATE_RULES[5]
    use7 = seven & c7 & (jnp.abs(x7) < 1.0)
    x = jnp.where(use7, x7, x5)
    value = jnp.where(use7, v7, v5)
    distance = jnp.where(use7, jnp.abs(x7 - x5), jnp.abs(x5 - vertex)) * step
    error = jnp.where(use7, safety7 * distance + floor7, safety5 * distance + floor5)
    served = concave & c5 & (jnp.abs(x5) < 1.0)
    # A grid maximum on the hyperopic limit (0 D) has no neighbour below it: the maximum
    # is the limit itself when the curve falls from it, i.e. when the parabola through the
    # logarithms of the first three values and the cubic through the first four both peak
    # below 0 D (their extrapolated maxima lie beyond the limit)
    at_limit = (centre <= 0.0) & jnp.all(usable[..., 3:], axis=-1)
    step_up = jnp.where(at_limit, s[..., 4] - centre, 1.0)
    u_up = jnp.where(at_limit[..., None], (s[..., 3:] - centre[..., None]) / step_up[..., None],
                     jnp.arange(4.0, dtype=s.dtype))
    a0, a1, a2 = log_y[..., 3], log_y[..., 4], log_y[..., 5]
    bend = a0 - 2 * a1 + a2  # parabola through u = 0, 1, 2: slope at u = 0 is (−3a0 + 4a1 − a2)/2
    falls3 = (bend < 0) & (-3 * a0 + 4 * a1 - a2 < 0)
    powers = jnp.arange(4, dtype=s.dtype)
    cubic = jnp.linalg.solve(u_up[..., :, None] ** powers, log_y[..., 3:, None])[..., 0]
    slope = lambda u: cubic[..., 1] + 2 * cubic[..., 2] * u + 3 * cubic[..., 3] * u * u  # noqa: E731
    falls4 = (slope(0.0) < 0) & (slope(0.5) < 0) & (slope(1.0) < 0)
    on_limit = at_limit & falls3 & falls4 & ~served
    # unserved: the grid maximum itself, its value; the error is unknown
    return GridEstimate(jnp.where(served, centre + x * step, centre),
                        jnp.exp(jnp.where(served, value, l1)),
                        jnp.where(served, error, jnp.where(on_limit, floor5, jnp.inf)),
                        jnp.where(served, jnp.where(use7, 7, 5),
                                  jnp.where(on_limit, 4, 0)).astype(jnp.int32))


def _map_flagged(fn, flagged, batch: int, fallback, *args):
    """``fn`` (one (eye, depth) pair → pytree) on the pairs where ``flagged`` (n_eyes,
    n_depth) is true, ``fallback`` (a pytree of (n_eyes, n_depth, …) arrays) elsewhere.

    The flagged pairs are gathered first and evaluated ``batch`` at a time in one
    ``lax.map``; a batch with no flagged pair is skipped (``lax.cond``), so the work is
    that of the flagged pairs rounded up to a batch."""
    lead = flagged.shape
    n_pairs = lead[0] * lead[1]
    batch = max(1, min(int(batch), n_pairs))
    n_batches = -(-n_pairs // batch)
    flat = lambda x: x.reshape((n_pairs,) + x.shape[2:])  # noqa: E731
    order = jnp.argsort(~flagged.reshape(-1), stable=True)  # flagged pairs first
    n_flagged = jnp.sum(flagged)
    pad = n_batches * batch - n_pairs
    order_padded = jnp.concatenate([order, jnp.broadcast_to(order[-1:], (pad,))])
    gathered = jax.tree_util.tree_map(
        lambda x: flat(x)[order_padded].reshape((n_batches, batch) + x.shape[2:]), args)
    skipped = jax.tree_util.tree_map(
        lambda x: flat(x)[order_padded].reshape((n_batches, batch) + x.shape[2:]), fallback)

    def one_batch(item):
        k, xs, rest = item
        return jax.lax.cond(k * batch < n_flagged, lambda: jax.vmap(fn)(*xs), lambda: rest)

    out = jax.lax.map(one_batch, (jnp.arange(n_batches), gathered, skipped))
    inverse = jnp.argsort(order)

    def scatter(computed, default):
        computed = computed.reshape((n_batches * batch,) + computed.shape[2:])[:n_pairs][inverse]
        keep = flagged.reshape((n_pairs,) + (1,) * (computed.ndim - 1))
        return jnp.where(keep, computed, flat(default)).reshape(lead + computed.shape[1:])

    return jax.tree_util.tree_map(scatter, out, fallback)


__all__ = ["Peak", "result_name", "refine_peak", "GridEstimate", "grid_peak_estimate",
           "local_refinement", "adaptive_refinement", "map_pairs", "pairs_per_batch",
           "parabola_value", "LOCAL_OFFSETS_D", "LOCAL_TRUST_D", "TYPICAL_REFINED_FRACTION",
           "ADAPTIVE_BATCHES", "STATE_COST", "ESTIMATE_RULES", "ESTIMATE_NEWTON_STEPS"]
