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

import dataclasses
from dataclasses import dataclass

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optimistix as optx
from jaxtyping import Array, ArrayLike, Bool, Float, Int

from lfjax.base.errors import ParameterError
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

PEAK_METHODS = ("auto", "newton", "golden", "bfgs", "local", "parabola", "vertex", "grid",
                "adaptive")
METRICS = ("vsotf", "strehl")

DEFAULT_TOLERANCE_D = 0.01
"""``"adaptive"`` refines a peak whose grid estimate may be further than this from the
true maximum, D (the paper study's target for a predicted accommodation)."""


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


def check_tolerance(tolerance_D) -> None:
    """Refuse a peak tolerance that is not a positive, finite number of dioptres."""
    ok = isinstance(tolerance_D, (int, float, np.floating, np.integer)) and not isinstance(
        tolerance_D, bool) and np.isfinite(tolerance_D) and 0 < float(tolerance_D) < 1
    if not ok:
        raise ParameterError("tolerance_D", "{tolerance_D} must lie in (0, 1) D (the "
                             "largest error a grid-estimated peak may keep), got {got!r}",
                             owner="PeakOptions", got=tolerance_D)


@dataclass(frozen=True)
class PeakOptions:
    """How continuous accommodation peaks are found: one frozen object, checked when built.

    Every entry point that finds peaks takes one (``through_focus(..., peaks=...)``,
    :func:`accommodation_peaks`, the sweep, the study), so a new peak option is a new field
    here, not a keyword threaded through each signature.

    Attributes
    ----------
    metrics : the metrics whose continuous peak is refined, a tuple of :data:`METRICS`;
        ``()`` (default): grid peaks only (entry points that always refine, such as
        :func:`accommodation_peaks`, take the metric on its own)
    method : the refinement, one of :data:`PEAK_METHODS` (module docstring; ``"auto"``:
        Newton for VSOTF, golden section for the Strehl ratio)
    tolerance_D : ``"adaptive"`` only: refine the peaks whose grid estimate may lie further
        than this from the true maximum, D, in (0, 1) (default :data:`DEFAULT_TOLERANCE_D`)
    second_peaks : refine second local maxima too (default); False halves the refinement's
        cost (the second peak is then located by the grid parabola and valued on the grid)
    prominence : a second local maximum is reported when it stands this fraction of its
        value above the valley between it and the global one, in [0, 1)
    atol_D : the solvers' location tolerance, D, > 0
    max_steps : the solvers' step limit, an integer ≥ 1

    Examples
    --------
    >>> from lfjax.vision.peaks import PeakOptions
    >>> PeakOptions(metrics=("vsotf",), method="vertex").method
    'vertex'
    >>> PeakOptions(method="nope")
    Traceback (most recent call last):
    ...
    lfjax.base.errors.ParameterError: PeakOptions.method must be one of ...
    """

    metrics: tuple[str, ...] = ()
    method: str = "auto"
    tolerance_D: float = DEFAULT_TOLERANCE_D
    second_peaks: bool = True
    prominence: float = 0.05
    atol_D: float = 1e-5
    max_steps: int = 32

    def __post_init__(self):
        metrics = self.metrics
        if isinstance(metrics, str) or not isinstance(metrics, (tuple, list)):
            raise ParameterError("metrics", "{metrics} must be a tuple of metric names from "
                                 "{allowed}, got {got!r}", owner="PeakOptions",
                                 allowed=METRICS, got=metrics)
        for name in metrics:
            if name not in METRICS:
                raise ParameterError("metrics", "{metrics} must name metrics in {allowed}, "
                                     "got {got!r}", owner="PeakOptions", allowed=METRICS,
                                     got=name)
        # a list would make the object unhashable (it is a static argument of jitted calls)
        object.__setattr__(self, "metrics", tuple(metrics))
        if self.method not in PEAK_METHODS:
            raise ParameterError("method", "{method} must be one of {allowed}, got {got!r}",
                                 owner="PeakOptions", allowed=PEAK_METHODS, got=self.method)
        check_tolerance(self.tolerance_D)
        if not isinstance(self.second_peaks, (bool, np.bool_)):
            raise ParameterError("second_peaks", "{second_peaks} must be True or False, got "
                                 "{got!r}", owner="PeakOptions", got=self.second_peaks)
        object.__setattr__(self, "second_peaks", bool(self.second_peaks))
        if not _real(self.prominence) or not 0 <= float(self.prominence) < 1:
            raise ParameterError("prominence", "{prominence} must lie in [0, 1), got {got!r}",
                                 owner="PeakOptions", got=self.prominence)
        if not _real(self.atol_D) or not 0 < float(self.atol_D) < 1:
            raise ParameterError("atol_D", "{atol_D} must lie in (0, 1) D, got {got!r}",
                                 owner="PeakOptions", got=self.atol_D)
        if (isinstance(self.max_steps, bool) or not isinstance(self.max_steps, (int, np.integer))
                or self.max_steps < 1):
            raise ParameterError("max_steps", "{max_steps} must be an integer >= 1, got {got!r}",
                                 owner="PeakOptions", got=self.max_steps)
        # floats and ints as Python numbers: the repr is part of the compiled program's key
        for name in ("tolerance_D", "prominence", "atol_D"):
            object.__setattr__(self, name, float(getattr(self, name)))
        object.__setattr__(self, "max_steps", int(self.max_steps))

    def replace(self, **changes) -> PeakOptions:
        """A copy with ``changes`` (checked again)."""
        return dataclasses.replace(self, **changes)


def _real(x) -> bool:
    return (isinstance(x, (int, float, np.floating, np.integer)) and not isinstance(x, bool)
            and bool(np.isfinite(x)))


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


def resolved_method(metric: str, method: str) -> str:
    """The refinement ``method`` runs for ``metric``: ``"auto"`` is Newton for VSOTF (smooth
    in accommodation) and golden section for the Strehl ratio; ``"adaptive"`` is itself for
    VSOTF and golden section for the Strehl ratio (its grid estimate assumes a smooth
    curve; the Strehl ratio's is piecewise smooth); any other name is itself."""
    if method == "auto":
        return "newton" if metric == "vsotf" else "golden"
    if method == "adaptive" and metric != "vsotf":
        return "golden"
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


def _local_refinement(value_fn, vertex_D, lower_D, upper_D, args, batch: int) -> Peak:
    centre, points = _local_stencil(vertex_D, lower_D, upper_D)
    batched = jax.vmap(value_fn, in_axes=(0, None))  # over the stencil's points
    values = _map_pairs(batched, batch, points, args)  # (n_eyes, n_depth, n_points)
    return _local_fit(centre, points, values, lower_D, upper_D)


def _adaptive_refinement(value_fn, estimate: GridEstimate, vertex_D, lower_D, upper_D, args,
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
    metric: str = "vsotf", method: str = "auto",
    allowed: Bool[ArrayLike, "n_depth n_k"] | None = None, prominence: float = 0.05,
    atol_D: float = 1e-5, max_steps: int = 32, refine_second: bool = True,
    tolerance_D: float = DEFAULT_TOLERANCE_D,
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
    tolerance_D : ``"adaptive"`` only: refine the peaks whose grid estimate's error
        (:func:`grid_peak_estimate`) may exceed this, D; the others keep the estimate
    """
    _check_method(method)
    if metric not in METRICS:
        raise ValueError(f"metric must be one of {METRICS}, got {metric!r}")
    reference = reference_normalisers(scene, spectrum, grid, config)
    on_grid = retinal_metrics(eyes, scene, spectrum, grid, config, reference)
    return peaks_from_grid(getattr(on_grid, metric), eyes, scene, spectrum, grid, config,
                           reference, metric, method, allowed, prominence, atol_D, max_steps,
                           refine_second, tolerance_D)


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
    refine_second: bool = True, tolerance_D: float = DEFAULT_TOLERANCE_D,
) -> Peaks:
    """:func:`accommodation_peaks` from metric values already computed on the grid,
    ``values`` (n_eyes, n_depth, n_k); ``reference`` = the scene's
    :func:`lfjax.kernel.pipeline.reference_normalisers`; ``tolerance_D``: see
    :func:`accommodation_peaks`."""
    _check_method(method)
    check_tolerance(tolerance_D)
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

    masked = jnp.where(allowed_b, values, -jnp.inf)
    has_second = second >= 0
    second_index = jnp.where(has_second, second, best)

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

    if method == "adaptive":
        # The candidates go side by side along the eye axis (not vmapped: under vmap the
        # skipped batches would be computed); a pair with a second peak refines both, since
        # the choice between them reads their refined values.
        n_cand = 2 if refine_second else 1
        index = jnp.concatenate([best, second_index][:n_cand])
        bounds = [bracket_of(i) for i in (best, second_index)[:n_cand]]
        lo = jnp.concatenate([b[0] for b in bounds])
        hi = jnp.concatenate([b[1] for b in bounds])
        tile = lambda x: jnp.concatenate([x] * n_cand)  # noqa: E731
        estimate = grid_peak_estimate(tile(states_b), tile(masked), index)
        vertex = parabola_vertex(tile(states_b), tile(masked), index)
        force = tile(has_second) if refine_second else jnp.zeros(index.shape, bool)
        n_pairs = index.shape[0] * index.shape[1]
        adaptive_batch = max(1, min(batch, -(-n_pairs // ADAPTIVE_BATCHES)))
        both = _adaptive_refinement(value_fn, estimate, vertex, lo, hi,
                                    (tile(z_b), tile(depths_b)), tolerance_D, force,
                                    adaptive_batch)
        n_eyes = values.shape[0]
        main = jax.tree_util.tree_map(lambda x: x[:n_eyes], both)
        if refine_second:
            other = jax.tree_util.tree_map(lambda x: x[n_eyes:], both)
        else:
            located = jnp.clip(parabola_vertex(states_b, masked, second_index),
                               *bracket_of(second_index))
            other = Peak(located, take(values, second_index), jnp.ones(located.shape, bool),
                         jnp.full(located.shape, -1, jnp.int32),
                         jnp.zeros(located.shape, jnp.int32))
    elif refine_second:
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
        grid_error_D=grid_peak_estimate(states_b, masked, edge_index).error_D,
    )


__all__ = [
    "PEAK_METHODS",
    "single_state_metric",
    "GridEstimate",
    "grid_peak_estimate",
    "Peak",
    "Peaks",
    "refine_peak",
    "accommodation_peaks",
    "peaks_from_grid",
    "result_name",
    "resolved_method",
]
