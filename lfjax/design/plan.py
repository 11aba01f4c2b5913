"""What a design will cost, known before the first fit: per views-per-side count the fit's
and the report's sampling, their transforms, and an estimate of time and peak memory.

:func:`fit_design` prints :meth:`DesignPlan.summary` first (``lfjax design`` always), then
its progress. The estimates follow the sweep's (:mod:`lfjax.sweep.guard`): a cost unit is one
complex FFT point·log2 size or one rendered view-pixel, timed at
:data:`lfjax.sweep.guard.SECONDS_PER_UNIT` on 2 CPU cores; memory is the largest arrays
of one eye (the fit's gradient holds one chunk of eyes at a time,
:func:`lfjax.design.box.design_loss_chunked`) times a measured allowance. They are
estimates, calibrated on the measurements of benchmarks/RESULTS.md §21; the progress lines
give the measured time as it goes.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import jax

from lfjax.kernel.pipeline import held_elemental_planes, streams_views, transform_units
from lfjax.sweep.guard import SECONDS_PER_UNIT, host_memory_bytes
from lfjax.base.units import format_bytes as _bytes
from lfjax.base.units import format_duration as _duration

EVALUATIONS_PER_STEP = 1.3
"""L-BFGS-B's loss-and-gradient evaluations per step (its line search mostly accepts the
first point; measured 1.1–1.5 on the presets' counts), plus the start's."""

TYPICAL_STEPS = 2
"""L-BFGS-B steps a count's fit typically takes before its projected gradient falls below
``tol``: every fit of the near-eye preset's 2x2, 3x3 and 4x4 at the defaults stopped after 2
of its 10 (RESULTS §21, §31); the box has three to four coordinates. The plan gives the time
at this many steps and at ``steps``."""

GRADIENT_COST = 4.0
"""Time of one value and gradient through checkpointed eye chunks over one forward
evaluation: the forward, its recomputation in the reverse pass, and the reverse pass
(about twice a forward)."""

REPORT_PASSES = 2.0
"""Forward evaluations of the report per panel and eye: the peak grid (:func:`lfjax.layout_opt.evaluate_layout`)
and the perceivable resolution at the predicted accommodation (one eye per call, its
compilation and host work amortised over the eyes)."""

COMPILE_SECONDS = 30.0
"""Compilation per count (its shapes differ from every other count's): the fit's value and
gradient, the report's evaluation and its perceivable resolution; about 10 s each with a
cold cache (RESULTS §21, 21 s for the near-eye 2x2 gradient under a load of 9 on 2 cores)."""

FORWARD_ALLOWANCE = 3.0
"""Working set of a forward evaluation over the largest arrays of one eye (elemental OTFs
and the rendered block): FFT workspaces and temporaries (the sweep's
:data:`lfjax.sweep.guard.DEVICE_ALLOWANCE`)."""

REVERSE_ALLOWANCE = 6.8
"""Working set of one chunk's checkpointed reverse pass (the recomputed forward and its
reverse) over the same arrays of one eye: the phone preset's 3x3 fit, one eye per chunk,
peaked at 3.93 GB with 0.46 GB of them (RESULTS §21; all at once it kept 2.1 GB per
training eye, §15)."""

STREAMED_FORWARD_ALLOWANCE = 1.5
""":data:`FORWARD_ALLOWANCE` where the views stream (:func:`lfjax.kernel.pipeline.streams_views`):
the phone preset's 4x4 report of one eye peaked at 2.79 GiB, 1.2 times its arrays over the
process's base (RESULTS §36; 3.0 when the same evaluation held the whole stack)."""

STREAMED_REVERSE_ALLOWANCE = 3.0
""":data:`REVERSE_ALLOWANCE` where the views stream: the phone preset's 4x4 fit gradient of
one eye peaked at 2.08 GiB, 2.45 times its arrays over the base (RESULTS §36)."""

SCREEN_MARGIN = 0.25
"""With ``report_counts="chosen"`` (:func:`lfjax.design.fit_design`), a count is reported
beside the first count to pass when its training loss (the fit's last, on the fit's setting)
exceeds that count's by at most this fraction of its magnitude. Why a quarter: the fit's
setting (550 nm, vertex peaks) reads the image lower than the report does by a factor that
hardly moves between counts — held-out over training loss was 1.15, 1.18 and 1.19 for the
near-eye preset's 2x2, 3x3 and 4x4 at the defaults (RESULTS §21) — so a count 25 % behind
in training loss would need that factor to move about seven times as far between two counts
to overtake."""

BASE_BYTES = 0.8e9
"""Resident memory of the process before any transform: the interpreter, JAX, XLA's
compiled programs and the host arrays (measured 0.5–0.8 GB)."""


def evaluation_size(problem, n_views: int, states: int | None = None) -> tuple[float, float, bool]:
    """(cost units, bytes, whether the views stream) of one forward evaluation of one eye of ``problem`` (a
    :class:`~lfjax.layout_opt.LayoutProblem`) with ``n_views`` views on ``states``
    accommodation states (default its peak grid's): every state transforms every view at
    every wavelength of each band; every (depth, state) pair renders every view. The bytes
    count the elemental OTFs the pipeline holds at once (:func:`lfjax.kernel.pipeline.held_elemental_planes`:
    one view's when a large stack streams its views)."""
    config = problem.config
    grid = problem.peak_grid
    n_states = int(grid.states_D.shape[0]) if states is None else int(states)
    n_depth, n_k = (int(s) for s in grid.pair_index.shape)
    per_state = n_views * transform_units(config.bands)
    n_fft = config.n_fft
    plane = n_fft * (n_fft // 2 + 1) * (16 if jax.config.jax_enable_x64 else 8)
    units = n_states * per_state + n_views * n_depth * n_k * n_fft * (n_fft // 2 + 1)
    held = held_elemental_planes(n_states, n_views, n_depth * n_k, n_fft, config.sampling)
    arrays = plane * (held + 2 * n_depth * n_k)
    return float(units), float(arrays), streams_views(n_states, n_views, n_fft, config.sampling)


@dataclass
class CountPlan:
    """One views-per-side count: what its fit and its report transform, and their cost."""

    n_per_side: int
    refused: str | None = None
    resumed: str | None = None  # where the count fitted by an earlier run is kept
    fit_fft: int = 0
    fit_df_cpd: float = float("nan")
    fit_states: int = 0
    fit_wavelengths: int = 0
    report_fft: int = 0
    report_df_cpd: float = float("nan")
    report_states: int = 0
    report_wavelengths: int = 0
    fit_seconds: float = 0.0  # at every step the fit may take
    fit_seconds_typical: float = 0.0  # at TYPICAL_STEPS (or fewer, when fewer are allowed)
    report_seconds: float = 0.0
    fit_bytes: float = 0.0
    report_bytes: float = 0.0

    @property
    def seconds(self) -> float:
        return self.fit_seconds + self.report_seconds

    @property
    def peak_bytes(self) -> float:
        return BASE_BYTES + max(self.fit_bytes, self.report_bytes)


@dataclass
class DesignPlan:
    """Every count's :class:`CountPlan`, and the run's settings."""

    counts: list = field(default_factory=list)
    train_eyes: int = 0
    report_eyes: int = 0
    eye_chunk: int = 1
    steps: int = 0
    report_accuracy: str = ""
    report_counts: str = "all"  # lfjax.design.settings.REPORT_COUNTS
    available_bytes: float | None = None  # memory this process may use (None: MemAvailable)

    @property
    def seconds(self) -> float:
        """Estimated seconds: every count's fit, and the reports the run will make — every
        count's, or (``report_counts="chosen"``) the dearest count's, standing for the one
        count reported when the first ranked passes and no other lies within the margin."""
        fits = sum(c.fit_seconds for c in self.counts)
        reports = [c.report_seconds for c in self.counts]
        if self.report_counts == "chosen":
            return fits + max(reports, default=0.0)
        return fits + sum(reports)

    @property
    def seconds_all_reported(self) -> float:
        return sum(c.seconds for c in self.counts)

    @property
    def peak_bytes(self) -> float:
        return max([c.peak_bytes for c in self.counts if c.refused is None] or [BASE_BYTES])

    def summary(self) -> str:
        which = ("every count" if self.report_counts == "all" else
                 "the count first by training loss that passes, and any within "
                 f"{SCREEN_MARGIN:.0%} of it")
        lines = [f"plan: {self.train_eyes} training eyes in chunks of {self.eye_chunk}, "
                 f"{self.steps} L-BFGS-B steps per count; report ({self.report_accuracy}) on "
                 f"{self.report_eyes} eyes, fitted and starting panels, of {which}"]
        for c in self.counts:
            if c.resumed is not None:
                lines.append(f"  {c.n_per_side}x{c.n_per_side}  resumed: {c.resumed}")
                continue
            if c.refused is not None:
                lines.append(f"  {c.n_per_side}x{c.n_per_side}  refused before fitting: {c.refused}")
                continue
            fit_time = (f"~{_duration(c.fit_seconds)}" if c.fit_seconds_typical >= c.fit_seconds else
                        f"~{_duration(c.fit_seconds_typical)} (~{_duration(c.fit_seconds)} at all {self.steps} steps)")
            lines.append(
                f"  {c.n_per_side}x{c.n_per_side}  fit FFT {c.fit_fft} (df {c.fit_df_cpd:.3g} cpd, "
                f"{c.fit_states} states, {c.fit_wavelengths} wavelength(s)) {fit_time}; "
                f"report FFT {c.report_fft} (df {c.report_df_cpd:.3g} cpd, {c.report_states} states, "
                f"{c.report_wavelengths} wavelengths) ~{_duration(c.report_seconds)}; "
                f"memory ~{_bytes(c.peak_bytes)}")
        reports = [c.report_seconds for c in self.counts if c.refused is None and c.resumed is None]
        typical = sum(c.fit_seconds_typical for c in self.counts)
        if self.report_counts == "all" or len(reports) < 2:
            low = typical + sum(reports)
        else:  # which count leads is known only after the fits
            low = typical + min(reports)
        total = (f"~{_duration(low)} if the fits stop after {TYPICAL_STEPS} steps as they "
                 f"typically do, at most ~{_duration(self.seconds)}" if low < self.seconds
                 else f"~{_duration(self.seconds)}")
        if self.report_counts == "chosen" and len(reports) >= 2:
            total += (f" with one count reported (~{_duration(self.seconds_all_reported)} if every "
                      f"count is)")
        lines.append(f"  total on 2 CPU cores (estimated): {total}; peak memory "
                     f"~{_bytes(self.peak_bytes)}")
        available = host_memory_bytes() if self.available_bytes is None else self.available_bytes
        if self.peak_bytes > available:
            lines.append(f"  warning: more memory than the {_bytes(available)} available here; "
                         f"fewer --views, a coarser --freq-step or --diffraction off need less "
                         f"(the fit's gradient already takes one training eye at a time)")
        return "\n".join(lines)


def count_plan(n_per_side: int, fit_problem, report_problem, train_eyes: int, report_eyes: int,
               steps: int, eye_chunk: int, report_refined_states: int = 0) -> CountPlan:
    """:class:`CountPlan` of one count from its fit and report problems
    (:func:`lfjax.design.fit.design_problem`, :func:`lfjax.design.fit.report_problem`);
    ``report_refined_states``: the states a refined peak adds per (eye, depth)."""
    views = n_per_side * n_per_side
    fit_units, fit_arrays, fit_streams = evaluation_size(fit_problem, views)
    n_peak_depths = int(report_problem.peak_grid.pair_index.shape[0])
    grid = report_problem.values_grid if report_problem.values_grid is not None else report_problem.peak_grid
    report_states = int(grid.states_D.shape[0]) + n_peak_depths * int(report_refined_states)
    report_units, report_arrays, report_streams = evaluation_size(report_problem, views, report_states)
    reverse = STREAMED_REVERSE_ALLOWANCE if fit_streams else REVERSE_ALLOWANCE
    forward = STREAMED_FORWARD_ALLOWANCE if report_streams else FORWARD_ALLOWANCE
    evaluations = 1 + EVALUATIONS_PER_STEP * steps if steps > 0 else 0
    typical = 1 + EVALUATIONS_PER_STEP * min(steps, TYPICAL_STEPS) if steps > 0 else 0
    per_evaluation = GRADIENT_COST * fit_units * train_eyes * SECONDS_PER_UNIT
    return CountPlan(
        n_per_side,
        fit_fft=int(fit_problem.config.n_fft), fit_df_cpd=float(fit_problem.config.freq_step_cpd),
        fit_states=int(fit_problem.peak_grid.states_D.shape[0]),
        fit_wavelengths=int(fit_problem.spectrum.wavelengths_nm.shape[0]),
        report_fft=int(report_problem.config.n_fft),
        report_df_cpd=float(report_problem.config.freq_step_cpd), report_states=report_states,
        report_wavelengths=int(report_problem.spectrum.wavelengths_nm.shape[0]),
        fit_seconds=0.0 if steps == 0 else evaluations * per_evaluation + COMPILE_SECONDS,
        fit_seconds_typical=0.0 if steps == 0 else typical * per_evaluation + COMPILE_SECONDS,
        report_seconds=2 * REPORT_PASSES * report_units * report_eyes * SECONDS_PER_UNIT,
        fit_bytes=0.0 if steps == 0 else reverse * fit_arrays * eye_chunk,
        report_bytes=forward * report_arrays)


__all__ = ["SCREEN_MARGIN", "TYPICAL_STEPS", "CountPlan", "DesignPlan", "count_plan", "evaluation_size"]
