"""lfjax.sweep.store_lock: one writer at a time on a store (no JAX, no store needed: the
lock is a file beside the store's path)."""

import json
import os
import socket
import subprocess
import sys

import pytest

from lfjax.base import files
from lfjax.sweep.store_lock import LOCK_SUFFIX, StoreLock, StoreLockedError, lock_path


def test_the_lock_file_lies_beside_the_store(tmp_path):
    assert lock_path(tmp_path / "pop.zarr") == tmp_path / f"pop.zarr{LOCK_SUFFIX}"


def test_a_second_writer_is_refused_until_the_first_releases(tmp_path):
    store = tmp_path / "pop.zarr"
    with StoreLock(store) as lock:
        holder = json.loads(lock_path(store).read_text())
        assert holder["pid"] == os.getpid() and holder["host"] == socket.gethostname()
        with pytest.raises(StoreLockedError, match=f"PID {os.getpid()}"):
            StoreLock(store).acquire()
    assert not lock_path(store).exists()
    with StoreLock(store):  # free again
        pass


def test_a_dead_holders_lock_is_taken_over(tmp_path):
    store = tmp_path / "pop.zarr"
    gone = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"],
                          capture_output=True, text=True, check=True)
    stale = {"host": socket.gethostname(), "pid": int(gone.stdout), "started_utc": "then"}
    lock_path(store).write_text(json.dumps(stale))
    with StoreLock(store) as lock:
        assert lock.recovered == stale
    assert not lock_path(store).exists()


def test_an_emergency_exit_releases_the_lock(tmp_path):
    store = tmp_path / "pop.zarr"
    lock = StoreLock(store).acquire()
    files.emergency_cleanup()
    assert not lock_path(store).exists()
    lock.release()  # nothing left to release
