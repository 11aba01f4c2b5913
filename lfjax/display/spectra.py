"""Spectra of real displays: R, G, B primaries and the model Spectrum a display emits.

A display does not emit equal-energy white light. This module builds, on the host (numpy
and colour-science; nothing here is traced), the spectral weights of the eye model for
light from a display: emission(λ) × V(λ) × Δλ, with V the CIE 2008 2° physiologically
relevant LEF (:func:`lfjax.model.spectral.luminous_efficiency`), sampled at only the wavelengths
that carry weight, and passes them to :func:`lfjax.model.spectral.make_spectrum`.

Built-in displays (:func:`display_primaries`, names in :data:`DISPLAY_NAMES`)
---------------------------------------------------------------------------
``"crt"``
    colour-science ``colour.MSDS_DISPLAY_PRIMARIES['Typical CRT Brainard 1997']``
    (380–780 nm, 5 nm; Machado 2010 after Brainard 1997).
``"lcd"``
    colour-science ``colour.MSDS_DISPLAY_PRIMARIES['Apple Studio Display']``
    (380–780 nm, 5 nm; Fairchild & Wyble 1998, via Machado 2010).
``"laser"``
    Gaussian lines at the ITU-R BT.2020 (2015) monochromatic primaries 630 (R), 532 (G)
    and 467 nm (B), 1 nm FWHM each (a width typical of laser diodes / DPSS lasers; below
    the 5 nm sampling floor, so each line is one sample).
``"oled"``
    Gaussian primaries at 620 (R), 530 (G), 460 nm (B) with FWHM 35, 35, 25 nm. These are
    *typical* values, not a measurement of one panel: RGB AMOLED emitters peak near
    455–465, 525–535 and 615–630 nm with 20–40 nm FWHM (e.g. a measured Samsung S95B
    QD-OLED: green 531 nm / 31 nm FWHM, red 641 nm / 35 nm FWHM, blue just above 450 nm;
    Palomaki, DisplayDaily 2022, "Give me back my gamut, QD-OLED!"; colour-science's
    Ohno (2005) multi-LED example uses 457/530/615 nm with 20/30/20 nm).

Wavelengths per built-in display (default ``ModelOptions()``, i.e. Stiles–Crawford on,
computed range 400–700 nm, ``weight_tolerance=1e-3``, default steps)
-------------------------------------------------------------------------------------
======== ======= ===== ======= ======
display   white   red   green   blue
======== ======= ===== ======= ======
crt       27      31     20      24
lcd       25      18     17      14
oled      27      10     10      9
laser     3       1      1       1
======== ======= ===== ======= ======

(counts as of writing; what is tested, in ``tests/display/test_display_spectra.py``, is that the
LCD white's 25 wavelengths give the VSOTF of its 61 fine samples within
``weight_tolerance``). CRT red puts 0.15 % of its V-weighted power above 700 nm (its
far-red tail); it is merged into the 700 nm sample with a warning. Every white mix keeps
its photometric centroid Σwλ within 0.1 nm of the fine-grid one (tested).

How the wavelengths are chosen ("model no more than a scene needs")
-----------------------------------------------------------------
1. Fine samples: the primaries' own grid (5 nm for the colour-science data; for Gaussian
   primaries a 390–830 nm grid of step min(1 nm, FWHM/10)); w_i = E(λ_i) V(λ_i) Δλ_i.
2. Weight outside the computed range (400–700 nm with the Stiles–Crawford effect on — the
   range of the ρ(λ) table —, 390–830 nm, the LEF table, with ``options.sce="off"``) is
   merged into the nearest kept sample (a warning says so when it exceeds
   ``weight_tolerance``); none inside the range is an error.
3. The smallest fine samples are dropped while their total stays ≤ ``weight_tolerance`` of
   the whole; each dropped sample's weight is added to the nearest kept wavelength, so
   the total (and the share of each band) is unchanged.
4. Each contiguous run of kept fine samples is cut into ceil(extent/step) equal cells
   (each fine sample's weight split by the overlap of its Δλ cell); a cell becomes one
   wavelength at its photometric centroid Σwλ/Σw carrying its summed weight, so the
   zeroth and first moments are exact and the wavelengths strictly increasing. The step
   resolves the bands: ``step_nm`` if given, else for Gaussian primaries min(FWHM)/3 of
   the driven channels clipped to 5–10 nm, else 10 nm (the default grid of
   :func:`lfjax.model.spectral.make_spectrum`; broad phosphor/filter spectra). A band narrower
   than the 5 nm floor is one line: across 5 nm the LCA changes by ≤ 0.05 D and the
   diffraction scale by ≈ 1 %.
5. Cells whose weight still fits in the remaining tolerance are merged likewise.

Explicit weights are always passed to ``make_spectrum`` (its default trapezoid widths are
wrong for clustered wavelengths).

References: colour-science (Mansencal et al.) datasets named above; ITU-R BT.2020-2
(2015) Table 3; CIE 170-1:2006 / Sharpe et al. (2005, 2011) for V(λ); CIE 1931 2°
standard observer and CIE D65 (x, y) = (0.3127, 0.3290) for the white balance.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field
from functools import lru_cache

import numpy as np

from lfjax.base.errors import ParameterError
from lfjax.model.options import ModelOptions
from lfjax.model.spectral import (
    Spectrum,
    computed_range_nm,
    lef_data,
    lef_range_nm,
    make_spectrum,
)

CMFS_NAME = "CIE 1931 2 Degree Standard Observer"
D65_XY = (0.3127, 0.3290)
CRT_KEY = "Typical CRT Brainard 1997"
LCD_KEY = "Apple Studio Display"
LASER_PEAKS_NM = (630.0, 532.0, 467.0)
LASER_FWHM_NM = 1.0
OLED_PEAKS_NM = (620.0, 530.0, 460.0)
OLED_FWHM_NM = (35.0, 35.0, 25.0)
DISPLAY_NAMES = ("crt", "lcd", "oled", "laser")
CHANNELS = ("white", "red", "green", "blue")
MIN_STEP_NM = 5.0
BROAD_STEP_NM = 10.0


def _colour():
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message='.*"Matplotlib" related API')
        import colour
    return colour


@dataclass(frozen=True, eq=False)
class DisplayPrimaries:
    """Relative spectral power of a display's R, G, B primaries.

    Attributes
    ----------
    name : str
    wavelengths_nm : (n,) strictly increasing wavelengths, nm.
    emission : (n, 3) relative spectral power (per nm) of R, G, B at full drive; finite,
        non-negative, every column with some power.
    source : str
        Where the data come from.
    fwhm_nm : (3,) tuple or None
        FWHM (nm) of Gaussian primaries; sets the default sampling step of
        :func:`display_spectrum` (None: broad spectra, 10 nm).
    """

    name: str
    wavelengths_nm: np.ndarray
    emission: np.ndarray
    source: str = ""
    fwhm_nm: tuple | None = field(default=None)

    def __post_init__(self):
        wl = np.asarray(self.wavelengths_nm, float)
        em = np.asarray(self.emission, float)
        if wl.ndim != 1 or wl.size < 1:
            raise ValueError(f"wavelengths_nm must be 1-D with >= 1 values, got shape {wl.shape}")
        if not np.all(np.isfinite(wl)) or (wl.size > 1 and np.any(np.diff(wl) <= 0)):
            raise ValueError("wavelengths_nm must be finite and strictly increasing")
        if em.shape != (wl.size, 3):
            raise ValueError(
                f"emission must have shape (n_wavelengths, 3) = ({wl.size}, 3), got {em.shape}"
            )
        if not np.all(np.isfinite(em)) or np.any(em < 0):
            raise ValueError("emission must be finite and non-negative")
        if np.any(em.sum(axis=0) <= 0):
            raise ValueError("emission: every primary (column) needs some power")
        wl.setflags(write=False)
        em.setflags(write=False)
        object.__setattr__(self, "wavelengths_nm", wl)
        object.__setattr__(self, "emission", em)
        if self.fwhm_nm is not None:
            object.__setattr__(self, "fwhm_nm", tuple(float(f) for f in self.fwhm_nm))


def gaussian_primaries(peaks_nm, fwhm_nm, name: str = "gaussian", source: str = "") -> DisplayPrimaries:
    """Primaries with Gaussian emission E_c(λ) = exp(−4 ln2 (λ − peak_c)² / FWHM_c²).

    Parameters
    ----------
    peaks_nm : (3,) peak wavelengths of R, G, B, nm, each in 390–830 nm (the LEF data).
    fwhm_nm : scalar or (3,) full widths at half maximum, nm, > 0.
    name, source : str

    Sampled on 390–830 nm with step min(1 nm, min(FWHM)/10); unit peak each.
    """
    lo, hi = lef_range_nm()
    peaks = np.asarray(peaks_nm, float)
    if peaks.shape != (3,):
        raise ValueError(f"peaks_nm must have shape (3,) (R, G, B), got {peaks.shape}")
    if not np.all(np.isfinite(peaks)) or np.any((peaks < lo) | (peaks > hi)):
        raise ValueError(
            f"peaks_nm must lie in {lo:g}–{hi:g} nm (CIE 2008 LEF data); got {peaks.tolist()}"
        )
    fwhm = np.broadcast_to(np.asarray(fwhm_nm, float), (3,)) if np.ndim(fwhm_nm) == 0 else (
        np.asarray(fwhm_nm, float))
    if fwhm.shape != (3,):
        raise ValueError(f"fwhm_nm must be a scalar or have shape (3,), got {fwhm.shape}")
    if not np.all(np.isfinite(fwhm)) or np.any(fwhm <= 0):
        raise ValueError(f"fwhm_nm must be finite and > 0 nm; got {fwhm.tolist()}")
    step = min(1.0, float(fwhm.min()) / 10.0)
    n = int(round((hi - lo) / step)) + 1
    wl = np.linspace(lo, hi, n)
    em = np.exp(-4.0 * np.log(2.0) * ((wl[:, None] - peaks) / fwhm) ** 2)
    return DisplayPrimaries(name=name, wavelengths_nm=wl, emission=em,
                            source=source or "Gaussian model", fwhm_nm=tuple(fwhm))


@lru_cache(maxsize=None)
def _builtin(name: str) -> DisplayPrimaries:
    if name in ("crt", "lcd"):
        key = CRT_KEY if name == "crt" else LCD_KEY
        msds = _colour().MSDS_DISPLAY_PRIMARIES[key]
        return DisplayPrimaries(
            name=name, wavelengths_nm=np.asarray(msds.wavelengths, float),
            emission=np.asarray(msds.values, float),
            source=f"colour-science MSDS_DISPLAY_PRIMARIES[{key!r}]",
        )
    if name == "laser":
        return gaussian_primaries(
            LASER_PEAKS_NM, LASER_FWHM_NM, name="laser",
            source="ITU-R BT.2020 (2015) monochromatic primaries 630/532/467 nm, "
                   "Gaussian lines of 1 nm FWHM (typical of laser diodes)",
        )
    return gaussian_primaries(
        OLED_PEAKS_NM, OLED_FWHM_NM, name="oled",
        source="typical RGB OLED emitters (not one measured panel): peaks 620/530/460 nm, "
               "FWHM 35/35/25 nm",
    )


def display_primaries(name: str) -> DisplayPrimaries:
    """Primaries of a built-in display: ``"crt"``, ``"lcd"``, ``"oled"`` or ``"laser"``.

    crt: colour-science ``MSDS_DISPLAY_PRIMARIES['Typical CRT Brainard 1997']``; lcd:
    ``MSDS_DISPLAY_PRIMARIES['Apple Studio Display']`` (both 380–780 nm at 5 nm); laser:
    ITU-R BT.2020 (2015) lines 630/532/467 nm, 1 nm FWHM; oled: typical Gaussian emitters
    620/530/460 nm, FWHM 35/35/25 nm (see the module docstring for the sources).
    """
    if name not in DISPLAY_NAMES:
        raise ParameterError("name", "{name} {got!r} is not a built-in display; allowed: {allowed}",
                             got=name, allowed=", ".join(DISPLAY_NAMES))
    return _builtin(name)


@lru_cache(maxsize=1)
def _cmfs() -> tuple[np.ndarray, np.ndarray]:
    cmfs = _colour().MSDS_CMFS[CMFS_NAME]
    return np.asarray(cmfs.wavelengths, float), np.asarray(cmfs.values, float)


def _cell_widths(wl: np.ndarray) -> np.ndarray:
    if wl.size == 1:
        return np.ones(1)
    mid = 0.5 * (wl[1:] + wl[:-1])
    edges = np.concatenate([[wl[0] - (mid[0] - wl[0])], mid, [wl[-1] + (wl[-1] - mid[-1])]])
    return np.diff(edges)


def emission_XYZ(wavelengths_nm, emission) -> np.ndarray:
    """CIE 1931 2° tristimulus values of sampled emission (relative units).

    wavelengths_nm (n,) nm; emission (n,) or (n, k) → (3,) or (3, k):
    Σ E(λ) {x̄, ȳ, z̄}(λ) Δλ, the CMFs (colour-science ``MSDS_CMFS['CIE 1931 2 Degree
    Standard Observer']``, 360–830 nm) linearly interpolated, zero outside.
    """
    wl = np.asarray(wavelengths_nm, float)
    em = np.asarray(emission, float)
    cw, cv = _cmfs()
    xyz = np.stack([np.interp(wl, cw, cv[:, i], left=0.0, right=0.0) for i in range(3)])
    return xyz @ (em * (_cell_widths(wl) if em.ndim == 1 else _cell_widths(wl)[:, None]))


def channel_drive(primaries: DisplayPrimaries, channel="white") -> np.ndarray:
    """Drive levels (3,) of R, G, B (multipliers of ``primaries.emission``) for ``channel``.

    ``"white"``: the mix whose CIE 1931 2° chromaticity is CIE D65 (x, y) = (0.3127,
    0.3290) at Y = 1, from the 3×3 system [XYZ_R XYZ_G XYZ_B] a = XYZ_D65 (XYZ of each
    primary from :func:`emission_XYZ`). ``"red"``, ``"green"``, ``"blue"``: that primary
    alone (drive 1). Or three non-negative, finite drive levels, not all zero.
    """
    if isinstance(channel, str):
        if channel not in CHANNELS:
            raise ValueError(
                f"channel {channel!r} unknown; allowed: {', '.join(CHANNELS)} or three "
                "non-negative channel weights"
            )
        if channel != "white":
            return np.eye(3)[CHANNELS.index(channel) - 1]
        M = emission_XYZ(primaries.wavelengths_nm, primaries.emission)
        x, y = D65_XY
        target = np.array([x / y, 1.0, (1.0 - x - y) / y])
        drive = np.linalg.solve(M, target)
        if np.any(drive < 0):
            raise ValueError(
                f"primaries {primaries.name!r}: D65 white lies outside their gamut "
                f"(white-balance drive {drive.tolist()} has a negative entry)"
            )
        return drive
    drive = np.asarray(channel, float)
    if drive.shape != (3,):
        raise ValueError(
            f"channel weights must have shape (3,) (R, G, B) or channel be one of "
            f"{', '.join(CHANNELS)}; got shape {drive.shape}"
        )
    if not np.all(np.isfinite(drive)) or np.any(drive < 0) or drive.sum() <= 0:
        raise ValueError(
            f"channel weights must be finite, >= 0 and not all zero; got {drive.tolist()}"
        )
    return drive


def _check_tolerance_step(weight_tolerance, step_nm):
    if not (np.isfinite(weight_tolerance) and 0.0 <= weight_tolerance < 1.0):
        raise ValueError(f"weight_tolerance must lie in [0, 1); got {weight_tolerance}")
    if step_nm is not None and not (np.isfinite(step_nm) and step_nm > 0):
        raise ValueError(f"step_nm must be finite and > 0 nm; got {step_nm}")


def _nearest(targets: np.ndarray, wl: np.ndarray) -> np.ndarray:
    """Index into sorted ``targets`` nearest to each of ``wl``."""
    j = np.clip(np.searchsorted(targets, wl), 1, max(targets.size - 1, 1))
    if targets.size == 1:
        return np.zeros(wl.shape, int)
    left = targets[j - 1]
    right = targets[j]
    return np.where(np.abs(wl - left) <= np.abs(right - wl), j - 1, j)


def _prune_mask(w: np.ndarray, budget: float) -> np.ndarray:
    """Keep mask dropping the smallest weights while their total stays <= budget."""
    order = np.argsort(w, kind="stable")
    csum = np.cumsum(w[order])
    n_drop = int(np.searchsorted(csum, budget, side="right"))
    n_drop = min(n_drop, w.size - 1)  # always keep the largest sample
    keep = np.ones(w.size, bool)
    keep[order[:n_drop]] = False
    keep &= w > 0
    return keep


def resample_weights(
    wavelengths_nm, weights, step_nm: float, weight_tolerance: float = 1e-3,
    range_nm: tuple[float, float] | None = None, parameter: str = "emission",
) -> tuple[np.ndarray, np.ndarray]:
    """The fewest wavelengths that carry fine-sampled spectral weights (module docstring
    steps 2–5).

    Parameters
    ----------
    wavelengths_nm : (n,) strictly increasing fine wavelengths, nm.
    weights : (n,) non-negative weights of the fine samples (already × V(λ) Δλ).
    step_nm : cell width resolving the bands, nm.
    weight_tolerance : fraction of the total weight that may be moved to another sample.
    range_nm : (lo, hi) computed range, nm; None: no limit.
    parameter : name used in error messages.

    Returns ``(wavelengths_nm (m,), weights (m,))``, strictly increasing, weights summing
    to 1.
    """
    wl = np.asarray(wavelengths_nm, float)
    w = np.asarray(weights, float)
    total = w.sum()
    if range_nm is not None:
        lo, hi = range_nm
        inside = (wl >= lo) & (wl <= hi)
    else:
        inside = np.ones(wl.size, bool)
    if not np.any(w[inside] > 0):
        lo, hi = range_nm if range_nm is not None else (wl[0], wl[-1])
        raise ValueError(
            f"{parameter} has no weight (emission × V(λ)) inside the computed range "
            f"{lo:g}–{hi:g} nm (the Stiles–Crawford ρ(λ) table spans 400–700 nm; with "
            "ModelOptions(sce='off') the range is the LEF data's 390–830 nm)"
        )
    outside = float(w[~inside].sum()) / total
    if outside > weight_tolerance:
        warnings.warn(
            f"{parameter}: {outside:.3g} of the weight lies outside the computed range "
            f"{range_nm[0]:g}–{range_nm[1]:g} nm; it is merged into the nearest computed "
            "wavelength", stacklevel=3,
        )
    budget = max(weight_tolerance - outside, 0.0) * total
    fw = _cell_widths(wl)
    idx = np.flatnonzero(inside)
    keep_in = _prune_mask(w[idx], budget)
    kept = idx[keep_in]
    budget -= w[idx[~keep_in]].sum()

    # Runs of consecutive fine samples -> cells of width <= step at their centroids.
    out_w, out_m = [], []
    breaks = np.flatnonzero(np.diff(kept) != 1) + 1
    for run in np.split(kept, breaks):
        e_lo = wl[run[0]] - 0.5 * fw[run[0]]
        e_hi = wl[run[-1]] + 0.5 * fw[run[-1]]
        n = max(1, math.ceil((e_hi - e_lo) / step_nm - 1e-9))
        edges = np.linspace(e_lo, e_hi, n + 1)
        c_lo = wl[run] - 0.5 * fw[run]
        c_hi = wl[run] + 0.5 * fw[run]
        overlap = np.clip(
            np.minimum(c_hi[:, None], edges[None, 1:]) - np.maximum(c_lo[:, None], edges[None, :-1]),
            0.0, None,
        ) / fw[run][:, None]
        overlap /= overlap.sum(axis=1, keepdims=True)
        cw = (w[run][:, None] * overlap).sum(axis=0)
        cm = (w[run][:, None] * wl[run][:, None] * overlap).sum(axis=0)
        ok = cw > 0
        out_w.append(cw[ok])
        out_m.append(cm[ok])
    cw = np.concatenate(out_w)
    cl = np.concatenate(out_m) / cw

    # Cells that fit in what is left of the tolerance.
    keep_c = _prune_mask(cw, budget)
    new_wl = cl[keep_c]
    new_w = cw[keep_c].copy()
    # Everything not kept (outside range, dropped fine samples, dropped cells) goes to the
    # nearest kept wavelength.
    moved = np.ones(wl.size, bool)
    moved[kept] = False
    moved &= w > 0
    np.add.at(new_w, _nearest(new_wl, wl[moved]), w[moved])
    np.add.at(new_w, _nearest(new_wl, cl[~keep_c]), cw[~keep_c])
    if new_wl.size > 1 and np.any(np.diff(new_wl) <= 0):  # pragma: no cover - by construction
        raise RuntimeError("resampled wavelengths are not strictly increasing")
    return new_wl, new_w / new_w.sum()


def _fine_weights(wl: np.ndarray, emission: np.ndarray) -> np.ndarray:
    lef_wl, lef_v = lef_data()
    v = np.interp(wl, lef_wl, lef_v, left=0.0, right=0.0)
    return emission * v * _cell_widths(wl)


def display_spectrum(
    primaries: DisplayPrimaries | str,
    channel="white",
    options: ModelOptions = ModelOptions(),
    weight_tolerance: float = 1e-3,
    step_nm: float | None = None,
) -> Spectrum:
    """Model :class:`~lfjax.model.spectral.Spectrum` of light from a display.

    Parameters
    ----------
    primaries : DisplayPrimaries or a built-in name (``"crt"``, ``"lcd"``, ``"oled"``,
        ``"laser"``).
    channel : ``"white"`` (the R, G, B mix with CIE D65 chromaticity, solved from the
        primaries' CIE 1931 XYZ — see :func:`channel_drive`), ``"red"``, ``"green"``,
        ``"blue"``, or (3,) non-negative drive levels of R, G, B.
    options : ModelOptions (LCA constants, Stiles–Crawford form/table; the SCE sets the
        computed range 400–700 nm, ``sce="off"`` 390–830 nm).
    weight_tolerance : fraction (in [0, 1)) of the V-weighted power that may be moved to a
        neighbouring wavelength to use fewer wavelengths.
    step_nm : cell width, nm; default min(FWHM)/3 of the driven Gaussian primaries clipped
        to 5–10 nm, or 10 nm for measured (broad) primaries.

    Weights = emission(λ) × V(λ) × Δλ on the fine grid, resampled as the module docstring
    describes, normalised to sum 1. Wavelength counts of the built-in displays are in the
    module docstring.
    """
    if isinstance(primaries, str):
        primaries = display_primaries(primaries)
    elif not isinstance(primaries, DisplayPrimaries):
        raise ValueError(
            f"primaries must be a DisplayPrimaries or one of {', '.join(DISPLAY_NAMES)}; "
            f"got {type(primaries).__name__}"
        )
    _check_tolerance_step(weight_tolerance, step_nm)
    drive = channel_drive(primaries, channel)
    if step_nm is None:
        if primaries.fwhm_nm is not None:
            fwhm = min(f for f, d in zip(primaries.fwhm_nm, drive) if d > 0)
            step_nm = float(np.clip(fwhm / 3.0, MIN_STEP_NM, BROAD_STEP_NM))
        else:
            step_nm = BROAD_STEP_NM
    wl = primaries.wavelengths_nm
    w = _fine_weights(wl, primaries.emission @ drive)
    new_wl, new_w = resample_weights(
        wl, w, step_nm, weight_tolerance, computed_range_nm(options),
        parameter=f"primaries {primaries.name!r} with channel {channel!r}",
    )
    return make_spectrum(new_wl, options, weights=new_w)


def user_spectrum(
    wavelengths_nm,
    emission,
    options: ModelOptions = ModelOptions(),
    weight_tolerance: float = 1e-3,
    step_nm: float = BROAD_STEP_NM,
) -> Spectrum:
    """Model Spectrum of any sampled emission spectrum.

    Parameters
    ----------
    wavelengths_nm : (n,) strictly increasing, finite wavelengths, nm.
    emission : (n,) finite, non-negative relative spectral power (per nm).
    options, weight_tolerance : as :func:`display_spectrum`.
    step_nm : cell width, nm (default 10 nm; a line narrower than it becomes one sample).

    V(λ) is taken as 0 outside the CIE 2008 LEF data (390–830 nm). Resampled as the module
    docstring describes; with ``weight_tolerance=0`` and emission sampled on the cells
    (e.g. 400–700 nm at 10 nm, ``step_nm=10``) the samples are kept unchanged.
    """
    wl = np.asarray(wavelengths_nm, float)
    em = np.asarray(emission, float)
    if wl.ndim != 1 or wl.size < 1:
        raise ValueError(f"wavelengths_nm must be 1-D with >= 1 values, got shape {wl.shape}")
    if not np.all(np.isfinite(wl)) or (wl.size > 1 and np.any(np.diff(wl) <= 0)):
        raise ValueError("wavelengths_nm must be finite and strictly increasing")
    if em.shape != wl.shape:
        raise ValueError(
            f"emission must have the shape of wavelengths_nm {wl.shape}, got {em.shape}"
        )
    if not np.all(np.isfinite(em)) or np.any(em < 0):
        raise ValueError("emission must be finite and non-negative")
    _check_tolerance_step(weight_tolerance, step_nm)
    w = _fine_weights(wl, em)
    if not np.any(w > 0):
        lo, hi = computed_range_nm(options)
        raise ValueError(
            f"emission has no weight (emission × V(λ)) inside the computed range "
            f"{lo:g}–{hi:g} nm (V(λ) data: 390–830 nm)"
        )
    new_wl, new_w = resample_weights(
        wl, w, step_nm, weight_tolerance, computed_range_nm(options), parameter="emission"
    )
    return make_spectrum(new_wl, options, weights=new_w)


__all__ = [
    "DISPLAY_NAMES",
    "CHANNELS",
    "DisplayPrimaries",
    "display_primaries",
    "gaussian_primaries",
    "emission_XYZ",
    "channel_drive",
    "resample_weights",
    "display_spectrum",
    "user_spectrum",
]
