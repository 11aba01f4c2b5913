"""``lfjax sweep``: a population sweep into a resumable Zarr store (:func:`lfjax.sweep.run_sweep`)."""

from __future__ import annotations

import argparse
import signal
import sys
import time
from pathlib import Path

from lfjax.base.errors import ParameterError
from lfjax.base.files import atomic_write_text, check_writable
from lfjax.cli import cache, common, flags
from lfjax.sweep import (
    StoreMismatchError,
    SweepConfigError,
    SweepTooLargeError,
    load_config,
    plan_sweep,
    run_sweep,
)
from lfjax.sweep.config_files import config_template
from lfjax.sweep.distributed import DISTRIBUTED_TIMEOUT_S, start_distributed
from lfjax.sweep.store import StoreRaceError, is_disk_full
from lfjax.sweep.store_checks import StoreDamagedError, verify_store
from lfjax.sweep.store_lock import StoreLockedError
from lfjax.sweep.target import check_store_target, check_store_writable

COMMAND = "sweep"


def add_parser(sub) -> None:
    sw = sub.add_parser(
        COMMAND,
        help="population sweep from a TOML config into a resumable Zarr store",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description=(
            "Compute through-focus VSOTF and Strehl ratio, grid and continuous predicted\n"
            "accommodation and MTF cut-off frequencies for a population of virtual eyes\n"
            "(Thibos et al. 2002) x pupils x layouts x rendered depths, as described by\n"
            "CONFIG (TOML; every key and its unit: --template FILE, or the guide\n"
            "docs/guides/population-sweeps.md, also on the documentation site).\n"
            "The whole config is validated first and every problem listed.\n\n"
            "Results go to STORE, a Zarr store of one xarray Dataset (open it with\n"
            "lfjax.sweep.open_store or xarray.open_zarr), written one chunk of eyes at a time;\n"
            "an interrupted sweep continues with --resume and recomputes no finished chunk.\n"
            "The plan (sizes, estimated time, memory, store size) is printed first, and a\n"
            "sweep that cannot fit this machine is refused before anything is written.\n"
            "One writer per STORE: STORE.lock names it (host, PID, start).\n"
            "The eye axis is sharded over all local JAX devices (run.chunk_size must be a\n"
            "multiple of their number). Several processes or hosts: start one process per\n"
            "host with --distributed (jax.distributed.initialize; the coordinator is found\n"
            "from the cluster environment, or give --coordinator, --num-processes and\n"
            "--process-id); each computes its share of the chunks into the shared STORE."
        ),
    )
    sw.add_argument("config", metavar="CONFIG.toml",
                    help="sweep configuration (TOML); with --template the file to write; with "
                         "--verify the STORE to check")
    sw.add_argument("--dry-run", action="store_true",
                    help="print the plan (eyes, layouts, depths, states, wavelengths, sampling, "
                         "estimated time, memory and store size), check it fits, write nothing")
    sw.add_argument("--verify", action="store_true",
                    help="check STORE (given in place of CONFIG.toml): read every finished chunk "
                         "back and compare it with its checksum; exit 1 if any is corrupt "
                         "(--resume recomputes those)")
    sw.add_argument("--template", action="store_true",
                    help="write CONFIG.toml: a commented config with every key and its default")
    flags.add_out(sw, None, "Zarr store to write (default: CONFIG's name with .zarr, in the "
                             "current folder); must not exist unless --resume", metavar="STORE")
    sw.add_argument("--resume", action="store_true",
                    help="complete an existing STORE made by the same config (finished chunks "
                         "are skipped, those whose data fail their checksum recomputed; a store "
                         "of another config is refused, listing the differences)")
    sw.add_argument("--max-chunks", metavar="N", type=flags.positive_int, default=None,
                    help="stop after computing N chunks (continue later with --resume)")
    flags.add_no_progress(sw)
    sw.add_argument("--distributed", action="store_true",
                    help="call jax.distributed.initialize first (one process per host)")
    sw.add_argument("--coordinator", metavar="HOST:PORT", default=None,
                    help="with --distributed: address of process 0's coordinator service")
    sw.add_argument("--num-processes", metavar="N", type=flags.positive_int, default=None,
                    help="with --distributed: total number of processes")
    sw.add_argument("--process-id", metavar="I", type=flags.count, default=None,
                    help="with --distributed: this process's index, 0 ... N-1")
    sw.add_argument("--distributed-timeout", metavar="S", type=flags.positive_int,
                    default=DISTRIBUTED_TIMEOUT_S,
                    help=f"with --distributed: seconds to wait for every process to connect "
                         f"to the coordinator before stopping with an error that names it "
                         f"(default {DISTRIBUTED_TIMEOUT_S})")


def _terminated(signum, frame):
    # a batch scheduler's SIGTERM (preemption, time limit) ends the run as Ctrl-C does:
    # the lock is released and finished chunks are kept for --resume
    raise KeyboardInterrupt


def run(args) -> int:
    prog = f"{common.PROG} {COMMAND}"
    explicit = [args.coordinator, args.num_processes, args.process_id]
    if args.distributed_timeout != DISTRIBUTED_TIMEOUT_S:
        explicit.append(args.distributed_timeout)
    if any(x is not None for x in explicit) and not args.distributed:
        return common.refuse(prog, "--coordinator, --num-processes, --process-id and "
                                   "--distributed-timeout need --distributed")
    if args.distributed:
        # before anything touches a JAX device (loading a layout file does)
        def timed_out(err) -> None:
            print(f"{prog}: error: {common.message(err, COMMAND)}", file=sys.stderr, flush=True)

        try:
            start_distributed(args.coordinator, args.num_processes, args.process_id,
                              timeout_s=args.distributed_timeout, on_timeout=timed_out)
        except ParameterError as err:  # a value refused before anything started
            return common.refuse(prog, err, COMMAND)
        except Exception as err:  # noqa: BLE001 - report any start-up failure in one line
            return common.refuse(prog, f"jax.distributed.initialize failed: {err}")

    if args.verify:
        try:
            check = verify_store(args.config)
        except ValueError as err:  # not a sweep store (or one whose metadata are unreadable)
            return common.refuse(prog, err, COMMAND)
        except Exception as err:  # noqa: BLE001 - a report, never a traceback
            print(f"{prog}: {args.config}: could not be verified: {type(err).__name__}: "
                  f"{' '.join(str(err).split())}", file=sys.stderr)
            return 1
        print(f"{prog}: {args.config}: {check.summary()}")
        return 0 if check.healthy else 1
    if args.template:
        target = Path(args.config)
        if target.exists():
            return common.refuse(prog, f"{target} already exists; --template writes a new file")
        try:
            check_writable(target, parameter="config")
            atomic_write_text(target, config_template())  # whole or not at all
        except ValueError as err:
            return common.refuse(prog, err, COMMAND)
        except OSError as err:
            return common.refuse(prog, f"cannot write {target}: {err.strerror or err}")
        print(f"{prog}: wrote {target} (every key with its default; edit, then "
              f"'lfjax sweep {target} --dry-run')")
        return 0
    try:
        config = load_config(args.config)
    except SweepConfigError as err:
        return common.refuse(prog, err, COMMAND)
    out = Path(args.out) if args.out else Path(Path(args.config).stem + ".zarr")
    try:
        # before planning, and in a dry run too: a store that cannot be written is refused now
        check_store_writable(out)
    except ValueError as err:
        return common.refuse(prog, err, COMMAND)
    if args.dry_run:
        try:
            *_, est = plan_sweep(config, None if out.exists() else out)
        except SweepTooLargeError as err:
            return common.refuse(prog, err, COMMAND)
        except (ValueError, OSError) as err:
            return common.refuse(prog, err, COMMAND, fold=True)
        print(f"{prog}: plan for {args.config} (dry run: nothing written)")
        print(est.summary(out))
        return 0
    try:
        check_store_target(out, args.resume)
    except FileExistsError as err:
        return common.refuse(prog, err, COMMAND)
    cache.enable_compilation_cache()
    try:
        previous = signal.signal(signal.SIGTERM, _terminated)
    except ValueError:  # not the main thread: leave signals alone
        previous = None
    def kept() -> str:
        if out.exists():
            return f"; finished chunks are kept in {out} (continue with --resume)"
        return " before any chunk finished; no store was kept"

    def failed(err: Exception) -> str | None:
        if isinstance(err, (StoreRaceError, StoreDamagedError)):  # found as the run starts
            return " ".join(str(err).split())
        if is_disk_full(err):
            return ("the disk is full: " +
                    (f"finished chunks are kept in {out}; free space and continue with --resume"
                     if out.exists() else "no chunk had finished, so no store was kept"))
        return None

    try:
        run, status = common.guarded(
            prog, COMMAND,
            lambda: run_sweep(config, out, resume=args.resume, progress=not args.no_progress,
                              max_chunks=args.max_chunks,
                              on_plan=lambda est: print(f"{prog}: plan\n{est.summary(out)}",
                                                        flush=True)),
            note=kept, refused=(StoreMismatchError, SweepTooLargeError, StoreLockedError),
            failed=failed)
    finally:
        if previous is not None:
            signal.signal(signal.SIGTERM, previous)
    if status is not None:
        return status
    who = f" (process {run.process_index} of {run.process_count})" if run.process_count > 1 else ""
    print(f"{prog}: {run.eyes_computed} eyes in {len(run.computed_chunks)} chunks computed"
          f"{who}, {len(run.skipped_chunks)} chunks already complete; "
          f"{run.eyes_per_second:.2f} eyes/s, peak memory {run.peak_rss_mb:.0f} MiB")
    print(f"{prog}: store {out} ({time.perf_counter() - args.t_start:.1f} s)")
    return 0
