"""The command line's persistent compilation cache: JAX's compiled programs, the planner's
plans and the exported programs kept between runs, so a second run skips most compilation,
tracing and all planning.
"""

from __future__ import annotations

import os
from pathlib import Path

import jax

from lfjax.base.programs import enable_program_cache
from lfjax.planner.cache import enable_plan_cache

def compilation_cache_dir() -> Path:
    """Folder of the persistent JAX compilation cache used by the command line.

    ``$LFJAX_CACHE_DIR`` if set, else ``$XDG_CACHE_HOME/lfjax/jax`` (default
    ``~/.cache/lfjax/jax``).
    """
    explicit = os.environ.get("LFJAX_CACHE_DIR")
    if explicit:
        return Path(explicit).expanduser()
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "lfjax" / "jax"


PLAN_FOLDER = "lfjax-plans"
"""Sub-folder of the compilation cache where the planner's plans are kept
(:mod:`lfjax.planner.cache`)."""


PROGRAM_FOLDER = "lfjax-programs"
"""Sub-folder of the compilation cache where exported programs are kept
(:mod:`lfjax.base.programs`)."""


def enable_compilation_cache(folder: Path | None = None) -> Path | None:
    """Turn on JAX's persistent compilation cache in ``folder`` (returns it, or None when
    the folder cannot be created), and keep the planner's plans in its ``lfjax-plans``
    sub-folder and the exported programs in ``lfjax-programs``. A second run then skips
    most compilation and tracing, and all planning."""
    folder = compilation_cache_dir() if folder is None else Path(folder)
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError:
        return None
    if not os.access(folder, os.W_OK):
        return None
    jax.config.update("jax_compilation_cache_dir", str(folder))
    jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.0)
    jax.config.update("jax_persistent_cache_min_entry_size_bytes", 0)
    # the planner's sampling plans beside the programs: a warm run re-plans nothing
    enable_plan_cache(folder / PLAN_FOLDER)
    # and the largest programs exported: a warm run does not trace them again
    enable_program_cache(folder / PROGRAM_FOLDER)
    return folder


__all__ = ["compilation_cache_dir", "enable_compilation_cache", "PLAN_FOLDER", "PROGRAM_FOLDER"]
