"""One writer at a time on a sweep store: :class:`StoreLock`, the file ``STORE.lock`` beside
the store, created atomically and taken over when its holder is gone.
"""

from __future__ import annotations

import json
import os
import socket
from pathlib import Path

from lfjax.base.files import pid_alive, register_emergency_cleanup, unregister_emergency_cleanup
from lfjax._version import utc_now

LOCK_SUFFIX = ".lock"


def lock_path(path) -> Path:
    """The lock file of the store at ``path``: ``STORE.lock`` beside it."""
    path = Path(path)
    return path.with_name(path.name + LOCK_SUFFIX)


class StoreLockedError(RuntimeError):
    """Another live process is writing the store (``holder``: its host, PID, start)."""

    def __init__(self, path, holder: dict):
        self.holder = holder
        super().__init__(
            f"{path} is being written by another process: host {holder.get('host')}, PID "
            f"{holder.get('pid')}, since {holder.get('started_utc')}. Wait for it to finish; if "
            f"that process is gone (another host cannot be checked from here), delete "
            f"{lock_path(path)} and resume.")


class StoreLock:
    """An exclusive writer's lock on a store: the file ``STORE.lock`` beside it (inside, Zarr
    would list it as a stray node) holding the host, PID and start time of its holder,
    created atomically (O_EXCL). A lock whose holder ran on this host and is no longer alive
    is stale: it is taken over (``recovered`` names it). Use as a context manager."""

    def __init__(self, path):
        self.file = lock_path(path)
        self.path = Path(path)
        self.recovered: dict | None = None
        self.record = {"host": socket.gethostname(), "pid": os.getpid(), "started_utc": utc_now()}

    def acquire(self) -> StoreLock:
        for _ in range(2):
            try:
                fd = os.open(self.file, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o644)
            except FileExistsError:
                holder = self._holder()
                if (holder.get("host") == self.record["host"]
                        and isinstance(holder.get("pid"), int)
                        and not pid_alive(holder["pid"])):
                    self.recovered = holder  # stale: its process died (SIGKILL, power)
                    self.file.unlink(missing_ok=True)
                    continue
                raise StoreLockedError(self.path, holder) from None
            with os.fdopen(fd, "w") as f:
                json.dump(self.record, f)
            register_emergency_cleanup(id(self), self.release)  # also on an immediate exit
            return self
        raise StoreLockedError(self.path, self._holder())

    def _holder(self) -> dict:
        try:
            return json.loads(self.file.read_text())
        except (OSError, ValueError):
            return {"host": "?", "pid": "?", "started_utc": "? (unreadable lock file)"}

    def release(self) -> None:
        unregister_emergency_cleanup(id(self))
        if self._holder().get("pid") == self.record["pid"]:
            self.file.unlink(missing_ok=True)

    def __enter__(self) -> StoreLock:
        return self.acquire()

    def __exit__(self, *exc) -> None:
        self.release()


__all__ = [
    "lock_path",
    "LOCK_SUFFIX",
    "StoreLock",
    "StoreLockedError",
]
