"""One plan's working state: what :func:`lfjax.planner.plan.plan_sampling` has settled so far,
passed from step to step (Zernike order, field guard, wavelength step, frequency step).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from lfjax.base.sampling import Sampling, wavelength_bands
from lfjax.kernel.optics import field_radius_arcmin
from lfjax.model.spectral import Spectrum
from lfjax.planner.scene import PlanScene
from lfjax.planner.targets import FieldGuard, Overrides, Targets


@dataclass
class PlanningState:
    """What :func:`~lfjax.planner.plan.plan_sampling` has settled so far (one plan's working
    state; each step reads it and adds its choice, errors and reasons)."""

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


    def bands(self, sampling: Sampling) -> tuple:
        """The wavelength bands and FFT sizes ((start, stop, n_fft), …) of ``sampling`` on the
        chosen wavelengths."""
        return wavelength_bands(self.wl, self.scene.window_mm, self.scene.pupil_diameter_mm,
                                sampling)


__all__ = ["PlanningState"]
