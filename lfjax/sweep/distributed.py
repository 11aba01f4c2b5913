"""Starting a sweep over several processes or hosts (``jax.distributed``), with a time-out
that says who is missing.

:func:`start_distributed` calls ``jax.distributed.initialize`` before anything touches a JAX
device. XLA's own wait for the processes (300 s by default) ends the process with SIGABRT
and a C++ stack trace, and the main thread cannot be interrupted while it waits; so a
watcher thread stops the process after ``timeout_s`` seconds with one line naming the
coordinator, the processes seen and the time waited (XLA's time-out is set later than the
watcher's). The coordinator's process counts the processes that reached it from the
kernel's socket table (:func:`clients_connected`, Linux); any other process can see only
whether the coordinator answers (:func:`coordinator_reachable`).
"""

from __future__ import annotations

import os
import socket
import sys
import threading
import time
from collections.abc import Callable

import jax

from lfjax.base.errors import ParameterError

DISTRIBUTED_TIMEOUT_S = 60
"""Default of :func:`start_distributed`'s ``timeout_s``: seconds a process waits for its
peers at start-up."""

XLA_GRACE_S = 60
"""Seconds XLA's own start-up time-out is set later than the watcher's, so the watcher's
one-line message comes first."""


def check_coordinator(address: str | None) -> str | None:
    """``address`` if it is HOST:PORT — a host name or address (an IPv6 address in
    brackets, ``[::1]:1234``) and a port, a whole number 1 ... 65535 — or None (found from
    the cluster environment); else a :class:`~lfjax.base.errors.ParameterError` naming
    ``coordinator_address``, before anything starts."""
    if address is None:
        return None
    host, colon, port = str(address).strip().rpartition(":")
    bare = host[1:-1] if host.startswith("[") and host.endswith("]") else host
    ok = (colon and bare and not any(c.isspace() for c in bare) and port.isascii()
          and port.isdigit() and 1 <= int(port) <= 65535 and (":" not in bare or host != bare))
    if not ok:
        raise ParameterError(
            "coordinator_address", "{coordinator_address} must be HOST:PORT (a host name or "
            "address, an IPv6 one in brackets, and a port 1 ... 65535, e.g. host0:12345), "
            "got {got!r}", got=address)
    return str(address).strip()


def coordinator_reachable(address: str | None) -> str:
    """Whether something accepts connections at ``address`` (HOST:PORT), in words."""
    host, _, port = (address or "").rpartition(":")
    if not host or not port.isdigit():
        return "the coordinator's address is unknown"
    try:
        with socket.create_connection((host.strip("[]"), int(port)), timeout=1.0):
            return "the coordinator accepts connections"
    except OSError as err:
        return f"the coordinator does not answer ({err.strerror or err})"


def clients_connected(address: str | None) -> int | None:
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


def startup_timeout(coordinator_address: str | None, num_processes: int | None,
                    process_id: int | None, waited_s: float) -> ParameterError:
    """The error of a start-up that waited ``waited_s`` seconds for processes that did not
    come: who runs the coordinator, who this process saw, and what to change. A
    :class:`~lfjax.base.errors.ParameterError` (not raised: a caller renders it with its own
    names for ``coordinator_address``, ``num_processes``, ``process_id`` and ``timeout_s``)."""
    address, n, i = coordinator_address, num_processes, process_id
    total = n if n is not None else "?"
    seen = clients_connected(address) if i == 0 else None
    if seen:
        # the coordinator sees who reached it; a peer sees only itself
        saw = f"{seen} of {total} processes connected to it (this one, process 0, included)"
    else:
        saw = (f"this process (process {i if i is not None else '?'} of {total}) "
               f"cannot see which others did; {coordinator_reachable(address)}")
    return ParameterError(
        "timeout_s", "distributed start-up: not every process connected to the coordinator "
        "{address}{role} within {waited:.0f} s: {saw}. Start all {n} processes with the same "
        "{coordinator_address} and {num_processes}, each with its own {process_id}, or wait "
        "longer ({timeout_s})",
        address=address or "(from the cluster environment)",
        role=" (this process runs it)" if i == 0 else "", waited=waited_s, saw=saw,
        n=n if n is not None else "")


def start_distributed(coordinator_address: str | None = None, num_processes: int | None = None,
                      process_id: int | None = None, *,
                      timeout_s: float = DISTRIBUTED_TIMEOUT_S,
                      on_timeout: Callable[[ParameterError], None] | None = None) -> None:
    """``jax.distributed.initialize`` (module docstring), given ``timeout_s`` seconds for every
    process to connect.

    Parameters
    ----------
    coordinator_address, num_processes, process_id : as ``jax.distributed.initialize``
        (None: found from the cluster environment)
    timeout_s : seconds to wait for every process, > 0
    on_timeout : told the :func:`startup_timeout` error when the wait is over (default:
        printed on stderr); the process then exits with status 1 at once, since its main
        thread is held inside XLA

    Call it before anything touches a JAX device; an error of ``jax.distributed.initialize``
    itself (e.g. a backend already started) is raised as it comes.
    """
    if not (timeout_s > 0):
        raise ParameterError("timeout_s", "{timeout_s} must be > 0 s, got {got}", got=timeout_s)
    coordinator_address = check_coordinator(coordinator_address)
    given = {k: v for k, v in (("coordinator_address", coordinator_address),
                               ("num_processes", num_processes),
                               ("process_id", process_id)) if v is not None}
    started = time.monotonic()
    connected = threading.Event()

    def give_up() -> None:
        if connected.wait(timeout_s):
            return
        err = startup_timeout(coordinator_address, num_processes, process_id,
                              time.monotonic() - started)
        if on_timeout is None:
            print(f"lfjax.sweep: error: {err}", file=sys.stderr, flush=True)
        else:
            on_timeout(err)
        os._exit(1)

    threading.Thread(target=give_up, name="lfjax-distributed-start", daemon=True).start()
    try:
        jax.distributed.initialize(**given, initialization_timeout=int(timeout_s) + XLA_GRACE_S)
    finally:
        connected.set()


__all__ = ["DISTRIBUTED_TIMEOUT_S", "check_coordinator", "clients_connected", "coordinator_reachable",
           "start_distributed", "startup_timeout"]
