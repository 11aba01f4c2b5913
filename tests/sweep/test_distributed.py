"""Starting a sweep over several processes (lfjax.sweep.distributed): the coordinator's
count of connected processes, a peer's view of the coordinator, and the one-line time-out
that names what to change, on local sockets and a stand-in for jax.distributed (the real
multi-process runs are in test_sweep.py)."""

import socket
import threading

import pytest

from lfjax.base.errors import ParameterError
from lfjax.sweep import distributed


@pytest.fixture
def listening():
    """A local server socket (HOST:PORT) with two clients connected to it."""
    server = socket.create_server(("127.0.0.1", 0))
    address = f"127.0.0.1:{server.getsockname()[1]}"
    clients = [socket.create_connection(server.getsockname()) for _ in range(2)]
    accepted = [server.accept()[0] for _ in clients]
    yield address
    for s in clients + accepted + [server]:
        s.close()


def test_the_coordinator_counts_the_processes_connected_to_it(listening):
    assert distributed.clients_connected(listening) == 2
    assert distributed.clients_connected("no port") is None


def test_a_peer_says_whether_the_coordinator_answers(listening):
    assert distributed.coordinator_reachable(listening) == "the coordinator accepts connections"
    assert distributed.coordinator_reachable(None) == "the coordinator's address is unknown"
    with socket.create_server(("127.0.0.1", 0)) as s:
        closed = f"127.0.0.1:{s.getsockname()[1]}"
    assert distributed.coordinator_reachable(closed).startswith("the coordinator does not answer")


def test_the_time_out_names_the_coordinator_who_was_seen_and_what_to_change(listening):
    err = distributed.startup_timeout(listening, 3, 0, 4.2)
    assert err.parameter == "timeout_s"
    text = err.naming({"timeout_s": "--distributed-timeout", "process_id": "--process-id"})
    assert text.startswith(f"distributed start-up: not every process connected to the "
                           f"coordinator {listening} (this process runs it) within 4 s: 2 of 3 "
                           f"processes connected to it (this one, process 0, included)"), text
    assert text.endswith("each with its own --process-id, or wait longer (--distributed-timeout)")
    peer = str(distributed.startup_timeout(None, None, None, 1.0))
    assert "(from the cluster environment)" in peer
    assert "this process (process ? of ?) cannot see which others did" in peer


def test_a_start_up_that_times_out_is_told_and_ends_the_process(monkeypatch):
    stopped, told = threading.Event(), []

    def waits(**kwargs):  # jax.distributed.initialize waiting for peers that never come
        told.append(kwargs)
        stopped.wait(10)

    def exit_(status):  # the watcher's os._exit, recorded instead of ending pytest
        told.append(status)
        stopped.set()

    monkeypatch.setattr(distributed.jax.distributed, "initialize", waits)
    monkeypatch.setattr(distributed.os, "_exit", exit_)
    distributed.start_distributed("127.0.0.1:1", 2, 1, timeout_s=0.2, on_timeout=told.append)
    assert told[0] == dict(coordinator_address="127.0.0.1:1", num_processes=2, process_id=1,
                           initialization_timeout=0 + distributed.XLA_GRACE_S)
    assert isinstance(told[1], ParameterError) and told[2] == 1


def test_a_bad_time_out_is_refused():
    with pytest.raises(ParameterError, match="timeout_s must be > 0"):
        distributed.start_distributed(timeout_s=0)


@pytest.mark.parametrize("address", ["nonsense", "host:0", "host:65536", ":80", "host:8o",
                                     "::1:1234", "two words:80"])
def test_a_malformed_coordinator_is_refused_naming_the_form(address):
    with pytest.raises(ParameterError, match=r"coordinator_address must be HOST:PORT .* port "
                                             r"1 \.\.\. 65535") as err:
        distributed.start_distributed(address, 2, 0, timeout_s=1)
    assert err.value.naming({"coordinator_address": "--coordinator"}).startswith("--coordinator ")


@pytest.mark.parametrize("address", ["host0:12345", "10.0.0.1:1", "[::1]:65535"])
def test_a_well_formed_coordinator_is_accepted(address):
    assert distributed.check_coordinator(address) == address
    assert distributed.check_coordinator(None) is None
