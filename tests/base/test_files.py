"""Output folders and files whole or absent (lfjax.base.files): the preflight refuses a
read-only folder and a full disk before any work, a file is written whole or not at all,
and a staged folder appears complete or not at all — faults injected (the tests run as
root, for whom permission bits forbid nothing, so read-only and full disks are simulated
by the errors the system would raise)."""

from __future__ import annotations

import errno
import os
import shutil
from collections import namedtuple
from pathlib import Path

import pytest

from lfjax.base import files
from lfjax.base.errors import ParameterError


def _fail_mkstemp(code):
    def mkstemp(*args, **kwargs):
        raise OSError(code, os.strerror(code))
    return mkstemp


@pytest.mark.parametrize("code", [errno.EROFS, errno.EACCES])
def test_a_folder_that_cannot_take_a_file_is_refused_before_any_work(tmp_path, monkeypatch, code):
    monkeypatch.setattr(files.tempfile, "mkstemp", _fail_mkstemp(code))
    with pytest.raises(ParameterError, match=rf"out_dir .*new/deeper is not writable: cannot "
                                             rf"create a file in .*\({os.strerror(code)}\)") as err:
        files.check_output_folder(tmp_path / "new" / "deeper")
    assert err.value.parameter == "out_dir"
    assert not (tmp_path / "new").exists()


def test_a_disk_without_room_for_the_outputs_is_refused(tmp_path, monkeypatch):
    usage = namedtuple("usage", "total used free")
    monkeypatch.setattr(files.shutil, "disk_usage", lambda p: usage(10**9, 10**9 - 1000, 1000))
    with pytest.raises(ParameterError, match=r"not enough free space on its disk \(1000 B free, "
                                             r"about 2 MiB needed for the outputs\)"):
        files.check_output_folder(tmp_path / "out", need_bytes=2 * 2**20)
    files.check_output_folder(tmp_path / "out", need_bytes=500)  # room: accepted
    assert list(tmp_path.iterdir()) == []  # the probe is gone


def test_the_preflight_names_the_callers_parameter(tmp_path):
    (tmp_path / "f").write_text("x")
    with pytest.raises(ParameterError, match="^store .*f exists and is not a folder") as err:
        files.check_output_folder(tmp_path / "f", parameter="store")
    assert err.value.naming({"store": "--out"}).startswith("--out ")
    (tmp_path / "d").mkdir()
    (tmp_path / "d" / "a").write_text("x")
    with pytest.raises(ParameterError, match="not empty"):
        files.check_output_folder(tmp_path / "d")
    assert files.check_output_folder(tmp_path / "d", force=True) == tmp_path / "d"


def _full_disk_after(monkeypatch, written: int):
    """Writes of more than ``written`` bytes in all fail with ENOSPC, as a full disk does
    (after writing what fitted)."""
    real_write = os.write
    state = {"left": written}

    class Full:
        def __init__(self, raw):
            self.raw = raw

        def write(self, data):
            if len(data) > state["left"]:
                self.raw.write(bytes(data[: state["left"]]))
                state["left"] = 0
                raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
            state["left"] -= len(data)
            return self.raw.write(data)

        def __getattr__(self, name):
            return getattr(self.raw, name)

        def __enter__(self):
            return self

        def __exit__(self, *exc):
            self.raw.close()

    real_fdopen = os.fdopen
    monkeypatch.setattr(files.os, "fdopen", lambda fd, mode="r", *a, **k: Full(real_fdopen(fd, mode, *a, **k)))
    return real_write


def test_a_file_is_written_whole_or_left_as_it_was(tmp_path, monkeypatch):
    target = tmp_path / "layout.json"
    files.atomic_write_text(target, "old contents\n")
    _full_disk_after(monkeypatch, 5)
    with pytest.raises(OSError) as err:
        files.atomic_write_text(target, "new contents, longer than the room left\n")
    assert err.value.errno == errno.ENOSPC
    assert target.read_text() == "old contents\n"  # not truncated, not half-new
    assert sorted(p.name for p in tmp_path.iterdir()) == ["layout.json"]  # no temporary file
    monkeypatch.undo()
    files.atomic_write_text(target, "new\n")
    assert target.read_text() == "new\n"
    assert oct(target.stat().st_mode & 0o777) == oct(0o666 & ~files._umask())


def test_a_figure_on_a_full_disk_leaves_no_truncated_png(tmp_path, monkeypatch):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig = plt.figure(figsize=(1, 1))
    _full_disk_after(monkeypatch, 100)
    with pytest.raises(OSError):
        files.atomic_savefig(fig, tmp_path / "through_focus.png", dpi=50)
    assert list(tmp_path.iterdir()) == []
    monkeypatch.undo()
    files.atomic_savefig(fig, tmp_path / "through_focus.png", dpi=50)
    assert (tmp_path / "through_focus.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    plt.close(fig)


@pytest.mark.parametrize("failure", [OSError(errno.ENOSPC, "No space left on device"),
                                     KeyboardInterrupt()])
def test_a_staged_folder_appears_complete_or_not_at_all(tmp_path, failure):
    out = tmp_path / "results"
    with pytest.raises(type(failure)):
        with files.staged_output(out) as stage:
            (stage / "layout.json").write_text("{}")
            assert files.live_staging_folders() == [stage]
            (stage / "layouts.png").write_bytes(b"\x89PNG half")
            raise failure
    assert list(tmp_path.iterdir()) == []  # neither the folder nor its staging copy
    assert files.live_staging_folders() == []
    with files.staged_output(out) as stage:
        (stage / "layout.json").write_text("{}")
        (stage / "sub").mkdir()
        assert not out.exists()  # nothing is visible before the block ends
    assert sorted(p.name for p in out.iterdir()) == ["layout.json", "sub"]
    assert [p.name for p in tmp_path.iterdir()] == ["results"]


def test_a_staged_folder_replaces_an_empty_one_and_merges_with_force(tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    with files.staged_output(out) as stage:
        assert stage.parent == out  # an existing folder: staged inside it
        (stage / "a.txt").write_text("1")
        assert [p.name for p in out.iterdir()] == [stage.name]  # hidden while it runs
    assert sorted(p.name for p in out.iterdir()) == ["a.txt"]
    (out / "keep.txt").write_text("kept")
    with files.staged_output(out, force=True) as stage:
        (stage / "a.txt").write_text("2")
    assert (out / "a.txt").read_text() == "2" and (out / "keep.txt").read_text() == "kept"
    with pytest.raises(FileExistsError, match="is not empty"):  # said on entry, before work
        with files.staged_output(out) as stage:
            raise AssertionError("the block ran")
    with pytest.raises(FileExistsError, match="no longer empty"):  # filled while it ran
        with files.staged_output(tmp_path / "late") as stage:
            (stage / "a.txt").write_text("3")
            (tmp_path / "late").mkdir()
            (tmp_path / "late" / "theirs.txt").write_text("")
    assert sorted(p.name for p in (tmp_path / "late").iterdir()) == ["theirs.txt"]
    assert (out / "a.txt").read_text() == "2"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["late", "out"]


def test_a_staged_folder_with_replace_swaps_the_whole_folder(tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    (out / "old.txt").write_text("an earlier result")
    (out / "same.txt").write_text("old")
    with files.staged_output(out, force=True, replace=True) as stage:
        (stage / "new.txt").write_text("new")
        (stage / "same.txt").write_text("new")
    assert sorted(p.name for p in out.iterdir()) == ["new.txt", "same.txt"]
    assert (out / "same.txt").read_text() == "new"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]  # nothing left beside it
    with pytest.raises(FileExistsError, match="is not empty"):  # replace needs force
        with files.staged_output(out, replace=True) as stage:
            (stage / "x").write_text("")
    assert sorted(p.name for p in out.iterdir()) == ["new.txt", "same.txt"]


def test_a_failed_staged_folder_leaves_no_parent_folders(tmp_path):
    out = tmp_path / "new" / "deeper"
    with pytest.raises(RuntimeError):
        with files.staged_output(out) as stage:
            assert stage.parent == tmp_path  # staged in the nearest existing folder
            raise RuntimeError("failed")
    assert list(tmp_path.iterdir()) == []
    with files.staged_output(out) as stage:
        (stage / "a").write_text("")
    assert (out / "a").exists()


def test_a_killed_runs_staging_folder_is_removed_by_the_next(tmp_path, capsys):
    import socket
    import subprocess
    import sys

    gone = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"],
                          capture_output=True, text=True, check=True)
    left = tmp_path / f"{files.STAGING_PREFIX}-out-{socket.gethostname()}-{int(gone.stdout)}-x1"
    left.mkdir()
    (left / "layouts.png").write_bytes(b"partial")
    with files.staged_output(tmp_path / "out") as stage:
        (stage / "a").write_text("")
    assert not left.exists()
    assert "removed 1 folder(s) left by an interrupted run" in capsys.readouterr().err
    shutil.rmtree(tmp_path / "out")
    assert Path(tmp_path).is_dir()


def test_an_emergency_exit_removes_staging_folders_and_runs_registered_cleanups(tmp_path):
    released = []
    files.register_emergency_cleanup(1, lambda: released.append("lock"))
    files.register_emergency_cleanup(2, lambda: 1 / 0)  # a failing one stops nothing
    with pytest.raises(KeyboardInterrupt):
        with files.staged_output(tmp_path / "out") as stage:
            (stage / "partial.png").write_bytes(b"\x89PNG")
            files.emergency_cleanup()
            assert not stage.exists() and released == ["lock"]
            raise KeyboardInterrupt
    files.unregister_emergency_cleanup(1)
    files.unregister_emergency_cleanup(2)
    files.emergency_cleanup()
    assert released == ["lock"] and list(tmp_path.iterdir()) == []


def _unmovable(monkeypatch, folder: Path, code=errno.EBUSY):
    """Renaming ``folder`` itself, or anything onto it, fails with ``code`` (as for a mount
    point: EBUSY; or a folder whose parent is read-only: EACCES), and so does creating a
    file beside it: the folder can be written into, not replaced."""
    real_replace, real_rename, real_mkstemp = os.replace, os.rename, files.tempfile.mkstemp

    def guard(real):
        def move(src, dst, *args, **kwargs):
            if folder in (Path(src).absolute(), Path(dst).absolute()):
                raise OSError(code, os.strerror(code), str(src))
            return real(src, dst, *args, **kwargs)
        return move

    def mkstemp(*args, dir=None, **kwargs):
        if dir is not None and Path(dir).absolute() == folder.parent:
            raise OSError(errno.EACCES, os.strerror(errno.EACCES))
        return real_mkstemp(*args, dir=dir, **kwargs)

    monkeypatch.setattr(files.os, "replace", guard(real_replace))
    monkeypatch.setattr(files.os, "rename", guard(real_rename))
    monkeypatch.setattr(files.tempfile, "mkstemp", mkstemp)


@pytest.mark.parametrize("code", [errno.EBUSY, errno.EACCES])
def test_an_existing_folder_that_cannot_be_replaced_still_takes_the_result(tmp_path, monkeypatch,
                                                                           code):
    """A mount point (EBUSY) or an empty folder in a read-only parent (EACCES): the check
    asks only the folder itself, and the result is staged inside it and its files renamed
    in (issue #52: the work was lost to the last rename)."""
    out = tmp_path / "volume"
    out.mkdir()
    _unmovable(monkeypatch, out, code)
    assert files.staging_parent(out) == out
    assert files.check_output_folder(out, need_bytes=1000) == out
    with files.staged_output(out) as stage:
        assert stage.parent == out
        (stage / "a.txt").write_text("1")
        (stage / "sub").mkdir()
        (stage / "sub" / "b.txt").write_text("2")
    assert sorted(p.name for p in out.iterdir()) == ["a.txt", "sub"]
    assert (out / "sub" / "b.txt").read_text() == "2"
    with files.staged_output(out, force=True, replace=True) as stage:  # as reproduce --force
        (stage / "c.txt").write_text("3")
    assert sorted(p.name for p in out.iterdir()) == ["c.txt"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["volume"]
    with pytest.raises(ParameterError, match="not writable"):  # a new folder beside it is not
        files.check_output_folder(tmp_path / "new")


def test_a_killed_runs_staging_folder_inside_the_out_folder_is_not_counted_and_removed(
        tmp_path, capsys):
    import socket
    import subprocess
    import sys

    gone = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"],
                          capture_output=True, text=True, check=True)
    out = tmp_path / "out"
    out.mkdir()
    left = out / f"{files.STAGING_PREFIX}-out-{socket.gethostname()}-{int(gone.stdout)}-x1"
    left.mkdir()
    (left / "retina.npy").write_bytes(b"partial")
    assert files.folder_contents(out) == []
    assert files.check_output_folder(out) == out  # empty but for the orphan: no --force
    with files.staged_output(out) as stage:
        (stage / "a").write_text("")
    assert sorted(p.name for p in out.iterdir()) == ["a"]
    assert "removed 1 folder(s) left by an interrupted run" in capsys.readouterr().err
    alive = out / f"{files.STAGING_PREFIX}-out-{socket.gethostname()}-{os.getpid()}-x2"
    alive.mkdir()  # a live run's: counted
    assert sorted(files.folder_contents(out)) == sorted([out / "a", alive])
