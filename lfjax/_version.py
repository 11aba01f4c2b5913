"""The installed package's version, in a module of its own so that any layer can stamp its
outputs with it without importing the package's face (``lfjax/__init__.py``)."""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("lfjax")
except PackageNotFoundError:  # pragma: no cover
    __version__ = "0.0.0"
