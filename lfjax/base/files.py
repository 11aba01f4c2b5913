"""Temporary folders named after their process, so the next run can clean up after a kill.

A folder built before it is renamed into place (a sweep store, a reproduction's results) is
named ``PREFIX-HOST-PID-RANDOM``. A SIGKILL leaves it behind; :func:`remove_orphans` later
removes those whose process ran on this host and is gone, and leaves a live process's, or
another host's (whose processes cannot be checked from here), alone.

:func:`check_output_folder` checks, before any work, a folder a result will be written into
(new or empty, writable, with room for the estimated outputs). :func:`staged_output` builds
a result in a staging folder and moves it into place when complete — a new folder renamed
into place whole, or, into a folder that exists (a mount point, a folder whose parent is
read-only), its files renamed in one by one, each whole; :func:`staging_parent` says which,
and both check the same folder. :func:`atomic_write_bytes` (``_text``,
:func:`atomic_savefig`) writes one file whole or not at all (temporary name, then rename).
"""

from __future__ import annotations

import contextlib
import io
import os
import shutil
import socket
import sys
import tempfile
from pathlib import Path

from lfjax.base.errors import ParameterError
from lfjax.base.units import format_bytes


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
    removed = []
    for folder in Path(parent).glob(f"{prefix}-{socket.gethostname()}-*"):
        if folder.is_dir() and is_orphan(folder, prefix):
            shutil.rmtree(folder, ignore_errors=True)
            removed.append(folder)
    if removed:
        print(f"lfjax: removed {len(removed)} folder(s) left by {what}: "
              f"{', '.join(p.name for p in removed)}", file=sys.stderr)
    return removed


def is_orphan(folder, prefix: str) -> bool:
    """Whether ``folder`` is named ``PREFIX-HOST-PID-…`` for this host and a process that
    is gone (its owner was killed)."""
    head = f"{prefix}-{socket.gethostname()}-"
    name = Path(folder).name
    if not name.startswith(head):
        return False
    pid = name[len(head):].split("-", 1)[0]
    return pid.isdigit() and not pid_alive(int(pid))


# ----------------------------------------------------------------------------- output folders

PROBE_PREFIX = ".lfjax-write-probe"


def nearest_existing(path) -> Path:
    """``path`` itself or its nearest existing ancestor (where a new folder would be made)."""
    p = Path(path).absolute()
    while not p.exists() and p.parent != p:
        p = p.parent
    return p


def staging_parent(out_dir) -> Path:
    """Where :func:`staged_output` builds a result for ``out_dir``, and so the folder that
    must take files and hold the result's size: ``out_dir`` itself when it is an existing
    folder (the result's files are then renamed into it one by one: a mount point, or a
    folder whose parent is read-only, can be written into but not renamed or replaced),
    else the nearest existing folder above it (the staging folder is renamed to
    ``out_dir`` whole)."""
    out = Path(out_dir).absolute()
    return out if out.is_dir() else nearest_existing(out.parent)


def folder_contents(out_dir) -> list[Path]:
    """What an existing output folder holds, less the staging folders of
    :func:`staged_output` runs that were killed (removed by the next run into it)."""
    out = Path(out_dir)
    prefix = f"{STAGING_PREFIX}-{out.absolute().name}"
    return [p for p in out.iterdir() if not (p.is_dir() and is_orphan(p, prefix))]


def check_output_folder(out_dir, force: bool = False, *, need_bytes: int = 0,
                        parameter: str = "out_dir") -> Path:
    """``out_dir`` as a Path if a result may be written into it, checked before any work:

    * a new folder, an empty one, or (``force``) one with files in it (files of the same
      names are then replaced); not a file;
    * writable where :func:`staged_output` will build the result (:func:`staging_parent`:
      the folder itself when it exists, a mount point included; for a new folder, its
      nearest existing ancestor): a probe file is created and removed there, so a
      read-only folder or file system is found now, not after the work (permission bits
      alone say nothing for root or a read-only mount);
    * ``need_bytes`` (the estimated size of what will be written, bytes) free on that
      folder's file system.

    Otherwise a :class:`~lfjax.base.errors.ParameterError` naming ``parameter`` (the
    caller's name for the folder: ``out_dir``, ``out``, ``store``)."""
    out = Path(out_dir)
    name = "{" + parameter + "}"
    if out.exists() and not out.is_dir():
        raise ParameterError(parameter, name + " {path} exists and is not a folder", path=out)
    if out.is_dir() and folder_contents(out) and not force:
        raise ParameterError(parameter, name + " {path} is not empty (use {force} to write "
                             "into it)", path=out)
    check_writable(out, need_bytes, parameter)  # in staging_parent(out), or refused there
    return out


def check_writable(path, need_bytes: int = 0, parameter: str = "out_dir",
                   shown=None) -> Path:
    """The folder where ``path`` (a folder or file to be made) would be written: ``path``
    when it is an existing folder, else its nearest existing ancestor, if a file can be
    created there and ``need_bytes`` are free on its file system; otherwise a
    :class:`~lfjax.base.errors.ParameterError` naming ``parameter``, one line, before any
    work. ``shown``: the path the message names (default ``path``)."""
    path = Path(path)
    anchor = path if path.is_dir() else nearest_existing(path.parent)
    path = path if shown is None else Path(shown)
    name = "{" + parameter + "}"
    if not anchor.is_dir():
        raise ParameterError(parameter, "cannot create " + name + " {path}: {anchor} is not a "
                             "folder", path=path, anchor=anchor)
    try:
        fd, probe = tempfile.mkstemp(prefix=PROBE_PREFIX, dir=anchor)
        os.close(fd)
        os.unlink(probe)
    except OSError as err:
        why = os.strerror(err.errno) if err.errno else str(err)
        raise ParameterError(parameter, name + " {path} is not writable: cannot create a file "
                             "in {anchor} ({why})", path=path, anchor=anchor, why=why) from None
    if need_bytes > 0:
        free = shutil.disk_usage(anchor).free
        if free < need_bytes:
            raise ParameterError(parameter, name + " {path}: not enough free space on its disk "
                                 "({free} free, about {need} needed for the outputs)", path=path,
                                 free=format_bytes(free), need=format_bytes(need_bytes))
    return anchor


def atomic_write_bytes(path, data: bytes) -> Path:
    """Write ``data`` to ``path`` whole or not at all: into a temporary file beside it
    (``.NAME.tmp-PID-…``), flushed to disk, then renamed over ``path``. A failure (a full
    disk, an interrupt) leaves ``path`` as it was and removes the temporary file."""
    path = Path(path)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.tmp-{os.getpid()}-", dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
        os.chmod(tmp, 0o666 & ~_umask())  # mkstemp makes it private; the result is ordinary
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return path


def atomic_write_text(path, text: str) -> Path:
    """:func:`atomic_write_bytes` of ``text`` in UTF-8."""
    return atomic_write_bytes(path, text.encode("utf-8"))


def atomic_savefig(fig, path, **kwargs) -> Path:
    """``fig.savefig(path, **kwargs)`` whole or not at all (rendered in memory, then
    :func:`atomic_write_bytes`); the format follows ``path``'s suffix."""
    buffer = io.BytesIO()
    fig.savefig(buffer, format=Path(path).suffix.lstrip(".") or "png", **kwargs)
    return atomic_write_bytes(path, buffer.getvalue())


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


STAGING_PREFIX = ".lfjax-staging"
"""Prefix of the folders :func:`staged_output` builds results in (``.lfjax-staging-NAME``…)."""

_LIVE_STAGING: set[Path] = set()  # what an emergency exit (a second Ctrl-C) removes


_EMERGENCY_CLEANUPS: dict[int, object] = {}  # id -> callable, e.g. a store lock's release


def live_staging_folders() -> list[Path]:
    """The staging folders of :func:`staged_output` now being written by this process."""
    return sorted(_LIVE_STAGING)


def register_emergency_cleanup(key: int, cleanup) -> None:
    """Have :func:`emergency_cleanup` call ``cleanup()`` (e.g. release a lock) until
    :func:`unregister_emergency_cleanup` (``key``: e.g. ``id`` of its owner)."""
    _EMERGENCY_CLEANUPS[key] = cleanup


def unregister_emergency_cleanup(key: int) -> None:
    _EMERGENCY_CLEANUPS.pop(key, None)


def emergency_cleanup() -> None:
    """What an immediate exit (a Ctrl-C that the main thread cannot answer in time) must
    still do: remove this process's staging folders and run the registered clean-ups
    (errors ignored: the process is ending)."""
    for folder in live_staging_folders():
        shutil.rmtree(folder, ignore_errors=True)
    for cleanup in list(_EMERGENCY_CLEANUPS.values()):
        try:
            cleanup()
        except Exception:  # noqa: BLE001 - best effort on the way out
            pass


@contextlib.contextmanager
def staged_output(out_dir, force: bool = False, *, replace: bool = False):
    """Build a result folder whole, or its files each whole, never a file in part.

    Which way is decided on entry, before the block's work (:func:`staging_parent`; the
    folder :func:`check_output_folder` checked):

    * ``out_dir`` does not exist: the result is built in ``.lfjax-staging-NAME-HOST-PID-…``
      beside it (in its nearest existing ancestor, so on the same file system) and renamed
      to ``out_dir`` when the block ends: one rename, so a reader sees no folder, then the
      complete one (folders above it are made only then).
    * ``out_dir`` exists (empty, or with files and ``force``; else FileExistsError on
      entry): the result is built in such a hidden folder inside it, so a mount point or a
      folder in a read-only parent works, and each file is renamed into ``out_dir`` when the
      block ends (files of the same names replaced). A reader sees the hidden folder while
      the block runs, then the files appear one by one, each whole; with ``replace`` (an
      earlier result is replaced, not merged) the files of the earlier result that the new
      one does not have are removed after the new ones are in.

    When the block raises (an error, a full disk, Ctrl-C) the staging folder is removed and
    ``out_dir`` and its parents are as they were. A process killed in the block, or in the
    final renames (a few milliseconds), leaves no partial file — at most some of the new
    files in ``out_dir`` — and its staging folder, which the next call for ``out_dir``
    removes (:func:`remove_orphans`) and :func:`check_output_folder` does not count as
    contents."""
    out = Path(out_dir).absolute()
    parent = staging_parent(out)
    if parent == out and folder_contents(out) and not force:
        raise FileExistsError(f"{out} is not empty: the result is not written into it "
                              f"without force")
    prefix = f"{STAGING_PREFIX}-{out.name}"
    remove_orphans(parent, prefix, "an interrupted run")
    tmp = owned_temp_dir(parent, prefix)
    os.chmod(tmp, 0o777 & ~_umask())  # mkdtemp makes it private; the result is ordinary
    _LIVE_STAGING.add(tmp)
    try:
        yield tmp
        if not out.exists():
            out.parent.mkdir(parents=True, exist_ok=True)
            try:
                os.replace(tmp, out)  # one rename: the folder appears complete
                return
            except OSError:
                if not out.is_dir():  # not made meanwhile: a real failure
                    raise
        _move_files_in(tmp, out, force, replace)
    finally:
        _LIVE_STAGING.discard(tmp)
        if tmp.exists():
            shutil.rmtree(tmp, ignore_errors=True)


def _move_files_in(tmp: Path, out: Path, force: bool, replace: bool) -> None:
    """Each item of ``tmp`` renamed into the existing folder ``out`` (a file: one atomic
    rename over one of the same name; a folder: the old one removed first); with
    ``replace``, then the rest of ``out`` removed (other staging folders left alone)."""
    earlier = [p for p in folder_contents(out) if p != tmp]
    if earlier and not force:
        raise FileExistsError(f"{out} is no longer empty: the result is not moved into it")
    items = sorted(tmp.iterdir())
    for item in items:
        target = out / item.name
        if target.is_dir() and not item.is_dir():
            raise IsADirectoryError(f"{target} is a folder; the file {item.name} would replace it")
    for item in items:
        target = out / item.name
        if item.is_dir() and target.exists():
            shutil.rmtree(target) if target.is_dir() else target.unlink()
        os.replace(item, target)
    if replace:
        new = {item.name for item in items}
        for old in earlier:
            if old.name in new or old.name.startswith(STAGING_PREFIX):
                continue
            shutil.rmtree(old) if old.is_dir() and not old.is_symlink() else old.unlink()
