"""The probes of issue #52 for outputs and stores, kept so they run on every change: each
one the fault the issue found, injected, and the behaviour now asserted.

* ``--out`` a mount point (a real ``mount --bind``; skipped where the machine cannot make
  one) and an empty folder in a parent that cannot take files (``chattr +i`` as root,
  ``chmod 0o555`` otherwise): ``optimise``, ``design``, ``retina``, ``sweep-report`` and
  ``reproduce`` did all their work, then failed renaming the staging folder onto it
  (``OSError: [Errno 16] Device or resource busy``). ``retina`` and ``sweep-report`` run
  for real at tiny sizes; ``optimise``, ``design`` and ``reproduce`` (a minute or more
  each here) have their computation replaced by a stand-in that returns a result at once,
  and their own checks, staging and writing run as they are.
* Free space is checked before any work by every writing command (``retina`` checked it
  only after its work: ``Errno 28`` at the end).
* ``sweep-report`` on a store with a chunk file deleted, replaced or with a flipped byte
  wrote percentiles from the wrong numbers and said "All 3 chunks complete" (or failed with
  ``RuntimeError: error during blosc decompression: -1`` naming nothing): it now refuses,
  naming the chunk and the repair, and writes nothing.
* ``--coordinator nonsense`` failed with "list index out of range".

The store is a real tiny sweep (4 virtual eyes and the average eye in 3 chunks of 2,
natural view and 2x2, one depth, two wavelengths: about a minute here).

Covers: lfjax.cli.sweep_report
"""

from __future__ import annotations

import os
import shutil
import subprocess
import types
from collections import namedtuple
from pathlib import Path

import pytest

from lfjax import cli
from lfjax.base import files
from lfjax.sweep import config_from_dict, config_to_toml, run_sweep

TINY3 = {"population": {"n_eyes": 4, "seed": 0},
         "display": {"layouts": ["natural", "2x2"], "depth_offsets_D": [0.0]},
         "spectrum": {"wavelengths_nm": [500.0, 600.0, 100.0]},
         "run": {"chunk_size": 2}}
"""3 chunks: eyes 0-1, 2-3, and the last virtual eye with the average eye."""

RESULT_VARIABLES = ("accommodation_error", "continuous_error", "cutoff_frequency")
"""Store variables percentiles.csv is made from: the chunk files the damage probes alter."""


@pytest.fixture(scope="module")
def store3(tmp_path_factory):
    path = tmp_path_factory.mktemp("store") / "tiny3.zarr"
    run_sweep(config_from_dict(TINY3), path, progress=False)
    return path


@pytest.fixture
def mount_point(tmp_path):
    """An empty folder that is a bind mount of another: it takes files but cannot be
    renamed or replaced (EBUSY), as a container volume or a network share."""
    point, backing = tmp_path / "volume", tmp_path / "backing"
    point.mkdir()
    backing.mkdir()
    try:
        made = subprocess.run(["mount", "--bind", str(backing), str(point)],
                              capture_output=True, text=True, timeout=30)
    except (OSError, subprocess.TimeoutExpired) as err:
        pytest.skip(f"no bind mount on this machine ({err})")
    if made.returncode != 0:
        pytest.skip(f"mount --bind is not permitted here (it needs root or CAP_SYS_ADMIN): "
                    f"{made.stderr.strip()}")
    try:
        yield point
    finally:
        subprocess.run(["umount", "-l", str(point)], capture_output=True, timeout=30)


@pytest.fixture
def fixed_parent(tmp_path):
    """An empty folder whose parent cannot take a file, nor let it be renamed: ``chattr +i``
    on the parent as root (whom permission bits do not stop), ``chmod 0o555`` otherwise."""
    parent = tmp_path / "fixed"
    out = parent / "out"
    out.mkdir(parents=True)
    if os.geteuid() == 0:
        made = subprocess.run(["chattr", "+i", str(parent)], capture_output=True, text=True)
        if made.returncode != 0:
            pytest.skip(f"chattr +i is not supported here: {made.stderr.strip()}")
        undo = ["chattr", "-i", str(parent)]
    else:
        parent.chmod(0o555)
        undo = None
    try:
        yield out
    finally:
        if undo is not None:
            subprocess.run(undo, capture_output=True)
        else:
            parent.chmod(0o755)


def _stand_in_work(monkeypatch):
    """optimise, design and reproduce with their computation replaced by a result made at
    once; their checks, staging folder and writers run as they are."""
    from lfjax.cli import design
    from lfjax.layout_opt import _run
    from lfjax.reproduce import run as rep

    def fit_design(*args, **kwargs):  # what save_design and the summary read of a result
        return types.SimpleNamespace(record=lambda command: {"stand_in": True},
                                     figure=lambda: None, provenance={}, best=object(),
                                     fits=[], summary=lambda: "stand-in design")

    def write_outputs(settings, fit, problem, curves, constraints, command, test, stage):
        files.atomic_write_text(stage / "layout.json", "{}\n")
        return types.SimpleNamespace(files=[stage / "layout.json"], summary="",
                                     front=None)

    def write_results(tmp, *args):
        (tmp / "REPORT.md").write_text("stand-in for the study\n")
        (tmp / rep.MARKER_FILE).write_text("")
        return ["REPORT.md", rep.MARKER_FILE], []

    monkeypatch.setattr(design, "fit_design", fit_design)
    for name in ("make_problem", "through_focus_curves", "planning_eyes"):
        monkeypatch.setattr(_run, name, lambda *a, **k: None)
    monkeypatch.setattr(_run, "optimise_layout", lambda *a, **k: types.SimpleNamespace(
        initial_params=None, params=None))
    monkeypatch.setattr(_run, "_write_outputs", write_outputs)
    monkeypatch.setattr(rep, "_write_results", write_results)
    monkeypatch.setattr(cli.cache, "enable_compilation_cache", lambda folder=None: None)


COMMANDS = {  # command line (--out added), files it writes
    "optimise": (["optimise", "--train-eyes", "1", "--test-eyes", "1", "--steps", "1",
                  "--no-progress"], {"layout.json"}),
    "design": (["design", "--depths", "1", "2", "--views", "2", "--train-eyes", "1",
                "--test-eyes", "0", "--steps", "1", "--no-progress"], {"design.json"}),
    "reproduce": (["reproduce", "--quick", "--no-progress"], {"REPORT.md", ".lfjax-reproduce"}),
    "retina": (["retina", "--demo", "--size", "16", "--display", "natural",
                "--accommodation", "2"], {"retina.png", "retina.npy", "retina.json"}),
    "sweep-report": (["sweep-report", "STORE", "--draws", "5", "--no-progress"],
                     {"summary.md", "percentiles.csv", "accommodation_error.png",
                      "cutoff_frequency.png", "layouts.png"}),
}


def _run(name, out, store, capsys):
    argv, written = COMMANDS[name]
    argv = [str(store) if a == "STORE" else a for a in argv] + ["--out", str(out)]
    code = cli.main(argv)
    captured = capsys.readouterr()
    return code, captured, written


@pytest.mark.parametrize("name", list(COMMANDS))
def test_a_mount_point_as_out_takes_every_commands_files(name, mount_point, store3, capsys,
                                                         monkeypatch):
    """Before: the work done, then ``OSError: [Errno 16] Device or resource busy``, exit 1,
    nothing written."""
    if name in ("optimise", "design", "reproduce"):
        _stand_in_work(monkeypatch)
    code, captured, written = _run(name, mount_point, store3, capsys)
    assert code == 0, captured.err
    assert "Errno" not in captured.err
    assert {p.name for p in mount_point.iterdir()} >= written
    # the staging folder was inside the mount point, and is gone
    assert not [p for p in mount_point.iterdir() if p.name.startswith(files.STAGING_PREFIX)]
    assert not [p for p in mount_point.parent.iterdir()
                if p.name.startswith(files.STAGING_PREFIX)]


def test_an_empty_folder_in_a_parent_that_cannot_change_takes_the_result(fixed_parent,
                                                                          capsys, monkeypatch):
    """reproduce into an existing empty folder that cannot be replaced (its parent
    immutable, or read-only): the result is staged inside it. Before: refused or failed at
    the end (the result was renamed onto it)."""
    _stand_in_work(monkeypatch)
    code, captured, written = _run("reproduce", fixed_parent, None, capsys)
    assert code == 0, captured.err
    assert {p.name for p in fixed_parent.iterdir()} == written
    (fixed_parent / "old.txt").write_text("of an earlier result")
    code = cli.main(COMMANDS["reproduce"][0] + ["--out", str(fixed_parent), "--force"])
    assert code == 0, capsys.readouterr().err
    assert {p.name for p in fixed_parent.iterdir()} == written  # replaced whole


# ----------------------------------------------------------------------------- free space


def _full_disk(monkeypatch, free=64 * 1024):
    usage = namedtuple("usage", "total used free")
    monkeypatch.setattr(files.shutil, "disk_usage", lambda path: usage(10**12, 10**12 - free,
                                                                        free))


@pytest.fixture
def no_work(monkeypatch):
    """Any start of a command's work fails the test: the refusal must come first."""
    from lfjax import layout_opt, reproduce
    from lfjax.cli import design, retina, sweep_report
    from lfjax.sweep import report
    from lfjax.sweep import run as sweep_run

    def work(*args, **kwargs):
        raise AssertionError("the work started before the free space was checked")

    # the sweep plans first (its estimate of the store's size), then creates the store
    for module, name in ((layout_opt, "optimise_and_save"), (design, "fit_design"),
                         (reproduce, "reproduce"), (sweep_run, "create_store"),
                         (retina, "retinal_scene"), (report, "open_verified_store")):
        monkeypatch.setattr(module, name, work)
    assert sweep_report.sweep_report is report.sweep_report
    monkeypatch.setattr(cli.cache, "enable_compilation_cache", lambda folder=None: None)


@pytest.mark.parametrize("name", list(COMMANDS) + ["sweep"])
def test_every_writing_command_checks_free_space_before_any_work(name, tmp_path, store3,
                                                                 capsys, monkeypatch, no_work):
    """64 KiB free: every command refuses before its work, exit 2, one line. Before:
    retina computed the image, then failed with Errno 28."""
    _full_disk(monkeypatch)
    if name == "sweep":
        toml = tmp_path / "tiny.toml"
        toml.write_text(config_to_toml(config_from_dict({**TINY3, "population": {
            "n_eyes": 100_000, "seed": 0}})))
        argv = ["sweep", str(toml), "--out", str(tmp_path / "s.zarr"), "--no-progress"]
        code = cli.main(argv)
        err = capsys.readouterr().err
        assert code == 2 and "disk: the store may need up to" in err, err
        return
    code, captured, _ = _run(name, tmp_path / "out", store3, capsys)
    assert code == 2, captured.err
    assert len(captured.err.strip().splitlines()) == 1, captured.err
    assert "not enough free space on its disk (64 KiB free, about" in captured.err
    assert not (tmp_path / "out").exists()


# ----------------------------------------------------------------------------- damaged stores


def _damage(store, kind, at):
    """A copy of ``store`` at ``at`` with chunk 1's result files deleted, replaced by chunk
    0's, or one with a byte flipped in its compressed header."""
    shutil.copytree(store, at)
    for name in RESULT_VARIABLES:
        chunk_file = at / name / "1.0.0.0.0"
        if kind == "deleted":
            chunk_file.unlink()
        elif kind == "replaced":
            shutil.copyfile(at / name / "0.0.0.0.0", chunk_file)
        else:
            data = bytearray(chunk_file.read_bytes())
            data[12] ^= 0xFF  # within blosc's header: the chunk no longer decodes
            chunk_file.write_bytes(bytes(data))
            return at
    return at


def test_a_healthy_store_is_reported_complete(store3, tmp_path, capsys):
    code, captured, _ = _run("sweep-report", tmp_path / "rep", store3, capsys)
    assert code == 0, captured.err
    assert "- All 3 chunks complete (2 eyes per chunk)." in (tmp_path / "rep" / "summary.md").read_text()


@pytest.mark.parametrize("kind", ["deleted", "replaced", "flipped"])
def test_sweep_report_refuses_a_damaged_store_naming_the_chunk(kind, store3, tmp_path, capsys):
    """Before: deleted or replaced, "All 3 chunks complete" and percentiles from the wrong
    numbers, exit 0; flipped, ``RuntimeError: error during blosc decompression: -1``."""
    damaged = _damage(store3, kind, tmp_path / f"{kind}.zarr")
    out = tmp_path / "rep"
    code, captured, _ = _run("sweep-report", out, damaged, capsys)
    assert code == 2, captured.err
    err = captured.err.strip()
    assert len(err.splitlines()) == 1, err
    assert err.startswith(f"lfjax sweep-report: error: STORE {damaged} fails verification "
                          f"(what lfjax sweep --verify checks): chunk 1: "), err
    why = "unreadable (RuntimeError" if kind == "flipped" else "data do not match the checksum"
    assert why in err and "chunk 0" not in err and "chunk 2" not in err, err
    assert f"lfjax sweep CONFIG.toml --out {damaged} --resume" in err, err
    assert err.endswith("no report is written"), err
    assert "complete" not in err and not out.exists()
    assert cli.main(["sweep", str(damaged), "--verify"]) == 1  # the same verdict
    assert "1 corrupt" in capsys.readouterr().out


def test_reproduce_refuses_a_damaged_population_store_before_the_study(store3, tmp_path,
                                                                        capsys, monkeypatch):
    """``reproduce --population`` reads the store as ``sweep --verify`` would, before the
    study's minutes (it read its complete chunks unchecked after the study)."""
    from lfjax.reproduce import run as rep  # where reproduce looks its parts up

    def no_study(*args, **kwargs):
        raise AssertionError("the study ran before the population store was verified")

    monkeypatch.setattr(rep, "run_study", no_study)
    damaged = _damage(store3, "replaced", tmp_path / "replaced.zarr")
    out = tmp_path / "out"
    code = cli.main(["reproduce", "--quick", "--out", str(out), "--population", str(damaged),
                     "--no-progress"])
    err = capsys.readouterr().err
    assert code == 2 and "--population" in err and "chunk 1" in err, err
    assert not out.exists()


# ----------------------------------------------------------------------------- --coordinator


@pytest.mark.parametrize("address", ["nonsense", "host:0", "host:99999", ":1234"])
def test_a_malformed_coordinator_is_refused_before_anything_starts(address, tmp_path, capsys,
                                                                   monkeypatch):
    """Before: "list index out of range" from jax.distributed.initialize."""
    import jax

    def started(**kwargs):
        raise AssertionError("jax.distributed.initialize was called")

    monkeypatch.setattr(jax.distributed, "initialize", started)
    toml = tmp_path / "tiny.toml"
    toml.write_text(config_to_toml(config_from_dict(TINY3)))
    code = cli.main(["sweep", str(toml), "--distributed", "--coordinator", address,
                     "--num-processes", "2", "--process-id", "0"])
    err = capsys.readouterr().err
    assert code == 2, err
    assert err.strip() == (
        "lfjax sweep: error: --coordinator must be HOST:PORT (a host name or address, an "
        f"IPv6 one in brackets, and a port 1 ... 65535, e.g. host0:12345), got {address!r}")
    assert not (tmp_path / "tiny.zarr").exists() and not Path("tiny.zarr").exists()
