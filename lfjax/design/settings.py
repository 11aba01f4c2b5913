"""The display design's option objects, each checked when made: what a buildable design
must satisfy (:class:`DesignConstraints`), what it renders (:class:`DesignTarget`), how its
lenslets are fitted (:class:`FitSettings`) and how it is reported (:class:`ReportSettings`).

A refused value is a :class:`~lfjax.base.errors.ParameterError` naming the field and the
allowed range, before anything is traced."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from lfjax.base.errors import ParameterError
from lfjax.base.types import finite_scalar
from lfjax.display.aberrations import LENS_FORMS
from lfjax.layout_opt import check_depth_range, depth_grid
from lfjax.model.options import ModelOptions
from lfjax.model.spectral import make_spectrum
from lfjax.vision.prepare import check_eye_chunk


MIN_F_NUMBER = 0.5
"""Fastest lenslet f-number a design may ask for: a lens in air has a numerical aperture
NA = 1/(2N) of at most 1, so no lens is faster than f/0.5 (real lenslet arrays stay above
about f/1)."""


@dataclass(frozen=True)
class DesignConstraints:
    """What a buildable design must satisfy (host numbers; lengths in mm).

    Attributes
    ----------
    min_eye_box_mm : the viewing zone Δu·(1 + z_m/z_0) must be at least this wide, mm
        (default 10: a 3 mm pupil and the eye's movement in a near-eye display)
    min_fill : smallest lenslet fill (aperture/pitch), in (0, 1] (default 0.5)
    min_f_number, max_f_number : the lenslets' focal length over aperture (default 1 … 8),
        min_f_number ≥ :data:`MIN_F_NUMBER` (no lens in air is faster), max_f_number ≥
        min_f_number
    distance_range_mm : (low, high) to fit the viewing distance too, mm; None (default)
        keeps the panel's
    lens_form : None (default: aberration-free lenslets, the designs as before) or the
        lenslets' form (:data:`lfjax.display.aberrations.LENS_FORMS`): each view then carries
        its lenslet's on-axis spherical aberration, which grows as a⁴/f³, so the fit weighs
        fast, wide lenslets against their aberration
    refractive_index : the lenslets' refractive index, in (1, 4] (default 1.5; with ``lens_form``)
    min_gap_fraction : the gap's lower bound as a fraction of its upper bound, in (0, 1]
        (default 0.75; the fastest f-number still applies). At a fixed CDP and distance the
        gap changes nothing but the pixels' angle p/(z_0·M), which a shorter gap only
        widens; the bound keeps the widest pixel blur of the box — what the sampling is
        planned for — within 4/3 of the narrowest at the same lenslets
    """

    min_eye_box_mm: float = 10.0
    min_fill: float = 0.5
    min_f_number: float = 1.0
    max_f_number: float = 8.0
    distance_range_mm: tuple | None = None
    min_gap_fraction: float = 0.75
    lens_form: str | None = None
    refractive_index: float = 1.5

    def __post_init__(self):
        finite_scalar("min_gap_fraction", self.min_gap_fraction, 0.0, 1.0, lo_open=True)
        if self.lens_form is not None and self.lens_form not in LENS_FORMS:
            raise ParameterError("lens_form", "{lens_form} must be one of {allowed} or None "
                                 "(aberration-free lenslets), got {got!r}",
                                 allowed=", ".join(LENS_FORMS), got=self.lens_form)
        finite_scalar("refractive_index", self.refractive_index, 1.0, 4.0, lo_open=True)
        finite_scalar("min_eye_box_mm", self.min_eye_box_mm, 0.0, lo_open=True)
        finite_scalar("min_fill", self.min_fill, 0.0, 1.0, lo_open=True)
        # the two ends of one range (one flag, --f-number LO HI): each says which end it is
        lo = finite_scalar(f"low end (no lens in air is faster than f/{MIN_F_NUMBER:g})", self.min_f_number,
                           MIN_F_NUMBER, parameter="min_f_number")
        finite_scalar("high end (at least the low end)", self.max_f_number, lo,
                      parameter="max_f_number")
        if self.distance_range_mm is not None:
            a, b = (float(v) for v in self.distance_range_mm)
            finite_scalar("low end", a, 0.0, lo_open=True, parameter="distance_range_mm")
            finite_scalar("high end", b, a, parameter="distance_range_mm")
            object.__setattr__(self, "distance_range_mm", (a, b))

    def as_dict(self) -> dict:
        return dataclasses.asdict(self)



REPORT_ACCURACIES = ("fast", "full", "fit")
"""Settings of the held-out report: ``"fast"`` (default) — :data:`FAST_REPORT_WAVELENGTHS_NM`,
the full setting's peak window, each peak at the grid parabola's vertex (no states beyond
the grid); ``"full"`` — :func:`lfjax.layout_opt.make_problem`'s full setting (31
wavelengths, peaks refined by ``local``); ``"fit"`` — the fit's own setting (its
wavelengths, 550 nm by default). RESULTS §21 compares "fast" with "full" on the presets."""

FAST_REPORT_WAVELENGTHS_NM = tuple(float(w) for w in np.arange(400.0, 701.0, 30.0))
"""The fast report's spectrum: 400–700 nm in 30 nm steps (11 wavelengths), V(λ)-weighted."""

REPORT_COUNTS = ("chosen", "all")
"""Which counts the held-out report scores: ``"chosen"`` (default) — the count with the lowest
training loss among those that pass the report, and any count whose training loss lies within
:data:`SCREEN_MARGIN` of it; ``"all"`` — every fitted count."""





def _integer(name: str, value, lowest: int, highest: int | None = None) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < lowest or (
            highest is not None and value > highest):
        span = f"in [{lowest}, {highest}]" if highest is not None else f">= {lowest}"
        raise ParameterError(name, "{%s} must be an integer %s, got {got!r}" % (name, span), got=value)
    return int(value)


def cdp_within(cdp: float, lo: float, hi: float) -> float:
    """``cdp`` (D) when it lies in the depth range [lo, hi] D; a
    :class:`~lfjax.base.errors.ParameterError` naming ``cdp_D`` otherwise."""
    if not (lo - 1e-6 <= cdp <= hi + 1e-6):
        raise ParameterError(
            "cdp_D", "{cdp_D} = {cdp:.4g} D lies outside the depth range [{lo:g}, {hi:g}] D: depths on "
            "one side of the CDP only would be rendered far from it, where the views' defocus and "
            "the sampling limit are worst; choose {cdp_D} within the range (e.g. its dioptric "
            "middle, {middle:g} D) or widen the range", cdp=cdp, lo=lo, hi=hi, middle=0.5 * (lo + hi))
    return cdp


@dataclass(frozen=True)
class DesignTarget:
    """What a design renders and which view counts it tries (host numbers).

    Attributes
    ----------
    depth_range_D : (low, high) rendered depths, D, 0 ≤ low < high (low == high with
        ``n_depths`` = 1)
    n_depths : depths evenly spanning the range, ≥ 2 (default 3)
    cdp_D : the CDP, D ≥ 0, within the depth range (None, the default: the panel's own,
        :meth:`cdp_for`)
    views_per_side : the counts n to try, integers in [1, 8] (n×n views; the n of 1×n strips
        for a lenticular design)
    wavelengths_nm : the fit's spectrum (V(λ)-weighted), nm, increasing, 400–700
    """

    depth_range_D: tuple
    n_depths: int = 3
    cdp_D: float | None = None
    views_per_side: tuple = (1, 2, 3, 4)
    wavelengths_nm: tuple = (550.0,)

    def __post_init__(self):
        lo, hi = check_depth_range(self.depth_range_D, allow_empty=True)
        object.__setattr__(self, "depth_range_D", (lo, hi))
        depth_grid(lo, hi, self.n_depths)
        if self.cdp_D is not None:
            object.__setattr__(self, "cdp_D", cdp_within(finite_scalar("cdp_D", self.cdp_D, 0.0), lo, hi))
        try:
            counts = tuple(int(n) for n in self.views_per_side)
            ok = bool(counts) and all(n == v and not isinstance(v, bool) and 1 <= n <= 8
                                      for n, v in zip(counts, self.views_per_side))
        except (TypeError, ValueError):
            ok = False
        if not ok:
            raise ParameterError("views_per_side", "{views_per_side} must be integers in [1, 8], got {got}",
                                 got=list(self.views_per_side) if hasattr(self.views_per_side, "__iter__")
                                 else self.views_per_side)
        object.__setattr__(self, "views_per_side", counts)
        wavelengths = tuple(float(w) for w in np.atleast_1d(np.asarray(self.wavelengths_nm, float)))
        make_spectrum(np.asarray(wavelengths), ModelOptions(vsotf_reference="open_pupil"))  # checks them
        object.__setattr__(self, "wavelengths_nm", wavelengths)

    @property
    def depths_D(self) -> np.ndarray:
        """The rendered depths, D (n_depths,)."""
        return depth_grid(*self.depth_range_D, self.n_depths)

    def cdp_for(self, panel) -> float:
        """The design's CDP, D: :attr:`cdp_D`, or the panel's own (which must then lie in the
        depth range)."""
        if self.cdp_D is not None:
            return self.cdp_D
        return cdp_within(float(panel.cdp_D), *self.depth_range_D)


@dataclass(frozen=True)
class FitSettings:
    """How each count's lenslets are fitted (:func:`lfjax.design.fit.fit_design`).

    Attributes
    ----------
    steps : L-BFGS-B steps per count, an integer ≥ 0 (default 10; 0: the start, scored)
    tol : its tolerance on the projected gradient, > 0 (default 1e-4)
    eye_chunk : training eyes per chunk of the gradient, an integer ≥ 1 (default 1: the
        reverse pass holds one eye's intermediates; :func:`lfjax.design.box.design_loss_chunked`),
        or None: all at once, :func:`lfjax.design.box.design_loss` without checkpoints
    """

    steps: int = 10
    tol: float = 1e-4
    eye_chunk: int | None = 1

    def __post_init__(self):
        object.__setattr__(self, "steps", _integer("steps", self.steps, 0))
        object.__setattr__(self, "tol", finite_scalar("tol", self.tol, 0.0, lo_open=True))
        object.__setattr__(self, "eye_chunk", check_eye_chunk(self.eye_chunk))


@dataclass(frozen=True)
class ReportSettings:
    """How a design is reported.

    Attributes
    ----------
    accuracy : the report's setting, one of :data:`REPORT_ACCURACIES` (default ``"fast"``)
    counts : which fitted counts the report scores, one of :data:`REPORT_COUNTS` (default
        ``"chosen"``)
    """

    accuracy: str = "fast"
    counts: str = "chosen"

    def __post_init__(self):
        if self.accuracy not in REPORT_ACCURACIES:
            raise ParameterError("report_accuracy", "{report_accuracy} must be one of {allowed}, got {got!r}",
                                 allowed=", ".join(REPORT_ACCURACIES), got=self.accuracy)
        if self.counts not in REPORT_COUNTS:
            raise ParameterError("report_counts", "{report_counts} must be one of {allowed}, got {got!r}",
                                 allowed=", ".join(REPORT_COUNTS), got=self.counts)


__all__ = ["DesignConstraints", "DesignTarget", "FitSettings", "ReportSettings", "REPORT_ACCURACIES",
           "REPORT_COUNTS", "FAST_REPORT_WAVELENGTHS_NM", "MIN_F_NUMBER", "cdp_within"]
