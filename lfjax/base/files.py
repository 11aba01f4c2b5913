"""Temporary folders named after their process, so the next run can clean up after a kill.

A folder built before it is renamed into place (a sweep store, a reproduction's results) is
named ``PREFIX-HOST-PID-RANDOM``. A SIGKILL leaves it behind; :func:`remove_orphans` later
removes those whose process ran on this host and is gone, and leaves a live process's, or
another host's (whose processes cannot be checked from here), alone.

:func:`check_output_folder` checks, before any work, a folder a result will be written into.
"""

from __future__ import annotations

import os
import shutil
import socket
import sys
import tempfile
from pathlib import Path

from lfjax.base.errors import ParameterError


def pid_alive(pid: int) -> bool:
    """Whether process ``pid`` exists on this host."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # alive, another user's
        return True
    return True


def owned_temp_dir(parent, prefix: str) -> Path:
    """A new empty folder ``parent/PREFIX-HOST-PID-RANDOM`` (``prefix`` starts with '.')."""
    return Path(tempfile.mkdtemp(prefix=f"{prefix}-{socket.gethostname()}-{os.getpid()}-",
                                 dir=parent))


def remove_orphans(parent, prefix: str, what: str) -> list[Path]:
    """Remove ``parent/PREFIX-HOST-PID-*`` folders of dead processes on this host, saying
    so on stderr (``what`` names what left them); returns them."""
    host = socket.gethostname()
    removed = []
    for folder in Path(parent).glob(f"{prefix}-{host}-*"):
        pid = folder.name[len(f"{prefix}-{host}-"):].split("-", 1)[0]
        if folder.is_dir() and pid.isdigit() and not pid_alive(int(pid)):
            shutil.rmtree(folder, ignore_errors=True)
            removed.append(folder)
    if removed:
        print(f"lfjax: removed {len(removed)} folder(s) left by {what}: "
              f"{', '.join(p.name for p in removed)}", file=sys.stderr)
    return removed


def check_output_folder(out_dir, force: bool = False) -> Path:
    """``out_dir`` as a Path if a result may be written into it: a new folder, an empty one,
    or (``force``) one with files in it (files of the same names are then replaced).
    Otherwise a :class:`~lfjax.base.errors.ParameterError` naming ``out_dir``. Reads the
    folder only: call it before any work."""
    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise ParameterError("out_dir", "{out_dir} {path} exists and is not a folder", path=out)
    if out.is_dir() and any(out.iterdir()) and not force:
        raise ParameterError("out_dir", "{out_dir} {path} is not empty (use {force} to write into it)",
                             path=out)
    return out
