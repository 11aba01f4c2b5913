"""The ``lfjax`` command line; the entry point is :func:`lfjax.cli.main.main`."""
