"""Sampling planner: the cheapest sampling that meets an accuracy target, with its reasons.

"Model no more than a scene needs." In lfjax's FFT path one number, the frequency step df
(cpd), fixes the numerics: the PSF field is 60/df arcmin (the blur must fit or it wraps)
and the pupil is sampled at λ·df per wavelength (d/(λ·df) samples across a subaperture of
diameter d). The matrix Fourier transform path (``Sampling(transform="mft")``) separates
the two: df sets the field, ``mft_pupil_samples`` the pupil sampling. The planner also
chooses the wavelength step and the Zernike order the eyes need.

:func:`plan_sampling` takes the scene it plans for (:class:`~lfjax.planner.scene.PlanScene`)
and what the plan must meet (:class:`~lfjax.planner.targets.Targets`), and optionally fixed
choices (:class:`~lfjax.planner.targets.Overrides`) and the field guard's knobs
(:class:`~lfjax.planner.targets.FieldGuard`): small frozen objects, each checked when built
(:mod:`~lfjax.planner.targets`). Each step reads and extends one
:class:`~lfjax.planner.state.PlanningState`. How each choice is made (all on the host, in
numpy; 1–30 s per plan):

* **Field (frequency step).** Hard limit: the pipeline's aliasing guard
  (:func:`lfjax.kernel.optics.field_radius_arcmin`, geometric blur + display shifts + diffraction
  + the eyes' ray angles); the search down the ladder is :mod:`~lfjax.planner.frequency_step`. Within it, the PSF that wraps back into the field is *measured*
  on a proxy (:mod:`lfjax.planner.proxy`): the largest ratio of wrapped intensity to the
  PSF's peak must stay within ``Targets.psf``.
* **Pupil sampling.** The VSOTF error of the discretised, soft-edged aperture is *measured*
  on the proxy, at every (depth, state) pair of the scene: the candidate's distance from
  one converged proxy value (Richardson, order 2, from a half and a quarter of the largest
  admissible step, or a quarter and an eighth for tight targets), × ``ESTIMATE_SAFETY``.
* **Wavelength step** (when only a range is given; :mod:`~lfjax.planner.spectral_step`):
  proxy through-focus curves at each candidate step against a 5 nm reference; the step must
  keep the VSOTF error within its share of the tolerance and leave every proxy peak where it
  was.
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

Steps are taken from fixed ladders (df = 2^(k/8) cpd, :mod:`~lfjax.planner.ladder`; pupil
samples 16, 20, 24, 32, …), so
"one step cheaper" is well defined: :attr:`Plan.cheaper` lists it for every dimension.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from lfjax.base.sampling import EYE_BLOCK, Sampling
from lfjax.base.units import DEGREES_PER_RADIAN
from lfjax.base.zernike import n_modes_for_order, nm_from_ansi, zernike_basis_host
from lfjax.model.options import ModelOptions
from lfjax.model.spectral import Spectrum, make_spectrum
from lfjax.planner.cost import fft_work
from lfjax.planner.frequency_step import accuracy_sampling, guard_only_sampling
from lfjax.planner.ladder import ladder_floor
from lfjax.planner.scene import PlanScene
from lfjax.planner.spectral_step import choose_wavelength_step
from lfjax.planner.state import PlanningState
from lfjax.planner.targets import FieldGuard, Overrides, Targets


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



def plan_sampling(scene: PlanScene, targets: Targets = Targets(), *,  # noqa: B008 (frozen)
                  estimate_accuracy: bool = True, overrides: Overrides = Overrides(),  # noqa: B008
                  guard: FieldGuard = FieldGuard()) -> Plan:  # noqa: B008
    """Choose the cheapest sampling that meets ``targets`` for ``scene``, and say why.

    Parameters
    ----------
    scene : :class:`~lfjax.planner.scene.PlanScene` — the layout, pupil, CDP, the pairs the
        computation evaluates, the spectrum (given, or a range whose step is planned), the
        eyes, options and display
    targets : :class:`~lfjax.planner.targets.Targets` — the VSOTF error, peak shift (D),
        cut-off shift (cpd) and wrapped PSF the plan must keep within (default: a VSOTF
        error of 1e-3)
    estimate_accuracy : False skips the proxy for the frequency step (the field guard alone
        picks it, in a few milliseconds; its errors are reported as NaN). A spectrum given
        as a range still gets its step planned for ``targets``.
    overrides : :class:`~lfjax.planner.targets.Overrides` — choices fixed by the caller
        (frequency step, transform, MFT pupil samples, wavelength step, Zernike order,
        aperture edge)
    guard : :class:`~lfjax.planner.targets.FieldGuard` — the field guard's margin, wrap
        tolerance and floor on pupil samples

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
    p = PlanningState(scene, targets, overrides, guard)
    _choose_zernike_order(p)
    _apply_field_guard(p)
    choose_wavelength_step(p)
    if not estimate_accuracy:
        return _finish(p, *guard_only_sampling(p))
    return _finish(p, *accuracy_sampling(p))




def _finish(p: PlanningState, sampling: Sampling, bands: tuple, cost: dict,
            cheaper: dict) -> Plan:
    """The :class:`Plan` of ``p`` at ``sampling`` (its bands, modelled cost per eye and
    cheaper neighbours)."""
    s = p.scene
    weights = None if p.weights is None else tuple(float(w) for w in p.weights)
    return Plan(sampling, tuple(float(x) for x in p.wl), p.order_kept,
                float(p.radius), float(p.df_guard), p.errors, cost, cheaper, bands,
                fft_work(bands, s.layout.n_subapertures), s.options, p.reasons, weights,
                p.rule)


def _choose_zernike_order(p: PlanningState) -> None:
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


def _apply_field_guard(p: PlanningState) -> None:
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



__all__ = ["Plan", "plan_sampling"]
