"""The installed package's version, in a module of its own so that any layer can stamp its
outputs with it without importing the package's face (``lfjax/__init__.py``)."""

import tomllib
from importlib.metadata import PackageNotFoundError, version
from pathlib import Path


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
