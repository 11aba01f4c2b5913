"""Subaperture layout optimisation: fit where the views enter the pupil and how large they are.

A light-field display samples the eye's pupil with subapertures (views). Their layout sets
the depth of field, the accommodation the display drives and the resolution the eye sees.
This module fits a layout to a population of virtual eyes with the pure, differentiable
pipeline (:func:`lfjax.pipeline.retinal_metrics`) and reports it on a held-out population.

Parametrisations
----------------
:class:`LatticeParams`
    a square (n×n) or hexagonal lattice: pitch (mm), one subaperture diameter (mm) and a
    rotation (rad). The lattice sites are chosen once (``lattice_sites``), so the view count
    and every array shape stay fixed during a fit.
:class:`FreeParams`
    free centres (n_views, 2) and diameters (n_views,), mm.

Both expose ``centres_mm`` and ``diameters_mm``, differentiable in their leaves, and so does
:class:`lfjax.layouts.Layout`; every objective accepts any of the three.

Constraints (:class:`Constraints`)
----------------------------------
* inside the pupil, one of two readings (``containment``):
  ``"centre"`` (default) — each subaperture's centre lies in the pupil, |c| ≤ R. The pupil
  crops the rest, as it crops the paper's tangent n×n grids (whose corner views reach
  beyond the pupil: |c| + d/2 > R), and every view transmits light (at least the part of
  its disc on the pupil side of its centre). ``"contained"`` — each disc lies wholly in
  the pupil, |c| + d/2 ≤ R (the paper's grids violate it);
* diameters in [``min_diameter_mm``, ``max_diameter_mm``] (positive by construction;
  ``max_diameter_mm`` also sizes the static FFT windows);
* optionally no overlap, |c_i − c_j| ≥ (d_i + d_j)/2 (``non_overlap``).

Violations are impossible by construction: a fit moves in *feasible coordinates* whose
every value maps to a feasible layout, and a starting layout that is not feasible raises a
``ValueError`` naming the parameter and its allowed range. (One degenerate exception: free
views that must not overlap and whose centres coincide exactly would need a zero diameter;
the pipeline refuses it, "diameters_mm must be > 0 mm".) Two coordinate systems, two
solvers:

* ``method="lbfgsb"`` — box coordinates, solved with ``jaxopt.LBFGSB``. Lattice: diameter
  and pitch as fractions in [0, 1] of their feasible interval (the pitch interval depends
  on the diameter when discs must be contained or must not overlap), rotation in
  ±π/4 (square) or ±π/6 (hex). Free: each centre a point of the square [−1, 1]² mapped onto
  the pupil disc by the elliptical grid map (smooth, one-to-one; Fong 2015), each diameter
  a fraction in [0, 1] between the lower bound and its cap (the largest diameter the
  constraints allow at that centre: ``max_diameter_mm``, 2(R − |c|) when contained, a
  smooth lower bound of the nearest other centre's distance when views must not overlap).
* ``method="bfgs"`` — unconstrained coordinates, solved with ``optimistix.BFGS``:
  fractions = sigmoid(u), centre = R·tanh(|u|)·u/|u| (the tanh-radial map of the plane
  onto the open disc), rotation free.

Objectives (each a mean over the eyes and the rendered depths of the problem)
-------------------------------------------------------------------------------
Every eye's *predicted accommodation* is found as the project's peak finder finds it
(:func:`predicted_peaks`): the global maximum of its through-focus VSOTF on a grid over a
window that holds both the rendered depth and the display's CDP (:func:`peak_window`) —
the two places a light-field display can draw the eye — refined from the grid. Nothing
caps the search around the rendered depth, so a layout that lets the eye focus on the CDP
is seen doing so; a maximum on the window's edge is reported as a failure.

``"accommodation_aware"`` (the default, :data:`DEFAULT_OBJECTIVE`)
    maximise ``image_at_peak`` subject to the display's accommodation error within
    ``accommodation_tolerance_D`` (0.25 D), by a quadratic penalty
    (:func:`accommodation_penalty`). The display's error is each eye's error at the
    rendered depth less its own error on the CDP, where every view reaches the eye
    unshifted as from a real point (:class:`Objective`).
``"image_at_peak"`` (maximised)
    population-mean VSOTF at each eye's own predicted accommodation. Alone it is won by
    removing the light field: views stacked on the pupil centre make one pinhole, sharp at
    every depth, whose every eye focuses on the CDP (tests pin the ordering).
``"depth_of_field"`` (maximised)
    population-mean VSOTF at the correct accommodation (accommodation = rendered depth),
    :func:`depth_of_field`. It also rewards the pinhole.
``"accommodation"`` (minimised)
    mean squared error (D²) of the predicted accommodation against the rendered depth,
    :func:`accommodation_mse`.
``"resolution"`` (maximised)
    a smooth MTF cut-off (cpd) at the correct accommodation: the frequency extent over
    which the radial MTF exceeds ``mtf_threshold`` (0.05, the paper's cut-off criterion),
    counted with a logistic step of width ``mtf_softness`` instead of a hard threshold,
    :func:`soft_cutoff_cpd`. For a monotone MTF it equals the cut-off frequency to within
    the frequency step; where the MTF of an off-CDP rendering dips below the threshold and
    rises again, the bands above it count too.

Two settings (:func:`make_problem`'s ``accuracy``): a fit runs on the cheap ``"fit"``
setting (550 nm, a 0.25 D peak grid, the grid parabola's vertex), and the report scores
held-out eyes on the ``"full"`` one (31 wavelengths, a 0.25 D grid refined by the
``"local"`` three-state fit) — model no more than the fit needs, verify on what the study
uses. :func:`trade_off_front` fits one layout per tolerance and scores them beside the
tangent grids and natural viewing.

A dict of weights gives a weighted sum: loss = −w_dof·DoF + w_acc·MSE − w_res·resolution
(units: VSOTF, D², cpd — scale the weights accordingly, e.g. resolution 0.01 per cpd).

Why the open-pupil VSOTF reference is enforced
-----------------------------------------------
The paper normalises VSOTF by the same layout without aberrations. That reference moves
with the layout: shrink the subapertures and reference and eye both lose contrast, but
the eye's defocus and aberrations matter less, so the ratio rises. Every objective then
rewards shrinking the subapertures without bound (measured by :func:`diameter_scan`: 2×2
at 1.5 mm pitch, 4 seeded eyes, correct accommodation at 0–4 D, 450/550/650 nm: mean
VSOTF 0.82 at d = 0.5 mm against 0.43 at the tangent 1.5 mm). Scored against the natural
open pupil (``ModelOptions(vsotf_reference="open_pupil")``, a reference that does not
depend on the layout) the same scan has an interior optimum at d ≈ 1 mm (0.367 against
0.316 for the tangent grid; worst depth 0.291 against 0.148). :func:`make_problem`
refuses any other reference.

What the old default favoured (benchmarks/layout_optimisation.py, 2×2 lattice, 10 training
eyes, 200 held-out eyes, 0–4 D): depth of field alone, with overlapping views allowed,
collapsed the lattice onto the pupil centre (one 0.93 mm aperture, no light field left),
and an evaluation that searched for peaks only ±0.3 D around each depth reported 0.28 D
of accommodation RMSE for it where every eye focuses within 0.3 D of the CDP (1.4 D RMSE).
Hence the accommodation-aware default and the uncapped evaluation.
"""

from __future__ import annotations

import dataclasses
import datetime
import json
import math
import time
import warnings
from dataclasses import dataclass
from pathlib import Path

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optimistix as optx
from jaxtyping import Array, Float

from ._types import FULL, as_real_array as _real
from .display import DisplayOptics
from .eyes import Eyes
from .layouts import Layout, make_layout
from .options import ModelOptions
from .peaks import PEAK_METHODS, Peaks, peaks_from_grid
from .pipeline import (
    Accommodation,
    PipelineConfig,
    RetinalMetrics,
    Scene,
    reference_normalisers,
    retinal_metrics,
)
from .planner import plan_sampling
from .sampling import Sampling
from .spectral import Spectrum, make_spectrum

OBJECTIVES = ("image_at_peak", "depth_of_field", "accommodation", "resolution")
MAXIMISED = ("image_at_peak", "depth_of_field", "resolution")
DEFAULT_OBJECTIVE = "accommodation_aware"
DEFAULT_TOLERANCE_D = 0.25
ACCURACIES = ("fit", "full")
LATTICES = ("square", "hex")
CONTAINMENTS = ("centre", "contained")
METHODS = ("lbfgsb", "bfgs")
DEFAULT_WAVELENGTHS_NM = (550.0,)
"""The fit setting's spectrum: one wavelength at the LCA reference (550 nm, no chromatic
defocus). A fit needs the ordering of layouts, not their absolute VSOTF; the report
re-scores the fitted layout on 31 wavelengths (:data:`FULL_WAVELENGTHS_NM`)."""
LAYOUT_FORMAT = "lfjax-layout/1"

_ROTATION_RANGE = {"square": math.pi / 4.0, "hex": math.pi / 6.0}
TOL_MM = 1e-6
"""Lengths within this many mm of a constraint's bound count as on it (float32 round-off)."""
_EPS = 1e-6  # fraction clip for the unconstrained (logit / artanh) starting point


# ----------------------------------------------------------------------------- helpers


def _safe_sqrt(x):
    """sqrt with a finite (zero) gradient at 0 (double-where)."""
    positive = x > 0
    return jnp.where(positive, jnp.sqrt(jnp.where(positive, x, 1.0)), 0.0)


def _finite_scalar(name: str, value, lo: float | None = None, hi: float | None = None,
                   lo_open: bool = False) -> float:
    """Host check of one scalar parameter: finite and inside [lo, hi] (or (lo, hi])."""
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a number, got {value!r}") from None
    bad_lo = lo is not None and (x <= lo if lo_open else x < lo)
    bad_hi = hi is not None and x > hi
    if not math.isfinite(x) or bad_lo or bad_hi:
        left = "(" if lo_open else "["
        rng = f"{left}{'-inf' if lo is None else f'{lo:g}'}, {'inf' if hi is None else f'{hi:g}'}]"
        raise ValueError(f"{name} must be finite and in {rng}, got {value!r}")
    return x


# ----------------------------------------------------------------------------- lattices


def lattice_sites(kind: str, n_views: int) -> np.ndarray:
    """Lattice sites in units of the pitch, (n_views, 2), host array.

    ``"square"``: ``n_views`` must be n² — the n×n grid centred on the pupil (row-major,
    as :func:`lfjax.layouts.grid_layout`). ``"hex"``: the ``n_views`` sites of the unit
    triangular lattice nearest the pupil centre (one site at the centre; ties broken by
    angle, so 1, 7, 19, 37 views give whole rings).
    """
    if kind not in LATTICES:
        raise ValueError(f"kind must be one of {LATTICES}, got {kind!r}")
    if isinstance(n_views, bool) or int(n_views) != n_views or n_views < 1:
        raise ValueError(f"n_views must be an integer >= 1, got {n_views!r}")
    n_views = int(n_views)
    if kind == "square":
        n = int(round(math.sqrt(n_views)))
        if n * n != n_views:
            raise ValueError(f"a square lattice needs n_views = n*n (1, 4, 9, 16, ...), got {n_views}")
        offsets = np.arange(n) - (n - 1) / 2.0
        xx, yy = np.meshgrid(offsets, offsets)
        return np.stack([xx.ravel(), yy.ravel()], axis=1)
    reach = int(math.ceil(math.sqrt(n_views))) + 2
    i, k = np.meshgrid(np.arange(-reach, reach + 1), np.arange(-reach, reach + 1), indexing="ij")
    pts = np.stack([k.ravel() + 0.5 * i.ravel(), i.ravel() * math.sqrt(3.0) / 2.0], axis=1)
    radius = np.round(np.hypot(pts[:, 0], pts[:, 1]), 9)
    angle = np.round(np.mod(np.arctan2(pts[:, 1], pts[:, 0]), 2 * math.pi), 9)
    order = np.lexsort((angle, radius))
    return pts[order[:n_views]]


def hex_sites_in_pupil(pitch_mm: float, pupil_diameter_mm: float) -> np.ndarray:
    """Hexagonal lattice sites (pitch units) whose centres fall inside the pupil at this pitch."""
    pitch = _finite_scalar("pitch_mm", pitch_mm, 0.0, None, lo_open=True)
    radius = 0.5 * _finite_scalar("pupil_diameter_mm", pupil_diameter_mm, 0.0, None, lo_open=True)
    n_max = int(math.ceil((radius / pitch + 2) ** 2 * 4))
    sites = lattice_sites("hex", n_max)
    keep = np.hypot(sites[:, 0], sites[:, 1]) * pitch <= radius * (1 - 1e-9)
    return sites[keep]


class LatticeParams(eqx.Module):
    """A lattice of equal subapertures: pitch, diameter and rotation (array leaves).

    Attributes
    ----------
    pitch_mm : () distance between neighbouring sites, mm
    diameter_mm : () subaperture diameter, mm
    rotation_rad : () rotation of the lattice about the pupil centre, rad (counter-clockwise)
    sites : static tuple of (u, v) site coordinates in units of the pitch
    kind : static, ``"square"`` or ``"hex"``
    """

    pitch_mm: Float[Array, ""] = eqx.field(converter=_real)
    diameter_mm: Float[Array, ""] = eqx.field(converter=_real)
    rotation_rad: Float[Array, ""] = eqx.field(converter=_real)
    sites: tuple = eqx.field(static=True)
    kind: str = eqx.field(static=True)

    def __check_init__(self):
        if self.kind not in LATTICES:
            raise ValueError(f"kind must be one of {LATTICES}, got {self.kind!r}")
        if len(self.sites) < 1:
            raise ValueError("a lattice needs at least one site")

    @property
    def n_views(self) -> int:
        return len(self.sites)

    @property
    def max_site_radius(self) -> float:
        """Largest |site| in pitch units (host float)."""
        return max(math.hypot(u, v) for u, v in self.sites)

    @property
    def centres_mm(self):
        s = jnp.asarray(np.asarray(self.sites, float), self.pitch_mm.dtype)
        c, si = jnp.cos(self.rotation_rad), jnp.sin(self.rotation_rad)
        x = c * s[:, 0] - si * s[:, 1]
        y = si * s[:, 0] + c * s[:, 1]
        return self.pitch_mm * jnp.stack([x, y], axis=1)

    @property
    def diameters_mm(self):
        return jnp.broadcast_to(self.diameter_mm, (self.n_views,))


def lattice_params(kind: str, n_views: int | None, pitch_mm: float, diameter_mm: float | None = None,
                   rotation_rad: float = 0.0, pupil_diameter_mm: float = 3.0) -> LatticeParams:
    """Lattice layout parameters, checked on the host.

    ``n_views`` fixes the sites (:func:`lattice_sites`); for ``kind="hex"`` it may be None:
    the sites whose centres fall inside the pupil at ``pitch_mm`` (:func:`hex_sites_in_pupil`).
    ``diameter_mm`` defaults to the pitch (tangent discs).
    """
    pitch = _finite_scalar("pitch_mm", pitch_mm, 0.0, None, lo_open=True)
    diameter = pitch if diameter_mm is None else _finite_scalar("diameter_mm", diameter_mm, 0.0,
                                                                None, lo_open=True)
    rotation = _finite_scalar("rotation_rad", rotation_rad)
    if n_views is None:
        if kind != "hex":
            raise ValueError("n_views is required for a square lattice (n*n views)")
        sites = hex_sites_in_pupil(pitch, pupil_diameter_mm)
    else:
        sites = lattice_sites(kind, n_views)
    return LatticeParams(pitch, diameter, rotation, tuple(map(tuple, sites.tolist())), kind)


def tangent_lattice(kind: str, n_views: int, pupil_diameter_mm: float = 3.0) -> LatticeParams:
    """Tangent discs (pitch = diameter) filling the pupil as the paper's grids do: square
    n×n with pitch = pupil/n (:func:`lfjax.layouts.grid_layout`); hex with pitch =
    pupil/(2ρ + 1), ρ the outermost site's radius in pitches (one pitch for 7 views)."""
    sites = lattice_sites(kind, n_views)
    if kind == "square":
        pitch = float(pupil_diameter_mm) / int(round(math.sqrt(n_views)))
    else:
        rho = float(np.hypot(sites[:, 0], sites[:, 1]).max())
        pitch = float(pupil_diameter_mm) / (2.0 * rho + 1.0) if rho > 0 else float(pupil_diameter_mm)
    return LatticeParams(pitch, pitch, 0.0, tuple(map(tuple, sites.tolist())), kind)


class FreeParams(eqx.Module):
    """Free subapertures: centres (n_views, 2) and diameters (n_views,), mm (array leaves)."""

    centres_mm: Float[Array, "n_views 2"] = eqx.field(converter=_real)
    diameters_mm: Float[Array, " n_views"] = eqx.field(converter=_real)

    def __check_init__(self):
        if self.centres_mm.ndim != 2 or self.centres_mm.shape[-1] != 2:
            raise ValueError(f"centres_mm must have shape (n_views, 2), got {self.centres_mm.shape}")
        if self.diameters_mm.shape != self.centres_mm.shape[:1]:
            raise ValueError(f"diameters_mm must have shape ({self.centres_mm.shape[0]},), "
                             f"got {self.diameters_mm.shape}")

    @property
    def n_views(self) -> int:
        return int(self.diameters_mm.shape[0])


def free_params(centres_mm, diameters_mm) -> FreeParams:
    """Free layout parameters from host arrays (mm), checked finite."""
    c = np.asarray(centres_mm, float).reshape(-1, 2)
    d = np.asarray(diameters_mm, float).reshape(-1)
    if c.shape[0] < 1:
        raise ValueError("a layout needs at least one view (n_views >= 1)")
    if d.shape[0] != c.shape[0]:
        raise ValueError(f"{c.shape[0]} centres_mm but {d.shape[0]} diameters_mm")
    for name, x in (("centres_mm", c), ("diameters_mm", d)):
        if not np.all(np.isfinite(x)):
            raise ValueError(f"{name} must be finite (no NaN or inf), got {x.tolist()}")
    return FreeParams(jnp.asarray(c), jnp.asarray(d))


def as_free(params) -> FreeParams:
    """Any layout-like (LatticeParams, FreeParams, Layout) as FreeParams."""
    return FreeParams(params.centres_mm, params.diameters_mm)


# ----------------------------------------------------------------------------- constraints


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
        pupil = _finite_scalar("pupil_diameter_mm", self.pupil_diameter_mm, 0.0, None, lo_open=True)
        dmax = pupil if self.max_diameter_mm is None else _finite_scalar(
            "max_diameter_mm", self.max_diameter_mm, 0.0, pupil, lo_open=True)
        dmin = _finite_scalar("min_diameter_mm", self.min_diameter_mm, 0.0, dmax, lo_open=True)
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


# ----------------------------------------------------------------------------- feasible maps


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
    r = _safe_sqrt(r2)
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
        r = _safe_sqrt(jnp.sum(centres * centres, axis=-1))
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


def _check_finite_params(params) -> None:
    if isinstance(params, LatticeParams):
        for name in ("pitch_mm", "diameter_mm", "rotation_rad"):
            _finite_scalar(name, np.asarray(getattr(params, name)))
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
    _check_finite_params(params)
    margin = _finite_scalar("margin", margin, 0.0, 0.49)
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
    _check_finite_params(params)
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
    _check_finite_params(params)
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


# ----------------------------------------------------------------------------- objectives


@dataclass(frozen=True)
class Objective:
    """What a fit optimises (static, hashable).

    Attributes
    ----------
    weights : ((name, weight), …) over :data:`OBJECTIVES`; loss = Σ ± weight·term with −
        for the maximised terms (image_at_peak and depth_of_field: VSOTF; resolution: cpd)
        and + for accommodation (D²)
    accommodation_tolerance_D : a constraint on the display's accommodation error (D), or
        None: the RMSE over eyes and depths of each eye's predicted accommodation error at
        the rendered depth less its own error on the CDP (where every view reaches the eye
        unshifted, as from a real point: what remains is the eye's refraction and lag,
        which no display causes or corrects — natural viewing alone misses the rendered
        depth by 0.3–0.4 D RMS on the Thibos population, so a bound on the raw error
        would be unattainable for reasons that are not the layout's). When the RMSE
        exceeds the tolerance the loss gains ``penalty_per_D2``·(RMSE − tolerance)² (a
        quadratic penalty: zero, with zero gradient, inside the tolerance)
    penalty_per_D2 : weight of that penalty, loss units per D²
    mtf_threshold : MTF level of the cut-off (the paper's 0.05)
    mtf_softness : width of the logistic step that counts frequencies above the threshold

    The default, ``Objective()`` (:data:`DEFAULT_OBJECTIVE`, "accommodation_aware"), is
    image quality at each eye's own predicted accommodation (population-mean VSOTF at the
    global peak of its through-focus curve) subject to an accommodation RMSE within
    0.25 D (the display's share, above), about the eye's depth of focus: a display that drives no accommodation (views
    stacked on the pupil centre: a pinhole whose every eye focuses on the CDP) violates it
    by a dioptre or more and scores far below the paper's tangent grids.
    """

    weights: tuple = (("image_at_peak", 1.0),)
    accommodation_tolerance_D: float | None = DEFAULT_TOLERANCE_D
    penalty_per_D2: float = 100.0
    mtf_threshold: float = 0.05
    mtf_softness: float = 0.02

    def __post_init__(self):
        w = tuple((str(k), float(v)) for k, v in dict(self.weights).items())
        for name, value in w:
            if name not in OBJECTIVES:
                raise ValueError(f"objective {name!r} unknown; choose from {OBJECTIVES}")
            _finite_scalar(f"weight of {name}", value, 0.0)
        if not any(v > 0 for _, v in w):
            raise ValueError(f"at least one objective weight must be > 0, got {dict(w)}")
        object.__setattr__(self, "weights", w)
        if self.accommodation_tolerance_D is not None:
            object.__setattr__(self, "accommodation_tolerance_D", _finite_scalar(
                "accommodation_tolerance_D", self.accommodation_tolerance_D, 0.0, 2.0, lo_open=True))
        _finite_scalar("penalty_per_D2", self.penalty_per_D2, 0.0, None, lo_open=True)
        _finite_scalar("mtf_threshold", self.mtf_threshold, 0.0, 1.0, lo_open=True)
        _finite_scalar("mtf_softness", self.mtf_softness, 0.0, 1.0, lo_open=True)

    @classmethod
    def parse(cls, objective, accommodation_tolerance_D="default") -> Objective:
        """An Objective from itself, ``"accommodation_aware"`` (the default), a name of
        :data:`OBJECTIVES` (alone, unconstrained) or a {name: weight} dict (unconstrained).
        ``accommodation_tolerance_D`` (D or None) replaces the constraint when given."""
        if isinstance(objective, Objective):
            out = objective
        elif objective is None or objective == DEFAULT_OBJECTIVE:
            out = cls()
        elif isinstance(objective, str):
            if objective not in OBJECTIVES:
                raise ValueError(f"objective must be {DEFAULT_OBJECTIVE!r}, one of {OBJECTIVES} or a "
                                 f"dict of weights, got {objective!r}")
            out = cls(((objective, 1.0),), accommodation_tolerance_D=None)
        elif isinstance(objective, dict):
            out = cls(tuple(objective.items()), accommodation_tolerance_D=None)
        else:
            raise ValueError(f"objective must be a name, a dict of weights or an Objective, got {objective!r}")
        if accommodation_tolerance_D != "default":
            out = dataclasses.replace(out, accommodation_tolerance_D=accommodation_tolerance_D)
        return out

    def weight(self, name: str) -> float:
        return dict(self.weights).get(name, 0.0)

    @property
    def active(self) -> tuple[str, ...]:
        return tuple(k for k, v in self.weights if v > 0)

    @property
    def needs_peaks(self) -> bool:
        """Whether the loss needs each eye's predicted accommodation."""
        return (self.accommodation_tolerance_D is not None
                or "image_at_peak" in self.active or "accommodation" in self.active)

    @property
    def name(self) -> str:
        terms = (self.active[0] if len(self.active) == 1
                 else " + ".join(f"{v:g}·{k}" for k, v in self.weights if v > 0))
        if self.accommodation_tolerance_D is None:
            return terms
        return f"{terms} s.t. accommodation RMSE <= {self.accommodation_tolerance_D:g} D"

    def as_dict(self) -> dict:
        return dict(weights=dict(self.weights), accommodation_tolerance_D=self.accommodation_tolerance_D,
                    penalty_per_D2=self.penalty_per_D2, mtf_threshold=self.mtf_threshold,
                    mtf_softness=self.mtf_softness)


class LayoutProblem(eqx.Module):
    """Everything a layout objective needs besides the layout (see :func:`make_problem`).

    Attributes
    ----------
    eyes : the population the objective averages over
    spectrum : wavelengths, weights, LCA, SCE
    depths_D : (n_depth,) rendered depths, D
    cdp_D : () central depth plane, D
    accommodation : the correct-focus states (accommodation = rendered depth)
    peak_grid : the accommodation grid on which each eye's through-focus VSOTF is
        evaluated to find its predicted accommodation: absolute states shared by every
        depth, each depth seeing (``peak_allowed``) the states between its own depth and
        the CDP, widened by ``peak_margin_D`` on both sides (lower end ≥ 0 D). The two
        attractors of a light-field display — the rendered depth and the display's CDP —
        are both inside every depth's window, so a layout that lets the eye focus on the
        CDP is seen doing so.
    peak_depths_D : (n_depth + 1,) the rendered depths and, last, the CDP: a point rendered
        on the CDP reaches the eye from every view unshifted, as a real point would, so the
        eye's peak there is its own accommodation error (refraction, lag, aberrations),
        which the display neither causes nor can correct; errors are also reported
        relative to it
    peak_allowed : (n_depth + 1, n_k) bool, the states each of those depths sees
    reference : open-pupil VSOTF/Strehl normalisers (independent of the layout)
    config, objective, constraints, options : static
    accuracy : static, ``"fit"`` (the cheap training setting) or ``"full"`` (the report's)
    peak_method : static, refinement of the grid peak (:mod:`lfjax.peaks`)
    peak_step_D, peak_margin_D : static, the peak grid's step and margin, D
    window_D : static, accommodation offsets (± D) drawn by :func:`through_focus_curves`
    spectrum_given : static, whether the spectrum was the caller's (a display's) rather
        than V(λ)-weighted wavelengths (the full setting then keeps it)
    display : the display's optics (lenslet diffraction, pixels) or None (ideal display)
    values_grid : the peak grid's states and the correct-focus states in one grid, for
        reports: pairs (n_depth + 1, n_k + 1), the first n_k columns the peak grid's
        (``peak_allowed``), the last each rendered depth's correct focus (unused in the
        CDP's row). A report then computes each shared state's elemental OTFs once
        (:func:`evaluate_layout`); None for a problem built without it
    """

    eyes: Eyes
    spectrum: Spectrum
    depths_D: Float[Array, " n_depth"]
    cdp_D: Float[Array, ""]
    accommodation: Accommodation
    peak_grid: Accommodation
    peak_depths_D: Float[Array, " n_peak_depth"]
    peak_allowed: Array
    reference: tuple
    config: PipelineConfig = eqx.field(static=True)
    objective: Objective = eqx.field(static=True)
    constraints: Constraints = eqx.field(static=True)
    options: ModelOptions = eqx.field(static=True)
    accuracy: str = eqx.field(static=True)
    peak_method: str = eqx.field(static=True)
    peak_step_D: float = eqx.field(static=True)
    peak_margin_D: float = eqx.field(static=True)
    window_D: float = eqx.field(static=True)
    spectrum_given: bool = eqx.field(static=True)
    display: DisplayOptics | None = None
    values_grid: Accommodation | None = None

    @property
    def pupil_diameter_mm(self) -> float:
        return self.constraints.pupil_diameter_mm

    def with_eyes(self, eyes: Eyes) -> LayoutProblem:
        """The same problem on another population (the held-out eyes)."""
        if eyes.measured_pupil_mm < self.pupil_diameter_mm:
            raise ValueError(f"eyes measured on {eyes.measured_pupil_mm:g} mm cannot be evaluated "
                             f"on a {self.pupil_diameter_mm:g} mm pupil")
        return eqx.tree_at(lambda p: p.eyes, self, eyes)

    def with_objective(self, objective) -> LayoutProblem:
        """The same problem with another objective."""
        return dataclasses.replace(self, objective=Objective.parse(objective))

    def at_accuracy(self, accuracy: str = "full", eyes: Eyes | None = None,
                    sampling: Sampling | None = None) -> LayoutProblem:
        """The same scene at another accuracy setting (:func:`make_problem`'s
        ``accuracy``), on ``eyes`` (default this problem's); the sampling is planned anew
        for that setting unless given."""
        eyes = self.eyes if eyes is None else eyes
        return make_problem(
            eyes, np.asarray(self.depths_D, float), self.constraints, self.objective,
            cdp_D=float(self.cdp_D), options=self.options, window_D=self.window_D,
            spectrum=self.spectrum if self.spectrum_given else None,
            display=self.display, accuracy=accuracy, sampling=sampling)

    def scene(self, layout) -> Scene:
        return Scene(layout.centres_mm, layout.diameters_mm, self.cdp_D, self.depths_D,
                     self.pupil_diameter_mm, self.display)


def depth_grid(low_D: float, high_D: float, n_depths: int) -> np.ndarray:
    """``n_depths`` rendered depths evenly spanning [low_D, high_D] (D), validated:
    0 ≤ low < high, finite; n_depths ≥ 2 (or 1 with low == high)."""
    lo = _finite_scalar("depth range low end (D)", low_D, 0.0)
    hi = _finite_scalar("depth range high end (D)", high_D, 0.0)
    if isinstance(n_depths, bool) or int(n_depths) != n_depths or n_depths < 1:
        raise ValueError(f"n_depths must be an integer >= 1, got {n_depths!r}")
    if n_depths == 1 and hi == lo:
        return np.array([lo])
    if not hi > lo:
        raise ValueError(f"depth range must satisfy 0 <= low < high (D); got low = {lo:g}, "
                         f"high = {hi:g} ({'empty' if hi == lo else 'inverted'})")
    if n_depths < 2:
        raise ValueError(f"n_depths must be >= 2 for a depth range, got {n_depths}")
    return np.linspace(lo, hi, int(n_depths))


def _check_depths(depths_D) -> np.ndarray:
    d = np.atleast_1d(np.asarray(depths_D, float))
    if d.ndim != 1 or d.size < 1:
        raise ValueError(f"depths_D must be a non-empty 1-D array, got shape {d.shape}")
    if not np.all(np.isfinite(d)) or np.any(d < 0):
        raise ValueError(f"depths_D must be finite and >= 0 D (0 D is optical infinity), got {d.tolist()}")
    return d


def peak_window(depths_D, cdp_D: float, step_D: float, margin_D: float):
    """The accommodation grid on which predicted accommodation is searched (host numbers).

    Each rendered depth d sees the states in [max(min(d, CDP) − margin, 0),
    max(d, CDP) + margin]: both places a light-field display can draw the eye to. States
    are multiples of ``step_D`` from 0 D. Returns (states_D (n_k,), index (n_depth, n_k),
    allowed (n_depth, n_k) bool); every state is seen by at least one depth.
    """
    depths = _check_depths(depths_D)
    step = _finite_scalar("peak_step_D", step_D, 0.0, 1.0, lo_open=True)
    margin = _finite_scalar("peak_margin_D", margin_D, 0.0, 5.0)
    lo = np.maximum(np.minimum(depths, cdp_D) - margin, 0.0)
    hi = np.maximum(depths, cdp_D) + margin
    states = np.round(np.arange(0.0, hi.max() + 0.5 * step, step), 9)
    allowed = (states[None, :] >= lo[:, None] - 1e-9) & (states[None, :] <= hi[:, None] + 1e-9)
    if np.any(allowed.sum(axis=1) < 3):
        raise ValueError(f"peak_step_D = {step:g} D leaves fewer than 3 states in some depth's "
                         f"window; use a smaller step or a larger margin")
    used = allowed.any(axis=0)
    states, allowed = states[used], allowed[:, used]
    index = np.broadcast_to(np.arange(states.size), allowed.shape)
    return states, index, allowed


def _values_grid_pairs(states_D, depths_D, cdp_D: float):
    """(states (n,), pair_index (n_depth + 1, n_k + 1)) of :attr:`LayoutProblem.values_grid`:
    the peak grid's states, then every rendered depth not already among them; the first
    n_k columns index the peak grid's states, the last each depth's own state (index 0 in
    the CDP's row, which has no correct-focus pair)."""
    states = np.asarray(states_D, float)
    depths = np.asarray(depths_D, float)
    missing = [d for d in depths if not np.any(np.abs(states - d) <= 1e-9)]
    union = np.concatenate([states, np.asarray(missing, float)])
    own = np.array([int(np.argmin(np.abs(union - d))) for d in depths] + [0])
    index = np.empty((depths.size + 1, states.size + 1), np.int32)
    index[:, :-1] = np.arange(states.size)
    index[:, -1] = own
    return union, index


def envelope_layout(constraints: Constraints) -> Layout:
    """The worst case of the feasible set for the sampling guard: the largest disc at the
    pupil edge (widest defocus blur and display shift) and the smallest one (widest
    diffraction blur)."""
    radius = constraints.centre_radius_mm
    if constraints.containment == "contained":
        radius = constraints.radius_mm - 0.5 * constraints.max_diameter_mm
    edge = max(radius * (1 - 1e-6), 0.0)
    return make_layout([[edge, 0.0], [0.0, 0.0]],
                       [constraints.max_diameter_mm, constraints.min_diameter_mm],
                       constraints.pupil_diameter_mm, name="envelope",
                       window_diameter_mm=constraints.max_diameter_mm)


def guard_sampling(constraints: Constraints, depths_D, cdp_D: float, wavelengths_nm, eyes_zernike_um=None,
                   measured_pupil_mm: float = 3.0, window_D: float = 0.5,
                   options: ModelOptions = ModelOptions(vsotf_reference="open_pupil"),
                   display: DisplayOptics | None = None, spectral_weights=None,
                   pairs: tuple | None = None) -> Sampling:
    """Frequency sampling whose aliasing guard holds for every feasible layout: the
    planner's guard (``estimate_accuracy=False``) on :func:`envelope_layout`, for
    accommodation within ±``window_D`` of each depth, or for the (accommodation D, depth D)
    ``pairs`` when given."""
    depths = _check_depths(depths_D)
    extra = {}
    if pairs is not None:
        extra = dict(pairs=(np.asarray(pairs[0], float), np.asarray(pairs[1], float)),
                     accommodation_D=np.unique(np.asarray(pairs[0], float)))
    plan = plan_sampling(
        envelope_layout(constraints), pupil_diameter_mm=constraints.pupil_diameter_mm,
        cdp_D=float(cdp_D), depths_D=depths,
        accommodation_window_D=None if pairs is not None else window_D,
        wavelengths_nm=np.asarray(wavelengths_nm, float), eyes_zernike_um=eyes_zernike_um,
        measured_pupil_mm=measured_pupil_mm, options=options, estimate_accuracy=False,
        display=display, spectral_weights=spectral_weights, **extra,
    )
    return plan.sampling


def _evaluated_pairs(depths, cdp: float, step_D: float, margin_D: float):
    """Every (accommodation D, depth D) pair a problem evaluates: the peak grid (rendered
    depths and the CDP) and the correct focus."""
    peak_depths = np.append(depths, cdp)
    states, index, allowed = peak_window(peak_depths, cdp, step_D, margin_D)
    depth_of = np.broadcast_to(peak_depths[:, None], allowed.shape)
    return (np.concatenate([states[index][allowed], depths]),
            np.concatenate([depth_of[allowed], depths]))


_SETTINGS = {
    # wavelengths (None: as given), peak grid step (D), margin (D), refinement
    "fit": dict(peak_step_D=0.25, peak_margin_D=0.5, peak_method="vertex"),
    "full": dict(peak_step_D=0.25, peak_margin_D=0.75, peak_method="local"),
}
FULL_WAVELENGTHS_NM = tuple(float(w) for w in np.arange(400.0, 701.0, 10.0))
"""The full setting's spectrum: 400–700 nm in 10 nm steps (31 wavelengths, the study's)."""


def make_problem(
    eyes: Eyes, depths_D, constraints: Constraints = Constraints(), objective=DEFAULT_OBJECTIVE,
    *, cdp_D: float = 2.0, wavelengths_nm=DEFAULT_WAVELENGTHS_NM,
    options: ModelOptions = ModelOptions(vsotf_reference="open_pupil"),
    sampling: Sampling | None = None, window_D: float = 0.5, planning_eyes: Eyes | None = None,
    eye_chunk: int | None = None, spectrum: Spectrum | None = None,
    display: DisplayOptics | None = None, accuracy: str = "fit",
    peak_step_D: float | None = None, peak_margin_D: float | None = None,
    peak_method: str | None = None,
) -> LayoutProblem:
    """A layout-optimisation problem, validated on the host.

    Parameters
    ----------
    eyes : population the objective averages over (the training eyes)
    depths_D : rendered depths, D (finite, ≥ 0)
    constraints : feasible layouts (pupil, diameter range, containment, overlap)
    objective : ``"accommodation_aware"`` (default), a name of :data:`OBJECTIVES`, a
        {name: weight} dict or an :class:`Objective`
    cdp_D : the display's central depth plane, D
    wavelengths_nm : spectrum (V(λ)-weighted), nm; the ``"full"`` setting replaces it by
        :data:`FULL_WAVELENGTHS_NM`
    options : model options; ``vsotf_reference`` must be ``"open_pupil"`` (module docstring)
    sampling : frequency sampling; default :func:`guard_sampling` for the constraints'
        envelope and every (accommodation, depth) pair the problem evaluates (the peak
        grid and the correct focus), for ``planning_eyes`` (default ``eyes``)
    window_D : accommodation offsets (± D) drawn by :func:`through_focus_curves`
    eye_chunk : eyes evaluated together inside the pipeline's map (None: one at a time)
    spectrum : a :class:`~lfjax.spectral.Spectrum` instead of ``wavelengths_nm`` (e.g. a
        display's, :func:`lfjax.display_spectra.display_spectrum`); kept by both settings
    display : :class:`~lfjax.display.DisplayOptics` of a real display (lenslet diffraction,
        pixels; e.g. ``LensletArray.optics()``) the layout is optimised for; default the
        paper's ideal display. The reference stays the ideal open pupil.
    accuracy : ``"fit"`` (default) — what a fit needs: the given wavelengths (550 nm by
        default), predicted accommodation on a 0.25 D grid within 0.5 D around each
        depth's window, located by the grid parabola's vertex (``"vertex"``: no evaluation
        beyond the grid); ``"full"`` — what a report needs: 31 wavelengths
        (400–700 nm, 10 nm), a 0.25 D grid within 0.75 D around each window, refined by
        ``"local"`` (the sweep's and the study's peak finder). Both find the *global*
        maximum of each eye's through-focus VSOTF over a window holding the rendered depth
        and the CDP (:func:`peak_window`); a maximum on a window edge is reported as such.
    peak_step_D, peak_margin_D, peak_method : override the setting's values
    """
    if accuracy not in ACCURACIES:
        raise ValueError(f"accuracy must be one of {ACCURACIES}, got {accuracy!r}")
    setting = dict(_SETTINGS[accuracy])
    for key, value in (("peak_step_D", peak_step_D), ("peak_margin_D", peak_margin_D),
                       ("peak_method", peak_method)):
        if value is not None:
            setting[key] = value
    if setting["peak_method"] not in PEAK_METHODS or setting["peak_method"] == "auto":
        raise ValueError(f"peak_method must be one of {tuple(m for m in PEAK_METHODS if m != 'auto')}, "
                         f"got {setting['peak_method']!r}")
    if display is not None and not isinstance(display, DisplayOptics):
        raise ValueError(f"display must be lfjax.display.DisplayOptics or None, got {type(display).__name__}")
    if options.vsotf_reference != "open_pupil":
        raise ValueError(
            "layout objectives need ModelOptions(vsotf_reference='open_pupil'): the paper's "
            "reference (the same layout without aberrations) shrinks with the subapertures, so "
            f"every objective would reward shrinking them without bound; got {options.vsotf_reference!r}"
        )
    if not isinstance(eyes, Eyes):
        raise ValueError(f"eyes must be lfjax.Eyes, got {type(eyes).__name__}")
    if not np.all(np.isfinite(np.asarray(eyes.zernike_um))):
        raise ValueError("eyes.zernike_um contains non-finite values (NaN or inf)")
    if eyes.measured_pupil_mm < constraints.pupil_diameter_mm - 1e-12:
        raise ValueError(f"pupil_diameter_mm = {constraints.pupil_diameter_mm:g} exceeds the eyes' "
                         f"measured pupil {eyes.measured_pupil_mm:g} mm")
    depths = _check_depths(depths_D)
    cdp = _finite_scalar("cdp_D", cdp_D, 0.0)
    objective = Objective.parse(objective)
    window_D = _finite_scalar("window_D", window_D, 0.0, None, lo_open=True)
    spectrum_given = spectrum is not None
    if spectrum is None:
        wl = FULL_WAVELENGTHS_NM if accuracy == "full" else wavelengths_nm
        spectrum = make_spectrum(np.atleast_1d(np.asarray(wl, float)), options)
    elif not isinstance(spectrum, Spectrum):
        raise ValueError(f"spectrum must be lfjax.Spectrum or None, got {type(spectrum).__name__}")
    wl = np.asarray(spectrum.wavelengths_nm, float)
    peak_depths = np.append(depths, cdp)
    states, index, allowed = peak_window(peak_depths, cdp, setting["peak_step_D"],
                                         setting["peak_margin_D"])
    if sampling is None:
        plan_eyes = eyes if planning_eyes is None else planning_eyes
        pairs = _evaluated_pairs(depths, cdp, setting["peak_step_D"], setting["peak_margin_D"])
        sampling = guard_sampling(constraints, depths, cdp, wl, np.asarray(plan_eyes.zernike_um),
                                  plan_eyes.measured_pupil_mm, window_D, options, display,
                                  np.asarray(spectrum.weights), pairs=pairs)
    config = PipelineConfig.build(wl, constraints.max_diameter_mm, constraints.pupil_diameter_mm,
                                  sampling, options, eye_chunk, display=display)
    accommodation = Accommodation.per_depth(depths[:, None], options, constraints.pupil_diameter_mm)
    peak_grid = Accommodation.shared(states, index, options, constraints.pupil_diameter_mm)
    values_grid = Accommodation.shared(*_values_grid_pairs(states, depths, cdp), options,
                                       constraints.pupil_diameter_mm)
    dtype = jnp.result_type(float)
    cdp_arr, depths_arr = jnp.asarray(cdp, dtype), jnp.asarray(depths, dtype)
    # Open-pupil reference: independent of the layout, so computed once (any layout will do).
    any_layout = Scene(jnp.zeros((1, 2), dtype), jnp.full((1,), constraints.max_diameter_mm, dtype),
                       cdp_arr, depths_arr, constraints.pupil_diameter_mm)
    reference = _reference_jit(any_layout, spectrum, accommodation, config)
    return LayoutProblem(eyes, spectrum, depths_arr, cdp_arr, accommodation, peak_grid,
                         jnp.asarray(peak_depths, dtype), jnp.asarray(allowed), tuple(jax.lax.stop_gradient(r) for r in reference),
                         config, objective, constraints, options, accuracy,
                         setting["peak_method"], float(setting["peak_step_D"]),
                         float(setting["peak_margin_D"]), window_D, spectrum_given, display,
                         values_grid)


_reference_jit = eqx.filter_jit(reference_normalisers)


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
    (:func:`lfjax.peaks.peaks_from_grid`): the global maximum of the through-focus VSOTF
    on the problem's peak grid (:func:`peak_window`: the rendered depth and the CDP both
    inside), refined by ``problem.peak_method``. Never a search capped around the rendered
    depth. Differentiable in the layout (through the refinement's values; the grid
    maximum's index is piecewise constant). Fields (n_eyes, n_depth + 1): the rendered
    depths, then the CDP (``problem.peak_depths_D``); ``success`` is False where the
    maximum lies on a window edge (``at_grid_edge``)."""
    scene = Scene(layout.centres_mm, layout.diameters_mm, problem.cdp_D, problem.peak_depths_D,
                  problem.pupil_diameter_mm, problem.display)
    grid = problem.peak_grid
    values = retinal_metrics(problem.eyes, scene, problem.spectrum, grid, problem.config,
                             problem.reference).vsotf
    return peaks_from_grid(values, problem.eyes, scene, problem.spectrum, grid, problem.config,
                           problem.reference, "vsotf", problem.peak_method, problem.peak_allowed,
                           refine_second=problem.peak_method in ("vertex", "grid"))


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
    excess = jax.nn.relu(_safe_sqrt(relative_mse_D2) - objective.accommodation_tolerance_D)
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


# ----------------------------------------------------------------------------- evaluation


def _eye_chunks(eyes: Eyes, chunk: int):
    """(sub-batch of ``chunk`` eyes, valid mask) covering ``eyes``; the last chunk is padded
    with repeats of the last eye, so every chunk has one shape (one compilation)."""
    chunk = int(chunk)
    if chunk < 1:
        raise ValueError(f"chunk must be >= 1, got {chunk}")
    n = eyes.n_eyes
    for start in range(0, n, chunk):
        idx = np.arange(start, start + chunk)
        valid = idx < n
        yield Eyes(eyes.zernike_um[np.minimum(idx, n - 1)], eyes.measured_pupil_mm,
                   eyes.orientation), valid


@eqx.filter_jit
def _values_jit(layout, problem: LayoutProblem):
    """Per (eye, depth) values of every reported quantity, each (n_eyes, n_depth).

    One pipeline call covers the peak grid and the correct focus
    (:attr:`LayoutProblem.values_grid`): a rendered depth on the peak grid shares its
    elemental OTFs instead of computing them a second time."""
    if problem.values_grid is None:
        m = correct_focus_metrics(layout, problem)
        peaks = predicted_peaks(layout, problem)
        vsotf, radial_mtf = m.vsotf[..., 0], m.radial_mtf[..., 0, :]
    else:
        scene = Scene(layout.centres_mm, layout.diameters_mm, problem.cdp_D, problem.peak_depths_D,
                      problem.pupil_diameter_mm, problem.display)
        both = retinal_metrics(problem.eyes, scene, problem.spectrum, problem.values_grid,
                               problem.config, problem.reference)
        peaks = peaks_from_grid(both.vsotf[..., :-1], problem.eyes, scene, problem.spectrum,
                                problem.peak_grid, problem.config, problem.reference, "vsotf",
                                problem.peak_method, problem.peak_allowed,
                                refine_second=problem.peak_method in ("vertex", "grid"))
        vsotf, radial_mtf = both.vsotf[:, :-1, -1], both.radial_mtf[:, :-1, -1, :]
    o = problem.objective
    depth = lambda x: x[:, :-1]  # noqa: E731 - the last column is the CDP's
    return {
        "vsotf": vsotf,
        "cutoff_cpd": soft_cutoff_cpd(radial_mtf, problem.config.freq_step_cpd,
                                      o.mtf_threshold, o.mtf_softness),
        "peak_D": depth(peaks.accommodation_D),
        "peak_vsotf": depth(peaks.value),
        "peak_success": depth(peaks.success),
        "peak_at_edge": depth(peaks.at_grid_edge),
        "peak_at_hyperopic_limit": depth(peaks.at_hyperopic_limit),
        "cdp_peak_D": peaks.accommodation_D[:, -1],
        "cdp_peak_success": peaks.success[:, -1],
    }


def accommodation_gain(depths_D, predicted_D) -> float:
    """Slope of the population-mean predicted accommodation against the rendered depth
    (least squares over the depths; 1 = the eye follows the display, 0 = it does not move).
    ``predicted_D`` (n_eyes, n_depth), D. NaN for fewer than two distinct depths."""
    d = np.asarray(depths_D, float)
    if np.unique(d).size < 2:
        return float("nan")
    mean = np.asarray(predicted_D, float).mean(axis=0)
    return float(np.polyfit(d, mean, 1)[0])


PARALLAX_MIN_GAIN = 0.5
"""Below this accommodation gain a fitted layout is reported as driving no accommodation."""


def parallax_warning(layout, evaluation: dict | None = None) -> str | None:
    """A warning when a layout's views no longer form a light field: their centres span
    less than half the mean view diameter (the views overlap into one aperture, so the
    rendered depth sets no parallax on the retina), or the evaluated accommodation gain is
    below :data:`PARALLAX_MIN_GAIN`. None when neither holds."""
    c = np.asarray(layout.centres_mm, float).reshape(-1, 2)
    d = np.asarray(layout.diameters_mm, float).reshape(-1)
    span = float(np.max(np.linalg.norm(c[:, None] - c[None], axis=-1))) if len(c) > 1 else 0.0
    problems = []
    if span < 0.5 * float(d.mean()):
        problems.append(f"the views' centres span {span:.3g} mm, less than half their mean diameter "
                        f"{d.mean():.3g} mm: the views have collapsed into one aperture")
    if evaluation is not None and math.isfinite(evaluation.get("accommodation_gain", math.nan)):
        gain = evaluation["accommodation_gain"]
        if gain < PARALLAX_MIN_GAIN:
            problems.append(f"the predicted accommodation follows the rendered depth with gain "
                            f"{gain:.2f} (< {PARALLAX_MIN_GAIN}): the display drives little accommodation")
    return ("; ".join(problems)) if problems else None


def evaluate_layout(layout, problem: LayoutProblem, eyes: Eyes | None = None, terms=None,
                    chunk: int | None = None) -> dict:
    """Everything a report says of a layout on a population (host numbers).

    ``eyes`` (default the problem's) are evaluated ``chunk`` at a time (default the
    problem's eye count, so the fit's compiled functions are reused; the last chunk is
    padded with repeats). Each eye's predicted accommodation is the global maximum of its
    through-focus VSOTF over the problem's peak window (:func:`predicted_peaks`), never a
    search capped around the rendered depth; a maximum on a window edge is a failure.
    Returns a dict with each term's population mean (as the objective defines it:
    ``image_at_peak``, ``depth_of_field``, ``accommodation`` (D²), ``resolution`` (cpd)),
    ``loss`` (the problem's weighted objective with its penalty),
    ``accommodation_rmse_D`` (against the rendered depth), ``relative_accommodation_rmse_D``
    (less each eye's own error on the CDP: the display's share, which the default
    objective constrains), ``own_error_rmse_D`` (the eyes' own errors on the CDP),
    ``penalty``, ``accommodation_gain`` (:func:`accommodation_gain`),
    ``peak_success_fraction`` (peaks that converged inside their window, not on an edge),
    ``n_edge_peaks``, ``n_peaks``, per-depth means ``vsotf_by_depth``,
    ``image_at_peak_by_depth``, ``cutoff_by_depth`` (cpd), ``peak_by_depth`` (D),
    ``peak_error_by_depth`` (D), ``worst_depth_vsotf``, ``accuracy`` (the problem's
    setting) and the per-(eye, depth) arrays under ``values``. ``terms`` is accepted for
    compatibility and ignored: every quantity is reported.
    """
    del terms
    eyes = problem.eyes if eyes is None else eyes
    layout = as_free(layout)
    parts = []
    for sub, valid in _eye_chunks(eyes, problem.eyes.n_eyes if chunk is None else chunk):
        vals = _values_jit(layout, problem.with_eyes(sub))
        parts.append({k: np.asarray(v)[valid] for k, v in vals.items()})
    values = {k: np.concatenate([p[k] for p in parts]) for k in parts[0]}
    depths = np.asarray(problem.depths_D, float)
    out = {"n_eyes": eyes.n_eyes, "depths_D": depths.tolist(), "accuracy": problem.accuracy,
           "values": values}
    by_depth = values["vsotf"].mean(axis=0)
    out["image_at_peak"] = float(values["peak_vsotf"].mean())
    out["image_at_peak_by_depth"] = values["peak_vsotf"].mean(axis=0).tolist()
    out["depth_of_field"] = float(values["vsotf"].mean())
    out["vsotf_by_depth"] = by_depth.tolist()
    out["worst_depth_vsotf"] = float(by_depth.min())
    out["resolution"] = float(values["cutoff_cpd"].mean())
    out["cutoff_by_depth"] = values["cutoff_cpd"].mean(axis=0).tolist()
    err = values["peak_D"] - depths[None, :]
    out["accommodation"] = float(np.mean(err**2))
    out["accommodation_rmse_D"] = float(math.sqrt(out["accommodation"]))
    own = values["cdp_peak_D"] - float(problem.cdp_D)
    relative = err - own[:, None]
    out["relative_accommodation"] = float(np.mean(relative**2))
    out["relative_accommodation_rmse_D"] = float(math.sqrt(out["relative_accommodation"]))
    out["own_error_rmse_D"] = float(np.sqrt(np.mean(own**2)))
    out["accommodation_gain"] = accommodation_gain(depths, values["peak_D"])
    out["peak_by_depth"] = values["peak_D"].mean(axis=0).tolist()
    out["peak_error_by_depth"] = err.mean(axis=0).tolist()
    out["peak_success_fraction"] = float(values["peak_success"].mean())
    out["n_edge_peaks"] = int(values["peak_at_edge"].sum())
    out["n_peaks"] = int(values["peak_success"].size)
    out["penalty"] = float(accommodation_penalty(out["relative_accommodation"], problem.objective))
    out["loss"] = float(combine(out, problem.objective))
    for k, v in out.items():
        if isinstance(v, float) and not math.isfinite(v) and k != "accommodation_gain":
            raise FloatingPointError(f"evaluation gave a non-finite {k}")
    return out


@eqx.filter_jit
def _curves_jit(layout, problem: LayoutProblem, accommodation_D):
    acc = Accommodation.per_depth(accommodation_D, problem.options, problem.pupil_diameter_mm)
    m = retinal_metrics(problem.eyes, problem.scene(layout), problem.spectrum, acc, problem.config,
                        problem.reference)
    return m.vsotf


def through_focus_curves(layout, problem: LayoutProblem, offsets_D=None, eyes: Eyes | None = None,
                         chunk: int | None = None):
    """Through-focus VSOTF of a layout: (accommodation_D (n_depth, n_k), vsotf (n_eyes,
    n_depth, n_k)); accommodation = depth + offsets (default ±``window_D`` in 0.1 D steps),
    states below 0 D are NaN (the eye cannot relax beyond infinity)."""
    if offsets_D is None:
        w = problem.window_D
        offsets_D = np.round(np.arange(-w, w + 1e-9, 0.1), 9)
    offsets = np.asarray(offsets_D, float)
    depths = np.asarray(problem.depths_D)
    acc = depths[:, None] + offsets[None, :]
    eyes = problem.eyes if eyes is None else eyes
    rows = []
    for sub, valid in _eye_chunks(eyes, eyes.n_eyes if chunk is None else chunk):
        rows.append(np.asarray(_curves_jit(as_free(layout), problem.with_eyes(sub),
                                           jnp.asarray(np.maximum(acc, 0.0))))[valid])
    vs = np.concatenate(rows)
    vs[:, acc < 0] = np.nan
    return acc, vs


def diameter_scan(eyes: Eyes, n_per_side: int, pitch_mm: float, diameters_mm, depths_D,
                  reference: str = "open_pupil", *, pupil_diameter_mm: float = 3.0,
                  cdp_D: float = 2.0, wavelengths_nm=DEFAULT_WAVELENGTHS_NM,
                  sampling: Sampling | None = None, options: ModelOptions = ModelOptions()):
    """Mean VSOTF at the correct accommodation of an n×n grid at a fixed pitch for each
    subaperture diameter: (n_diameters, n_depth), the mean over ``eyes``.

    ``reference`` selects the VSOTF reference (``"paper"`` or ``"open_pupil"``); this is the
    check behind the module docstring's warning (with ``"paper"`` the mean rises as the
    subapertures shrink). ``sampling`` defaults to the planner's guard for the largest and
    smallest diameter on this grid.
    """
    from .layouts import make_layout
    from .pipeline import retinal_metrics_jit

    d = np.atleast_1d(np.asarray(diameters_mm, float))
    depths = _check_depths(depths_D)
    options = options.replace(vsotf_reference=reference)
    sites = lattice_sites("square", int(n_per_side) ** 2)
    centres = float(pitch_mm) * sites
    pupil = float(pupil_diameter_mm)
    window = float(min(d.max(), pupil))
    wl = np.atleast_1d(np.asarray(wavelengths_nm, float))
    if sampling is None:
        from .planner import plan_sampling

        envelope = make_layout(np.concatenate([centres, centres[:1]]),
                               np.concatenate([np.full(len(centres), d.max()), [d.min()]]), pupil,
                               window_diameter_mm=window)
        sampling = plan_sampling(envelope, pupil_diameter_mm=pupil, cdp_D=cdp_D, depths_D=depths,
                                 accommodation_window_D=0.5, wavelengths_nm=wl,
                                 eyes_zernike_um=np.asarray(eyes.zernike_um),
                                 measured_pupil_mm=eyes.measured_pupil_mm, options=options,
                                 estimate_accuracy=False).sampling
    config = PipelineConfig.build(wl, window, pupil, sampling, options)
    spectrum = make_spectrum(wl, options)
    acc = Accommodation.per_depth(depths[:, None], options, pupil)
    rows = []
    for di in d:
        scene = Scene(centres, np.full(len(centres), di), cdp_D, depths, pupil)
        rows.append(np.asarray(retinal_metrics_jit(eyes, scene, spectrum, acc, config).vsotf)[..., 0].mean(0))
    return np.stack(rows)


# ----------------------------------------------------------------------------- solvers
#
# The expensive part of every solver step is the objective and its gradient with respect to
# the subapertures' centres and diameters. It is compiled once (layout_value_and_grad, per
# view count and problem) and shared by both routes and both parametrisations; the
# coordinate maps (box or unconstrained → layout) and their pullbacks are small compiled
# functions, and the solvers' own steps run eagerly on these compiled pieces. Compiling the
# solvers' steps whole would trace the pipeline once per call site (jaxopt's zoom line
# search: 8 times, ~40 s to compile on 2 cores; optimistix BFGS: ~16 s) for no speed-up.

layout_value_and_grad = eqx.filter_jit(eqx.filter_value_and_grad(layout_loss))
"""(loss, gradient) of :func:`layout_loss` with respect to a FreeParams' centres and
diameters, compiled (``layout_value_and_grad(FreeParams, problem)``)."""


def _coords_to_params(coords, template, constraints: Constraints, route: str):
    if route == "box":
        return from_box(coords, template, constraints)
    return from_unconstrained(coords, template, constraints)


@eqx.filter_jit
def _coords_to_free(coords, template, constraints: Constraints, route: str):
    return as_free(_coords_to_params(coords, template, constraints, route))


@eqx.filter_jit
def _coords_pullback(coords, template, constraints: Constraints, route: str, grad_free):
    _, pull = jax.vjp(lambda x: as_free(_coords_to_params(x, template, constraints, route)), coords)
    return pull(grad_free)[0]


class _CoordinateObjective:
    """Loss and gradient in solver coordinates: compiled pieces composed on the host."""

    def __init__(self, template, problem: LayoutProblem, route: str):
        self.template, self.problem, self.route = template, problem, route
        self.constraints = problem.constraints
        self._last = None  # (coordinates, result): jaxopt asks twice for an accepted step

    def value_and_grad(self, coords):
        key = [np.asarray(x) for x in jax.tree_util.tree_leaves(coords)]
        if self._last is not None and len(key) == len(self._last[0]) and all(
                a.shape == b.shape and np.array_equal(a, b) for a, b in zip(key, self._last[0])):
            return self._last[1]
        free = _coords_to_free(coords, self.template, self.constraints, self.route)
        value, grad_free = layout_value_and_grad(free, self.problem)
        result = (value, _coords_pullback(coords, self.template, self.constraints, self.route,
                                          grad_free))
        self._last = (key, result)
        return result

    def optimistix_fn(self):
        """fn(y, args) → (loss, None) for optimistix, differentiable through a custom JVP
        whose tangent is ⟨∇loss, t⟩ from the compiled gradient."""

        @jax.custom_jvp
        def loss(y):
            return self.value_and_grad(y)[0]

        @loss.defjvp
        def loss_jvp(primals, tangents):
            value, grad = self.value_and_grad(primals[0])
            dot = sum(jnp.vdot(g, t, precision=FULL)
                      for g, t in zip(jax.tree_util.tree_leaves(grad),
                                      jax.tree_util.tree_leaves(tangents[0])))
            return value, dot

        return lambda y, args: (loss(y), None)


def _lbfgsb(fun, tol: float):
    import warnings

    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message="JAXopt is no longer maintained")
        import jaxopt
    # jit=False: jaxopt's loop and line search run on the host around the compiled
    # objective; backtracking needs one objective + gradient per trial step (zoom ~2x more).
    solver = jaxopt.LBFGSB(fun=fun, value_and_grad=True, tol=tol, maxls=12, jit=False,
                           linesearch="backtracking")
    # Sufficient decrease alone (Armijo), halving the step. jaxopt's backtracking checks the
    # strong Wolfe curvature condition by default, which a search that can only shrink the
    # step rarely meets on a loss that is smooth only piecewise (the predicted peak's grid
    # index switches): measured on the default objective, 4 eyes, 8 steps: 107 objective
    # evaluations, most of them shrinking steps that already improved the loss.
    line_search = solver.run_ls.__self__
    line_search.condition = "armijo"
    line_search.decrease_factor = 0.5
    return solver


class LayoutWarning(UserWarning):
    """A fitted layout that no longer forms a light field (:func:`parallax_warning`)."""


@dataclass
class LayoutFit:
    """Result of :func:`optimise_layout`.

    Attributes
    ----------
    layout, initial_layout : fitted and starting :class:`lfjax.layouts.Layout`
    params, initial_params : fitted and starting parameters (LatticeParams or FreeParams)
    history : loss (the problem's weighted objective) at the accepted iterate after each
        solver step, starting with the initial layout's
    method, n_steps, converged : solver, steps taken, tolerance met
    time_s : wall time of the fit, s
    evaluation_s : wall time of all before/after evaluations, s; test_evaluation_s of the
        held-out ones alone
    train : {"before": …, "after": …} :func:`evaluate_layout` on the training eyes (the
        fit's setting)
    test : the same on the held-out eyes (None without them), at the report's setting
    objective, constraints : what was optimised, within which bounds
    """

    layout: Layout
    params: object
    initial_layout: Layout
    initial_params: object
    history: np.ndarray
    method: str
    n_steps: int
    converged: bool
    time_s: float
    train: dict
    test: dict | None
    objective: Objective
    constraints: Constraints
    evaluation_s: float = float("nan")
    test_evaluation_s: float = float("nan")

    @property
    def warning(self) -> str | None:
        """:func:`parallax_warning` of the fitted layout (held-out evaluation when present)."""
        return parallax_warning(self.layout, (self.test or self.train)["after"])

    def summary(self) -> str:
        lines = [f"objective: {self.objective.name}; method {self.method}, {self.n_steps} steps "
                 f"({'converged' if self.converged else 'step limit'}) in {self.time_s:.1f} s, "
                 f"evaluation {self.evaluation_s:.1f} s"
                 + (f" (held-out {self.test_evaluation_s:.1f} s)" if self.test is not None else ""),
                 f"loss: {self.history[0]:.6g} -> {self.history[-1]:.6g}"]
        rows = (("image at the predicted accommodation (mean VSOTF)", "image_at_peak", "{:.4f}"),
                ("accommodation RMSE against the rendered depth (D)", "accommodation_rmse_D", "{:.3f}"),
                ("  of which the display's (relative to each eye's own error on the CDP)",
                 "relative_accommodation_rmse_D", "{:.3f}"),
                ("accommodation gain (slope)", "accommodation_gain", "{:.3f}"),
                ("VSOTF at the rendered depth", "depth_of_field", "{:.4f}"),
                ("worst-depth VSOTF at the rendered depth", "worst_depth_vsotf", "{:.4f}"),
                ("smooth cut-off (cpd)", "resolution", "{:.2f}"))
        for label, ev in (("train", self.train), ("test", self.test)):
            if ev is None:
                continue
            b, a = ev["before"], ev["after"]
            lines.append(f"{label}: {b['n_eyes']} eyes, {b['accuracy']} accuracy; before -> after")
            for text, key, fmt in rows:
                lines.append(f"  {text}: {fmt.format(b[key])} -> {fmt.format(a[key])}")
            lines.append(f"  peaks found (not on a window edge): {b['peak_success_fraction']:.1%} "
                         f"-> {a['peak_success_fraction']:.1%} of {a['n_peaks']}")
        lines.append("fitted: " + describe_params(self.params))
        if self.warning is not None:
            lines.append("WARNING: " + self.warning)
        return "\n".join(lines)


def describe_params(params) -> str:
    """One line describing layout parameters (mm, rad)."""
    if isinstance(params, LatticeParams):
        return (f"{params.kind} lattice, {params.n_views} views: pitch {float(params.pitch_mm):.4f} mm, "
                f"diameter {float(params.diameter_mm):.4f} mm, rotation {float(params.rotation_rad):.4f} rad")
    c = np.asarray(params.centres_mm, float)
    d = np.asarray(params.diameters_mm, float)
    return (f"free, {len(d)} views: diameters {np.round(d, 4).tolist()} mm, centres "
            f"{np.round(c, 4).tolist()} mm")


def to_layout(params, constraints: Constraints, name: str = "optimised") -> Layout:
    """A checked :class:`lfjax.layouts.Layout` of parameters (window = the diameter cap)."""
    c = np.asarray(params.centres_mm, float)
    d = np.asarray(params.diameters_mm, float)
    if not (np.all(np.isfinite(c)) and np.all(np.isfinite(d))):
        raise FloatingPointError(f"non-finite layout: centres {c.tolist()}, diameters {d.tolist()}")
    return make_layout(c, d, constraints.pupil_diameter_mm, name=name,
                       window_diameter_mm=constraints.max_diameter_mm)


def optimise_layout(
    initial, problem: LayoutProblem, *, method: str = "lbfgsb", max_steps: int = 50,
    tol: float = 1e-5, test_eyes: Eyes | None = None, progress: bool = True,
    name: str = "optimised", report_problem: LayoutProblem | str | None = "full",
    ftol: float = 2e-3, patience: int = 3,
) -> LayoutFit:
    """Fit a layout to the problem's (training) eyes and report it on held-out eyes.

    Parameters
    ----------
    initial : LatticeParams or FreeParams, feasible under ``problem.constraints`` (else a
        ``ValueError`` names the parameter and its allowed range)
    problem : :func:`make_problem`
    method : ``"lbfgsb"`` (jaxopt L-BFGS-B in box coordinates) or ``"bfgs"`` (optimistix BFGS
        in unconstrained coordinates); see the module docstring
    max_steps : solver steps (each one or a few objective + gradient evaluations)
    tol : stopping tolerance (L-BFGS-B: projected-gradient norm; BFGS: rtol = atol = tol)
    ftol, patience : also stop (converged) when the loss has improved by less than
        ``ftol``·|loss| over the last ``patience`` steps. The default objective is smooth
        only piecewise (the predicted peak's grid index switches), so its projected
        gradient rarely falls below ``tol``; measured on 4 eyes, 96 % of 8 steps' gain came
        in the first 2, and each later step improved the loss by 0.01–0.5 %. 0 disables
        the rule.
    test_eyes : held-out population (evaluated before and after, never fitted)
    progress : tqdm progress bar on stderr
    report_problem : how the held-out eyes are scored: ``"full"`` (default; the report's
        accuracy, :meth:`LayoutProblem.at_accuracy`), ``"fit"`` or None (the training
        setting), or a :class:`LayoutProblem` of the same scene. The training eyes are
        scored at the fit's own setting (what the solver saw).

    A layout whose views collapse or whose predicted accommodation stops following the
    rendered depth (:func:`parallax_warning`, judged on the held-out eyes when given) is
    returned with ``LayoutFit.warning`` set and a :class:`LayoutWarning` issued.

    Returns a :class:`LayoutFit`. Raises ``FloatingPointError`` rather than return a
    non-finite layout.
    """
    if method not in METHODS:
        raise ValueError(f"method must be one of {METHODS}, got {method!r}")
    if isinstance(max_steps, bool) or int(max_steps) != max_steps or max_steps < 0:
        raise ValueError(f"max_steps must be an integer >= 0, got {max_steps!r}")
    _finite_scalar("tol", tol, 0.0, None, lo_open=True)
    _finite_scalar("ftol", ftol, 0.0, 1.0)
    if isinstance(patience, bool) or int(patience) != patience or patience < 1:
        raise ValueError(f"patience must be an integer >= 1, got {patience!r}")
    constraints = problem.constraints

    def stalled() -> bool:
        if ftol <= 0 or len(history) <= patience:
            return False
        return history[-1 - patience] - history[-1] < ftol * abs(history[-1])
    if isinstance(initial, Layout):
        initial = free_params(initial.centres_mm, initial.diameters_mm)
    t0 = time.perf_counter()
    history = []
    converged = False
    bar = None
    if progress:
        from tqdm.auto import tqdm

        bar = tqdm(total=int(max_steps), desc=f"optimise {problem.objective.name}", unit="step",
                   leave=True)
    try:
        def tick():
            if bar is not None:
                bar.update(1)
                bar.set_postfix(loss=f"{history[-1]:.5g}")

        if method == "lbfgsb":
            x, bounds = to_box(initial, constraints)
            target = _CoordinateObjective(initial, problem, "box")
            solver = _lbfgsb(target.value_and_grad, float(tol))
            state = solver.init_state(x, bounds)
            history.append(float(state.value))
            for _ in range(int(max_steps)):
                if float(state.error) <= tol or stalled():
                    break
                x, state = solver.update(x, state, bounds)
                history.append(float(state.value))
                tick()
            converged = float(state.error) <= tol or stalled()
            fitted = from_box(x, initial, constraints)
        else:
            y = to_unconstrained(initial, constraints)
            target = _CoordinateObjective(initial, problem, "raw")
            fn = target.optimistix_fn()
            solver = optx.BFGS(rtol=float(tol), atol=float(tol))
            f_struct = jax.ShapeDtypeStruct((), jnp.result_type(float))
            state = solver.init(fn, y, None, {}, f_struct, None, frozenset())
            history.append(float(target.value_and_grad(y)[0]))
            for _ in range(int(max_steps)):
                y, state, _ = solver.step(fn, y, None, {}, state, frozenset())
                accepted = int(state.num_accepted_steps) > 0
                history.append(float(state.f_info.f) if accepted else history[0])
                tick()
                done, result = solver.terminate(fn, y, None, {}, state, frozenset())
                if bool(done):
                    converged = result == optx.RESULTS.successful
                    break
                if accepted and stalled():
                    converged = True
                    break
            fitted = from_unconstrained(y, initial, constraints)
    finally:
        if bar is not None:
            bar.close()
    t_fit = time.perf_counter() - t0
    history = np.asarray(history, float)
    if not np.all(np.isfinite(history)):
        raise FloatingPointError(f"the objective became non-finite during the fit: {history.tolist()}")
    _check_finite_params(fitted)
    layout = to_layout(fitted, constraints, name)
    constraints.check(layout)  # by construction; kept as a guard against regressions
    initial_layout = to_layout(initial, constraints, "initial")
    train = {"before": evaluate_layout(initial, problem), "after": evaluate_layout(fitted, problem)}
    test = None
    t_eval = time.perf_counter()
    if test_eyes is not None:
        if isinstance(report_problem, LayoutProblem):
            held_out = report_problem.with_eyes(test_eyes)
        else:
            held_out = problem.at_accuracy(report_problem or problem.accuracy, eyes=test_eyes)
        chunk = min(test_eyes.n_eyes, max(problem.eyes.n_eyes, 8))
        test = {"before": evaluate_layout(initial, held_out, chunk=chunk),
                "after": evaluate_layout(fitted, held_out, chunk=chunk)}
    t_end = time.perf_counter()
    fit = LayoutFit(layout, fitted, initial_layout, initial, history, method, len(history) - 1,
                    bool(converged), t_fit, train, test, problem.objective, constraints,
                    t_end - t0 - t_fit, t_end - t_eval)
    if fit.warning is not None:
        warnings.warn(f"fitted layout: {fit.warning}", LayoutWarning, stacklevel=2)
    return fit


def default_max_diameter_mm(kind: str, n_views: int, pupil_diameter_mm: float = 3.0) -> float:
    """The optimiser's default diameter cap (mm): 1.2 × the tangent lattice's diameter,
    at most the pupil. The cap sizes every view's FFT window, so it sets the cost of each
    step (2×2 on 3 mm: a 1.8 mm cap costs a quarter of the 3 mm window's step); views
    larger than the tangent ones overlap and lose the parallax a light field needs."""
    tangent = tangent_lattice(kind, n_views, pupil_diameter_mm)
    return float(min(pupil_diameter_mm, 1.2 * float(tangent.diameter_mm)))


def natural_evaluation(problem: LayoutProblem, eyes: Eyes | None = None) -> dict:
    """:func:`evaluate_layout`'s numbers for natural viewing of real points at the
    rendered depths (open pupil, each depth its own focal plane; no display), at the
    problem's setting: the best a display can hope to match."""
    eyes = problem.eyes if eyes is None else eyes
    pupil = problem.pupil_diameter_mm
    open_constraints = Constraints(pupil, pupil, min(problem.constraints.min_diameter_mm, pupil))
    parts = []
    depths = np.asarray(problem.depths_D, float)
    kwargs = dict(options=problem.options, window_D=problem.window_D,
                  spectrum=problem.spectrum if problem.spectrum_given else None,
                  accuracy=problem.accuracy, peak_step_D=problem.peak_step_D,
                  peak_margin_D=problem.peak_margin_D, peak_method=problem.peak_method)
    # One sampling for every depth (the finest of their guards): one compiled program.
    wl = (np.asarray(problem.spectrum.wavelengths_nm, float) if problem.spectrum_given
          else np.asarray(FULL_WAVELENGTHS_NM if problem.accuracy == "full" else
                          problem.spectrum.wavelengths_nm, float))
    sampling = min((guard_sampling(open_constraints, [d], float(d), wl, np.asarray(eyes.zernike_um),
                                   eyes.measured_pupil_mm, problem.window_D, problem.options, None,
                                   None, pairs=_evaluated_pairs(np.array([d]), float(d),
                                                                problem.peak_step_D,
                                                                problem.peak_margin_D))
                    for d in depths), key=lambda smp: smp.freq_step_cpd)
    for d in depths:
        sub = make_problem(eyes, [d], open_constraints, problem.objective, cdp_D=float(d),
                           sampling=sampling, **kwargs)
        parts.append(evaluate_layout(free_params([[0.0, 0.0]], [pupil]), sub,
                                     chunk=min(eyes.n_eyes, max(problem.eyes.n_eyes, 8)))["values"])
    values = {k: np.concatenate([p[k] for p in parts], axis=1) for k in parts[0] if parts[0][k].ndim == 2}
    err = values["peak_D"] - depths[None, :]
    return {"n_eyes": eyes.n_eyes, "depths_D": depths.tolist(), "accuracy": problem.accuracy,
            "image_at_peak": float(values["peak_vsotf"].mean()),
            "accommodation_rmse_D": float(np.sqrt(np.mean(err**2))),
            "relative_accommodation_rmse_D": 0.0,  # each depth is its own focal plane
            "accommodation_gain": accommodation_gain(depths, values["peak_D"]),
            "peak_success_fraction": float(values["peak_success"].mean()), "values": values}


def tangent_grid_evaluations(problem: LayoutProblem, eyes: Eyes | None = None,
                             sizes=(2, 3, 4)) -> dict:
    """{"n×n": (Layout, evaluation)} of the paper's tangent n×n grids on ``eyes`` at the
    problem's setting (each grid's own window: a problem per grid)."""
    eyes = problem.eyes if eyes is None else eyes
    pupil = problem.pupil_diameter_mm
    out = {}
    for n in sizes:
        params = tangent_lattice("square", n * n, pupil)
        d = float(params.diameter_mm)
        sub = make_problem(eyes, np.asarray(problem.depths_D, float),
                           Constraints(pupil, d, min(problem.constraints.min_diameter_mm, d)),
                           problem.objective, cdp_D=float(problem.cdp_D), options=problem.options,
                           window_D=problem.window_D,
                           spectrum=problem.spectrum if problem.spectrum_given else None,
                           display=problem.display, accuracy=problem.accuracy,
                           peak_step_D=problem.peak_step_D, peak_margin_D=problem.peak_margin_D,
                           peak_method=problem.peak_method)
        layout = to_layout(params, sub.constraints, f"tangent {n}x{n}")
        out[f"{n}x{n}"] = (layout, evaluate_layout(params, sub,
                                                   chunk=min(eyes.n_eyes, max(problem.eyes.n_eyes, 8))))
    return out


@dataclass
class Front:
    """A trade-off front (:func:`trade_off_front`).

    Attributes
    ----------
    tolerances_D : (n,) accommodation-RMSE tolerances the points were fitted under, D
    fits : the n :class:`LayoutFit` (each with its held-out evaluation in ``test``)
    references : {"n×n": (Layout, evaluation)} tangent grids and {"natural": evaluation}
        on the same held-out eyes and setting
    """

    tolerances_D: np.ndarray
    fits: list
    references: dict

    def table(self) -> list[dict]:
        """One row per point and reference: held-out image quality at the predicted
        accommodation (mean VSOTF) and accommodation RMSE (D)."""
        rows = []
        for t, fit in zip(self.tolerances_D, self.fits):
            ev = (fit.test or fit.train)["after"]
            rows.append(dict(name=f"fit, tolerance {t:.3g} D", tolerance_D=float(t),
                             image_at_peak=ev["image_at_peak"],
                             accommodation_rmse_D=ev["accommodation_rmse_D"],
                             relative_accommodation_rmse_D=ev["relative_accommodation_rmse_D"],
                             accommodation_gain=ev["accommodation_gain"],
                             parameters=describe_params(fit.params)))
        for name, ref in self.references.items():
            ev = ref[1] if isinstance(ref, tuple) else ref
            rows.append(dict(name=name, tolerance_D=None, image_at_peak=ev["image_at_peak"],
                             accommodation_rmse_D=ev["accommodation_rmse_D"],
                             relative_accommodation_rmse_D=ev["relative_accommodation_rmse_D"],
                             accommodation_gain=ev["accommodation_gain"], parameters=None))
        return rows


def trade_off_front(initial, problem: LayoutProblem, tolerances_D, *, test_eyes: Eyes | None = None,
                    method: str = "lbfgsb", max_steps: int = 30, tol: float = 1e-5,
                    progress: bool = True, report_problem="full", references: bool = True) -> Front:
    """Fit one layout per accommodation tolerance (D) — image quality at each eye's own
    predicted accommodation against how far that accommodation may stray — each started
    from ``initial`` and scored on ``test_eyes`` (default the training eyes) at the
    report's setting, with the tangent 2×2…4×4 grids and natural viewing as references.
    Tight tolerances keep the light field's accommodation; loose ones let the views
    shrink towards one pinhole (sharp everywhere, accommodation on the CDP)."""
    tolerances = np.atleast_1d(np.asarray(tolerances_D, float))
    if tolerances.ndim != 1 or tolerances.size < 1 or not np.all(np.isfinite(tolerances)) or np.any(
            tolerances <= 0):
        raise ValueError(f"tolerances_D must be a non-empty list of finite values > 0 D, got {tolerances_D!r}")
    fits = []
    for t in tolerances:
        sub = problem.with_objective(Objective.parse(problem.objective, float(t)))
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", LayoutWarning)  # the front shows collapse on purpose
            fits.append(optimise_layout(initial, sub, method=method, max_steps=max_steps, tol=tol,
                                        test_eyes=test_eyes, progress=progress,
                                        report_problem=report_problem, name=f"front-{t:.3g}D"))
    refs = {}
    if references:
        if isinstance(report_problem, LayoutProblem):
            scored = report_problem.with_eyes(problem.eyes if test_eyes is None else test_eyes)
        else:
            scored = problem.at_accuracy(report_problem or problem.accuracy,
                                         eyes=problem.eyes if test_eyes is None else test_eyes)
        refs.update(tangent_grid_evaluations(scored))
        refs["natural"] = natural_evaluation(scored)
    return Front(tolerances, fits, refs)


# ----------------------------------------------------------------------------- files


def params_to_dict(params) -> dict:
    """JSON-ready description of layout parameters."""
    if isinstance(params, LatticeParams):
        return dict(kind="lattice", lattice=params.kind, pitch_mm=float(params.pitch_mm),
                    diameter_mm=float(params.diameter_mm), rotation_rad=float(params.rotation_rad),
                    sites=[list(s) for s in params.sites])
    return dict(kind="free", centres_mm=np.asarray(params.centres_mm, float).tolist(),
                diameters_mm=np.asarray(params.diameters_mm, float).tolist())


def params_from_dict(record: dict):
    """Inverse of :func:`params_to_dict` (host-checked)."""
    kind = record.get("kind")
    if kind == "lattice":
        for key in ("pitch_mm", "diameter_mm", "rotation_rad"):
            _finite_scalar(key, record[key])
        sites = tuple(tuple(float(v) for v in s) for s in record["sites"])
        return LatticeParams(record["pitch_mm"], record["diameter_mm"], record["rotation_rad"],
                             sites, record["lattice"])
    if kind == "free":
        return free_params(record["centres_mm"], record["diameters_mm"])
    raise ValueError(f"parameters kind must be 'lattice' or 'free', got {kind!r}")


def _jsonable(x):
    if isinstance(x, dict):
        return {str(k): _jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_jsonable(v) for v in x]
    if isinstance(x, (np.ndarray, jax.Array)):
        return _jsonable(np.asarray(x).tolist())
    if isinstance(x, (np.floating, np.integer, np.bool_)):
        return x.item()
    if isinstance(x, float) and not math.isfinite(x):
        return None
    return x


def save_layout_json(path, layout: Layout, pupil_diameter_mm: float, *, objective=None,
                     provenance: dict | None = None, parameters=None) -> Path:
    """Write a layout as JSON: centres_mm, diameters_mm, pupil_diameter_mm, name, objective,
    provenance (+ parameters when given: LatticeParams/FreeParams or their dict).

    ``objective``: an :class:`Objective`, a name, or a dict (e.g. with its values).
    ``provenance`` gets the lfjax version and a UTC time stamp added.
    """
    from . import __version__

    make_layout(layout.centres_mm, layout.diameters_mm, pupil_diameter_mm)  # validates
    if isinstance(objective, Objective):
        objective = objective.as_dict()
    elif isinstance(objective, str):
        objective = {"name": objective}
    if parameters is not None and not isinstance(parameters, dict):
        parameters = params_to_dict(parameters)
    prov = {"lfjax_version": __version__,
            "written_utc": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds")}
    prov.update(provenance or {})
    record = {
        "format": LAYOUT_FORMAT,
        "name": layout.name,
        "pupil_diameter_mm": float(pupil_diameter_mm),
        "window_diameter_mm": float(layout.window_diameter_mm),
        "centres_mm": np.asarray(layout.centres_mm, float).tolist(),
        "diameters_mm": np.asarray(layout.diameters_mm, float).tolist(),
        "objective": objective,
        "provenance": prov,
    }
    if parameters is not None:
        record["parameters"] = parameters
    path = Path(path)
    path.write_text(json.dumps(_jsonable(record), indent=2) + "\n")
    return path


def load_layout_json(path) -> tuple[Layout, dict]:
    """Read :func:`save_layout_json`'s file: (validated Layout, the whole record)."""
    record = json.loads(Path(path).read_text())
    if not isinstance(record, dict) or record.get("format") != LAYOUT_FORMAT:
        raise ValueError(f"{path}: not an lfjax layout file (format {LAYOUT_FORMAT!r} expected)")
    for key in ("centres_mm", "diameters_mm", "pupil_diameter_mm"):
        if key not in record:
            raise ValueError(f"{path}: missing {key!r}")
    pupil = _finite_scalar("pupil_diameter_mm", record["pupil_diameter_mm"], 0.0, None, lo_open=True)
    layout = make_layout(record["centres_mm"], record["diameters_mm"], pupil,
                         name=str(record.get("name", "custom")),
                         window_diameter_mm=record.get("window_diameter_mm"))
    return layout, record


__all__ = [
    "OBJECTIVES",
    "LATTICES",
    "CONTAINMENTS",
    "METHODS",
    "lattice_sites",
    "hex_sites_in_pupil",
    "LatticeParams",
    "lattice_params",
    "tangent_lattice",
    "initial_lattice",
    "feasible_start",
    "FreeParams",
    "free_params",
    "as_free",
    "Constraints",
    "to_box",
    "from_box",
    "to_unconstrained",
    "from_unconstrained",
    "Objective",
    "LayoutProblem",
    "DEFAULT_OBJECTIVE",
    "ACCURACIES",
    "FULL_WAVELENGTHS_NM",
    "depth_grid",
    "peak_window",
    "predicted_peaks",
    "accommodation_penalty",
    "accommodation_gain",
    "parallax_warning",
    "LayoutWarning",
    "default_max_diameter_mm",
    "natural_evaluation",
    "tangent_grid_evaluations",
    "Front",
    "trade_off_front",
    "envelope_layout",
    "guard_sampling",
    "make_problem",
    "correct_focus_metrics",
    "depth_of_field",
    "soft_cutoff_cpd",
    "resolution",
    "predicted_accommodation_D",
    "accommodation_mse",
    "objective_terms",
    "combine",
    "layout_loss",
    "layout_value_and_grad",
    "evaluate_layout",
    "through_focus_curves",
    "diameter_scan",
    "LayoutFit",
    "describe_params",
    "to_layout",
    "optimise_layout",
    "params_to_dict",
    "params_from_dict",
    "save_layout_json",
    "load_layout_json",
]
