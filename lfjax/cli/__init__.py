"""The ``lfjax`` command line (:func:`main`)."""

from lfjax.cli.main import main

__all__ = ["main"]
