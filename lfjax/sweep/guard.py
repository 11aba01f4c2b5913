"""What a sweep will cost, known before anything is created: sizes, memory, time, a summary.

:func:`estimate` sizes a sweep from its config (and, once planned, its tasks' FFT sizes):
the store on disk, the host memory of setup and of one chunk, the device memory of one
chunk, and the compute time. :func:`check_fits` refuses, with the numbers, a sweep whose
store exceeds the free disk or whose memory exceeds what this machine has, so that an
impossible sweep fails before a store exists rather than after (RESOURCE_EXHAUSTED,
MemoryError). :meth:`SweepEstimate.summary` is what ``lfjax sweep --dry-run`` prints, and a
normal run prints first.

The figures are estimates: array sizes are exact (dense, uncompressed), the device working
set is the pipeline's largest arrays times a stated allowance for FFT workspaces and
temporaries, and the time model is calibrated on one measured sweep (see
:data:`SECONDS_PER_UNIT`).
"""

from __future__ import annotations

import math
import os
import shutil
from dataclasses import dataclass, field
from pathlib import Path

import jax

from lfjax.kernel.pipeline import held_elemental_planes, transform_units
from lfjax.vision.peak_options import METRICS, resolved_method
from lfjax.vision.peak_refinement import STATE_COST, TYPICAL_REFINED_FRACTION
from lfjax.base.grids import grid_size
from lfjax.base.sampling import EYE_BLOCK
from lfjax.sweep.compute import sweep_spectra
from lfjax.sweep.config import KEYS, SweepConfig
from lfjax.base.units import format_bytes as _bytes
from lfjax.base.units import format_duration as _duration

N_FREQUENCIES = 61  # the stored MTF's 0 ... 60 cpd axis (compute.FREQUENCIES_CPD)
N_MODES = 45  # Zernike coefficients per eye (Thibos et al. 2002: OSA j = 0 ... 44)
GUARD_GRID = 48  # samples across the pupil of the host guards' wavefronts (lfjax.base.sampling)

DEVICE_ALLOWANCE = 3.0
"""Device working set / the pipeline's largest arrays (elemental OTFs and the rendered
block): FFT workspaces, the scan's carry and its update, and XLA temporaries."""

SECONDS_PER_UNIT = 2.2e-9
"""Seconds per cost unit (one complex FFT point·log2 size, or one rendered view-pixel), on 2
CPU cores: the default sweep (``lfjax sweep --template``: 25 nm, ``local`` peaks,
1.78e9 units per eye) computed its chunks at 3.92 s per eye, warm, on 2026-11-26
(benchmarks/RESULTS.md §19). The same machine has run 1.6x faster on other days (§11's
1,000-eye sweep at 20 nm with ``vertex`` peaks: 1.26e-9 s per unit); the first chunks'
eyes/s on the progress bar is the measured rate."""

TYPICAL_STEPS = {"newton": 3, "golden": 31, "bfgs": 12, "adaptive": TYPICAL_REFINED_FRACTION}
"""Typical solver steps per continuous peak (benchmarks/RESULTS.md §10: Newton 2.2, golden
section 31, BFGS 11.5), rounded up; the one-shot methods take one, and ``adaptive`` takes
the local stencil's one on the fraction of peaks it refines."""

REFINEMENT_STATES = {method: STATE_COST[method] * TYPICAL_STEPS.get(method, 1)
                     for method in STATE_COST} | {"vertex": 0, "grid": 0}
"""Accommodation states one continuous peak costs beyond the grid, per (eye, depth), by
method: each step's states (:data:`lfjax.vision.peak_refinement.STATE_COST`: ``local``'s three-point
stencil, Newton's value and two forward derivatives, …) times its typical steps; ``vertex``
and ``grid`` evaluate nothing beyond the grid. Each state transforms every view at every
wavelength, as a grid state does."""


class SweepTooLargeError(ValueError):
    """A sweep that cannot fit this machine (``problems``: one line each, with numbers)."""

    def __init__(self, problems: list[str]):
        self.problems = list(problems)
        lines = "\n".join(f"  - {p}" for p in self.problems)
        super().__init__(f"the sweep cannot run here ({len(self.problems)} problem(s); "
                         f"nothing was created):\n{lines}")


@dataclass
class TaskSize:
    """One (pupil, layout): its grid and per-eye cost."""

    pupil_mm: float
    layout: str
    n_fft: int
    freq_step_cpd: float
    n_subapertures: int
    n_depths: int
    n_states: int  # accommodation states the task evaluates
    n_pairs_per_depth: int
    bands: tuple  # ((start, stop, n_fft), ...) wavelength bands
    device_bytes_per_eye: float
    units_per_eye: float
    n_refined: int = 0  # states the continuous peaks add per eye (all depths)


ACCELERATOR_CHUNK = 256
"""Eyes per chunk measured on one GPU (:data:`ACCELERATOR_MEASURED`; 1,024 per chunk took the
same). The plan suggests it on an accelerator when ``run.chunk_size`` is smaller."""

ACCELERATOR_MEASURED = ("one H200 ran 10,000 eyes of the paper's scene in 110 s in chunks of "
                        f"{ACCELERATOR_CHUNK} (benchmarks/RESULTS.md §34)")
"""What the plan says in place of a time on an accelerator: the time model is the CPU's."""


@dataclass
class SweepEstimate:
    """Sizes of a sweep (bytes, seconds); ``tasks`` empty until the sampling is planned."""

    n_eyes: int
    n_chunks: int
    chunk_size: int
    pupils_mm: tuple
    layouts: tuple
    depths_D: tuple
    n_accommodation: int
    n_wavelengths: int
    store_bytes: float
    host_setup_bytes: float
    host_chunk_bytes: float
    tasks: list[TaskSize] = field(default_factory=list)
    n_devices: int = 1
    complex_bytes: int = 16
    display_effects: tuple = ()  # display_effects(config): the display keys set
    platform: str = "cpu"  # jax's backend: the time model is calibrated on the CPU only

    @property
    def device_chunk_bytes(self) -> float:
        """Largest task's working set for one chunk on one device."""
        if not self.tasks:
            return float("nan")
        # the pipeline maps over a chunk's eyes one at a time (lax.map), so the working set
        # is one eye's on each device; the chunk's outputs are small beside it
        return max(t.device_bytes_per_eye for t in self.tasks)

    @property
    def seconds(self) -> float:
        """Estimated compute time of the whole sweep on one device, s (nan unplanned)."""
        if not self.tasks:
            return float("nan")
        units = sum(t.units_per_eye for t in self.tasks) * self.n_eyes
        return units * SECONDS_PER_UNIT / max(self.n_devices, 1)

    def summary(self, store=None) -> str:
        """Human-readable plan: what is computed and what it costs."""
        depths = ", ".join(f"{d:g}" for d in self.depths_D)
        lines = [
            f"eyes        {self.n_eyes} in {self.n_chunks} chunks of {self.chunk_size}",
            f"pupils      {', '.join(f'{p:g}' for p in self.pupils_mm)} mm",
            f"layouts     {', '.join(self.layouts)}",
            f"depths      {len(self.depths_D)}: {depths} D",
            f"states      {self.n_accommodation} accommodation states on the grid",
            f"wavelengths {self.n_wavelengths}" + (" (the most of any layout)" if self.tasks else ""),
        ]
        if self.display_effects:
            lines.append(f"display     {'; '.join(self.display_effects)}")
        for t in self.tasks:
            lines.append(f"sampling    {t.pupil_mm:g} mm {t.layout}: df {t.freq_step_cpd:.4g} cpd, "
                         f"FFT {t.n_fft}, {t.bands[-1][1]} wavelengths, {t.n_states} states x "
                         f"{t.n_subapertures} views"
                         + (f" + {t.n_refined} peak states" if t.n_refined else ""))
        if not self.tasks:
            lines.append("sampling    planned when the sweep starts")
        if self.platform == "cpu":
            time_line = (f"time        ~{_duration(self.seconds)} estimated on {self.n_devices} "
                         f"device(s) (calibrated on 2 CPU cores)")
        else:  # no model of an accelerator: a CPU figure there misleads by orders of magnitude
            time_line = (f"time        not modelled on {self.platform} (~{_duration(self.seconds)} "
                         f"at 2 CPU cores' speed; {ACCELERATOR_MEASURED})")
        lines += [
            time_line,
            f"host memory ~{_bytes(self.host_setup_bytes + self.host_chunk_bytes)} "
            f"(setup {_bytes(self.host_setup_bytes)}, one chunk {_bytes(self.host_chunk_bytes)})",
            f"device mem  ~{_bytes(self.device_chunk_bytes)} per device for one chunk",
            f"store       ≤ {_bytes(self.store_bytes)} uncompressed"
            + (f" at {store}" if store is not None else ""),
        ]
        if self.platform != "cpu" and self.chunk_size < ACCELERATOR_CHUNK:
            lines.append(f"note        run.chunk_size {self.chunk_size}: one call per chunk; on "
                         f"{self.platform} a chunk of a few hundred eyes keeps the device busy "
                         f"(run.chunk_size = {ACCELERATOR_CHUNK} is what was measured)")
        return "\n".join(lines)


def _count(start: float, stop: float, step: float) -> float:
    """Points of the grid start … stop by step, without building it (inf if absurd)."""
    try:
        return float(grid_size(start, stop, step))
    except (OverflowError, ZeroDivisionError, ValueError):
        return math.inf


def _eye_bytes(config: SweepConfig, n_acc: float) -> float:
    """Bytes of one eye's row in every eye-dimensioned store variable."""
    n_pl = len(config.pupil_diameters_mm) * len(config.layouts) * len(config.depth_offsets_D)
    m = len(METRICS)
    return n_pl * (
        2 * n_acc * 4  # vsotf, strehl (float32)
        + m * (8 * 4 + 1 + 4 * 2)  # 4 float64 peaks/errors, success, 2 float32 values
        + m * N_FREQUENCIES * 4  # mtf_at_peak
    ) + N_MODES * 8


def estimate(config: SweepConfig, tasks=None, n_devices: int = 1,
             platform: str | None = None) -> SweepEstimate:
    """Sizes of ``config``'s sweep; with its planned ``tasks`` (:func:`build_tasks`) also the
    device memory and time. Computes nothing large (grids are counted, not built).
    ``platform``: the devices' (default ``jax.default_backend()``); the time is modelled for
    the CPU only, and the plan says so elsewhere."""
    n_acc = _count(0.0, config.accommodation_max_D, config.accommodation_step_D)
    if config.display_spectrum is None and not config.wavelength_step_planned:
        n_wl = _count(*config.wavelengths_nm)
    else:
        n_wl = float(len(_display_wavelengths(config)))
    n_eyes = config.n_total_eyes
    eye_bytes = _eye_bytes(config, n_acc)
    store = n_eyes * eye_bytes
    # the population's coefficients (a few copies), the host guards' block of wavefronts
    # and gradients (lfjax.base.sampling.EYE_BLOCK eyes, 48 x 48 samples, five arrays); the store
    # is created from one chunk's template, so its size does not count here
    setup = n_eyes * N_MODES * 8 * 4 + EYE_BLOCK * GUARD_GRID**2 * 8 * 5
    chunk = 2 * config.chunk_size * eye_bytes  # the chunk's arrays and their Dataset

    complex_bytes = 16 if jax.config.jax_enable_x64 else 8
    sizes = []
    for task in tasks or ():
        pc = task.pipeline_config
        n_fft = pc.n_fft
        n_states = int(task.accommodation.states_D.shape[0])
        n_k = int(task.accommodation.pair_index.shape[1])
        n_sub = int(task.layout.n_subapertures)
        n_depth = len(task.depth_slots)
        plane = n_fft * (n_fft // 2 + 1) * complex_bytes
        elemental = held_elemental_planes(n_states, n_sub, n_depth * n_k, n_fft, pc.sampling) * plane
        rendered = n_depth * n_k * plane
        device = DEVICE_ALLOWANCE * (elemental + 2 * rendered)
        per_state = n_sub * transform_units(pc.bands)  # a strip's narrow window counted
        refined = n_depth * refinement_states(config)
        ffts = (n_states + refined) * per_state
        render = n_sub * (n_depth * n_k + refined) * n_fft * (n_fft // 2 + 1)
        sizes.append(TaskSize(
            float(task.pupil_mm), task.layout_label, int(n_fft), float(pc.freq_step_cpd), n_sub,
            n_depth, n_states, n_k, tuple(pc.bands), float(device), float(ffts + render),
            int(refined)))
    return SweepEstimate(
        n_eyes=n_eyes, n_chunks=config.n_chunks, chunk_size=int(config.chunk_size),
        pupils_mm=tuple(config.pupil_diameters_mm), layouts=tuple(config.layouts),
        depths_D=tuple(float(d) for d in config.depths_D), n_accommodation=int(min(n_acc, 2**62)),
        n_wavelengths=int(min(n_wl, 2**62)), store_bytes=float(store),
        host_setup_bytes=float(setup), host_chunk_bytes=float(chunk), tasks=sizes,
        n_devices=int(n_devices), complex_bytes=complex_bytes,
        display_effects=display_effects(config),
        platform=jax.default_backend() if platform is None else str(platform))


DISPLAY_UNITS = {"D": "D", "mm": "mm", "um": "µm", "arcmin": "arcmin"}
"""How :func:`display_effects` writes a key's unit (the suffix of its name)."""

_SHOWN_ELSEWHERE = {"layouts", "cdp_D", "depth_offsets_D"}  # the plan's and report's own lines


def display_effects(config: SweepConfig) -> tuple[str, ...]:
    """Each ``[display]`` key of ``config`` that differs from its default (besides the
    layouts, the CDP and the depths, stated on their own), as ``"name = value unit
    (default d)"``: the lenticular strips' width ratio and y defocus, the leakage weight,
    the lenslets' distance, emitters and aberrations — what the sweep modelled beyond the
    paper's ideal display. Empty for the ideal display."""
    out = []
    for key in KEYS:
        if key.section != "display" or key.name in _SHOWN_ELSEWHERE:
            continue
        value = getattr(config, key.field)
        if value == key.default:
            continue
        unit = DISPLAY_UNITS.get(key.unit, key.unit) or "unitless"
        default = "not set" if key.default is None else f"{key.default:g}"
        out.append(f"{key.name} = {value:g} {unit} (default {default})")
    return tuple(out)


def refinement_states(config: SweepConfig) -> int:
    """Accommodation states the continuous peaks evaluate per (eye, depth) beyond the grid
    (:data:`REFINEMENT_STATES` of ``config.peak_method`` for each metric refined)."""
    return sum(REFINEMENT_STATES[resolved_method(metric, config.peak_method)]
               for metric in config.continuous_peaks)


def _display_wavelengths(config: SweepConfig):
    """The wavelengths of the (pupil, layout) with the most (each plans its own rule)."""
    return max((s.wavelengths_nm for s in sweep_spectra(config).values()), key=len)


def host_memory_bytes() -> float:
    """Memory this process may still use, bytes (MemAvailable on Linux; else physical)."""
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return float(line.split()[1]) * 1024
    except OSError:
        pass
    try:
        return float(os.sysconf("SC_PHYS_PAGES") * os.sysconf("SC_PAGE_SIZE"))
    except (ValueError, OSError, AttributeError):
        return math.inf


def device_memory_bytes(devices=None) -> float:
    """Memory of the smallest local device, bytes (the host's for a CPU device)."""
    devices = jax.local_devices() if devices is None else devices
    limits = []
    for d in devices:
        stats = None
        try:
            stats = d.memory_stats()
        except Exception:  # noqa: BLE001 - backends without memory statistics
            stats = None
        if stats and stats.get("bytes_limit"):
            limits.append(float(stats["bytes_limit"]))
    return min(limits) if limits else host_memory_bytes()


def free_disk_bytes(path) -> float:
    """Free space where ``path`` would be created, bytes."""
    p = Path(path).resolve()
    while not p.exists() and p != p.parent:
        p = p.parent
    try:
        return float(shutil.disk_usage(p).free)
    except OSError:
        return math.inf


def check_fits(est: SweepEstimate, store=None, host_bytes: float | None = None,
               device_bytes: float | None = None, disk_bytes: float | None = None) -> None:
    """Raise :class:`SweepTooLargeError` (every problem, with the numbers) unless the
    sweep's store fits the free disk and its memory fits this machine."""
    host = host_memory_bytes() if host_bytes is None else host_bytes
    problems = []
    need = est.host_setup_bytes + est.host_chunk_bytes
    if not need <= host:
        problems.append(
            f"host memory: ~{_bytes(need)} needed ({est.n_eyes} eyes, chunks of "
            f"{est.chunk_size} x {est.n_accommodation} states x {len(est.layouts)} layouts x "
            f"{len(est.depths_D)} depths x {len(est.pupils_mm)} pupils), {_bytes(host)} "
            f"available; use fewer eyes, a smaller run.chunk_size, a coarser "
            f"accommodation.step_D, or fewer depths/layouts")
    if est.tasks:
        device = device_memory_bytes() if device_bytes is None else device_bytes
        worst = max(est.tasks, key=lambda t: t.device_bytes_per_eye)
        if not worst.device_bytes_per_eye <= device:
            problems.append(
                f"device memory: ~{_bytes(worst.device_bytes_per_eye)} needed per chunk for "
                f"{worst.pupil_mm:g} mm {worst.layout} (FFT {worst.n_fft} at "
                f"{worst.freq_step_cpd:.3g} cpd, {worst.n_states} states x "
                f"{worst.n_subapertures} views), {_bytes(device)} available; use a coarser "
                f"sampling.freq_step_cpd (or \"planned\") or a coarser accommodation.step_D")
    if store is not None:
        disk = free_disk_bytes(store) if disk_bytes is None else disk_bytes
        if not est.store_bytes <= disk:
            problems.append(f"disk: the store may need up to {_bytes(est.store_bytes)}, "
                            f"{_bytes(disk)} free at {Path(store).resolve().parent}")
    if problems:
        raise SweepTooLargeError(problems)


__all__ = [
    "ACCELERATOR_CHUNK",
    "ACCELERATOR_MEASURED",
    "display_effects",
    "SweepEstimate",
    "SweepTooLargeError",
    "TaskSize",
    "check_fits",
    "device_memory_bytes",
    "estimate",
    "refinement_states",
    "free_disk_bytes",
    "host_memory_bytes",
]
