"""Compiled programs kept across processes without tracing them again.

JAX's persistent compilation cache keeps what XLA compiled, but a new process must still
trace the Python function and lower it before it can even look the program up: for the
study's largest programs that is seconds each, paid by every ``lfjax`` command. With
:func:`enable_program_cache`, :func:`call_cached` exports a program once (``jax.export``:
the lowered StableHLO, serialised to disk) and later processes call the exported form,
which skips the tracing; XLA's compilation of it is then found in the compilation cache.

A program is keyed by everything that shapes it: the function, its static arguments (by
``repr``, which must be deterministic), the structure, shapes, dtypes and weak types of its
array arguments, the source of the whole package (:func:`source_digest`), the JAX and jaxlib
versions, the backend and the configuration flags that change lowering. Anything the key
cannot see must not change the program: pass only pure functions of their arguments. An
unreadable entry is exported again and rewritten; a function that cannot be exported runs
as it would without the cache.
"""

from __future__ import annotations

import functools
import hashlib
import os
import pickle
from collections.abc import Callable
from pathlib import Path

import jax
import numpy as np

from lfjax.base.files import atomic_write_bytes

_FOLDER: Path | None = None
_LOADED: dict[str, tuple[Callable, object]] = {}
_FAILED: set[str] = set()


def in_callers_jax_context(fn: Callable) -> Callable:
    """``fn`` wrapped to run, in another thread, under the calling thread's JAX settings.

    ``jax.enable_x64`` and ``jax.default_device`` used as context managers hold for their
    own thread only: a worker thread would compute in the process-wide dtype (float64
    where the caller asked for float32, or the reverse) and on the default device. The
    wrapper reads both now, in the caller, and enters them around each call.
    """
    x64 = bool(jax.config.jax_enable_x64)
    device = jax.config.jax_default_device

    @functools.wraps(fn)
    def wrapped(*args, **kwargs):
        with jax.enable_x64(x64), jax.default_device(device):
            return fn(*args, **kwargs)

    return wrapped


def cache_folder(folder) -> Path | None:
    """``folder`` created if needed and returned when this process can write in it, else
    None (a cache that cannot be written is off). None gives None."""
    if folder is None:
        return None
    path = Path(folder)
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError:
        return None
    return path if os.access(path, os.W_OK) else None


def enable_program_cache(folder) -> Path | None:
    """Keep exported programs in ``folder`` (created if needed); None turns the cache off.
    Returns the folder, or None when it cannot be written."""
    global _FOLDER
    _FOLDER = cache_folder(folder)
    return _FOLDER


def program_cache_folder() -> Path | None:
    """Where exported programs are kept, or None (the cache is off)."""
    return _FOLDER


def clear_loaded() -> None:
    """Forget the programs loaded in this process (the files stay)."""
    _LOADED.clear()
    _FAILED.clear()


@functools.lru_cache(maxsize=1)
def source_digest() -> str:
    """SHA-256 of every source file of the package (path and bytes): a cached result or
    program is valid for exactly the code that made it."""
    digest = hashlib.sha256()
    root = Path(__file__).resolve().parents[1]
    for path in sorted(root.rglob("*.py")):
        digest.update(str(path.relative_to(root)).encode())
        digest.update(path.read_bytes())
    return digest.hexdigest()


def _is_array(x) -> bool:
    return isinstance(x, (jax.Array, np.ndarray))


def _key(fn: Callable, static: dict, array_tree, arrays, rest) -> str:
    backend = jax.default_backend()
    parts = [
        "lfjax-program-v1", source_digest(), jax.__version__, jax.lib.__version__
        if hasattr(jax.lib, "__version__") else "", backend,
        str(jax.devices()[0].device_kind), str(jax.config.jax_enable_x64),
        str(jax.config.jax_default_matmul_precision),
        f"{fn.__module__}.{getattr(fn, '__qualname__', repr(fn))}",
        repr(sorted(static.items())), str(array_tree), repr(rest),
        repr([(a.shape, str(a.dtype), bool(getattr(a, "weak_type", False))) for a in arrays]),
    ]
    return hashlib.sha256("\x1f".join(parts).encode()).hexdigest()


def call_cached(fn: Callable, *args, **static):
    """``fn(*args, **static)``, from an exported program when the cache is on.

    ``args``: pytrees whose array leaves (jax or numpy) become the program's inputs (their
    other leaves are part of its key, like ``static``); ``static``: hashable keyword
    arguments with a deterministic ``repr``. Without the cache, with traced arguments, or
    when ``fn`` cannot be exported, this is exactly ``fn(*args, **static)``.
    """
    leaves, tree = jax.tree_util.tree_flatten(args)
    if _FOLDER is None or any(isinstance(x, jax.core.Tracer) for x in leaves):
        return fn(*args, **static)
    is_array = [_is_array(x) for x in leaves]
    arrays = [x for x, a in zip(leaves, is_array) if a]
    rest = [x for x, a in zip(leaves, is_array) if not a]
    key = _key(fn, static, tree, arrays, rest)
    if key in _FAILED:
        return fn(*args, **static)
    if key not in _LOADED:
        loaded = _load(key) or _export(key, fn, static, tree, is_array, arrays, rest)
        if loaded is None:
            _FAILED.add(key)
            return fn(*args, **static)
        _LOADED[key] = loaded
    call, out_tree = _LOADED[key]
    return jax.tree_util.tree_unflatten(out_tree, call(*arrays))


def _load(key: str):
    path = _FOLDER / f"{key}.jaxexport"
    try:
        with open(path, "rb") as f:
            blob, skeleton = pickle.load(f)
        out_tree = jax.tree_util.tree_structure(skeleton)
        exported = jax.export.deserialize(bytearray(blob))
    except FileNotFoundError:
        return None
    except Exception:  # noqa: BLE001 - a damaged or foreign entry is exported again
        return None
    return jax.jit(exported.call), out_tree


def _export(key: str, fn, static, tree, is_array, arrays, rest):
    box = {}

    def flat(*array_leaves):
        it_arrays, it_rest = iter(array_leaves), iter(rest)
        leaves = [next(it_arrays) if a else next(it_rest) for a in is_array]
        out = fn(*jax.tree_util.tree_unflatten(tree, leaves), **static)
        out_leaves, box["tree"] = jax.tree_util.tree_flatten(out)
        return out_leaves

    specs = [jax.ShapeDtypeStruct(np.shape(a), a.dtype,
                                  weak_type=bool(getattr(a, "weak_type", False))) for a in arrays]
    try:
        exported = jax.export.export(jax.jit(flat))(*specs)
        blob = exported.serialize()
    except Exception:  # noqa: BLE001 - not exportable (e.g. host callbacks): run it directly
        return None
    # the output's structure travels as the output itself with its leaves numbered (a
    # pickled PyTreeDef of an equinox module does not unflatten again)
    skeleton = jax.tree_util.tree_unflatten(box["tree"], list(range(box["tree"].num_leaves)))
    _write(key, (bytes(blob), skeleton))
    return jax.jit(exported.call), box["tree"]


def _write(key: str, entry) -> None:
    try:  # whole or not at all: a reader never sees half a file
        atomic_write_bytes(_FOLDER / f"{key}.jaxexport",
                           pickle.dumps(entry, protocol=pickle.HIGHEST_PROTOCOL))
    except (OSError, pickle.PicklingError, TypeError, AttributeError):
        pass  # an optimisation: a full disk or an unpicklable output costs a re-trace


__all__ = [
    "in_callers_jax_context",
    "cache_folder",
    "call_cached",
    "clear_loaded",
    "enable_program_cache",
    "program_cache_folder",
    "source_digest",
]
