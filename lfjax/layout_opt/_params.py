"""Parametrisations of a layout: lattices (square or hexagonal) and free views, mm and rad.

Part of :mod:`lfjax.layout_opt` (its public names are re-exported there)."""

from __future__ import annotations

import math

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from lfjax.base.errors import ParameterError
from lfjax.base.types import as_real_array as _real
from lfjax.base.types import finite_scalar

LATTICES = ("square", "hex")


CONTAINMENTS = ("centre", "contained")


TOL_MM = 1e-6
"""Lengths within this many mm of a constraint's bound count as on it (float32 round-off)."""


def lattice_sites(kind: str, n_views: int) -> np.ndarray:
    """Lattice sites in units of the pitch, (n_views, 2), host array.

    ``"square"``: ``n_views`` must be n² — the n×n grid centred on the pupil (row-major,
    as :func:`lfjax.model.layouts.grid_layout`). ``"hex"``: the ``n_views`` sites of the unit
    triangular lattice nearest the pupil centre (one site at the centre; ties broken by
    angle, so 1, 7, 19, 37 views give whole rings).
    """
    if kind not in LATTICES:
        raise ParameterError("kind", "{kind} must be one of {allowed}, got {got!r}", allowed=LATTICES,
                             got=kind)
    if isinstance(n_views, bool) or int(n_views) != n_views or n_views < 1:
        raise ParameterError("n_views", "{n_views} must be an integer >= 1, got {got!r}", got=n_views)
    n_views = int(n_views)
    if kind == "square":
        n = int(round(math.sqrt(n_views)))
        if n * n != n_views:
            raise ParameterError("n_views", "a square lattice needs {n_views} = n*n (1, 4, 9, 16, ...), "
                                 "got {got}", got=n_views)
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
    pitch = finite_scalar("pitch_mm", pitch_mm, 0.0, None, lo_open=True)
    radius = 0.5 * finite_scalar("pupil_diameter_mm", pupil_diameter_mm, 0.0, None, lo_open=True)
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
    pitch = finite_scalar("pitch_mm", pitch_mm, 0.0, None, lo_open=True)
    diameter = pitch if diameter_mm is None else finite_scalar("diameter_mm", diameter_mm, 0.0,
                                                                None, lo_open=True)
    rotation = finite_scalar("rotation_rad", rotation_rad)
    if n_views is None:
        if kind != "hex":
            raise ValueError("n_views is required for a square lattice (n*n views)")
        sites = hex_sites_in_pupil(pitch, pupil_diameter_mm)
    else:
        sites = lattice_sites(kind, n_views)
    return LatticeParams(pitch, diameter, rotation, tuple(map(tuple, sites.tolist())), kind)


def tangent_lattice(kind: str, n_views: int, pupil_diameter_mm: float = 3.0) -> LatticeParams:
    """Tangent discs (pitch = diameter) filling the pupil as the paper's grids do: square
    n×n with pitch = pupil/n (:func:`lfjax.model.layouts.grid_layout`); hex with pitch =
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


def describe_params(params) -> str:
    """One line describing layout parameters (mm, rad)."""
    if isinstance(params, LatticeParams):
        return (f"{params.kind} lattice, {params.n_views} views: pitch {float(params.pitch_mm):.4f} mm, "
                f"diameter {float(params.diameter_mm):.4f} mm, rotation {float(params.rotation_rad):.4f} rad")
    c = np.asarray(params.centres_mm, float)
    d = np.asarray(params.diameters_mm, float)
    return (f"free, {len(d)} views: diameters {np.round(d, 4).tolist()} mm, centres "
            f"{np.round(c, 4).tolist()} mm")


def default_max_diameter_mm(kind: str, n_views: int, pupil_diameter_mm: float = 3.0) -> float:
    """The optimiser's default diameter cap (mm): 1.2 × the tangent lattice's diameter,
    at most the pupil. The cap sizes every view's FFT window, so it sets the cost of each
    step (2×2 on 3 mm: a 1.8 mm cap costs a quarter of the 3 mm window's step); views
    larger than the tangent ones overlap and lose the parallax a light field needs."""
    tangent = tangent_lattice(kind, n_views, pupil_diameter_mm)
    return float(min(pupil_diameter_mm, 1.2 * float(tangent.diameter_mm)))
