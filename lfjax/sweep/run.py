"""Running a sweep: chunks of eyes through the compiled pipeline into the store.

:func:`run_sweep` is what ``lfjax sweep CONFIG.toml`` calls. It draws the population,
plans each (pupil, layout)'s sampling once on all of it, creates the store (or checks that
an existing one was made by the same configuration when resuming), then computes the
chunks that are not yet complete — in several processes, each its own share
(``chunk % process_count == process_index``) — with a progress bar in eyes per second.
"""

from __future__ import annotations

import os
import resource
import shutil
import signal
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import jax
import numpy as np
from jax.experimental import multihost_utils

from lfjax._version import utc_now
from lfjax.sweep.compute import ChunkEvaluator, build_tasks, population
from lfjax.sweep.config import SweepConfig
from lfjax.sweep.guard import check_fits, estimate
from lfjax.sweep.store import (
    chunk_dataset,
    create_store,
    record_run,
    stored_attribute,
    stored_samplings,
    stored_spectra,
    template,
    unmark_chunks,
    write_chunk,
)
from lfjax.sweep.target import check_store_target
from lfjax.sweep.store_checks import (
    check_store_matches,
    completed_chunks,
    read_bookkeeping,
    verify_store,
)
from lfjax.sweep.store_lock import StoreLock


@dataclass
class SweepRun:
    """What one call of :func:`run_sweep` did.

    Attributes
    ----------
    store : path of the Zarr store
    computed_chunks : chunk indices this process computed (in order)
    skipped_chunks : chunk indices already complete when it started (resume)
    recomputed_chunks : {chunk: why} complete chunks whose data failed verification on
        resume (missing or corrupt), computed again
    eyes_computed : eyes in the computed chunks (the average eye counts as one)
    seconds : wall time of the chunk loop (excludes planning and store creation), s
    setup_seconds : drawing the eyes, planning the sampling and creating the store, s
    chunk_seconds : wall time of each computed chunk, s (the first includes compilation)
    traces : {(pupil_index, layout_index): traces} of the compiled chunk functions
    peak_rss_mb : peak resident memory of this process, MiB
    process_index, process_count : this process among the sweep's
    """

    store: Path
    computed_chunks: list[int] = field(default_factory=list)
    skipped_chunks: list[int] = field(default_factory=list)
    recomputed_chunks: dict = field(default_factory=dict)
    eyes_computed: int = 0
    seconds: float = 0.0
    setup_seconds: float = 0.0
    chunk_seconds: list[float] = field(default_factory=list)
    traces: dict = field(default_factory=dict)
    peak_rss_mb: float = 0.0
    process_index: int = 0
    process_count: int = 1

    @property
    def eyes_per_second(self) -> float:
        return self.eyes_computed / self.seconds if self.seconds > 0 else float("nan")


def _process() -> tuple[int, int]:
    return jax.process_index(), jax.process_count()


def _barrier(name: str) -> None:
    if jax.process_count() > 1:
        multihost_utils.sync_global_devices(name)


def peak_rss_mb() -> float:
    """Peak resident set size of this process, MiB (Linux reports KiB, macOS bytes)."""
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return peak / 1024.0 if sys.platform != "darwin" else peak / 2**20


def _say(text: str) -> None:
    print(f"lfjax sweep: {text}", file=sys.stderr, flush=True)


def plan_sweep(config: SweepConfig, store=None, devices=None, samplings: dict | None = None,
               progress: bool = False, spectra: dict | None = None):
    """Everything a sweep decides before it creates anything: the population, the spectrum,
    each (pupil, layout)'s task (sampling planned on the whole population) and the
    :class:`~lfjax.sweep.guard.SweepEstimate`; refuses (:class:`SweepTooLargeError`, with
    the numbers) a sweep that cannot fit — the store on ``store``'s disk, the memory on this
    host and its devices. Writes nothing.

    ``progress``: say on stderr what is being drawn and planned, and how long it took.
    ``samplings`` and ``spectra``: a resumed store's (:func:`~lfjax.sweep.store.stored_samplings`,
    :func:`~lfjax.sweep.store.stored_spectra`), used instead of planning.

    Returns ``(eyes, is_average, spectrum, tasks, estimate)``; ``spectrum`` is None: each
    task carries its own (``Task.spectrum``, :func:`~lfjax.sweep.compute.sweep_spectra`).
    """
    n_devices = len(jax.local_devices() if devices is None else devices)
    # sizes known from the config alone first: planning an impossible grid would itself
    # take the memory or time the check is there to spare
    check_fits(estimate(config, n_devices=n_devices), store=store)
    t0 = time.perf_counter()
    eyes, is_average = population(config)
    spectrum = None  # each task carries its own (build_tasks: sweep_spectra)
    n_tasks = len(config.pupil_diameters_mm) * len(config.layouts)
    if progress:
        _say(f"drew {config.n_total_eyes} eyes; "
             + ("reading the stored sampling of" if samplings else "planning the sampling of")
             + f" {n_tasks} (pupil, layout) pair(s) on them ...")
    tasks = build_tasks(config, eyes, None, samplings, spectra)
    if progress:
        _say(f"planned in {time.perf_counter() - t0:.1f} s")
    est = estimate(config, tasks, n_devices=n_devices)
    check_fits(est, store=store)
    return eyes, is_average, spectrum, tasks, est


def run_sweep(
    config: SweepConfig,
    store,
    resume: bool = False,
    progress: bool = True,
    devices=None,
    max_chunks: int | None = None,
    on_plan=None,
) -> SweepRun:
    """Compute a population sweep into a Zarr store (see :mod:`lfjax.sweep`).

    Parameters
    ----------
    config : a validated :class:`~lfjax.sweep.config.SweepConfig`
    store : path of the Zarr store to create (or, with ``resume``, to complete)
    resume : continue an existing store made by the same configuration: finished chunks
        are skipped, the rest computed. Without it an existing path is refused.
    progress : show a progress bar (eyes, eyes/s, ETA) on stderr
    devices : local devices to shard the eye axis over (default: all local devices)
    max_chunks : stop after computing this many chunks (the rest stays for ``resume``)
    on_plan : called with the :class:`~lfjax.sweep.guard.SweepEstimate` once the sweep is
        planned and checked, before the store is created (the command line prints it)

    Sizes are checked before anything is created (:func:`plan_sweep`): a sweep that cannot
    fit raises :class:`~lfjax.sweep.guard.SweepTooLargeError` and leaves no store. A store
    this call created is removed again if the run fails before any chunk is finished.

    In a multi-process run (``jax.distributed.initialize`` called first), process 0 creates
    the store and each process computes the chunks ``i`` with ``i % process_count ==
    process_index``, writing them into the shared store.
    """
    t0 = time.perf_counter()
    started = utc_now()
    store = Path(store)
    pid, nproc = _process()
    exists = check_store_target(store, resume)
    lock = None
    if exists:
        check_store_matches(store, config)
        if pid == 0:  # one writer per store (the processes of one run share it)
            lock = _take_lock(store)
    try:
        samplings = stored_samplings(store) if exists else None
        spectra = stored_spectra(store, config) if exists else None  # what its chunks summed
        eyes, is_average, spectrum, tasks, est = plan_sweep(
            config, None if exists else store, devices, samplings, progress=progress and pid == 0,
            spectra=spectra)
        if on_plan is not None and pid == 0:
            on_plan(est)
        created = False
        if not exists and pid == 0:
            zernike = np.asarray(eyes.zernike_um)
            first = min(int(config.chunk_size), zernike.shape[0])  # memory of one chunk
            create_store(store, template(config, tasks, zernike[:first], is_average[:first]),
                         config.chunk_size, eyes=(zernike, is_average))
            created = True
            lock = _take_lock(store)
        try:
            run = _run_chunks(config, store, tasks, eyes, spectrum, devices, max_chunks,
                              progress, pid, nproc, exists, t0)
        except BaseException as err:
            # a failed start (the first chunk out of memory, an interrupt during compilation)
            # must not leave a store that blocks the next run: remove it if nothing finished
            if created and nproc == 1 and store.exists() and not completed_chunks(store).any():
                lock.release()
                lock = None
                shutil.rmtree(store, ignore_errors=True)
                err.add_note(f"{store} was removed: no chunk had finished")
            raise
        if pid == 0:
            record_run(store, started, run.computed_chunks)
        return run
    finally:
        if lock is not None:
            lock.release()


def _take_lock(store: Path) -> StoreLock:
    lock = StoreLock(store).acquire()
    if lock.recovered is not None:
        held = lock.recovered
        print(f"lfjax sweep: {store}: took over a stale lock (host {held.get('host')}, PID "
              f"{held.get('pid')} since {held.get('started_utc')}: that process is gone)",
              file=sys.stderr)
    return lock


def _run_chunks(config, store, tasks, eyes, spectrum, devices, max_chunks, progress, pid, nproc,
                exists, t0) -> SweepRun:
    _barrier("lfjax-sweep-store-created")
    if not exists and pid != 0:
        check_store_matches(store, config)
    evaluator = ChunkEvaluator(config, eyes.measured_pupil_mm, spectrum, devices)
    marks = read_bookkeeping(store)
    done = marks.done
    mine = [i for i in range(config.n_chunks) if i % nproc == pid]
    recomputed = {}
    if exists:
        # a resumed store's finished chunks are read back and checked against their
        # checksums: a deleted or damaged chunk file is computed again, not trusted, and so
        # is a chunk whose own marks (chunk_complete/<i>, chunk_checksum/<i>) are damaged
        recomputed = verify_store(store, [i for i in mine
                                          if done[i] or i in marks.damaged]).corrupt
        if recomputed:
            unmark_chunks(store, recomputed)
            done = completed_chunks(store)
            print(f"lfjax sweep: {store}: recomputing {len(recomputed)} chunk(s) whose data "
                  f"failed verification: {sorted(recomputed)}", file=sys.stderr)
            for i, why in sorted(recomputed.items()):
                print(f"lfjax sweep:   chunk {i}: {why}", file=sys.stderr)
    todo = [i for i in mine if not done[i]]
    if max_chunks is not None:
        todo = todo[: int(max_chunks)]
    run = SweepRun(store, skipped_chunks=[i for i in mine if done[i]], process_index=pid,
                   process_count=nproc, setup_seconds=time.perf_counter() - t0,
                   recomputed_chunks=recomputed)
    zernike = np.asarray(eyes.zernike_um)
    size = int(config.chunk_size)
    # a store of checksum scheme 2 covers (and each chunk rewrites) its eyes' coefficients
    with_zernike = int(stored_attribute(store, "checksum_scheme", 1)) >= 2
    bar = None
    if progress and todo:
        _say(f"compiling {len(tasks)} chunk function(s) with the first chunk (or loading them "
             f"from the compilation cache) ...")
    if progress:
        from tqdm.auto import tqdm

        total = sum(min(size, config.n_total_eyes - i * size) for i in todo)
        bar = tqdm(total=total, unit="eye", desc=f"sweep {store.name}"
                   + (f" [process {pid}/{nproc}]" if nproc > 1 else ""),
                   dynamic_ncols=True, file=sys.stderr)
    t1 = time.perf_counter()
    try:
        for i in todo:
            tc = time.perf_counter()
            start, stop = i * size, min((i + 1) * size, config.n_total_eyes)
            results = {task.key: evaluator.evaluate(task, zernike[start:stop]) for task in tasks}
            write_chunk(store, i, chunk_dataset(config, tasks, results, start, stop), start, stop,
                        zernike[start:stop] if with_zernike else None)
            run.chunk_seconds.append(time.perf_counter() - tc)
            run.computed_chunks.append(i)
            run.eyes_computed += stop - start
            # test hook: signal this process (SIGKILL unless LFJAX_TEST_ABORT_SIGNAL names
            # another, e.g. TERM) right after chunk i is marked complete, so the interruption
            # tests stop the sweep at a known point instead of racing a poll
            if os.environ.get("LFJAX_TEST_ABORT_AFTER_CHUNK") == str(i):
                name = os.environ.get("LFJAX_TEST_ABORT_SIGNAL", "KILL")
                os.kill(os.getpid(), getattr(signal, f"SIG{name}"))
            if bar is not None:
                bar.update(stop - start)
    finally:
        if bar is not None:
            bar.close()
        run.seconds = time.perf_counter() - t1
        run.traces = dict(evaluator.traces)
        run.peak_rss_mb = peak_rss_mb()
    evaluator.assert_no_retrace()
    _barrier("lfjax-sweep-chunks-done")
    return run


__all__ = ["SweepRun", "plan_sweep", "run_sweep", "peak_rss_mb"]
