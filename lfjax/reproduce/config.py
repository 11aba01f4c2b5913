"""The study's configuration: what the reproduction computes, on which eyes and sampling.

:class:`StudyConfig` holds the settings (defaults: the paper's experiment;
:meth:`~StudyConfig.quick` for tests, :meth:`~StudyConfig.reduced` for the modelling
alternatives). :func:`study_eyes` draws the virtual eyes plus the average eye.
:func:`planned_sampling` asks :func:`lfjax.planner.plan.plan_sampling` for the frequency step of one
layout's scene. ``METRICS`` and ``LF_LAYOUTS`` name the metrics and the light-field layouts
the study reads.

The bottom layer of :mod:`lfjax.reproduce`: it imports no other part of the package.
"""

from __future__ import annotations

import dataclasses
import json
from dataclasses import dataclass, field

import numpy as np

from lfjax.base.grids import DepthGrid, inclusive_grid
from lfjax.model.eyes import Eyes, append_average_eye, sample_eyes
from lfjax.model.layouts import LF_LAYOUTS as LF_LAYOUTS
from lfjax.model.layouts import PAPER_LAYOUTS
from lfjax.model.options import ModelOptions
from lfjax.planner.cache import cached_plan_sampling
from lfjax.model.spectral import gauss_rule
from lfjax.planner.targets import Overrides, Targets
from lfjax.planner.scene import PlanScene
from lfjax.base.sampling import Sampling

METRICS = ("vsotf", "strehl")

SPECTRAL_RULES = ("auto", "uniform")
"""How ``accuracy="claims"`` may sample each layout's spectrum (:attr:`StudyConfig.spectral_rule`)."""

ACCURACY_PLANS = ("claims", "vsotf")
"""How the study samples the spectrum: ``"claims"`` plans each layout's wavelength step for
what the claims read (peaks to ``peak_tolerance_D``, cut-offs to ``cutoff_tolerance_cpd``);
``"vsotf"`` uses the fixed ``wavelengths_nm`` grid (400–700 nm in 10 nm steps, the plan of
lfjax ≤ 0.3, made for a VSOTF error of 1e-3)."""


@dataclass(frozen=True)
class StudyConfig(DepthGrid):
    """Settings of the reproduction (defaults: the paper's experiment).

    Attributes
    ----------
    n_eyes : int
        Virtual eyes drawn from Thibos et al. (2002), ``sample_eyes(seed, n_eyes)``; the
        average eye is always added as one more eye.
    seed : int
        Seed of the eye draw (0 ≤ seed < 2³²).
    pupil_diameter_mm : float, mm
    cdp_D : float, D
        Central depth plane of the display.
    depth_offsets_D : tuple of float, D
        Rendered depths relative to the CDP (natural view: the CDP only).
    accommodation_step_D, accommodation_max_D : float, D
        Shared absolute accommodation grid 0 … max in steps (the paper's 0.2 D).
    window_D : float, D
        Each rendered depth is evaluated over accommodation states within ±window_D of it
        (and ≥ 0 D, the hyperopic limit). ±2 D keeps the CDP inside the range for every
        depth, which the Strehl-ratio finding for 2×2 viewpoints needs.
    wavelengths_nm : (start, stop, step), nm
    layouts : names from ``lfjax.model.layouts.PAPER_LAYOUTS``
    options : ModelOptions
    cutoff_threshold : float
        MTF value defining the cut-off frequency (paper: 0.05).
    dof_fraction : float
        Depth of field: depth range where the mean cut-off frequency stays ≥ this fraction
        of its best value.
    example_letter_arcmin : float, arcmin
        Snellen E height for the simulated retinal images (Fig. 9).
    alternatives : bool
        Run the modelling-choice alternatives (on a reduced set, see :meth:`reduced`).
    accuracy : ``"claims"`` or ``"vsotf"`` (:data:`ACCURACY_PLANS`)
        ``"claims"`` (default): each layout's wavelength step is planned
        (:func:`lfjax.planner.plan.plan_sampling` over ``wavelengths_nm``' range) so that no
        through-focus peak moves by more than ``peak_tolerance_D`` and no cut-off by more
        than ``cutoff_tolerance_cpd``; ``"vsotf"``: the fixed ``wavelengths_nm`` grid.
        Either way the frequency step is the field guard's.
    peak_tolerance_D : float, D
        Peak target of the ``"claims"`` plan (the claims compare peaks to 0.2 D and
        means to 0.25 D; 0.01 D leaves them a twentieth).
    cutoff_tolerance_cpd : float, cpd
        Cut-off target of the ``"claims"`` plan (the cut-off claims compare layouts that
        differ by several cpd).
    spectral_rule : ``"auto"`` or ``"uniform"`` (:data:`SPECTRAL_RULES`)
        With ``accuracy="claims"``: ``"auto"`` (default) lets the planner take, per layout,
        the Gauss rule for V(λ) with the fewest nodes that meets the same peak and cut-off
        targets when it needs fewer wavelengths than the planned uniform step
        (:attr:`lfjax.planner.plan.Plan.spectral_rule`); ``"uniform"`` keeps the step.
    settle_verdicts : bool
        With ``accuracy="claims"``: compute again at the reference spectrum (``"vsotf"``'s
        uniform steps) the layouts on which a claim's verdict turns when the planned
        spectrum's error could change it (:mod:`lfjax.reproduce.settling`), so that every
        verdict is the one ``--accuracy vsotf`` gives. Off: such verdicts are reported as
        unsettled, with the layouts they turn on.
    wavelength_rules : ((layout, rule, value), ...)
        Spectra fixed per layout instead of planned: ``("2x2", "uniform", 30.0)`` is a 30 nm
        step over ``wavelengths_nm``' range, ``("3x3", "gauss", 6)`` the 6-node Gauss rule
        for V(λ) on it (:func:`lfjax.model.spectral.gauss_rule`). The alternatives reuse the
        main study's plan this way, so each change is measured on the same spectrum.
    mft_pupil_samples : ((layout, samples), ...)
        Layouts whose elemental PSFs come from the matrix Fourier transform with this many
        pupil samples across a view (:class:`~lfjax.base.sampling.Sampling`), at the field guard's
        frequency step; the others use the FFT. The FFT's pupil step is λ·Δf, so a small
        view gets few samples at long wavelengths (26 across a 4×4 view at 700 nm). On the
        paper's grid (benchmarks/RESULTS.md §9), MFT 48 is twice as accurate as the FFT for
        4×4 (5.4e-4 against 1.1e-3 in VSOTF, the planner's target being 1e-3) at the same
        cost in the whole job; for 3×3 it is as accurate as the FFT, for 2×2 as fast at
        equal accuracy, so those keep the FFT.
    label : str
    """

    n_eyes: int = 10
    seed: int = 0
    pupil_diameter_mm: float = 3.0
    cdp_D: float = 2.0
    depth_offsets_D: tuple[float, ...] = tuple(inclusive_grid(-2.0, 2.0, 0.5).tolist())
    accommodation_step_D: float = 0.2
    accommodation_max_D: float = 5.0
    window_D: float = 2.0
    wavelengths_nm: tuple[float, float, float] = (400.0, 700.0, 10.0)
    layouts: tuple[str, ...] = PAPER_LAYOUTS
    options: ModelOptions = field(default_factory=ModelOptions)
    cutoff_threshold: float = 0.05
    dof_fraction: float = 0.8
    example_letter_arcmin: float = 15.0
    alternatives: bool = True
    mft_pupil_samples: tuple[tuple[str, int], ...] = (("4x4", 48),)
    label: str = "full"
    accuracy: str = "claims"
    peak_tolerance_D: float = 0.01
    cutoff_tolerance_cpd: float = 0.25
    spectral_rule: str = "auto"
    wavelength_rules: tuple[tuple[str, str, float], ...] = ()
    settle_verdicts: bool = False

    def __post_init__(self):
        if int(self.n_eyes) != self.n_eyes or self.n_eyes < 1:
            raise ValueError(f"n_eyes must be an integer >= 1, got {self.n_eyes}")
        if int(self.seed) != self.seed or not (0 <= self.seed < 2**32):
            raise ValueError(f"seed must be an integer in [0, 2**32), got {self.seed}")
        if not (self.accommodation_step_D > 0 and self.accommodation_max_D > 0):
            raise ValueError("accommodation_step_D and accommodation_max_D must be > 0 D")
        if not (self.window_D > 0):
            raise ValueError(f"window_D must be > 0 D, got {self.window_D}")
        if len(self.depth_offsets_D) < 1:
            raise ValueError("depth_offsets_D must hold at least one depth")
        if any(self.cdp_D + d < 0 for d in self.depth_offsets_D):
            raise ValueError("every rendered depth cdp_D + offset must be >= 0 D")
        if 0.0 not in [round(d, 9) for d in self.depth_offsets_D]:
            raise ValueError("depth_offsets_D must include 0 (the CDP)")
        unknown = [name for name in self.layouts if name not in PAPER_LAYOUTS]
        if unknown or not self.layouts:
            raise ValueError(
                f"layouts must be a non-empty subset of {PAPER_LAYOUTS}, got {unknown}"
            )
        if not (0 < self.cutoff_threshold < 1 and 0 < self.dof_fraction < 1):
            raise ValueError("cutoff_threshold and dof_fraction must be in (0, 1)")
        if self.accuracy not in ACCURACY_PLANS:
            raise ValueError(f"accuracy must be one of {ACCURACY_PLANS}, got {self.accuracy!r}")
        if not (0 < self.peak_tolerance_D <= 0.5):
            raise ValueError(f"peak_tolerance_D must be in (0, 0.5] D, got {self.peak_tolerance_D}")
        if not (0 < self.cutoff_tolerance_cpd <= 10):
            raise ValueError(
                f"cutoff_tolerance_cpd must be in (0, 10] cpd, got {self.cutoff_tolerance_cpd}")
        if self.spectral_rule not in SPECTRAL_RULES:
            raise ValueError(f"spectral_rule must be one of {SPECTRAL_RULES}, "
                             f"got {self.spectral_rule!r}")
        if not isinstance(self.settle_verdicts, (bool, np.bool_)):
            raise ValueError(f"settle_verdicts must be True or False, got {self.settle_verdicts!r}")
        if self.settle_verdicts and self.accuracy == "vsotf":
            raise ValueError("settle_verdicts needs accuracy='claims' (--accuracy claims): "
                             "accuracy='vsotf' is the reference spectrum itself")
        for entry in self.wavelength_rules:
            if not _valid_rule(entry):
                raise ValueError(
                    f"wavelength_rules must hold (layout, 'uniform', step in (0, 100] nm) or "
                    f"(layout, 'gauss', integer nodes in [1, 40]) entries with a layout in "
                    f"{PAPER_LAYOUTS}, got {entry!r}")
        for entry in self.mft_pupil_samples:
            if (len(entry) != 2 or entry[0] not in PAPER_LAYOUTS
                    or int(entry[1]) != entry[1] or entry[1] < 16):
                raise ValueError(
                    f"mft_pupil_samples must hold (layout, samples) pairs with a layout in "
                    f"{PAPER_LAYOUTS} and an integer >= 16 samples, got {entry!r}"
                )

    @classmethod
    def quick(cls, n_eyes: int = 2, seed: int = 0, **changes) -> StudyConfig:
        """A small version for tests: 2 eyes, depths CDP−2/CDP/CDP+2, 0.5 D accommodation
        steps, 30 nm wavelength steps, no alternatives."""
        base = dict(
            n_eyes=n_eyes, seed=seed, depth_offsets_D=(-2.0, 0.0, 2.0),
            accommodation_step_D=0.5, wavelengths_nm=(400.0, 700.0, 30.0),
            alternatives=False, label="quick", accuracy="vsotf",
        )
        base.update(changes)
        return cls(**base)

    def reduced(self, wavelength_rules=None) -> StudyConfig:
        """The reduced set on which modelling-choice alternatives run: the same eyes and
        accommodation grid, rendered depths CDP−2 … CDP+2 in 1 D steps (a baseline is rerun
        on the same set, so changes are like for like). Wavelengths: with the ``"claims"``
        plan, ``wavelength_rules`` ({layout: (rule, value)}, the main study's plan,
        :func:`~lfjax.reproduce.study.study_wavelength_rules`) or each layout's own plan;
        with ``"vsotf"``, 20 nm steps."""
        offsets = tuple(d for d in self.depth_offsets_D if abs(d - round(d)) < 1e-9)
        start, stop, step = self.wavelengths_nm
        changes = dict(depth_offsets_D=offsets, alternatives=False, label=f"{self.label}-reduced")
        if self.accuracy == "vsotf":
            changes["wavelengths_nm"] = (start, stop, max(step, 20.0))
        elif wavelength_rules:
            changes["wavelength_rules"] = tuple(
                (name, str(rule), float(value))
                for name, (rule, value) in dict(wavelength_rules).items())
        return dataclasses.replace(self, **changes)

    def reference(self) -> StudyConfig:
        """The configuration whose numbers ``accuracy="vsotf"`` computes for this one's
        set: its fixed wavelength grid and every peak refined (the reference that
        :mod:`lfjax.reproduce.settling` settles verdicts at). A reduced set's reference is the
        reduced set of the full configuration's reference: use ``full.reference().reduced()``."""
        return dataclasses.replace(self, accuracy="vsotf", wavelength_rules=(), settle_verdicts=False)

    def replace(self, **changes) -> StudyConfig:
        return dataclasses.replace(self, **changes)

    @property
    def wavelength_grid_nm(self) -> np.ndarray:
        return inclusive_grid(*self.wavelengths_nm)

    def as_attrs(self) -> dict:
        """Flat, netCDF-safe description (numbers and strings)."""
        out = {}
        for f in dataclasses.fields(self):
            value = getattr(self, f.name)
            if f.name == "options":
                continue
            if isinstance(value, bool):
                value = str(value)
            elif isinstance(value, tuple):
                value = json.dumps(list(value))
            out[f"config_{f.name}"] = value
        return out



# ----------------------------------------------------------------------------- eyes


def study_eyes(config: StudyConfig) -> tuple[Eyes, list[str]]:
    """The virtual eyes and the average eye in one batch (average last), with labels."""
    both = append_average_eye(sample_eyes(int(config.seed), int(config.n_eyes)))
    labels = [f"eye{i + 1:02d}" for i in range(config.n_eyes)] + ["average"]
    return both, labels



# ----------------------------------------------------------------------------- sampling


def planned_sampling(eyes, layout, depths, config, options
                     ) -> tuple[Sampling, np.ndarray, np.ndarray | None]:
    """(Sampling, wavelengths in nm, their weights or None for V(λ)·Δλ) of one layout's scene.

    The frequency step is :func:`lfjax.planner.plan.plan_sampling`'s field guard (the largest
    ladder step whose PSF field holds the blur). The accuracy proxy for the frequency step
    is skipped: it takes 9–27 s per layout on the paper's grid, and for a 1e-3 VSOTF target
    it asks the 3×3/4×4 layouts for about half the guard's step (~4× the compute); at the
    guard's steps its estimate is about 1.7e-3 (benchmarks/RESULTS.md §7). The wavelengths
    are ``config.wavelength_grid_nm`` (``accuracy="vsotf"``), the step fixed in
    ``config.wavelength_rules``, or the rule the planner chooses for the peak and cut-off
    targets (``accuracy="claims"``: a uniform step or, with ``spectral_rule="auto"``, a
    Gauss rule for V(λ) with fewer nodes; 3–15 s of host work per layout the first time; the plan
    is then remembered, in the process and, from the command line, on disk:
    :mod:`lfjax.planner.cache`). The transform is the FFT, or the MFT for the layouts in
    ``config.mft_pupil_samples``."""
    start, stop, _ = config.wavelengths_nm
    fixed = {name: (rule, value) for name, rule, value in config.wavelength_rules}.get(layout.name)
    spectrum = {"wavelengths_nm": config.wavelength_grid_nm}
    targets = Targets()
    overrides = Overrides()
    if config.accuracy == "claims" and fixed is not None:
        rule, value = fixed
        if rule == "gauss":
            nodes, weights = gauss_rule(int(value), start, stop)
            spectrum = {"wavelengths_nm": nodes, "spectral_weights": weights}
        else:
            spectrum = {"wavelengths_nm": inclusive_grid(start, stop, value)}
    elif config.accuracy == "claims":
        overrides = Overrides(spectral_rule=config.spectral_rule)
        spectrum = {"wavelength_range_nm": (start, stop)}
        targets = Targets(vsotf=None, peak_D=config.peak_tolerance_D,
                          cutoff_cpd=config.cutoff_tolerance_cpd,
                          cutoff_threshold=config.cutoff_threshold)
    plan = cached_plan_sampling(PlanScene(
        layout=layout, pupil_diameter_mm=config.pupil_diameter_mm, cdp_D=config.cdp_D,
        depths_D=np.asarray(depths, float), accommodation_D=config.accommodation_D,
        accommodation_window_D=config.window_D, eyes=eyes, options=options, **spectrum,
    ), targets, estimate_accuracy=False, overrides=overrides)
    wavelengths = np.asarray(plan.wavelengths_nm, float)
    weights = None if plan.spectral_weights is None else np.asarray(plan.spectral_weights, float)
    mft_samples = dict(config.mft_pupil_samples).get(layout.name)
    sampling = plan.sampling
    if mft_samples is not None:
        sampling = dataclasses.replace(sampling, transform="mft", mft_pupil_samples=int(mft_samples))
    return sampling, wavelengths, weights


def _valid_rule(entry) -> bool:
    """Is ``entry`` a (layout, rule, value) of :attr:`StudyConfig.wavelength_rules`?"""
    if len(entry) != 3 or entry[0] not in PAPER_LAYOUTS:
        return False
    _, rule, value = entry
    if rule == "uniform":
        return 0 < float(value) <= 100
    return rule == "gauss" and int(value) == value and 1 <= value <= 40


__all__ = [
    "ACCURACY_PLANS",
    "SPECTRAL_RULES",
    "LF_LAYOUTS",
    "METRICS",
    "StudyConfig",
    "planned_sampling",
    "study_eyes",
]
