"""Plans remembered: :func:`lfjax.planner.plan.plan_sampling` is pure and its wavelength search
costs seconds of host work per layout (3–10 s for the paper's layouts, the proxy on a 5 nm
reference), so a second ask of the same plan should cost nothing.

:func:`cached_plan_sampling` keys a plan by everything it is computed from — every argument
(the :class:`~lfjax.planner.scene.PlanScene`, the :class:`~lfjax.planner.targets.Targets`, the
overrides and the guard), by value (arrays by their bytes, dataclasses and equinox modules
field by field, defaults filled in) — and by the source of the package and the numpy version, so an edited planner or a new release
never answers from an old plan. Plans are kept for the process; with
:func:`enable_plan_cache` (the command line turns it on beside JAX's compilation cache) also
on disk, one pickle per plan, so a warm ``lfjax reproduce`` or a resumed sweep re-plans
nothing. An unreadable file is planned again and rewritten, never trusted.
"""

from __future__ import annotations

import dataclasses
import hashlib
import inspect
import os
import pickle
import tempfile
from pathlib import Path

import numpy as np

from lfjax.base.programs import cache_folder, source_digest
from lfjax.planner.plan import Plan, plan_sampling

_SIGNATURE = inspect.signature(plan_sampling)  # the arguments a plan is keyed by
_MEMORY: dict[str, object] = {}
_MEMORY_SIZE = 256
_FOLDER: Path | None = None


def enable_plan_cache(folder) -> Path | None:
    """Keep plans on disk in ``folder`` (created if needed); None turns the disk cache off.
    Returns the folder, or None when it cannot be written (plans are then kept in memory
    only)."""
    global _FOLDER
    _FOLDER = cache_folder(folder)
    return _FOLDER


def plan_cache_folder() -> Path | None:
    """Where plans are kept on disk, or None (memory only)."""
    return _FOLDER


def _code_version() -> str:
    """The package's source digest and numpy's version: a plan is valid for exactly the
    code that made it."""
    return f"{source_digest()}:{np.__version__}"


def _feed(digest, value) -> None:
    """Feed ``value`` into ``digest`` unambiguously (type, shape and content)."""
    if value is None or isinstance(value, (bool, int, float, str)):
        digest.update(f"{type(value).__name__}:{value!r};".encode())
    elif dataclasses.is_dataclass(value) and not isinstance(value, type):
        digest.update(f"{type(value).__module__}.{type(value).__qualname__}{{".encode())
        for f in dataclasses.fields(value):
            digest.update(f"{f.name}=".encode())
            _feed(digest, getattr(value, f.name))
        digest.update(b"}")
    elif isinstance(value, dict):
        digest.update(b"dict{")
        for key in sorted(value, key=repr):
            _feed(digest, key)
            _feed(digest, value[key])
        digest.update(b"}")
    elif isinstance(value, (tuple, list)) and not all(
            isinstance(v, (int, float, np.number)) and not isinstance(v, bool) for v in value):
        digest.update(f"{type(value).__name__}[".encode())
        for v in value:
            _feed(digest, v)
        digest.update(b"]")
    else:  # arrays (numpy, jax) and sequences of numbers, by value
        array = np.asarray(value)
        if array.dtype.kind in "biuf":
            array = array.astype(np.float64)
        digest.update(f"array{array.dtype.str}{array.shape}:".encode())
        digest.update(np.ascontiguousarray(array).tobytes())


def plan_key(*args, **kwargs) -> str:
    """Hex key of a :func:`~lfjax.planner.plan.plan_sampling` call with these arguments (each
    named as the function names it, defaults filled in, so a default given or left out is
    the same plan)."""
    bound = _SIGNATURE.bind(*args, **kwargs)
    bound.apply_defaults()
    digest = hashlib.sha256(_code_version().encode())
    for name in sorted(bound.arguments):
        digest.update(f"{name}=".encode())
        _feed(digest, bound.arguments[name])
    return digest.hexdigest()


def cached_plan_sampling(*args, **kwargs) -> Plan:
    """:func:`lfjax.planner.plan.plan_sampling` with the same arguments, answered from memory
    or the disk cache when the same plan was made before by the same code."""
    key = plan_key(*args, **kwargs)
    if key in _MEMORY:
        return _MEMORY[key]
    plan = _read(key, Plan)
    if plan is None:
        plan = plan_sampling(*args, **kwargs)
        _write(key, plan)
    if len(_MEMORY) >= _MEMORY_SIZE:
        _MEMORY.pop(next(iter(_MEMORY)))
    _MEMORY[key] = plan
    return plan


def _read(key: str, kind):
    if _FOLDER is None:
        return None
    path = _FOLDER / f"{key}.pkl"
    try:
        with open(path, "rb") as f:
            plan = pickle.load(f)
    except FileNotFoundError:
        return None
    except Exception:  # noqa: BLE001 - a damaged or foreign file is re-planned, not trusted
        return None
    return plan if isinstance(plan, kind) else None


def _write(key: str, plan) -> None:
    if _FOLDER is None:
        return
    tmp = None
    try:  # written whole, then renamed: a reader never sees half a file
        fd, tmp = tempfile.mkstemp(dir=_FOLDER, suffix=".tmp")
        with os.fdopen(fd, "wb") as f:
            pickle.dump(plan, f, protocol=pickle.HIGHEST_PROTOCOL)
        os.replace(tmp, _FOLDER / f"{key}.pkl")
    except OSError:  # the cache is an optimisation: a full or read-only disk costs a re-plan
        if tmp is not None and os.path.exists(tmp):
            os.unlink(tmp)


def clear_memory() -> None:
    """Forget the plans kept in this process (the disk cache stays)."""
    _MEMORY.clear()
