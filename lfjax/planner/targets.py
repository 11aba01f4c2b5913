"""What a plan must meet (:class:`Targets`) and what its caller fixes (:class:`Overrides`,
:class:`FieldGuard`): small frozen objects, each checked when built, that
:func:`lfjax.planner.plan.plan_sampling` takes.
"""

from __future__ import annotations

from dataclasses import dataclass

TRANSFORMS = ("fft", "mft", "auto")
"""The transforms a plan may choose: the FFT, the MFT, or the cheaper of the two."""

SPECTRAL_RULES = ("uniform", "auto")
"""How a planned spectrum may sample its range: ``"uniform"``, a step from
:data:`lfjax.planner.spectral_step.WAVELENGTH_STEPS_NM`; ``"auto"``, that step or the Gauss
rule for V(λ) (:func:`lfjax.model.spectral.gauss_rule`), whichever meets the targets with
fewer wavelengths."""


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


__all__ = ["Targets", "Overrides", "FieldGuard", "TRANSFORMS", "SPECTRAL_RULES"]
