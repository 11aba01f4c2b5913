"""The installed package's version and the one provenance stamp of every file the package
writes, in a module of its own so that any layer can stamp its outputs without importing the
package's face (``lfjax/__init__.py``).

Every writer (the sweep's store, the paper's study, the layout optimiser's and the display
design's records) stamps its output with :func:`stamp`, so a reader finds the same keys,
spelled the same way, wherever it looks: :data:`STAMP_KEYS`.
"""

import datetime
import socket
import subprocess
import tomllib
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path

import jax


def _source_version() -> str:
    """The version in ``pyproject.toml`` beside the package, for a checkout used without
    installing it (on ``PYTHONPATH``, as on a machine with no package index); outputs are
    then stamped with the checkout's version rather than a placeholder."""
    try:
        with open(Path(__file__).resolve().parents[1] / "pyproject.toml", "rb") as f:
            project = tomllib.load(f).get("project", {})
    except (OSError, ValueError):
        return "0.0.0+unknown"
    if project.get("name") != "lfjax" or "version" not in project:
        return "0.0.0+unknown"
    return f"{project['version']}+source"


try:
    __version__ = version("lfjax")
except PackageNotFoundError:  # a checkout on PYTHONPATH (tests/base/test_version.py)
    __version__ = _source_version()

STAMP_KEYS = ("lfjax_version", "lfjax_git_commit", "jax_version", "jax_backend", "jax_devices",
              "process_count", "host", "created_utc")
"""The keys of :func:`stamp`, in order (a writer may add its own after them, e.g. ``command``)."""


def utc_now() -> str:
    """The time now, UTC, to the second (ISO 8601, e.g. ``2026-12-07T22:00:00+00:00``)."""
    return datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds")


def git_commit() -> str | None:
    """The commit of the lfjax source tree, when it is a git checkout (else None)."""
    here = Path(__file__).resolve().parents[1]
    if not (here / ".git").exists():
        return None
    try:
        out = subprocess.run(["git", "-C", str(here), "rev-parse", "HEAD"], capture_output=True,
                             text=True, timeout=5)
    except (OSError, subprocess.SubprocessError):
        return None
    return (out.stdout.strip() or None) if out.returncode == 0 else None


def stamp(**extra) -> dict:
    """The provenance of a file written now: lfjax version and git commit, JAX version,
    backend and devices, process count, host and UTC time (:data:`STAMP_KEYS`), then
    ``extra`` (JSON-serialisable values, e.g. ``command="lfjax design ..."``)."""
    devices = jax.devices()
    record = {
        "lfjax_version": __version__,
        "lfjax_git_commit": git_commit(),
        "jax_version": jax.__version__,
        "jax_backend": jax.default_backend(),
        "jax_devices": f"{len(devices)} x {devices[0].device_kind}",
        "process_count": jax.process_count(),
        "host": socket.gethostname(),
        "created_utc": utc_now(),
    }
    clash = set(extra) & set(record)
    if clash:
        raise ValueError(f"provenance fields {sorted(clash)} are the stamp's own")
    record.update(extra)
    return record

