"""Subaperture layouts of an ideal light-field display, in the eye's pupil plane.

Each ray (view) that enters the pupil fills one circular subaperture, centre (p_n, q_n) mm
and diameter d_n mm; the pupil crops it. Layouts are pytrees of arrays, so centres and
diameters are differentiable; ``window_diameter_mm`` is static and sizes the per-subaperture
FFT window (it must hold the largest subaperture).
"""

from __future__ import annotations

import math

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from lfjax.base.errors import ParameterError
from lfjax.base.types import as_real_array


class Layout(eqx.Module):
    """A set of circular subapertures in the pupil plane.

    Attributes
    ----------
    centres_mm : array (n_sub, 2), mm
        Subaperture centres (x, y) relative to the pupil centre.
    diameters_mm : array (n_sub,), mm
        Subaperture diameters.
    window_diameter_mm : float (static), mm
        Diameter the numerical window of each subaperture must hold: at least the largest
        subaperture, at most the pupil.
    name : str (static)
        Label for tables and plots.
    """

    centres_mm: jnp.ndarray = eqx.field(converter=as_real_array)
    diameters_mm: jnp.ndarray = eqx.field(converter=as_real_array)
    window_diameter_mm: float = eqx.field(static=True, converter=float)
    name: str = eqx.field(static=True, default="custom")

    def __check_init__(self):
        if self.centres_mm.ndim != 2 or self.centres_mm.shape[-1] != 2:
            raise ValueError(f"centres_mm must have shape (n_sub, 2), got {self.centres_mm.shape}")
        if self.diameters_mm.shape != self.centres_mm.shape[:1]:
            raise ValueError(
                f"diameters_mm must have shape ({self.centres_mm.shape[0]},), "
                f"got {self.diameters_mm.shape}"
            )
        if not (self.window_diameter_mm > 0):
            raise ValueError(f"window_diameter_mm must be > 0, got {self.window_diameter_mm}")

    @property
    def n_subapertures(self) -> int:
        return int(self.diameters_mm.shape[0])


def check_views_in_pupil(centres_mm, diameters_mm, pupil_diameter_mm: float, name: str = "custom",
                         *, parameter: str = "layout", pupil_parameter: str = "pupil_diameter_mm"
                         ) -> None:
    """Host check that every view (circle of ``centres_mm`` (n, 2) and ``diameters_mm`` (n,),
    mm) reaches into the pupil of ``pupil_diameter_mm`` (mm): a view entirely outside it
    brings no light, so a layout made for a larger pupil would give VSOTF 0/0 (NaN, or 1
    where the reference is the same layout) on the smaller one. Views partly outside are
    the model's (the pupil crops them). The one check of that concept: :func:`make_layout`
    and every computation on a layout (:func:`lfjax.vision.prepare.prepare`) call it.

    A refused layout is a :class:`~lfjax.base.errors.ParameterError` naming ``parameter``,
    the layout, the pupil, the views outside and how far outside they lie."""
    c = np.asarray(centres_mm, float).reshape(-1, 2)
    d = np.asarray(diameters_mm, float).reshape(-1)
    pupil = float(pupil_diameter_mm)
    radius = 0.5 * pupil
    gap = np.hypot(c[:, 0], c[:, 1]) - 0.5 * d - radius  # nearest edge beyond the pupil, mm
    outside = np.nonzero(gap >= 0)[0]
    if outside.size == 0:
        return
    shown = ", ".join(f"view {i} at ({c[i, 0]:.4g}, {c[i, 1]:.4g}) mm, diameter {d[i]:.4g} mm, "
                      f"{gap[i]:.4g} mm outside" for i in outside[:4])
    more = f" and {outside.size - 4} more" if outside.size > 4 else ""
    subject = "{%s} {layout_name!r}" if parameter == "layout" else "{%s}: layout {layout_name!r}"
    raise ParameterError(
        parameter, (subject + " has {n} of its {total} views entirely outside the {pupil:g} mm "
                    "pupil ({%s}; a view must reach |centre| - diameter/2 < {radius:g} mm): "
                    "{shown}{more}. Was it made for a larger pupil? Make it for this pupil, or "
                    "give a pupil that holds it") % (parameter, pupil_parameter),
        layout_name=name, n=int(outside.size), total=int(d.size), pupil=pupil, radius=radius,
        shown=shown, more=more)


def make_layout(
    centres_mm, diameters_mm, pupil_diameter_mm: float, name: str = "custom",
    window_diameter_mm: float | None = None,
) -> Layout:
    """Arbitrary layout from centres (n_sub, 2) and diameters (n_sub,) in mm, validated.

    Raises ``ValueError`` for non-positive diameters or a subaperture entirely outside the
    pupil of ``pupil_diameter_mm``. ``window_diameter_mm`` defaults to the largest diameter
    (capped at the pupil); give a larger bound when an optimiser will grow the subapertures.
    """
    c = np.asarray(centres_mm, float).reshape(-1, 2)
    d = np.asarray(diameters_mm, float).reshape(-1)
    if d.shape[0] != c.shape[0]:
        raise ValueError(f"{c.shape[0]} centres but {d.shape[0]} diameters_mm")
    if not (np.all(np.isfinite(c)) and np.all(np.isfinite(d))):
        raise ValueError("centres_mm and diameters_mm must be finite")
    if np.any(d <= 0):
        raise ValueError(f"diameters_mm must be > 0 mm, got {d[d <= 0].tolist()}")
    check_views_in_pupil(c, d, pupil_diameter_mm, name, parameter="centres_mm")
    if window_diameter_mm is None:
        window_diameter_mm = min(float(d.max()), float(pupil_diameter_mm))
    return Layout(jnp.asarray(c), jnp.asarray(d), float(window_diameter_mm), name)


def open_pupil(pupil_diameter_mm: float = 3.0) -> Layout:
    """Natural viewing: one subaperture equal to the pupil."""
    return make_layout([[0.0, 0.0]], [pupil_diameter_mm], pupil_diameter_mm, name="natural")


def grid_layout(n_per_side: int, pupil_diameter_mm: float = 3.0) -> Layout:
    """n×n tangent circles on a square grid filling the pupil (the paper's 2×2, 3×3, 4×4).

    Diameter and pitch both equal pupil/n; subapertures are cropped by the pupil.

    Examples
    --------
    >>> import lfjax
    >>> layout = lfjax.grid_layout(2, pupil_diameter_mm=3.0)
    >>> layout.centres_mm.shape  # (n_views, 2): x, y in mm
    (4, 2)
    >>> [float(d) for d in layout.diameters_mm]  # mm
    [1.5, 1.5, 1.5, 1.5]
    """
    if int(n_per_side) != n_per_side or n_per_side < 1:
        raise ValueError(f"n_per_side must be an integer >= 1, got {n_per_side}")
    n = int(n_per_side)
    pitch = pupil_diameter_mm / n
    offsets = (np.arange(n) - (n - 1) / 2.0) * pitch
    xx, yy = np.meshgrid(offsets, offsets)
    centres = np.stack([xx.ravel(), yy.ravel()], axis=1)
    if n == 1:
        return open_pupil(pupil_diameter_mm)
    return make_layout(centres, np.full(n * n, pitch), pupil_diameter_mm, name=f"{n}x{n}")


def hex_layout(
    pitch_mm: float, pupil_diameter_mm: float = 3.0, diameter_mm: float | None = None
) -> Layout:
    """Hexagonally packed circles (pitch ``pitch_mm``) overlapping the pupil.

    ``diameter_mm`` defaults to the pitch (tangent circles). One subaperture sits at the
    pupil centre; rows are ``pitch·√3/2`` apart and alternate rows are offset by half a pitch.
    """
    if not (pitch_mm > 0):
        raise ValueError(f"pitch_mm must be > 0 mm, got {pitch_mm}")
    d = pitch_mm if diameter_mm is None else float(diameter_mm)
    if not (d > 0):
        raise ValueError(f"diameter_mm must be > 0 mm, got {d}")
    radius = 0.5 * pupil_diameter_mm
    row_step = pitch_mm * math.sqrt(3.0) / 2.0
    n_rows = int(math.ceil((radius + d / 2) / row_step)) + 1
    centres = []
    for i in range(-n_rows, n_rows + 1):
        shift = 0.5 * pitch_mm * (i % 2)
        n_cols = int(math.ceil((radius + d / 2) / pitch_mm)) + 1
        for k in range(-n_cols, n_cols + 1):
            x, y = k * pitch_mm + shift, i * row_step
            if math.hypot(x, y) - d / 2 < radius - 1e-9 * radius:
                centres.append((x, y))
    return make_layout(centres, np.full(len(centres), d), pupil_diameter_mm, name=f"hex{pitch_mm:g}")


def subaperture_pitch_mm(modulation_pitch_mm, rendered_distance_m, modulation_distance_m):
    """Subaperture spacing in the pupil from the modulation-plane sampling (paper Eq. 1).

    .. math:: Δp = \\left|\\frac{z_r}{z_r - z_m}\\right| Δu

    Parameters
    ----------
    modulation_pitch_mm : sampling interval Δu of the modulation plane, mm.
    rendered_distance_m : distance z_r of the rendered point from the eye, m.
    modulation_distance_m : distance z_m of the modulation plane from the eye, m.
    """
    if np.any(np.asarray(rendered_distance_m) == np.asarray(modulation_distance_m)):
        raise ValueError("rendered_distance_m must differ from modulation_distance_m")
    return jnp.abs(rendered_distance_m / (rendered_distance_m - modulation_distance_m)) * (
        modulation_pitch_mm
    )


def modulation_pitch_mm(subaperture_pitch_mm, rendered_distance_m, modulation_distance_m):
    """Inverse of :func:`subaperture_pitch_mm`: modulation-plane sampling Δu in mm."""
    if np.any(np.asarray(rendered_distance_m) == 0):
        raise ValueError("rendered_distance_m must be non-zero")
    return subaperture_pitch_mm * jnp.abs(
        (rendered_distance_m - modulation_distance_m) / rendered_distance_m
    )


PAPER_LAYOUTS = ("natural", "2x2", "3x3", "4x4")
"""The layouts of the paper's study: the natural view and three n×n light-field layouts."""

LF_LAYOUTS = PAPER_LAYOUTS[1:]
"""The paper's light-field layouts (every one but the natural view)."""


def paper_layouts(pupil_diameter_mm: float = 3.0) -> dict[str, Layout]:
    """The paper's four viewing conditions: natural view and 2×2, 3×3, 4×4 viewpoints."""
    return {
        "natural": open_pupil(pupil_diameter_mm),
        "2x2": grid_layout(2, pupil_diameter_mm),
        "3x3": grid_layout(3, pupil_diameter_mm),
        "4x4": grid_layout(4, pupil_diameter_mm),
    }


__all__ = [
    "Layout",
    "make_layout",
    "check_views_in_pupil",
    "open_pupil",
    "grid_layout",
    "hex_layout",
    "subaperture_pitch_mm",
    "modulation_pitch_mm",
    "PAPER_LAYOUTS",
    "LF_LAYOUTS",
    "paper_layouts",
]
