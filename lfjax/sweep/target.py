"""Where a sweep's store goes: checked before any work (a dry run included), so a store that
cannot be written, or one that exists without ``resume``, is refused before planning.

A new store is built beside its final path and renamed into place; an existing store is
completed in place and locked by a lock file beside it (:mod:`lfjax.sweep.store`). Both
checks name the parameter ``store``'s path was given as.
"""

from __future__ import annotations

from pathlib import Path

from lfjax.base.errors import ParameterError
from lfjax.base.files import check_writable


def check_store_writable(store) -> None:
    """``store`` can be written: a new store's folder (the nearest existing one above it: the
    store is created beside it and renamed), or an existing store and the folder holding its
    lock file; else a :class:`~lfjax.base.errors.ParameterError` naming ``store``."""
    out = Path(store)
    if out.exists() and not out.is_dir():
        raise ParameterError("store", "{store} {path} exists and is not a folder", path=out)
    check_writable(out.absolute().parent if out.exists() else out, parameter="store")
    if out.is_dir():
        check_writable(out, parameter="store")


def check_store_target(store, resume: bool = False) -> bool:
    """Whether the store ``store`` exists; a ``FileExistsError`` when it does and ``resume``
    is not set (:func:`lfjax.sweep.run.run_sweep` checks it first; a command line checks it
    before any work)."""
    exists = Path(store).exists()
    if exists and not resume:
        raise FileExistsError(
            f"{store} already exists: pass --resume (resume=True) to complete it, or choose "
            f"another --out")
    return exists


__all__ = ["check_store_writable", "check_store_target"]
