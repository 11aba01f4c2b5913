"""The version lfjax stamps on its outputs: the installed distribution's, else, for a
checkout on PYTHONPATH (a machine with no package index, RESULTS §34), its pyproject.toml's
marked "+source", never a bare placeholder; and the provenance stamp every writer puts on
its files (``stamp``): its keys in their order, then the writer's own, none overwritten.

Covers: lfjax._version
"""

from __future__ import annotations

import datetime
import importlib.metadata
import importlib.util
import json
import tomllib
from pathlib import Path

import pytest

import lfjax
from lfjax._version import STAMP_KEYS, stamp

ROOT = Path(__file__).resolve().parents[2]


def _load_version_module(monkeypatch):
    def missing(name):
        raise importlib.metadata.PackageNotFoundError(name)

    monkeypatch.setattr(importlib.metadata, "version", missing)
    spec = importlib.util.spec_from_file_location("_version_probe", ROOT / "lfjax" / "_version.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_installed_version_is_pyprojects():
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    assert lfjax.__version__.split("+")[0] == project["version"]


def test_uninstalled_checkout_stamps_its_pyproject_version(monkeypatch):
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    module = _load_version_module(monkeypatch)
    assert module.__version__ == f"{project['version']}+source"


def test_no_pyproject_beside_the_package_says_unknown(monkeypatch, tmp_path):
    module = _load_version_module(monkeypatch)
    (tmp_path / "lfjax").mkdir()
    monkeypatch.setattr(module, "__file__", str(tmp_path / "lfjax" / "_version.py"))
    assert module._source_version() == "0.0.0+unknown"
    (tmp_path / "pyproject.toml").write_text('[project]\nname = "other"\nversion = "9"\n')
    assert module._source_version() == "0.0.0+unknown"


def test_the_stamp_has_its_keys_in_order_then_the_writers():
    record = stamp(command="lfjax design --out x")
    assert tuple(record)[:len(STAMP_KEYS)] == STAMP_KEYS
    assert list(record)[len(STAMP_KEYS):] == ["command"]
    assert record["lfjax_version"] == lfjax.__version__
    assert datetime.datetime.fromisoformat(record["created_utc"]).utcoffset().total_seconds() == 0
    json.dumps(record)  # every value is JSON


def test_a_writer_cannot_overwrite_the_stamps_own_fields():
    with pytest.raises(ValueError, match=r"provenance fields \['host'\] are the stamp's own"):
        stamp(host="elsewhere")
