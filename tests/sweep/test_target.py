"""Where a sweep's store goes (lfjax.sweep.target): an existing store without resume, a
file in its place or an unwritable folder refused before any work, naming ``store``."""

import errno
import os
from pathlib import Path

import pytest

from lfjax.base import files
from lfjax.base.errors import ParameterError
from lfjax.sweep.target import check_store_target, check_store_writable


def test_an_existing_store_needs_resume(tmp_path):
    store = tmp_path / "s.zarr"
    assert check_store_target(store) is False
    store.mkdir()
    with pytest.raises(FileExistsError, match="already exists"):
        check_store_target(store)
    assert check_store_target(store, resume=True) is True


def test_a_file_in_the_store_s_place_is_refused(tmp_path):
    (tmp_path / "s.zarr").write_text("")
    with pytest.raises(ParameterError, match="exists and is not a folder") as info:
        check_store_writable(tmp_path / "s.zarr")
    assert info.value.parameter == "store"


def test_a_read_only_folder_is_refused(tmp_path, monkeypatch):
    # tests run as root, for whom permission bits forbid nothing: the probe fails as on a
    # read-only mount
    def read_only(*args, dir=None, **kwargs):
        raise OSError(errno.EROFS, os.strerror(errno.EROFS))

    check_store_writable(tmp_path / "new.zarr")
    monkeypatch.setattr(files.tempfile, "mkstemp", read_only)
    with pytest.raises(ParameterError) as info:
        check_store_writable(Path(tmp_path / "new.zarr"))
    assert info.value.parameter == "store"
