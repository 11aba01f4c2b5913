"""Constraints on a layout and the feasible coordinates a solver moves in (box and unconstrained maps).

Part of :mod:`lfjax.layout_opt` (its public names are re-exported there)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import jax
import jax.numpy as jnp
import numpy as np

from lfjax.base.apertures import safe_sqrt
from lfjax.base.types import finite_scalar
from lfjax.model.layouts import Layout, make_layout
from lfjax.layout_opt._params import (
    CONTAINMENTS,
    TOL_MM,
    FreeParams,
    LatticeParams,
    free_params,
    tangent_lattice,
)

_ROTATION_RANGE = {"square": math.pi / 4.0, "hex": math.pi / 6.0}
"""Half the range of a lattice's rotation in box coordinates, rad (its symmetry's period / 2)."""

_EPS = 1e-6  # fraction clip for the unconstrained (logit / artanh) starting point


@dataclass(frozen=True)
class Constraints:
    """Feasible layouts (static, hashable; all lengths in mm).

    Attributes
    ----------
    pupil_diameter_mm : the eye's (calculation) pupil, mm
    max_diameter_mm : largest subaperture diameter, mm (default: the pupil); it also sizes
        the pipeline's static FFT windows, so a smaller cap makes every evaluation cheaper
    min_diameter_mm : smallest subaperture diameter, mm (default 0.5 mm: the sampling is
        planned for it, and below it the diffraction blur of a view dominates)
    containment : ``"centre"`` (|c| ≤ R; default) or ``"contained"`` (|c| + d/2 ≤ R)
    non_overlap : discs must not overlap, |c_i − c_j| ≥ (d_i + d_j)/2. Free views whose
        centres come closer than ``min_diameter_mm`` then get diameters below it (at most
        the nearest distance); coincident centres would need a zero diameter, which the
        pipeline refuses ("diameters_mm must be > 0 mm")
    """

    pupil_diameter_mm: float = 3.0
    max_diameter_mm: float | None = None
    min_diameter_mm: float = 0.5
    containment: str = "centre"
    non_overlap: bool = False

    def __post_init__(self):
        pupil = finite_scalar("pupil_diameter_mm", self.pupil_diameter_mm, 0.0, None, lo_open=True)
        dmax = pupil if self.max_diameter_mm is None else finite_scalar(
            "max_diameter_mm", self.max_diameter_mm, 0.0, pupil, lo_open=True)
        dmin = finite_scalar("min_diameter_mm", self.min_diameter_mm, 0.0, dmax, lo_open=True)
        if self.containment not in CONTAINMENTS:
            raise ValueError(f"containment must be one of {CONTAINMENTS}, got {self.containment!r}")
        object.__setattr__(self, "pupil_diameter_mm", pupil)
        object.__setattr__(self, "max_diameter_mm", dmax)
        object.__setattr__(self, "min_diameter_mm", dmin)
        object.__setattr__(self, "non_overlap", bool(self.non_overlap))

    @property
    def radius_mm(self) -> float:
        return 0.5 * self.pupil_diameter_mm

    @property
    def centre_radius_mm(self) -> float:
        """Radius of the disc the centres live in (mm): R, or R − d_min/2 when contained
        (so that every centre leaves room for the smallest disc)."""
        r = self.radius_mm
        return r - 0.5 * self.min_diameter_mm if self.containment == "contained" else r

    def as_dict(self) -> dict:
        return dict(pupil_diameter_mm=self.pupil_diameter_mm, max_diameter_mm=self.max_diameter_mm,
                    min_diameter_mm=self.min_diameter_mm, containment=self.containment,
                    non_overlap=self.non_overlap)

    def violations(self, layout, tol: float = TOL_MM) -> list[str]:
        """Host check of any layout-like: a list of messages (empty when feasible; lengths
        within ``tol`` mm of a bound count as on it — float32 round-off)."""
        c = np.asarray(layout.centres_mm, float).reshape(-1, 2)
        d = np.asarray(layout.diameters_mm, float).reshape(-1)
        out = []
        if not (np.all(np.isfinite(c)) and np.all(np.isfinite(d))):
            return ["centres_mm and diameters_mm must be finite"]
        r = np.hypot(c[:, 0], c[:, 1])
        gap = np.hypot(*(c[:, None, :] - c[None, :, :]).transpose(2, 0, 1))
        # without overlap, free views closer than min_diameter_mm may be smaller (at most
        # their smooth nearest distance, as the free parametrisation caps them)
        floor = np.full(d.shape, self.min_diameter_mm)
        if self.non_overlap and len(d) > 1:
            near = np.asarray(_soft_nearest_distance(jnp.asarray(c)), float)
            floor = np.minimum(floor, near)
        for i in np.nonzero(d <= 0)[0]:
            out.append(f"diameters_mm[{i}] = {d[i]:.6g} mm must be > 0 (non-overlapping views "
                       f"need distinct centres)")
        for i in np.nonzero((d < floor - tol) | (d > self.max_diameter_mm + tol))[0]:
            out.append(f"diameters_mm[{i}] = {d[i]:.6g} mm outside [{floor[i]:.6g}, "
                       f"{self.max_diameter_mm:g}] mm")
        reach = r + (0.5 * d if self.containment == "contained" else 0.0)
        for i in np.nonzero(reach > self.radius_mm + tol)[0]:
            what = "|centre| + d/2" if self.containment == "contained" else "|centre|"
            out.append(f"view {i}: {what} = {reach[i]:.6g} mm exceeds the pupil radius "
                       f"{self.radius_mm:g} mm")
        if self.non_overlap and len(d) > 1:
            need = 0.5 * (d[:, None] + d[None, :])
            bad = np.argwhere(np.triu(gap < need - tol, 1))
            for i, j in bad:
                out.append(f"views {i} and {j} overlap: distance {gap[i, j]:.6g} mm < "
                           f"(d_i + d_j)/2 = {need[i, j]:.6g} mm")
        return out

    def check(self, layout) -> None:
        """Raise ``ValueError`` listing every violated constraint of a layout-like."""
        bad = self.violations(layout)
        if bad:
            raise ValueError("layout violates the constraints: " + "; ".join(bad))


def _lattice_bounds(params: LatticeParams, constraints: Constraints):
    """(d_lo, d_hi, rho_max) on the host; raises when no lattice of these sites is feasible."""
    rho = params.max_site_radius
    radius = constraints.radius_mm
    d_lo, d_hi = constraints.min_diameter_mm, constraints.max_diameter_mm
    if constraints.non_overlap and params.n_views > 1 and rho > 0:
        # nearest neighbours are one pitch apart: d ≤ pitch ≤ p_hi(d)
        limit = radius / (rho + 0.5) if constraints.containment == "contained" else radius / rho
        d_hi = min(d_hi, limit)
    if d_hi < d_lo:
        raise ValueError(
            f"no feasible {params.kind} lattice of {params.n_views} views: non-overlapping discs "
            f"inside a {constraints.pupil_diameter_mm:g} mm pupil can be at most {d_hi:.4g} mm, "
            f"below min_diameter_mm = {d_lo:g} mm"
        )
    return d_lo, d_hi, rho


def _pitch_range(diameter, params: LatticeParams, constraints: Constraints, rho: float):
    """Feasible pitch interval (mm) for a lattice diameter (traced)."""
    radius = constraints.radius_mm
    reach = radius - 0.5 * diameter if constraints.containment == "contained" else radius
    # A single site at the centre does not move with the pitch: any positive pitch works.
    p_hi = reach / rho if rho > 0 else jnp.asarray(constraints.pupil_diameter_mm, diameter.dtype)
    p_lo = diameter if (constraints.non_overlap and params.n_views > 1) else jnp.zeros_like(diameter)
    return p_lo, p_hi


def _square_to_disc(s):
    """Elliptical grid map of [−1, 1]² onto the unit disc (smooth, one-to-one)."""
    x, y = s[..., 0], s[..., 1]
    return jnp.stack([x * jnp.sqrt(1.0 - 0.5 * y * y), y * jnp.sqrt(1.0 - 0.5 * x * x)], axis=-1)


def _disc_to_square(q: np.ndarray) -> np.ndarray:
    """Inverse of :func:`_square_to_disc` (host)."""
    u, v = q[..., 0], q[..., 1]
    r2 = 2.0 * math.sqrt(2.0)

    def half(a, b, t):
        return 0.5 * np.sqrt(np.maximum(2.0 + a * a - b * b + r2 * t, 0.0))

    x = half(u, v, u) - half(u, v, -u)
    y = half(v, u, v) - half(v, u, -v)
    return np.clip(np.stack([x, y], axis=-1), -1.0, 1.0)


def _plane_to_disc(u):
    """tanh-radial map of the plane onto the open unit disc: tanh(|u|)·u/|u| (smooth at 0)."""
    r2 = jnp.sum(u * u, axis=-1, keepdims=True)
    r = safe_sqrt(r2)
    small = r2 < 1e-12
    scale = jnp.where(small, 1.0 - r2 / 3.0, jnp.tanh(r) / jnp.where(small, 1.0, r))
    return u * scale


def _disc_to_plane(q: np.ndarray) -> np.ndarray:
    r = np.hypot(q[..., 0], q[..., 1])[..., None]
    rc = np.minimum(r, 1.0 - _EPS)
    scale = np.where(r > 1e-12, np.arctanh(rc) / np.where(r > 1e-12, r, 1.0), 1.0)
    return q * scale


def _diameter_caps(centres, constraints: Constraints):
    """Largest feasible diameter at each centre (mm): max_diameter, 2(R − |c|) when
    contained, a smooth lower bound of the nearest other centre's distance
    (:func:`_soft_nearest_distance`) when views must not overlap."""
    cap = jnp.full(centres.shape[:1], constraints.max_diameter_mm, centres.dtype)
    if constraints.containment == "contained":
        r = safe_sqrt(jnp.sum(centres * centres, axis=-1))
        cap = jnp.minimum(cap, 2.0 * (constraints.radius_mm - r))
    if constraints.non_overlap and centres.shape[0] > 1:
        cap = jnp.minimum(cap, _soft_nearest_distance(centres))
    return cap


NEAREST_SOFTNESS = 16.0
"""Exponent p of the smooth nearest-neighbour distance (Σ_j r_ij^−p)^(−1/p)."""


def _soft_nearest_distance(centres):
    """Smooth lower bound of each centre's distance to its nearest other centre (mm):
    (Σ_j r_ij^−p)^(−1/p) ≤ min_j r_ij, within a factor k^(−1/p) of it for k tied
    neighbours (2^(−1/16) ≈ 0.958: two equidistant neighbours, as on a lattice).

    The exact minimum has a kink wherever two neighbours are equally near — every lattice
    start — and a quasi-Newton step across it can only get worse (measured: optimistix
    BFGS rejected every step from a 2×2 lattice)."""
    n = centres.shape[0]
    diff = centres[:, None, :] - centres[None, :, :]
    r2 = jnp.sum(diff * diff, axis=-1)
    off = ~jnp.eye(n, dtype=bool)
    ok = off & (r2 > 0)
    # r^-p = (r²)^(-p/2); coincident centres give +inf → distance 0 (zero diameter)
    inv = jnp.where(ok, jnp.where(ok, r2, 1.0) ** (-0.5 * NEAREST_SOFTNESS),
                    jnp.where(off, jnp.inf, 0.0))
    total = jnp.sum(inv, axis=1)
    finite = jnp.isfinite(total)
    return jnp.where(finite, jnp.where(finite, total, 1.0) ** (-1.0 / NEAREST_SOFTNESS), 0.0)


def _free_diameters(centres, fraction, constraints: Constraints):
    cap = _diameter_caps(centres, constraints)
    lo = jnp.minimum(constraints.min_diameter_mm, cap)
    return lo + fraction * (cap - lo)


def _free_fraction(params: FreeParams, constraints: Constraints) -> np.ndarray:
    """Host inverse of the diameter map; raises naming the view and its allowed range."""
    c = np.asarray(params.centres_mm, float)
    d = np.asarray(params.diameters_mm, float)
    cap = np.asarray(_diameter_caps(jnp.asarray(c), constraints), float)
    lo = np.minimum(constraints.min_diameter_mm, cap)
    bad = (d < lo - TOL_MM) | (d > cap + TOL_MM)
    if np.any(bad):
        i = int(np.nonzero(bad)[0][0])
        raise ValueError(
            f"diameters_mm[{i}] = {d[i]:.6g} mm must be in [{lo[i]:.6g}, {cap[i]:.6g}] mm at its "
            f"centre (min/max_diameter_mm, containment={constraints.containment!r}, "
            f"non_overlap={constraints.non_overlap})"
        )
    span = cap - lo
    return np.clip(np.where(span > 1e-12, (d - lo) / np.where(span > 1e-12, span, 1.0), 0.0), 0, 1)


def _free_disc_points(params: FreeParams, constraints: Constraints) -> np.ndarray:
    c = np.asarray(params.centres_mm, float)
    rc = constraints.centre_radius_mm
    r = np.hypot(c[:, 0], c[:, 1])
    bad = r > rc + TOL_MM
    if np.any(bad):
        i = int(np.nonzero(bad)[0][0])
        raise ValueError(
            f"centres_mm[{i}] = {c[i].tolist()} lies {r[i]:.6g} mm from the pupil centre; allowed "
            f"|centre| <= {rc:.6g} mm (containment={constraints.containment!r})"
        )
    q = c / rc
    return q / np.maximum(np.hypot(q[:, 0], q[:, 1]), 1.0)[:, None]


def check_finite_params(params) -> None:
    """Every leaf of a layout's parameters must be finite (a ValueError naming it)."""
    if isinstance(params, LatticeParams):
        for name in ("pitch_mm", "diameter_mm", "rotation_rad"):
            finite_scalar(name, np.asarray(getattr(params, name)))
    elif isinstance(params, FreeParams):
        for name in ("centres_mm", "diameters_mm"):
            x = np.asarray(getattr(params, name), float)
            if not np.all(np.isfinite(x)):
                raise ValueError(f"{name} must be finite (no NaN or inf), got {x.tolist()}")
    else:
        raise TypeError(f"expected LatticeParams or FreeParams, got {type(params).__name__}")


def _lattice_fractions(params: LatticeParams, constraints: Constraints):
    """Host: (a, b) fractions of a lattice's diameter and pitch; raises when infeasible."""
    d_lo, d_hi, rho = _lattice_bounds(params, constraints)
    d = float(params.diameter_mm)
    if not (d_lo - TOL_MM <= d <= d_hi + TOL_MM):
        raise ValueError(
            f"diameter_mm = {d:.6g} mm must be in [{d_lo:.6g}, {d_hi:.6g}] mm "
            f"(min/max_diameter_mm{', non-overlap within the pupil' if d_hi < constraints.max_diameter_mm else ''})"
        )
    p_lo, p_hi = (float(x) for x in _pitch_range(jnp.asarray(d), params, constraints, rho))
    p = float(params.pitch_mm)
    if not (p_lo - TOL_MM <= p <= p_hi + TOL_MM):
        raise ValueError(
            f"pitch_mm = {p:.6g} mm must be in [{p_lo:.6g}, {p_hi:.6g}] mm for diameter_mm = {d:.6g} "
            f"(outermost site at {rho:.4g} pitches; containment={constraints.containment!r}, "
            f"non_overlap={constraints.non_overlap})"
        )
    a = (d - d_lo) / (d_hi - d_lo) if d_hi > d_lo else 0.5
    b = (p - p_lo) / (p_hi - p_lo) if p_hi > p_lo else 0.5
    return float(np.clip(a, 0, 1)), float(np.clip(b, 0, 1))


def _lattice_from_fractions(a, b, rotation, template: LatticeParams, constraints: Constraints):
    d_lo, d_hi, rho = _lattice_bounds(template, constraints)
    d = d_lo + a * (d_hi - d_lo)
    p_lo, p_hi = _pitch_range(d, template, constraints, rho)
    return LatticeParams(p_lo + b * (p_hi - p_lo), d, rotation, template.sites, template.kind)


def feasible_start(params, constraints: Constraints, margin: float = 0.0):
    """``params`` moved into the feasible set (host): the lattice diameter, then its pitch,
    clipped into their feasible intervals, the rotation wrapped into the symmetry range;
    free centres pulled into the centres' disc, each diameter clipped into [floor, cap] at
    its centre. ``margin`` ∈ [0, 0.5) keeps every fraction in [margin, 1 − margin]: starts
    for ``method="bfgs"``, whose sigmoid coordinates saturate on a bound (a start there
    cannot move)."""
    check_finite_params(params)
    margin = finite_scalar("margin", margin, 0.0, 0.49)
    if isinstance(params, LatticeParams):
        d_lo, d_hi, rho = _lattice_bounds(params, constraints)
        d = float(np.clip(float(params.diameter_mm), d_lo, d_hi))
        p_lo, p_hi = (float(x) for x in _pitch_range(jnp.asarray(d), params, constraints, rho))
        p = float(np.clip(float(params.pitch_mm), p_lo, p_hi))
        half = _ROTATION_RANGE[params.kind]
        rot = (float(params.rotation_rad) + half) % (2 * half) - half
        a, b = _lattice_fractions(LatticeParams(p, d, rot, params.sites, params.kind), constraints)
        a, b = (float(np.clip(x, margin, 1 - margin)) for x in (a, b))
        return _lattice_from_fractions(jnp.asarray(a), jnp.asarray(b), rot, params, constraints)
    c = np.asarray(params.centres_mm, float)
    rc = constraints.centre_radius_mm * (1 - margin)
    r = np.hypot(c[:, 0], c[:, 1])
    c = c * np.minimum(1.0, rc / np.maximum(r, 1e-300))[:, None]
    cap = np.asarray(_diameter_caps(jnp.asarray(c), constraints), float)
    lo = np.minimum(constraints.min_diameter_mm, cap)
    f = np.clip((np.asarray(params.diameters_mm, float) - lo) / np.maximum(cap - lo, 1e-300),
                margin, 1 - margin)
    return free_params(c, np.where(cap > lo, lo + f * (cap - lo), cap))


def initial_lattice(kind: str, n_views: int, constraints: Constraints, margin: float = 0.0):
    """A feasible starting lattice: :func:`tangent_lattice` moved into the feasible set by
    :func:`feasible_start` (e.g. shrunk so that discs are contained)."""
    return feasible_start(tangent_lattice(kind, n_views, constraints.pupil_diameter_mm),
                          constraints, margin)


def to_box(params, constraints: Constraints):
    """Box coordinates of a feasible layout and their bounds: (x, (lower, upper)).

    Raises ``ValueError`` naming the parameter and its allowed range when ``params`` is not
    feasible. Every point of the box maps back (:func:`from_box`) to a feasible layout.
    """
    check_finite_params(params)
    dtype = jnp.result_type(float)
    if isinstance(params, LatticeParams):
        a, b = _lattice_fractions(params, constraints)
        rot = float(params.rotation_rad)
        half = _ROTATION_RANGE[params.kind]
        if abs(rot) > half + 1e-12:
            raise ValueError(f"rotation_rad = {rot:.6g} must be in [{-half:.6g}, {half:.6g}] "
                             f"(the {params.kind} lattice's symmetry range)")
        x = dict(diameter=a, pitch=b, rotation=rot)
        lower = dict(diameter=0.0, pitch=0.0, rotation=-half)
        upper = dict(diameter=1.0, pitch=1.0, rotation=half)
        as_arr = lambda t: {k: jnp.asarray(v, dtype) for k, v in t.items()}  # noqa: E731
        return as_arr(x), (as_arr(lower), as_arr(upper))
    q = _free_disc_points(params, constraints)
    f = _free_fraction(params, constraints)
    x = dict(disc=jnp.asarray(_disc_to_square(q), dtype), fraction=jnp.asarray(f, dtype))
    lower = dict(disc=-jnp.ones_like(x["disc"]), fraction=jnp.zeros_like(x["fraction"]))
    upper = dict(disc=jnp.ones_like(x["disc"]), fraction=jnp.ones_like(x["fraction"]))
    return x, (lower, upper)


def from_box(x, template, constraints: Constraints):
    """Layout parameters of box coordinates ``x`` (traced; feasible for any x in the box)."""
    if isinstance(template, LatticeParams):
        return _lattice_from_fractions(x["diameter"], x["pitch"], x["rotation"], template,
                                       constraints)
    centres = constraints.centre_radius_mm * _square_to_disc(x["disc"])
    return FreeParams(centres, _free_diameters(centres, x["fraction"], constraints))


def _logit(p):
    p = np.clip(np.asarray(p, float), _EPS, 1.0 - _EPS)
    return np.log(p) - np.log1p(-p)


def to_unconstrained(params, constraints: Constraints):
    """Unconstrained coordinates (any real values) of a feasible layout; raises like
    :func:`to_box`. Fractions become logits, centres the inverse tanh-radial map."""
    check_finite_params(params)
    dtype = jnp.result_type(float)
    if isinstance(params, LatticeParams):
        a, b = _lattice_fractions(params, constraints)
        return dict(diameter=jnp.asarray(_logit(a), dtype), pitch=jnp.asarray(_logit(b), dtype),
                    rotation=jnp.asarray(float(params.rotation_rad), dtype))
    q = _free_disc_points(params, constraints)
    f = _free_fraction(params, constraints)
    return dict(disc=jnp.asarray(_disc_to_plane(q), dtype), fraction=jnp.asarray(_logit(f), dtype))


def from_unconstrained(u, template, constraints: Constraints):
    """Layout parameters of unconstrained coordinates ``u`` (traced; always feasible)."""
    if isinstance(template, LatticeParams):
        return _lattice_from_fractions(jax.nn.sigmoid(u["diameter"]), jax.nn.sigmoid(u["pitch"]),
                                       u["rotation"], template, constraints)
    centres = constraints.centre_radius_mm * _plane_to_disc(u["disc"])
    return FreeParams(centres, _free_diameters(centres, jax.nn.sigmoid(u["fraction"]), constraints))


def to_layout(params, constraints: Constraints, name: str = "optimised") -> Layout:
    """A checked :class:`lfjax.model.layouts.Layout` of parameters (window = the diameter cap)."""
    c = np.asarray(params.centres_mm, float)
    d = np.asarray(params.diameters_mm, float)
    if not (np.all(np.isfinite(c)) and np.all(np.isfinite(d))):
        raise FloatingPointError(f"non-finite layout: centres {c.tolist()}, diameters {d.tolist()}")
    return make_layout(c, d, constraints.pupil_diameter_mm, name=name,
                       window_diameter_mm=constraints.max_diameter_mm)
