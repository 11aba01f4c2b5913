"""Population sweeps: thousands of eyes × pupils × layouts × depths, chunked and resumable.

``lfjax sweep CONFIG.toml --out STORE [--resume]`` and :func:`run_sweep` compute a sweep
described by a TOML file (:mod:`lfjax.sweep.config`) into a Zarr store of one labelled
xarray Dataset (:mod:`lfjax.sweep.store`), a chunk of eyes per compiled call
(:mod:`lfjax.sweep.compute`), sharded over the local devices and, with
``jax.distributed``, over processes and hosts. ``lfjax sweep-report STORE`` /
:func:`sweep_report` draws the distributions and writes percentiles and a summary;
:func:`ten_eye_claims` asks how often ten random eyes reproduce each of the paper's claims.

Layers (imports go one way): config_keys → config → config_files → compute, store_checks,
store_lock → guard, store → run → report (with ten_eyes).
"""

from lfjax.sweep.compute import ChunkEvaluator, Task, build_tasks, population
from lfjax.sweep.config import config_from_dict, SweepConfig
from lfjax.sweep.config_files import config_to_toml, load_config
from lfjax.sweep.config_keys import SweepConfigError
from lfjax.sweep.guard import SweepEstimate, SweepTooLargeError, estimate
from lfjax.sweep.report import sweep_report
from lfjax.sweep.run import SweepRun, plan_sweep, run_sweep
from lfjax.sweep.store import open_store, study_view
from lfjax.sweep.store_checks import completed_chunks, StoreMismatchError
from lfjax.sweep.ten_eyes import ten_eye_claims, ten_eye_markdown

__all__ = [
    "ChunkEvaluator",
    "StoreMismatchError",
    "SweepConfig",
    "SweepConfigError",
    "SweepEstimate",
    "SweepTooLargeError",
    "SweepRun",
    "Task",
    "build_tasks",
    "completed_chunks",
    "config_from_dict",
    "config_to_toml",
    "estimate",
    "load_config",
    "open_store",
    "plan_sweep",
    "population",
    "run_sweep",
    "study_view",
    "sweep_report",
    "ten_eye_claims",
    "ten_eye_markdown",
]
