"""Sampling planner: the cheapest sampling that meets an accuracy target, with its reasons.

"Model no more than a scene needs." In lfjax's FFT path one number, the frequency step df
(cpd), fixes the numerics: the PSF field is 60/df arcmin (the blur must fit or it wraps)
and the pupil is sampled at λ·df per wavelength (d/(λ·df) samples across a subaperture of
diameter d). The matrix Fourier transform path (``Sampling(transform="mft")``) separates
the two: df sets the field, ``mft_pupil_samples`` the pupil sampling. The planner also
chooses the wavelength step and the Zernike order the eyes need.

:func:`plan_sampling` takes the scene it plans for (:class:`~lfjax.planner.scene.PlanScene`)
and what the plan must meet (:class:`Targets`), and optionally fixed choices
(:class:`Overrides`) and the field guard's knobs (:class:`FieldGuard`): small frozen
objects, each checked when built. How each choice is made (all on the host, in numpy;
1–30 s per plan):

* **Field (frequency step).** Hard limit: the pipeline's aliasing guard
  (:func:`lfjax.kernel.optics.field_radius_arcmin`, geometric blur + display shifts + diffraction
  + the eyes' ray angles). Within it, the PSF that wraps back into the field is *measured*
  on a proxy (:mod:`lfjax.planner.proxy`): the largest ratio of wrapped intensity to the
  PSF's peak must stay within ``Targets.psf``.
* **Pupil sampling.** The VSOTF error of the discretised, soft-edged aperture is *measured*
  on the proxy, at every (depth, state) pair of the scene: the candidate's distance from
  one converged proxy value (Richardson, order 2, from a half and a quarter of the largest
  admissible step, or a quarter and an eighth for tight targets), × ``ESTIMATE_SAFETY``.
* **Wavelength step** (when only a range is given): proxy through-focus curves at each
  candidate step against a 5 nm reference; the step must keep the VSOTF error within its
  share of the tolerance and leave every proxy peak where it was.
  With ``Overrides(spectral_rule="auto")`` the Gauss rule for V(λ)
  (:func:`lfjax.model.spectral.gauss_rule`) competes on the same criteria: its fewest nodes
  that meet them replace the step when they are fewer wavelengths (:attr:`Plan.spectral_rule`).
* **Zernike order**: the eyes' wavefront RMS above the kept order, converted to a VSOTF
  change by the Maréchal approximation (2πσ/λ)².
* **Targets in the question's units** (``Targets.peak_D``, ``Targets.cutoff_cpd``):
  a through-focus peak's error is the shift of the vertex of the parabola through the
  proxy's highest sample and its neighbours, candidate against converged (the VSOTF error's
  slope over the curve's curvature, to first order); a cut-off's error is the shift of the
  proxy's radial-MTF threshold crossing at every state near each depth's peak (the MTF
  error over the MTF's slope). Half of each target goes to the wavelength step, the rest
  to the frequency step.
* **FFT or MFT** (``Overrides(transform="auto")``, opt-in): each at its own cheapest
  accuracy-meeting sampling, each measured on a proxy that follows that path exactly; the
  cheaper by a cost model calibrated on this machine (:mod:`lfjax.planner.cost`).

The real eyes' aberrations enter through the field guard (their ray angles); see
benchmarks/RESULTS.md §6–7 for plans measured with real eyes.

Steps are taken from fixed ladders (df = 2^(k/8) cpd; pupil samples 16, 20, 24, 32, …), so
"one step cheaper" is well defined: :attr:`Plan.cheaper` lists it for every dimension.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field

import numpy as np

from lfjax.base.sampling import EYE_BLOCK, Sampling, wavelength_bands
from lfjax.base.units import DEGREES_PER_RADIAN
from lfjax.base.zernike import n_modes_for_order, nm_from_ansi, zernike_basis_host
from lfjax.kernel.optics import field_radius_arcmin
from lfjax.model.options import ModelOptions
from lfjax.model.spectral import Spectrum, gauss_rule, make_spectrum
from lfjax.planner.cost import cost_s, fft_work
from lfjax.planner.proxy import Estimates, Proxy, grid_peaks, peak_shift_D
from lfjax.planner.scene import PlanScene

STEPS_PER_OCTAVE = 8
"""Frequency-step ladder: df = 2^(k/8) cpd (9 % apart; one step ≈ 19 % of FFT work)."""

MFT_PUPIL_LADDER = (16, 20, 24, 28, 32, 40, 48, 56, 64, 80, 96, 112, 128, 160, 192, 256)
"""Pupil samples across the MFT window the planner chooses from."""

WAVELENGTH_STEPS_NM = (50.0, 30.0, 25.0, 20.0, 10.0, 5.0)
"""Wavelength steps the planner chooses from (coarsest first)."""

SPECTRAL_RULES = ("uniform", "auto")
"""How a planned spectrum may sample its range: ``"uniform"``, a step from
:data:`WAVELENGTH_STEPS_NM`; ``"auto"``, that step or the Gauss rule for V(λ)
(:func:`lfjax.model.spectral.gauss_rule`), whichever meets the targets with fewer
wavelengths."""

GAUSS_NODE_CANDIDATES = tuple(range(4, 17))
"""Node counts of the Gauss rule in V(λ) the planner tries (fewest first), each only while
it is fewer than the uniform step's wavelengths."""

SPECTRAL_REFERENCE_STEP_NM = 5.0
"""Wavelength step of the proxy's converged spectrum, against which candidate steps are
measured. The V(λ)-weighted sum is a trapezoid rule on an integrand that vanishes at both
ends of 400–700 nm, so it converges fast: on the study's eleven eyes 20 and 25 nm agree with
5 nm to 8e-4 D in peaks and 0.06 cpd in natural-view cut-offs (benchmarks/RESULTS.md §18).
(It was 2.5 nm; the 121-wavelength proxy cost 5–10 s per plan.)"""


def ladder_floor(x: float) -> float:
    """Largest ladder step 2^(k/8) ≤ x."""
    k = math.floor(STEPS_PER_OCTAVE * math.log2(x) + 1e-9)
    return 2.0 ** (k / STEPS_PER_OCTAVE)


def ladder_up(x: float) -> float:
    """The next ladder step above ``x`` (one step cheaper)."""
    return ladder_floor(x) * 2.0 ** (1.0 / STEPS_PER_OCTAVE)


@dataclass(frozen=True)
class Plan:
    """A chosen sampling with its estimated errors, cost and reasons.

    Attributes
    ----------
    sampling : Sampling to pass to the pipeline (frequency step, transform, pupil samples).
    wavelengths_nm : (n_λ,) wavelengths to use, nm (``spectrum()`` builds them).
    max_zernike_order : radial order of the eyes' Zernike terms to keep (None: all).
    blur_radius_arcmin : largest PSF radius the field must hold (the guard), arcmin.
    guard_freq_step_cpd : largest frequency step the aliasing guard accepts, cpd.
    errors : estimated VSOTF errors by source ("pupil", "spectral", "zernike", "total")
        and "psf_wrap" (wrapped intensity / PSF peak), from the proxy; with the targets in
        the question's units also the proxy's peak shifts in D ("spectral_peak_D", and
        "peak_D" for the whole plan) and cut-off shifts in cpd ("spectral_cutoff_cpd",
        "cutoff_cpd").
    cost_s : modelled seconds per eye for "fft" and "mft" at their own plans.
    cheaper : the sampling one ladder step cheaper in each dimension, with the reason it
        was rejected, e.g. {"field": (Sampling, "…"), "pupil": (Sampling, "…")}.
    bands : wavelength bands and FFT sizes ((start, stop, n_fft), …).
    fft_work : relative FFT work per eye and state, Σ n_λ·n_sub·n_fft²·log2(n_fft).
    reasons : one-line explanations.
    spectral_weights : the weights of ``wavelengths_nm`` when they are not V(λ)·Δλ (a
        display's spectrum given in the scene, or the Gauss rule's weights), else None.
    spectral_rule : how the wavelengths were chosen: ``"uniform"`` (a planned step),
        ``"gauss"`` (the Gauss rule for V(λ) on the scene's range, its nodes and weights)
        or ``"given"`` (the scene's spectrum, used as given).
    """

    sampling: Sampling
    wavelengths_nm: tuple
    max_zernike_order: int | None
    blur_radius_arcmin: float
    guard_freq_step_cpd: float
    errors: dict
    cost_s: dict
    cheaper: dict
    bands: tuple
    fft_work: float
    options: ModelOptions = ModelOptions()
    reasons: list = field(default_factory=list)
    spectral_weights: tuple | None = None
    spectral_rule: str = "uniform"

    def spectrum(self) -> Spectrum:
        """The planned spectrum (V(λ) weights, or the ``spectral_weights`` planned for; LCA
        and SCE of the plan's options)."""
        weights = None if self.spectral_weights is None else np.asarray(self.spectral_weights)
        return make_spectrum(np.asarray(self.wavelengths_nm), self.options, weights=weights)

    def truncate(self, zernike_um):
        """Eye coefficients (…, n_modes) cut to the planned Zernike order."""
        if self.max_zernike_order is None:
            return zernike_um
        n = min(n_modes_for_order(self.max_zernike_order), np.shape(zernike_um)[-1])
        return zernike_um[..., :n]

    def summary(self) -> str:
        """Printable explanation of the choice."""
        s = self.sampling
        wl = np.asarray(self.wavelengths_nm)
        if self.spectral_rule == "gauss":
            step = f"Gauss rule in V(λ), {wl.size} nodes"
        else:
            step = f"{wl[1] - wl[0]:g} nm steps" if wl.size > 1 else "one wavelength"
        transform = (
            f"MFT with {s.mft_pupil_samples} pupil samples" if s.transform == "mft"
            else "FFT (pupil sampled at λ·df)"
        )
        e = self.errors
        lines = [
            f"freq_step_cpd = {s.freq_step_cpd:.4g} cpd (PSF field {s.field_arcmin:.1f} arcmin; "
            f"guard allows ≤ {self.guard_freq_step_cpd:.4g})",
            f"transform: {transform}; aperture edge {s.edge_width_samples:g} samples",
            f"wavelengths: {wl[0]:.4g}–{wl[-1]:.4g} nm, {step} ({wl.size})",
            "Zernike order: " + ("all" if self.max_zernike_order is None else str(self.max_zernike_order)),
            f"estimated VSOTF error: {e.get('total', float('nan')):.2g} (pupil "
            f"{e.get('pupil', float('nan')):.2g}, spectral {e.get('spectral', float('nan')):.2g}, "
            f"Zernike {e.get('zernike', float('nan')):.2g}); wrapped PSF / peak "
            f"{e.get('psf_wrap', float('nan')):.2g}",
            "modelled time per eye: " + ", ".join(f"{k} {v:.3g} s" for k, v in self.cost_s.items()),
            "wavelength bands (start, stop, n_fft): " + ", ".join(map(str, self.bands)),
        ]
        lines += [f"- {r}" for r in self.reasons]
        for dim, (_, why) in self.cheaper.items():
            lines.append(f"- one step cheaper in {dim}: {why}")
        return "\n".join(lines)


# ----------------------------------------------------------------------------- what to meet


TRANSFORMS = ("fft", "mft", "auto")
"""The transforms a plan may choose: the FFT, the MFT, or the cheaper of the two."""


@dataclass(frozen=True)
class Targets:
    """What a plan must meet, each a bound (in the manner of diffrax's ``SaveAt``: one small
    object says what is asked). Any combination of ``vsotf``, ``peak_D`` and ``cutoff_cpd``;
    at least one of them.

    Attributes
    ----------
    vsotf : largest VSOTF error (absolute) against a converged sampling, in (0, 0.5); None:
        no VSOTF target (then every Zernike order is kept)
    peak_D : largest shift of a through-focus peak, D, in (0, 0.5]: the proxy's VSOTF error
        propagated through each curve's curvature (the vertex of the parabola through the
        peak and its neighbours, candidate against converged); half of it for the
        wavelength step, half for the frequency step. Without it the wavelength step must
        leave every proxy through-focus grid peak where it was.
    cutoff_cpd : largest shift of a cut-off frequency, cpd, in (0, 10] (the proxy's radial MTF
        at each depth's peak state falling to ``cutoff_threshold``; the MTF's error read
        through its slope); split as ``peak_D``
    psf : largest PSF intensity wrapped back into the field, relative to its peak, in (0, 1)
    cutoff_threshold : the MTF value whose crossing is the cut-off, in (0, 1)
    """

    vsotf: float | None = 1e-3
    peak_D: float | None = None
    cutoff_cpd: float | None = None
    psf: float = 2e-3
    cutoff_threshold: float = 0.05

    def __post_init__(self):
        if self.vsotf is None and self.peak_D is None and self.cutoff_cpd is None:
            raise ValueError("give an accuracy target: Targets.vsotf, Targets.peak_D or "
                             "Targets.cutoff_cpd")
        if self.vsotf is not None and not (0 < self.vsotf < 0.5):
            raise ValueError(f"Targets.vsotf must be in (0, 0.5), got {self.vsotf}")
        if self.peak_D is not None and not (0 < self.peak_D <= 0.5):
            raise ValueError(f"Targets.peak_D must be in (0, 0.5] D, got {self.peak_D}")
        if self.cutoff_cpd is not None and not (0 < self.cutoff_cpd <= 10):
            raise ValueError(f"Targets.cutoff_cpd must be in (0, 10] cpd, got {self.cutoff_cpd}")
        if not (0 < self.cutoff_threshold < 1):
            raise ValueError(f"Targets.cutoff_threshold must be in (0, 1), got {self.cutoff_threshold}")
        if not (0 < self.psf < 1):
            raise ValueError(f"Targets.psf must be in (0, 1) (fraction of the PSF peak), got {self.psf}")


@dataclass(frozen=True)
class Overrides:
    """Choices fixed by the caller; everything not fixed is still planned.

    Attributes
    ----------
    freq_step_cpd : frequency step, cpd (a plan refuses one the aliasing guard would refuse)
    transform : one of :data:`TRANSFORMS` — "fft" (default), "mft", or "auto" (the cheaper by
        the cost model). The MFT proxy is the pipeline's MFT path (tested); forced MFT plans
        met a 1e-3 target on an open pupil, 2×2 and 4×4 with one pupil step cheaper failing
        (RESULTS §7). "auto" is opt-in because its cost model rests on four calibration runs
        on one machine. The MFT's pupil samples are planned for ``Targets.vsotf``.
    mft_pupil_samples : pupil samples across the MFT window
    wavelength_step_nm : wavelength step over ``PlanScene.wavelength_range_nm``, nm, in (0, 100]
        (a uniform grid, whatever ``spectral_rule`` says)
    spectral_rule : one of :data:`SPECTRAL_RULES` — how a planned spectrum samples its range:
        ``"uniform"`` (default, a step), or ``"auto"`` (a step or the Gauss rule for V(λ),
        whichever meets the targets with fewer wavelengths)
    max_zernike_order : radial order of the eyes' Zernike terms kept
    edge_width_samples : the apertures' logistic edge, pupil samples
    """

    freq_step_cpd: float | None = None
    transform: str = "fft"
    mft_pupil_samples: int | None = None
    wavelength_step_nm: float | None = None
    max_zernike_order: int | None = None
    edge_width_samples: float = 0.25
    spectral_rule: str = "uniform"

    def __post_init__(self):
        if self.transform not in TRANSFORMS:
            raise ValueError(f"transform must be 'auto', 'fft' or 'mft', got {self.transform!r}")
        if self.wavelength_step_nm is not None and not (0 < self.wavelength_step_nm <= 100):
            raise ValueError(f"wavelength_step_nm must be in (0, 100] nm, got {self.wavelength_step_nm}")
        if self.spectral_rule not in SPECTRAL_RULES:
            raise ValueError(f"spectral_rule must be one of {SPECTRAL_RULES}, got {self.spectral_rule!r}")


@dataclass(frozen=True)
class FieldGuard:
    """The field guard's knobs (the hard limit on the frequency step).

    Attributes
    ----------
    margin : safety factor on the blur the field must hold, ≥ 1
    wrap_tolerance : spectral weight allowed to wrap (the most blurred wavelengths first)
    min_samples_per_subaperture : floor on pupil samples across the smallest view
    """

    margin: float = 1.05
    wrap_tolerance: float = 1e-3
    min_samples_per_subaperture: int = 8

    def __post_init__(self):
        if not (self.margin >= 1):
            raise ValueError(f"margin must be >= 1, got {self.margin}")


# ----------------------------------------------------------------------------- the plan


def plan_sampling(scene: PlanScene, targets: Targets = Targets(), *,  # noqa: B008 (frozen)
                  estimate_accuracy: bool = True, overrides: Overrides = Overrides(),  # noqa: B008
                  guard: FieldGuard = FieldGuard()) -> Plan:  # noqa: B008
    """Choose the cheapest sampling that meets ``targets`` for ``scene``, and say why.

    Parameters
    ----------
    scene : :class:`~lfjax.planner.scene.PlanScene` — the layout, pupil, CDP, the pairs the
        computation evaluates, the spectrum (given, or a range whose step is planned), the
        eyes, options and display
    targets : :class:`Targets` — the VSOTF error, peak shift (D), cut-off shift (cpd) and
        wrapped PSF the plan must keep within (default: a VSOTF error of 1e-3)
    estimate_accuracy : False skips the proxy for the frequency step (the field guard alone
        picks it, in a few milliseconds; its errors are reported as NaN). A spectrum given
        as a range still gets its step planned for ``targets``.
    overrides : :class:`Overrides` — choices fixed by the caller (frequency step, transform,
        MFT pupil samples, wavelength step, Zernike order, aperture edge)
    guard : :class:`FieldGuard` — the field guard's margin, wrap tolerance and floor on
        pupil samples

    The plan is made in steps, each reported in :attr:`Plan.reasons`: the Zernike order the
    eyes need, the field guard, the wavelength step, then (``estimate_accuracy``) the
    frequency step the proxy's error estimates accept, the MFT's pupil samples, and one
    ladder step cheaper in each dimension with the reason it fails.

    Examples
    --------
    The sampling for 2×2 views of a point at 1 D, the eye anywhere from 0 to 2 D, for the
    default target (a VSOTF error of 1e-3), the spectrum's step planned over 400–700 nm:

    >>> import lfjax
    >>> plan = lfjax.plan_sampling(lfjax.PlanScene(
    ...     layout=lfjax.grid_layout(2), depths_D=[1.0], accommodation_D=(0.0, 2.0)))
    >>> plan.sampling.freq_step_cpd <= plan.guard_freq_step_cpd  # inside the aliasing guard
    True
    >>> plan.errors["total"] <= 1e-3  # the estimated VSOTF error meets the target
    True
    >>> plan.wavelengths_nm[0], plan.wavelengths_nm[-1]
    (400.0, 700.0)
    """
    if overrides.transform != "fft" and targets.vsotf is None and estimate_accuracy:
        raise ValueError(f"transform={overrides.transform!r} plans the MFT's pupil samples for a "
                         "VSOTF target: give Targets.vsotf (the D / cpd targets plan the FFT path)")
    p = _Planning(scene, targets, overrides, guard)
    _choose_zernike_order(p)
    _apply_field_guard(p)
    _choose_wavelength_step(p)
    if not estimate_accuracy:
        return _guard_only_plan(p)
    return _accuracy_plan(p)


@dataclass
class _Planning:
    """What :func:`plan_sampling` has settled so far (one plan's working state)."""

    scene: PlanScene
    targets: Targets
    overrides: Overrides
    guard: FieldGuard
    errors: dict = field(default_factory=dict)
    reasons: list = field(default_factory=list)
    wl: np.ndarray | None = None  # the spectrum, nm (None while its step is to be chosen)
    weights: np.ndarray | None = None  # its weights when not V(λ)·Δλ (given, or the Gauss rule's)
    rule: str = "given"  # how wl was chosen: "given", "uniform" or "gauss"
    budget: float = math.inf  # what is left of the VSOTF target
    order_kept: int | None = None
    radius: float = math.nan  # the blur the field must hold, arcmin
    df_guard: float = math.nan  # the guard's largest step, cpd
    df_floor_samples: float = math.nan  # the step that puts the floor of samples on the smallest view
    df_top: float = math.nan  # the largest ladder step under both
    guard_wl: np.ndarray | None = None  # the wavelengths the guard ran on, nm

    def __post_init__(self):
        if self.scene.wavelengths_nm is not None:
            self.wl = np.atleast_1d(np.asarray(self.scene.wavelengths_nm, float))
            if self.scene.spectral_weights is not None:
                self.weights = np.asarray(self.scene.spectral_weights, float)
        # Without a VSOTF target the VSOTF budget is unbounded: the D/cpd targets decide.
        self.budget = math.inf if self.targets.vsotf is None else float(self.targets.vsotf)
        self.order_kept = self.overrides.max_zernike_order

    def field_radius(self, spectrum: Spectrum) -> float:
        """The guard's blur radius (arcmin) of the scene summed over ``spectrum``."""
        s = self.scene
        return field_radius_arcmin(
            s.eyes_zernike_um, s.measured_pupil_mm, s.pupil_diameter_mm, s.cdp_D,
            s.accommodation, s.pair_acc, s.pair_depth, s.layout, spectrum,
            self.guard.wrap_tolerance, s.display,
        )

    def bands(self, sampling: Sampling) -> tuple:
        return wavelength_bands(self.wl, self.scene.window_mm, self.scene.pupil_diameter_mm,
                                sampling)

    def plan(self, sampling, bands, cost, cheaper) -> Plan:
        s = self.scene
        weights = None if self.weights is None else tuple(float(w) for w in self.weights)
        return Plan(sampling, tuple(float(x) for x in self.wl), self.order_kept,
                    float(self.radius), float(self.df_guard), self.errors, cost, cheaper, bands,
                    fft_work(bands, s.layout.n_subapertures), s.options, self.reasons, weights,
                    self.rule)


def _choose_zernike_order(p: _Planning) -> None:
    """The eyes' Zernike order: the lowest whose RMS above it changes VSOTF (Maréchal) by at
    most 10 % of the VSOTF target, or every order without one."""
    eyes_zernike_um = p.scene.eyes_zernike_um
    vsotf_tolerance = p.targets.vsotf
    if eyes_zernike_um is not None and vsotf_tolerance is None and p.order_kept is None:
        p.errors["zernike"] = 0.0
        p.reasons.append("Zernike: every order kept (no VSOTF target to spend on truncation)")
    elif eyes_zernike_um is not None:
        rms = _order_rms_um(eyes_zernike_um, p.scene.measured_pupil_mm, p.scene.pupil_diameter_mm)
        orders = sorted(o for o in rms if o >= 2)
        if p.order_kept is None:
            p.order_kept = orders[-1] if orders else None
            for keep in orders:
                rest = math.sqrt(sum(rms[o] ** 2 for o in orders if o > keep))
                if (2 * math.pi * rest / 0.555) ** 2 <= 0.1 * vsotf_tolerance:
                    p.order_kept = keep
                    break
        order_kept = p.order_kept
        rest = math.sqrt(sum(rms[o] ** 2 for o in rms if order_kept is not None and o > order_kept))
        p.errors["zernike"] = (2 * math.pi * rest / 0.555) ** 2
        p.reasons.append(
            f"Zernike: order ≤ {order_kept} kept; RMS above it {rest * 1e3:.2g} nm → VSOTF change "
            f"≈ (2πσ/λ)² = {p.errors['zernike']:.2g} (budget 10 % of the tolerance)"
        )
    else:
        p.errors["zernike"] = 0.0
    p.budget -= p.errors["zernike"]


def _apply_field_guard(p: _Planning) -> None:
    """The hard limit, the pipeline's own rule: the field must hold the blur (on a 5 nm grid
    when the spectrum's step is still to be chosen), with the guard's margin; the step is
    also bounded by the floor of pupil samples across the smallest view."""
    s, g = p.scene, p.guard
    rng = s.wavelength_range_nm
    p.guard_wl = p.wl if p.wl is not None else np.arange(rng[0], rng[1] + 1e-6, 5.0)
    p.radius = p.field_radius(make_spectrum(p.guard_wl, s.options, weights=s.spectral_weights))
    p.df_guard = 30.0 / (p.radius * g.margin)
    p.reasons.append(
        f"field guard: blur reaches {p.radius:.1f} arcmin (defocus, LCA, display shifts, "
        f"diffraction, eyes' ray angles); ×{g.margin} margin → df ≤ {p.df_guard:.3g} cpd"
    )
    d_min = s.smallest_diameter_mm
    p.df_floor_samples = (d_min / (float(p.guard_wl.max()) * 1e-6 * g.min_samples_per_subaperture)
                          / DEGREES_PER_RADIAN)
    p.df_top = ladder_floor(min(p.df_guard, p.df_floor_samples))


def _choose_wavelength_step(p: _Planning) -> None:
    """The coarsest candidate step whose proxy curves keep within half of each target against
    a 5 nm reference (or the given step); with ``Overrides.spectral_rule="auto"`` also the
    Gauss rule for V(λ) with the fewest nodes that does the same, taken when it has fewer
    wavelengths than that step. Then the guard again on the chosen wavelengths. A given
    spectrum is kept (with a warning for steps over 20 nm)."""
    s, t = p.scene, p.targets
    if p.wl is not None:
        p.errors["spectral"] = float("nan")
        if p.wl.size > 1 and np.any(np.diff(p.wl) > 20.0):
            p.reasons.append("warning: wavelength steps over 20 nm under-sample LCA blur (Ravikumar et al. 2008; "
                             "benchmarks/speed/speed_accuracy.py: 50 nm moves a prediction by 0.2 D)")
        return
    step_choice = p.overrides.wavelength_step_nm
    spec_proxy_df = ladder_floor(min(p.df_top, s.smallest_diameter_mm
                                     / (float(p.guard_wl.max()) * 1e-6 * 24) / DEGREES_PER_RADIAN))
    peak = _peak_neighbourhood(s.pair_depth)
    lo, hi = map(float, s.wavelength_range_nm)

    def curves(wavelengths, weights=None):
        proxy = Proxy(s, make_spectrum(wavelengths, s.options, weights=weights),
                      p.overrides.edge_width_samples, n_wavelengths=wavelengths.size)
        if t.cutoff_cpd is None:
            return proxy.vsotf(spec_proxy_df, peak), None
        return proxy.vsotf_and_cutoffs(spec_proxy_df, peak, t.cutoff_threshold)

    ref, ref_cut = curves(np.arange(lo, hi + 1e-6, SPECTRAL_REFERENCE_STEP_NM))
    ref_peak = grid_peaks(ref, peak)
    # Cut-offs at each depth's peak state and its neighbours 0.1 D away, not the peak
    # alone: a real eye's aberrations blur it like a little defocus, and a blurred MTF
    # crosses the threshold with a shallower slope, where a spectral error moves it
    # more. Farther out the defocused MTF oscillates about the threshold and its first
    # crossing jumps between lobes: no predicted accommodation sits there.
    near_peak = np.abs(peak[0] - np.asarray(ref_peak)[
        np.searchsorted(np.unique(peak[1]), peak[1])]) <= 0.1 + 1e-9
    budget = p.budget

    def measure(wavelengths, weights=None):
        """(meets every target, errors, what they are against their budgets) of one spectrum
        on the proxy against the reference."""
        v, cuts = curves(wavelengths, weights)
        err = float(np.max(np.abs(v - ref)))
        same_peak = grid_peaks(v, peak) == ref_peak
        shift = peak_shift_D(v, ref, peak)
        cut = (float(np.max(np.abs(cuts - ref_cut)[near_peak])) if cuts is not None
               else float("nan"))
        ok = err <= 0.5 * budget
        ok &= shift <= 0.5 * t.peak_D if t.peak_D is not None else same_peak
        ok &= t.cutoff_cpd is None or cut <= 0.5 * t.cutoff_cpd
        text = (f"VSOTF error {err:.2g} (budget {0.5 * budget:.2g}), peaks "
                + (f"moved ≤ {shift:.2g} D (budget {0.5 * t.peak_D:.2g})"
                   if t.peak_D is not None else ('unchanged' if same_peak else 'MOVED'))
                + (f", cut-offs moved ≤ {cut:.2g} cpd (budget {0.5 * t.cutoff_cpd:.2g})"
                   if t.cutoff_cpd is not None else ""))
        return bool(ok), (err, shift, cut), text

    candidates = [step_choice] if step_choice is not None else [
        step for step in WAVELENGTH_STEPS_NM
        if abs((hi - lo) / step - round((hi - lo) / step)) < 1e-9
        and step > SPECTRAL_REFERENCE_STEP_NM]
    chosen = None
    for step in candidates:
        ok, errors, text = measure(np.arange(lo, hi + 1e-6, step))
        if step_choice is not None or ok:
            chosen = step
            p.errors["spectral"], p.errors["spectral_peak_D"], p.errors["spectral_cutoff_cpd"] = errors
            p.reasons.append(
                f"wavelength step {step:g} nm against {SPECTRAL_REFERENCE_STEP_NM:g} nm on the proxy: "
                + text + (" (user's step)" if step_choice is not None else ""))
            break
    if chosen is None:  # no coarser step meets the targets: the reference's own step
        chosen = SPECTRAL_REFERENCE_STEP_NM
        p.errors["spectral"] = 0.0
        p.errors["spectral_peak_D"] = p.errors["spectral_cutoff_cpd"] = 0.0
        p.reasons.append(f"wavelength step {chosen:g} nm: the reference step (no coarser "
                         f"candidate met the targets)")
    p.wl, p.weights, p.rule = np.arange(lo, hi + 1e-6, chosen), None, "uniform"
    if step_choice is None and p.overrides.spectral_rule == "auto":
        _try_gauss_rule(p, measure, lo, hi)
    # The guard ran on a 5 nm grid; on the chosen, coarser grid each wavelength carries
    # more of the weight, so the blue and red ends may no longer be light enough to let
    # wrap. The field must hold the spectrum the pipeline will sum.
    p.radius = max(p.radius, p.field_radius(make_spectrum(p.wl, s.options, weights=p.weights)))
    if 30.0 / (p.radius * p.guard.margin) < p.df_guard:
        p.df_guard = 30.0 / (p.radius * p.guard.margin)
        p.df_top = ladder_floor(min(p.df_guard, p.df_floor_samples))
        what = (f"{p.wl.size}-node Gauss rule" if p.rule == "gauss" else f"{chosen:g} nm grid")
        p.reasons.append(f"field guard on the chosen {what}: blur reaches "
                         f"{p.radius:.1f} arcmin → df ≤ {p.df_guard:.3g} cpd")
    if np.isfinite(p.errors["spectral"]):
        p.budget -= p.errors["spectral"]


def _try_gauss_rule(p: _Planning, measure, lo: float, hi: float) -> None:
    """The Gauss rule for V(λ) on [lo, hi] with the fewest nodes (of
    :data:`GAUSS_NODE_CANDIDATES`, each fewer than the uniform step's wavelengths) that
    meets the same criteria on the proxy as the step (``measure``); it replaces the step
    when found. Either way the reasons say which rule and why."""
    n_uniform = p.wl.size
    rejected = None
    for n in GAUSS_NODE_CANDIDATES:
        if n >= n_uniform:
            break
        nodes, weights = gauss_rule(n, lo, hi)
        ok, errors, text = measure(nodes, weights)
        if not ok:
            rejected = (n, text)
            continue
        p.wl, p.weights, p.rule = nodes, weights, "gauss"
        p.errors["spectral"], p.errors["spectral_peak_D"], p.errors["spectral_cutoff_cpd"] = errors
        p.reasons.append(
            f"wavelengths: Gauss rule in V(λ), {n} nodes ({nodes[0]:.1f}–{nodes[-1]:.1f} nm) "
            f"against {SPECTRAL_REFERENCE_STEP_NM:g} nm on the proxy: {text}; {n} wavelengths "
            f"instead of the uniform step's {n_uniform}"
            + (f" ({rejected[0]} nodes: {rejected[1]})" if rejected is not None else ""))
        return
    p.reasons.append(
        f"wavelengths: the uniform step kept ({n_uniform} wavelengths): "
        + (f"no Gauss rule in V(λ) with fewer nodes met the targets ({rejected[0]} nodes: "
           f"{rejected[1]})" if rejected is not None
           else "no Gauss rule candidate has fewer nodes"))


def _guard_only_plan(p: _Planning) -> Plan:
    """The field guard's step (or the one given, if the guard accepts it); no proxy."""
    freq_step_cpd = p.overrides.freq_step_cpd
    df = float(freq_step_cpd) if freq_step_cpd is not None else p.df_top
    if df > p.df_guard * p.guard.margin:
        raise ValueError(
            f"freq_step_cpd={df} aliases: the scene's blur ({p.radius:.1f} arcmin) needs "
            f"freq_step_cpd <= {p.df_guard * p.guard.margin:.3g} cpd")
    sampling = Sampling(df, edge_width_samples=p.overrides.edge_width_samples)
    bands = p.bands(sampling)
    p.reasons.append(f"field guard only (estimate_accuracy=False): df {df:.4g} cpd")
    p.errors.update(pupil=float("nan"), psf_wrap=float("nan"), total=float("nan"))
    return p.plan(sampling, bands, {}, {})


def _accuracy_plan(p: _Planning) -> Plan:
    """The frequency step (and the MFT's pupil samples) the proxy's estimates accept, the
    cheaper neighbours and why they fail, and the plan's error totals."""
    s, t, o = p.scene, p.targets, p.overrides
    spectrum = make_spectrum(p.wl, s.options, weights=p.weights)
    proxy = Proxy(s, spectrum, o.edge_width_samples)
    pairs = (s.pair_acc, s.pair_depth)  # all of them: the error peaks anywhere
    if o.freq_step_cpd is not None:
        if o.freq_step_cpd > p.df_guard * p.guard.margin:
            raise ValueError(
                f"freq_step_cpd={o.freq_step_cpd} aliases: the scene's blur ({p.radius:.1f} arcmin) "
                f"needs freq_step_cpd <= {p.df_guard * p.guard.margin:.3g} cpd"
            )
        df_candidates = [float(o.freq_step_cpd)]
    else:
        df_candidates = [p.df_top / 2.0 ** (k / STEPS_PER_OCTAVE) for k in range(0, 24)]
    estimates = Estimates(proxy, pairs, df_candidates[0],
                          p.budget if math.isfinite(p.budget) else 1e-3)
    # what the wavelength step left of the D / cpd targets (all of them for a given spectrum)
    peak_budget = cutoff_budget = None
    if t.peak_D is not None:
        peak_budget = t.peak_D - np.nan_to_num(p.errors.get("spectral_peak_D", 0.0))
    if t.cutoff_cpd is not None:
        cutoff_budget = t.cutoff_cpd - np.nan_to_num(p.errors.get("spectral_cutoff_cpd", 0.0))
    fft_plan, mft_field = _search_frequency_step(p, estimates, df_candidates, peak_budget,
                                                 cutoff_budget)
    df_fft, e_pupil_fft, wrap_fft = fft_plan

    n_modes = np.shape(s.eyes_zernike_um)[-1] if s.eyes is not None else 15
    if p.order_kept is not None:
        n_modes = min(n_modes, n_modes_for_order(p.order_kept))
    n_states = s.accommodation.size
    fft_sampling = Sampling(df_fft, edge_width_samples=o.edge_width_samples)
    fft_bands = p.bands(fft_sampling)
    cost = {"fft": cost_s(fft_bands, s.layout.n_subapertures, n_states, n_modes, fft_sampling)}
    mft_plan = _plan_mft(p, estimates, mft_field, df_fft, cost, n_states, n_modes)
    use_mft = mft_plan is not None and (
        o.transform == "mft" or (o.transform == "auto" and cost["mft"] < cost["fft"])
    )
    cheaper: dict = {}
    errors, budget = p.errors, p.budget
    if use_mft:
        sampling, errors["pupil"], errors["psf_wrap"], bands = mft_plan
        p.reasons.append(
            f"MFT: {sampling.mft_pupil_samples} pupil samples (VSOTF error {errors['pupil']:.2g}), "
            f"df {sampling.freq_step_cpd:.4g} cpd; modelled {cost['mft']:.3g} s vs FFT {cost['fft']:.3g} s per eye"
        )
        m = sampling.mft_pupil_samples
        cheaper_m = max([x for x in MFT_PUPIL_LADDER if x < m], default=None)
        if cheaper_m is not None:
            e = estimates.mft(sampling.freq_step_cpd, cheaper_m)
            cheaper["pupil"] = (dataclasses.replace(sampling, mft_pupil_samples=cheaper_m),
                                f"{cheaper_m} MFT pupil samples: VSOTF error {e:.2g} > budget {budget:.2g}")
    else:
        sampling, errors["pupil"], errors["psf_wrap"], bands = fft_sampling, e_pupil_fft, wrap_fft, fft_bands
        d_min, wl = s.smallest_diameter_mm, p.wl
        p.reasons.append(
            f"FFT: df {df_fft:.4g} cpd → {d_min / (float(wl.max()) * 1e-6 * df_fft * DEGREES_PER_RADIAN):.1f} "
            f"pupil samples across the smallest subaperture ({d_min:.3g} mm) at {wl.max():g} nm; "
            f"proxy VSOTF error {e_pupil_fft:.2g} (budget {budget:.2g}), wrapped PSF/peak "
            f"{wrap_fft:.2g} (tolerance {t.psf:g})"
            + (f"; MFT would cost {cost['mft']:.3g} s vs {cost['fft']:.3g} s per eye (modelled)"
               if "mft" in cost else "")
        )
    if o.freq_step_cpd is None:
        _one_step_cheaper(p, estimates, sampling, use_mft, peak_budget, cutoff_budget, cheaper)
    if t.peak_D is not None and not use_mft:
        errors["peak_D"] = np.nan_to_num(errors.get("spectral_peak_D", 0.0)) + \
            estimates.peak_shift(sampling.freq_step_cpd)
        p.reasons.append(f"peaks: proxy shift ≤ {errors['peak_D']:.2g} D (target {t.peak_D:g} D)")
    if t.cutoff_cpd is not None and not use_mft:
        errors["cutoff_cpd"] = np.nan_to_num(errors.get("spectral_cutoff_cpd", 0.0)) + \
            estimates.cutoff_shift(sampling.freq_step_cpd, t.cutoff_threshold)
        p.reasons.append(f"cut-offs: proxy shift ≤ {errors['cutoff_cpd']:.2g} cpd "
                         f"(target {t.cutoff_cpd:g} cpd)")
    errors["total"] = errors["pupil"] + errors["zernike"] + (
        errors["spectral"] if np.isfinite(errors["spectral"]) else 0.0)
    return p.plan(sampling, bands, cost, cheaper)


def _search_frequency_step(p: _Planning, estimates: Estimates, df_candidates, peak_budget,
                           cutoff_budget):
    """Down the ladder from the guard's step: the FFT's first step that meets every target
    and whose wrapped PSF is within ``Targets.psf`` — (df, VSOTF error, wrapped PSF) — and,
    unless the transform is the FFT, the MFT's field step (df, wrapped, truncation error) or
    None."""
    t, o, budget = p.targets, p.overrides, p.budget
    freq_step_cpd, transform = o.freq_step_cpd, o.transform
    fft_plan = None
    mft_field = None
    found_at = None
    for i, df in enumerate(df_candidates):
        if fft_plan is not None and (mft_field is not None or transform == "fft" or i > found_at + 3):
            break
        e_pupil = estimates.vsotf(df)
        meets = e_pupil <= budget
        if meets and peak_budget is not None:
            meets = estimates.peak_shift(df) <= peak_budget
        if meets and cutoff_budget is not None:
            meets = estimates.cutoff_shift(df, t.cutoff_threshold) <= cutoff_budget
        want_fft = fft_plan is None and (meets or freq_step_cpd is not None)
        want_mft = transform != "fft" and mft_field is None
        if not (want_fft or want_mft):
            continue  # the PSF on twice the field is the costly part: only where it decides
        wrapped, truncation = estimates.psf(df)
        psf_ok = wrapped <= t.psf
        # MFT truncates the PSF at the field edge: it may need a finer step than the FFT
        if want_mft and ((psf_ok and truncation <= 0.25 * budget) or freq_step_cpd is not None):
            mft_field = (df, wrapped, truncation)
        if want_fft and (psf_ok or freq_step_cpd is not None):
            fft_plan, found_at = (df, e_pupil, wrapped), i
    if fft_plan is None:
        raise ValueError(
            f"no frequency step down to {df_candidates[-1]:.3g} cpd meets Targets.vsotf="
            f"{t.vsotf} and Targets.psf={t.psf:g}; loosen the target"
        )
    return fft_plan, mft_field


def _plan_mft(p: _Planning, estimates: Estimates, mft_field, df_fft: float, cost: dict,
              n_states: int, n_modes: int):
    """The MFT's plan — (Sampling, VSOTF error, wrapped PSF, bands) — at its field step, with
    the fewest pupil samples that meet the VSOTF budget (or those given); None when the
    transform is the FFT or no field step was found. Adds the MFT's cost to ``cost``."""
    s, o = p.scene, p.overrides
    if o.transform not in ("auto", "mft") or mft_field is None:
        return None
    df_mft = mft_field[0]
    mft_budget = p.budget  # the MFT proxy truncates the PSF itself: its error includes the field's
    if o.mft_pupil_samples is not None:
        ladder = [o.mft_pupil_samples]
    else:
        # start just below the samples the FFT plan puts across the largest view
        fft_samples = s.largest_diameter_mm / (float(p.wl.max()) * 1e-6 * df_fft * DEGREES_PER_RADIAN)
        start = max([i for i, m in enumerate(MFT_PUPIL_LADDER) if m <= 0.6 * fft_samples], default=0)
        while start > 0 and estimates.mft(df_mft, MFT_PUPIL_LADDER[start]) <= mft_budget:
            start -= 1
        ladder = list(MFT_PUPIL_LADDER[start:])
    for m in ladder:
        e = estimates.mft(df_mft, m)
        if e <= mft_budget or o.mft_pupil_samples is not None:
            sampling = Sampling(df_mft, edge_width_samples=o.edge_width_samples, transform="mft",
                                mft_pupil_samples=m)
            bands = p.bands(sampling)
            cost["mft"] = cost_s(bands, s.layout.n_subapertures, n_states, n_modes, sampling)
            return sampling, e, mft_field[1], bands
    return None


def _one_step_cheaper(p: _Planning, estimates: Estimates, sampling: Sampling, use_mft: bool,
                      peak_budget, cutoff_budget, cheaper: dict) -> None:
    """The frequency step one ladder step cheaper, and the reason it fails (in ``cheaper``)."""
    t, budget, df_guard = p.targets, p.budget, p.df_guard
    up = ladder_up(sampling.freq_step_cpd)
    if up > df_guard:
        cheaper["field"] = (dataclasses.replace(sampling, freq_step_cpd=up),
                            f"df {up:.4g} cpd: refused by the aliasing guard (needs ≤ {df_guard:.4g})")
        return
    e, (wrapped_up, _) = estimates.vsotf(up), estimates.psf(up)
    if not use_mft:
        if e > budget:
            cheaper["pupil"] = (dataclasses.replace(sampling, freq_step_cpd=up),
                                f"df {up:.4g} cpd: VSOTF error {e:.2g} > budget {budget:.2g}")
        elif peak_budget is not None and estimates.peak_shift(up) > peak_budget:
            cheaper["pupil"] = (dataclasses.replace(sampling, freq_step_cpd=up),
                                f"df {up:.4g} cpd: peaks shift {estimates.peak_shift(up):.2g} D "
                                f"> {peak_budget:.2g} D")
        elif (cutoff_budget is not None
              and estimates.cutoff_shift(up, t.cutoff_threshold) > cutoff_budget):
            cheaper["pupil"] = (dataclasses.replace(sampling, freq_step_cpd=up),
                                f"df {up:.4g} cpd: cut-offs shift "
                                f"{estimates.cutoff_shift(up, t.cutoff_threshold):.2g} cpd "
                                f"> {cutoff_budget:.2g} cpd")
    if wrapped_up > t.psf:
        cheaper["field"] = (dataclasses.replace(sampling, freq_step_cpd=up),
                            f"df {up:.4g} cpd: wrapped PSF/peak {wrapped_up:.2g} > {t.psf:g}")


# ----------------------------------------------------------------------------- helpers


def _order_rms_um(zernike_um, measured_pupil_mm: float, pupil_mm: float) -> dict[int, float]:
    """Largest (over eyes) wavefront RMS of each radial order inside the calculation pupil, µm."""
    z = np.asarray(zernike_um, float).reshape(-1, np.shape(zernike_um)[-1])
    n = 48
    t = (np.arange(n) + 0.5) / n * 2.0 - 1.0
    xx, yy = np.meshgrid(t, t)
    inside = xx * xx + yy * yy <= 1.0
    scale = pupil_mm / measured_pupil_mm
    basis = zernike_basis_host(z.shape[1], xx * scale, yy * scale)[:, inside]
    orders = np.array([nm_from_ansi(j)[0] for j in range(z.shape[1])])
    out = {}
    for order in np.unique(orders):
        largest = 0.0
        # blocks of eyes: each eye's wavefront takes 1804 floats here, so the whole
        # population at once would need 14 KB per eye (14 GB for a million)
        for first in range(0, z.shape[0], EYE_BLOCK):
            w = z[first:first + EYE_BLOCK, orders == order] @ basis[orders == order]
            w = w - w.mean(axis=1, keepdims=True)
            largest = max(largest, float(np.sqrt((w * w).mean(axis=1)).max()))
        out[int(order)] = largest
    return out


PEAK_NEIGHBOURHOOD_D = np.round(np.arange(-3, 4) * 0.1, 9)
"""States (D from each rendered depth) where the wavelength step's proxy reads peaks and
cut-offs: fine enough for a parabola vertex whatever the scene's accommodation grid (on a
0.5 D grid the scene's own states near a depth would be one), wide enough to hold the
aberration-free proxy's peak."""


def _peak_neighbourhood(pair_depth) -> tuple[np.ndarray, np.ndarray]:
    """(accommodation, depth) pairs: every rendered depth ± :data:`PEAK_NEIGHBOURHOOD_D`,
    states ≥ 0 D (the hyperopic limit)."""
    depths = np.unique(np.asarray(pair_depth, float))
    acc = depths[:, None] + PEAK_NEIGHBOURHOOD_D[None, :]
    dep = np.broadcast_to(depths[:, None], acc.shape)
    keep = acc >= -1e-9
    return np.clip(acc[keep], 0.0, None), dep[keep]


__all__ = ["Plan", "Targets", "Overrides", "FieldGuard", "plan_sampling", "ladder_floor",
           "ladder_up", "STEPS_PER_OCTAVE", "MFT_PUPIL_LADDER", "WAVELENGTH_STEPS_NM",
           "SPECTRAL_REFERENCE_STEP_NM", "PEAK_NEIGHBOURHOOD_D", "TRANSFORMS", "SPECTRAL_RULES",
           "GAUSS_NODE_CANDIDATES"]
