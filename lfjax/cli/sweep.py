"""``lfjax sweep``: a population sweep into a resumable Zarr store (:func:`lfjax.sweep.run_sweep`)."""

from __future__ import annotations

import argparse
import os
import signal
import socket
import sys
import threading
import time
from pathlib import Path

import jax

from lfjax.base.errors import ParameterError
from lfjax.base.files import atomic_write_text, check_writable
from lfjax.cli import common
from lfjax.sweep import (
    StoreMismatchError,
    SweepConfigError,
    SweepTooLargeError,
    load_config,
    plan_sweep,
    run_sweep,
)
from lfjax.sweep.config_files import config_template
from lfjax.sweep.run import check_store_target
from lfjax.sweep.store import is_disk_full, StoreRaceError
from lfjax.sweep.store_checks import StoreDamagedError, verify_store
from lfjax.sweep.store_lock import StoreLockedError

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
    common.add_out(sw, None, "Zarr store to write (default: CONFIG's name with .zarr, in the "
                             "current folder); must not exist unless --resume", metavar="STORE")
    sw.add_argument("--resume", action="store_true",
                    help="complete an existing STORE made by the same config (finished chunks "
                         "are skipped, those whose data fail their checksum recomputed; a store "
                         "of another config is refused, listing the differences)")
    sw.add_argument("--max-chunks", metavar="N", type=common.positive_int, default=None,
                    help="stop after computing N chunks (continue later with --resume)")
    common.add_no_progress(sw)
    sw.add_argument("--distributed", action="store_true",
                    help="call jax.distributed.initialize first (one process per host)")
    sw.add_argument("--coordinator", metavar="HOST:PORT", default=None,
                    help="with --distributed: address of process 0's coordinator service")
    sw.add_argument("--num-processes", metavar="N", type=common.positive_int, default=None,
                    help="with --distributed: total number of processes")
    sw.add_argument("--process-id", metavar="I", type=common.count, default=None,
                    help="with --distributed: this process's index, 0 ... N-1")
    sw.add_argument("--distributed-timeout", metavar="S", type=common.positive_int,
                    default=DISTRIBUTED_TIMEOUT_S,
                    help=f"with --distributed: seconds to wait for every process to connect "
                         f"to the coordinator before stopping with an error that names it "
                         f"(default {DISTRIBUTED_TIMEOUT_S})")


DISTRIBUTED_TIMEOUT_S = 60
"""Default of ``--distributed-timeout``: seconds a process waits for its peers at start-up."""


def _reachable(address: str | None) -> str:
    """Whether something accepts connections at ``address`` (HOST:PORT), in words."""
    host, _, port = (address or "").rpartition(":")
    if not host or not port.isdigit():
        return "the coordinator's address is unknown"
    try:
        with socket.create_connection((host.strip("[]"), int(port)), timeout=1.0):
            return "the coordinator accepts connections"
    except OSError as err:
        return f"the coordinator does not answer ({err.strerror or err})"


def _clients_connected(address: str | None) -> int | None:
    """Connections the coordinator running in this process holds at ``address`` (HOST:PORT):
    the established TCP sockets whose local port is the coordinator's (one per process that
    reached it, this one included), read from Linux's /proc/net/tcp and tcp6. None where
    that cannot be read."""
    port = (address or "").rpartition(":")[2]
    if not port.isdigit():
        return None
    wanted = f"{int(port):04X}"
    peers = set()
    try:
        for table in ("/proc/net/tcp", "/proc/net/tcp6"):
            with open(table) as f:
                next(f)
                for line in f:
                    field = line.split()
                    local, remote, state = field[1], field[2], field[3]
                    if state == "01" and local.rpartition(":")[2] == wanted:
                        peers.add(remote)
    except OSError:
        return None
    return len(peers)


def start_distributed(prog: str, kwargs: dict, timeout_s: float) -> None:
    """``jax.distributed.initialize(**kwargs)``, given ``timeout_s`` seconds for every
    process to connect. XLA's own time-out (300 s by default) ends the process with SIGABRT
    and a C++ stack trace; instead, a watcher thread stops this process after
    ``timeout_s`` with one line naming the coordinator, the processes seen and the time
    waited, and exit status 1 (XLA's time-out is set later than the watcher's)."""
    started = time.monotonic()
    connected = threading.Event()

    def give_up() -> None:
        if connected.wait(timeout_s):
            return
        # as given (none: from the cluster environment, which JAX does not expose)
        address, n, i = (kwargs.get(k) for k in ("coordinator_address", "num_processes",
                                                 "process_id"))
        role = " (this process runs it)" if i == 0 else ""
        total = n if n is not None else "?"
        seen = _clients_connected(address) if i == 0 else None
        if seen:
            # the coordinator sees who reached it; a peer sees only itself
            saw = (f"{seen} of {total} processes connected to it (this one, process 0, "
                   f"included)")
        else:
            saw = (f"this process (process {i if i is not None else '?'} of {total}) "
                   f"cannot see which others did; {_reachable(address)}")
        print(f"{prog}: error: distributed start-up: not every process connected to the "
              f"coordinator {address or '(from the cluster environment)'}{role} within "
              f"{time.monotonic() - started:.0f} s: {saw}. Start all {n if n is not None else ''} processes with "
              f"the same --coordinator and --num-processes, each with its own --process-id, "
              f"or wait longer (--distributed-timeout)", file=sys.stderr, flush=True)
        os._exit(1)

    threading.Thread(target=give_up, name="lfjax-distributed-start", daemon=True).start()
    try:
        jax.distributed.initialize(**kwargs, initialization_timeout=int(timeout_s) + 60)
    finally:
        connected.set()


def check_store_writable(out: Path) -> None:
    """``out`` can be written: a new store's folder (the nearest existing one above it: the
    store is created beside it and renamed), or an existing store and the folder holding its
    lock file; else a :class:`~lfjax.base.errors.ParameterError` naming ``store``."""
    if out.exists() and not out.is_dir():
        raise ParameterError("store", "{store} {path} exists and is not a folder", path=out)
    check_writable(out.absolute().parent if out.exists() else out, parameter="store")
    if out.is_dir():
        check_writable(out, parameter="store")


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
        kwargs = {k: v for k, v in (("coordinator_address", args.coordinator),
                                    ("num_processes", args.num_processes),
                                    ("process_id", args.process_id)) if v is not None}
        try:
            start_distributed(prog, kwargs, args.distributed_timeout)
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
    common.enable_compilation_cache()
    try:
        previous = signal.signal(signal.SIGTERM, _terminated)
    except ValueError:  # not the main thread: leave signals alone
        previous = None
    try:
        run = run_sweep(config, out, resume=args.resume, progress=not args.no_progress,
                        max_chunks=args.max_chunks,
                        on_plan=lambda est: print(f"{prog}: plan\n{est.summary(out)}",
                                                  flush=True))
    except KeyboardInterrupt:
        if out.exists():
            note = f"; finished chunks are kept in {out} (continue with --resume)"
        else:
            note = " before any chunk finished; no store was kept"
        return common.interrupted(prog, note)
    except (StoreMismatchError, SweepTooLargeError, StoreLockedError) as err:
        return common.refuse(prog, err, COMMAND)
    except (StoreRaceError, StoreDamagedError) as err:  # found as the run starts: one line
        print(f"{prog}: error: {' '.join(str(err).split())}", file=sys.stderr)
        return 1
    except Exception as err:  # one line, no traceback
        if is_disk_full(err):
            kept = (f"finished chunks are kept in {out}; free space and continue with --resume"
                    if out.exists() else "no chunk had finished, so no store was kept")
            print(f"{prog}: error: the disk is full: {kept}", file=sys.stderr)
            return 1
        notes = " ".join(getattr(err, "__notes__", []))
        return common.unexpected_error(prog, err, f" ({notes})" if notes else "")
    finally:
        if previous is not None:
            signal.signal(signal.SIGTERM, previous)
    who = f" (process {run.process_index} of {run.process_count})" if run.process_count > 1 else ""
    print(f"{prog}: {run.eyes_computed} eyes in {len(run.computed_chunks)} chunks computed"
          f"{who}, {len(run.skipped_chunks)} chunks already complete; "
          f"{run.eyes_per_second:.2f} eyes/s, peak memory {run.peak_rss_mb:.0f} MiB")
    print(f"{prog}: store {out} ({time.perf_counter() - args.t_start:.1f} s)")
    return 0
