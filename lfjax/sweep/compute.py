"""A sweep's numerics: one compiled call per (pupil, layout) and chunk of eyes.

:func:`build_tasks` turns a :class:`~lfjax.sweep.config.SweepConfig` into one
:class:`Task` per (pupil, layout): the scene, the accommodation grid, the sampling (planned
once on the whole population, so every chunk sees the same grid) and the static pipeline
configuration. :class:`ChunkEvaluator` compiles each task's chunk function once — the
pipeline (:func:`lfjax.kernel.pipeline.retinal_metrics`), the grid and continuous peaks
(:func:`lfjax.vision.peaks.peaks_from_grid`) and the MTF cut-off, all inside one ``jit`` — and
re-uses it for every chunk of the same size; it counts traces, so a recompilation per chunk
is caught, not merely slow. With several local devices the eye axis is split over them with
``shard_map`` over a one-axis :class:`jax.sharding.Mesh` (each device runs its eyes' FFTs;
plain ``jit`` with a ``NamedSharding`` would all-gather the FFT batch: XLA does not
partition an FFT along its batch axis).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import jax
import jax.numpy as jnp
import numpy as np
from jax.sharding import Mesh
from jax.sharding import PartitionSpec as P

from lfjax.display.spectra import display_spectrum
from lfjax.model.eyes import Eyes, append_average_eye, sample_eyes
from lfjax.model.layout_files import load_layout_json
from lfjax.model.layouts import Layout, paper_layouts
from lfjax.kernel.metrics import cutoff_frequency
from lfjax.kernel.optics import validate_coefficients
from lfjax.vision.peak_options import METRICS, PeakOptions
from lfjax.vision.peaks import peaks_from_grid
from lfjax.vision.viewing import Viewing
from lfjax.kernel.pipeline import Accommodation, PipelineConfig, Scene, reference_normalisers, retinal_metrics
from lfjax.planner.cache import cached_plan_sampling
from lfjax.planner.plan import Plan
from lfjax.planner.targets import Overrides, Targets
from lfjax.planner.scene import PlanScene
from lfjax.base.sampling import Sampling
from lfjax.model.spectral import Spectrum, make_spectrum
from lfjax.vision.prepare import States, prepare, with_aliasing_retry
from lfjax.model.strips import strip_layout
from lfjax.sweep.config import SweepConfig
from lfjax.sweep.config_keys import strip_views

FREQUENCIES_CPD = np.arange(0.0, 61.0, 1.0)
"""Frequency axis (cpd) of the stored MTF at the predicted accommodation (claim 5 reads
0–60 cpd)."""


@dataclass(frozen=True, eq=False)
class Task:
    """One (pupil, layout) of a sweep: what its compiled chunk function computes.

    Attributes
    ----------
    pupil_index, layout_index : positions on the store's ``pupil`` and ``layout`` axes
    pupil_mm : calculation pupil, mm
    layout_label : the entry of ``SweepConfig.layouts`` (a paper name or a JSON path)
    layout : the Layout, mm
    depth_slots : indices of the store's ``depth`` axis this task fills (natural view: the
        CDP only)
    depths_D : (n_depth,) rendered depths, D
    allowed : (n_depth, n_acc) bool, states within the window (and ≥ 0 D)
    scene, accommodation : pipeline pytrees
    sampling : Sampling used (planned on the whole population or given)
    pipeline_config : static configuration of the compiled function
    spectrum : the wavelengths and weights this task sums (:func:`sweep_spectra`: its own
        planned rule, or the sweep's shared spectrum); None: the evaluator's
    """

    pupil_index: int
    layout_index: int
    pupil_mm: float
    layout_label: str
    layout: Layout
    depth_slots: tuple[int, ...]
    depths_D: np.ndarray
    allowed: np.ndarray
    scene: Scene
    accommodation: Accommodation
    sampling: Sampling
    pipeline_config: PipelineConfig
    spectrum: Spectrum | None = None

    @property
    def key(self) -> tuple[int, int]:
        return self.pupil_index, self.layout_index


def population(config: SweepConfig) -> tuple[Eyes, np.ndarray]:
    """All eyes of a sweep in store order (virtual eyes, then the average eye if asked), and
    the ``is_average`` flag of each."""
    eyes = sample_eyes(int(config.seed), int(config.n_eyes), config.fit_pupil_mm)
    flags = np.zeros(config.n_eyes, bool)
    if config.average_eye:
        eyes = append_average_eye(eyes)
        flags = np.concatenate([flags, [True]])
    return eyes, flags


def sweep_spectrum(config: SweepConfig) -> Spectrum:
    """The spectrum shared by every (pupil, layout) of a sweep with a wavelength step: V(λ)
    white on the config's grid, or the display's white (``display_spectrum``, cells of the
    grid's step) on the wavelengths that carry it. Without a step in ``wavelengths_nm`` each
    (pupil, layout) has its own planned rule (:func:`sweep_spectra`, what the sweep uses);
    this then returns the uniform grid at :func:`planned_wavelength_step`, the one spectrum
    the sweep shared before its rules were planned per layout."""
    if config.display_spectrum is not None:
        return display_spectrum(config.display_spectrum, "white", config.options,
                                step_nm=max(float(config.wavelengths_nm[2]), 5.0))
    if config.wavelength_step_planned:
        start, stop = config.wavelengths_nm
        step = planned_wavelength_step(config)
        return make_spectrum(np.round(np.arange(start, stop + 1e-6, step), 9), config.options)
    return make_spectrum(config.wavelength_grid_nm, config.options)


def sweep_spectra(config: SweepConfig) -> dict[tuple[int, int], Spectrum]:
    """The spectrum of each (pupil_index, layout_index): with a step in ``wavelengths_nm``
    (or a display's spectrum) the shared :func:`sweep_spectrum`; without one, each
    (pupil, layout)'s planned rule (:func:`spectral_plans`: a uniform step or the Gauss rule
    in V(λ), whichever meets the targets with fewer wavelengths)."""
    if config.wavelength_step_planned and config.display_spectrum is None:
        return {key: plan.spectrum() for key, plan in spectral_plans(config).items()}
    shared = sweep_spectrum(config)
    return {(pi, li): shared for pi in range(len(config.pupil_diameters_mm))
            for li in range(len(config.layouts))}


def spectral_plans(config: SweepConfig, rule: str = "auto") -> dict[tuple[int, int], Plan]:
    """For a sweep whose ``wavelengths_nm`` gives no step, each (pupil_index, layout_index)'s
    plan of its spectrum (:func:`lfjax.planner.plan.plan_sampling` with
    ``Overrides(spectral_rule=rule)``): the coarsest uniform step whose proxy peaks stay within
    ``peak_tolerance_D`` and cut-offs within ``cutoff_tolerance_cpd`` or, with ``rule="auto"``,
    the Gauss rule for V(λ) with the fewest nodes that does so when they are fewer
    wavelengths (:attr:`~lfjax.planner.plan.Plan.spectral_rule`, its reasons say why).
    Eye-independent and deterministic (a resumed sweep plans the same rules); 5–15 s per
    (pupil, layout) the first time, then remembered (:mod:`lfjax.planner.cache`: in the
    process and, from the command line, on disk)."""
    start, stop = config.wavelengths_nm
    all_depths = config.depths_D
    cdp = all_depths[[int(np.argmin(np.abs(all_depths - config.cdp_D)))]]
    plans = {}
    for pi, pupil in enumerate(config.pupil_diameters_mm):
        for li, entry in enumerate(config.layouts):
            layout = resolve_layout(config, entry, pupil)
            plans[(pi, li)] = cached_plan_sampling(PlanScene(
                layout=layout, pupil_diameter_mm=pupil, cdp_D=config.cdp_D,
                depths_D=cdp if entry == "natural" else all_depths,
                accommodation_D=config.accommodation_D, accommodation_window_D=config.window_D,
                wavelength_range_nm=(start, stop), options=config.options,
                display=config.display_optics(entry, layout),
            ), Targets(vsotf=None, peak_D=config.peak_tolerance_D,
                       cutoff_cpd=config.cutoff_tolerance_cpd,
                       cutoff_threshold=config.cutoff_threshold), estimate_accuracy=False,
                overrides=Overrides(spectral_rule=rule))
    return plans


def planned_wavelength_step(config: SweepConfig) -> float:
    """The uniform wavelength step (nm) of a sweep whose ``wavelengths_nm`` gives none, as
    the sweep shared it before its rules were planned per layout: for every (pupil, layout)
    the planner's coarsest step meeting the targets (:func:`spectral_plans` with
    ``rule="uniform"``), and the finest of those."""
    start, stop = config.wavelengths_nm
    steps = []
    for plan in spectral_plans(config, "uniform").values():
        wl = plan.wavelengths_nm
        steps.append(float(wl[1] - wl[0]) if len(wl) > 1 else float(stop - start))
    return min(steps)


def resolve_layout(config: SweepConfig, entry: str, pupil_mm: float) -> Layout:
    """A paper layout sized to ``pupil_mm`` (mm), a ``1xN`` strip layout across it (pitch
    ``pupil_mm``/N, width ``strip_width_ratio`` times the pitch:
    :func:`lfjax.model.strips.strip_layout`), or the layout of a JSON file."""
    n = strip_views(entry)
    if n is not None:
        pitch = float(pupil_mm) / n
        return strip_layout(n, pupil_mm, pitch_mm=pitch,
                            width_mm=config.strip_width_ratio * pitch)
    path = config.layout_path(entry)
    if path is None:
        return paper_layouts(pupil_mm)[entry]
    return load_layout_json(path)[0]


def layout_name(entry: str) -> str:
    """The store's label of a layout entry (a paper name, or the JSON file's stem)."""
    return entry if not entry.endswith(".json") else entry.rsplit("/", 1)[-1][: -len(".json")]


def _plan(config: SweepConfig, eyes: Eyes, entry: str, layout: Layout, pupil_mm: float, depths,
          pairs, spectrum: Spectrum) -> Sampling:
    plan = cached_plan_sampling(PlanScene(
        layout=layout, pupil_diameter_mm=pupil_mm, cdp_D=config.cdp_D,
        depths_D=np.asarray(depths, float), accommodation_window_D=None, pairs=pairs,
        wavelengths_nm=np.asarray(spectrum.wavelengths_nm),
        spectral_weights=np.asarray(spectrum.weights), eyes=eyes, options=config.options,
        display=config.display_optics(entry, layout),
    ), Targets(vsotf=config.vsotf_tolerance or 1e-3),
        estimate_accuracy=config.vsotf_tolerance is not None,
        overrides=Overrides(freq_step_cpd=config.freq_step_cpd))
    return plan.sampling


def build_tasks(config: SweepConfig, eyes: Eyes, spectrum: Spectrum | None = None,
                samplings: dict | None = None, spectra: dict | None = None) -> list[Task]:
    """One :class:`Task` per (pupil, layout), sampling checked against the whole population.

    ``spectrum``: one spectrum for every task; else ``spectra`` ({(pupil_index,
    layout_index): Spectrum}, a resumed store's) or each task's planned one
    (:func:`sweep_spectra`).

    ``samplings`` maps (pupil_index, layout_index) to a
    :class:`~lfjax.base.sampling.Sampling` to use instead of planning (a resumed store's);
    otherwise the planner's field guard (or its accuracy target, ``vsotf_tolerance``) picks
    the step, made finer while the aliasing guard still refuses it
    (:func:`lfjax.vision.prepare.with_aliasing_retry`). Each task is prepared by
    :func:`lfjax.vision.prepare.prepare`.
    """
    if spectrum is None and spectra is None:
        spectra = sweep_spectra(config)
    validate_coefficients(np.asarray(eyes.zernike_um))  # before planning reads the eyes
    all_depths = config.depths_D
    cdp_slot = int(np.argmin(np.abs(all_depths - config.cdp_D)))
    tasks = []
    for pi, pupil in enumerate(config.pupil_diameters_mm):
        for li, entry in enumerate(config.layouts):
            layout = resolve_layout(config, entry, pupil)
            task_spectrum = spectrum if spectrum is not None else spectra[(pi, li)]
            slots = (cdp_slot,) if entry == "natural" else tuple(range(all_depths.size))
            depths = all_depths[list(slots)]
            states = States.grid(config.accommodation_D, depths, config.window_D)

            # inputs are checked here on the host (config, population, layout files), so the
            # program carries no traced checks: JAX's persistent cache can then keep it for
            # the next process (a resumed sweep, another host)
            def prepared_at(sampling, check_aliasing=True, layout=layout, states=states,
                            pupil=pupil, spectrum=task_spectrum, entry=entry):
                viewing = Viewing(pupil_diameter_mm=pupil, cdp_D=config.cdp_D,
                                  display=config.display_optics(entry, layout))
                return prepare(eyes, layout, states, viewing, spectrum=spectrum,
                               options=config.options, sampling=sampling,
                               check_aliasing=check_aliasing, traced_checks=False)

            if samplings is not None and (pi, li) in samplings:
                prepared = prepared_at(samplings[(pi, li)], check_aliasing=False)
            else:
                prepared, _ = with_aliasing_retry(
                    prepared_at, _plan(config, eyes, entry, layout, pupil, depths,
                                       states.pairs, task_spectrum),
                    refine=config.freq_step_cpd is None, what=f"layout {entry} at {pupil:g} mm")
            tasks.append(Task(
                pi, li, float(pupil), entry, layout, slots, depths, states.allowed,
                prepared.scene, prepared.accommodation(config.options), prepared.sampling,
                prepared.config, task_spectrum,
            ))
    return tasks


# --------------------------------------------------------------------------- one chunk


def sweep_peaks(config) -> PeakOptions:
    """How a sweep refines its peaks: ``config``'s metrics, method and tolerance; second
    peaks stay grid-located (a sweep stores the global peak)."""
    return PeakOptions(metrics=tuple(config.continuous_peaks), method=config.peak_method,
                       tolerance_D=float(config.peak_tolerance_D), second_peaks=False)


def _chunk_metrics(zernike_um, scene: Scene, spectrum: Spectrum, accommodation: Accommodation, *,
                   config: PipelineConfig, measured_pupil_mm: float, allowed: np.ndarray,
                   peaks: PeakOptions, cutoff_threshold: float):
    """Everything a sweep stores for a batch of eyes of one (pupil, layout), as arrays with
    the eye axis first. Pure; the caller jits (and shards) it."""
    eyes = Eyes(zernike_um, measured_pupil_mm)
    reference = reference_normalisers(scene, spectrum, accommodation, config)
    metrics = retinal_metrics(eyes, scene, spectrum, accommodation, config, reference)
    mask = jnp.asarray(allowed)
    n_fft, df = config.n_fft, config.freq_step_cpd
    native_f = jnp.arange(n_fft // 2 + 1) * df
    out = {}
    indices, values, cutoffs, mtfs = [], [], [], []
    for name in METRICS:
        curve = getattr(metrics, name)
        index = jnp.argmax(jnp.where(mask, curve, -jnp.inf), axis=-1)  # (n_eyes, n_depth)
        indices.append(index.astype(jnp.int32))
        values.append(jnp.take_along_axis(curve, index[..., None], -1)[..., 0])
        mtf = jnp.take_along_axis(metrics.radial_mtf, index[..., None, None], axis=2)[:, :, 0]
        cutoffs.append(cutoff_frequency(mtf, native_f, cutoff_threshold))
        # 0 beyond the native grid, which ends past the optical cut-off
        mtfs.append(_interp_last(FREQUENCIES_CPD, native_f, mtf))
    out["vsotf"] = jnp.where(mask, metrics.vsotf, jnp.nan)
    out["strehl"] = jnp.where(mask, metrics.strehl, jnp.nan)
    out["grid_index"] = jnp.stack(indices, -1)
    out["peak_value"] = jnp.stack(values, -1)
    out["cutoff_frequency"] = jnp.stack(cutoffs, -1)
    out["mtf_at_peak"] = jnp.stack(mtfs, -2)
    cont_acc, cont_ok = [], []
    for name in METRICS:
        if name in peaks.metrics:
            found = peaks_from_grid(getattr(metrics, name), eyes, scene, spectrum, accommodation,
                                    config, reference, name, peaks, mask)
            cont_acc.append(found.accommodation_D)
            cont_ok.append(found.success)
        else:
            cont_acc.append(jnp.full(metrics.vsotf.shape[:2], jnp.nan, metrics.vsotf.dtype))
            cont_ok.append(jnp.zeros(metrics.vsotf.shape[:2], bool))
    out["continuous"] = jnp.stack(cont_acc, -1)
    out["continuous_success"] = jnp.stack(cont_ok, -1)
    return out


def _interp_last(x_new, x, y):
    """Linear interpolation of y (…, n) sampled at x (n,) onto x_new (host constant); 0
    beyond x[-1]."""
    x_new = jnp.asarray(x_new, y.dtype)
    idx = jnp.clip(jnp.searchsorted(x, x_new, side="right") - 1, 0, x.shape[0] - 2)
    w = jnp.clip((x_new - x[idx]) / (x[idx + 1] - x[idx]), 0.0, 1.0)
    out = y[..., idx] * (1.0 - w) + y[..., idx + 1] * w
    return jnp.where(x_new <= x[-1] + 1e-6, out, 0.0)


# Compiled chunk functions live for the process, keyed by everything static about them, so
# a second sweep (or a resumed one) of the same scene re-uses them; TRACES counts traces per
# key, which is how a recompilation is detected.
TRACES: dict[tuple, int] = {}


@functools.lru_cache(maxsize=64)
def _chunk_function(config: PipelineConfig, measured_pupil_mm: float, allowed: tuple,
                    peaks: PeakOptions, cutoff_threshold: float, devices: tuple):
    key = (config, measured_pupil_mm, allowed, peaks, cutoff_threshold, devices)
    body = functools.partial(
        _chunk_metrics, config=config, measured_pupil_mm=measured_pupil_mm,
        allowed=np.asarray(allowed, bool), peaks=peaks, cutoff_threshold=cutoff_threshold)

    def counted(zernike_um, scene, spectrum, accommodation):
        TRACES[key] = TRACES.get(key, 0) + 1
        return body(zernike_um, scene, spectrum, accommodation)

    if len(devices) > 1:
        mesh = Mesh(np.asarray(devices), ("eye",))
        counted = jax.shard_map(counted, mesh=mesh, in_specs=(P("eye"), P(), P(), P()),
                                out_specs=P("eye"), check_vma=False)
    return key, jax.jit(counted)


class ChunkEvaluator:
    """Compiled chunk functions of a sweep's tasks, sharded over ``devices``.

    ``evaluate(task, zernike_um)`` runs one chunk (``chunk_size`` eyes; a shorter last chunk
    is padded by repeating its last eye, so it re-uses the compiled function) and returns
    host numpy arrays. ``traces`` counts how often each task's function was traced while
    this evaluator ran: at most once per task for a whole sweep (zero when an earlier sweep
    in this process compiled it), which :meth:`assert_no_retrace` checks.
    """

    def __init__(self, config: SweepConfig, measured_pupil_mm: float,
                 spectrum: Spectrum | None = None, devices=None):
        self.config = config
        self.measured_pupil_mm = float(measured_pupil_mm)
        self.spectrum = spectrum
        self.devices = tuple(jax.local_devices() if devices is None else devices)
        n_dev = len(self.devices)
        if int(config.chunk_size) % n_dev:
            raise ValueError(
                f"run.chunk_size ({config.chunk_size}) must be a multiple of the number of local "
                f"devices ({n_dev}) to shard the eye axis over them")
        self.traces: dict[tuple[int, int], int] = {}
        self._start: dict[tuple[int, int], int] = {}

    def _function(self, task: Task):
        key, function = _chunk_function(
            task.pipeline_config, self.measured_pupil_mm,
            tuple(map(tuple, np.asarray(task.allowed, bool).tolist())),
            sweep_peaks(self.config), float(self.config.cutoff_threshold),
            self.devices)
        self._start.setdefault(task.key, TRACES.get(key, 0))
        return key, function

    def evaluate(self, task: Task, zernike_um) -> dict[str, np.ndarray]:
        """One chunk of eyes (n ≤ chunk_size, n_modes) µm → stored quantities (host arrays,
        eye axis first, n rows)."""
        z = np.asarray(zernike_um)
        n = z.shape[0]
        size = int(self.config.chunk_size)
        if n > size:
            raise ValueError(f"a chunk holds at most {size} eyes, got {n}")
        if n < size:
            z = np.concatenate([z, np.repeat(z[-1:], size - n, axis=0)])
        key, function = self._function(task)
        spectrum = task.spectrum if task.spectrum is not None else self.spectrum
        out = function(jnp.asarray(z), task.scene, spectrum, task.accommodation)
        self.traces[task.key] = TRACES.get(key, 0) - self._start[task.key]
        return {k: np.asarray(v)[:n] for k, v in out.items()}

    def assert_no_retrace(self) -> None:
        """Raise if any task's function was traced more than once (a recompilation)."""
        again = {k: v for k, v in self.traces.items() if v > 1}
        if again:
            raise RuntimeError(f"sweep chunk functions were recompiled: traces per "
                               f"(pupil, layout) {again}")


__all__ = [
    "FREQUENCIES_CPD",
    "Task",
    "ChunkEvaluator",
    "build_tasks",
    "population",
    "resolve_layout",
    "layout_name",
    "planned_wavelength_step",
    "spectral_plans",
    "sweep_spectra",
    "sweep_spectrum",
]
