"""lfjax.sweep.store_checks: recognising a store, its checksums and its configuration's
differences (small Zarr groups made here; a computed store's checks are in test_sweep.py)."""

import json

import numpy as np
import pytest
import xarray as xr

from lfjax.sweep.store_checks import (
    STORE_FORMAT,
    ZARR_FORMAT,
    chunk_checksum,
    metadata_checksum,
    metadata_problem,
    not_a_store,
    open_group,
    store_damage,
    is_store,
    EYE_VARIABLES,
)


def _small_store(path):
    ds = xr.Dataset({"freq_step_cpd": (("pupil",), np.array([1.0, 2.0]))},
                    coords={"eye": ("eye", np.arange(3)),
                            "is_average": ("eye", np.array([False, False, True]))},
                    attrs={"format": STORE_FORMAT, "config_json": "{}", "runs_json": "[]"})
    ds.to_zarr(path, zarr_format=ZARR_FORMAT, consolidated=False)
    group = open_group(path, "r+")
    group.attrs["metadata_checksum"] = str(metadata_checksum(group))
    return path


def test_a_store_is_recognised_and_a_plain_folder_refused(tmp_path):
    store = _small_store(tmp_path / "s.zarr")
    assert is_store(store) and not is_store(tmp_path) and not is_store(tmp_path / "none")
    assert "is not an lfjax sweep store" in not_a_store(tmp_path)


def test_a_damaged_attribute_file_is_named(tmp_path):
    store = _small_store(tmp_path / "s.zarr")
    (store / ".zattrs").write_text("{not json")
    assert not is_store(store)
    assert ".zattrs" in store_damage(store) and "damaged" in not_a_store(store)


def test_the_metadata_checksum_covers_the_configuration_not_the_runs(tmp_path):
    store = _small_store(tmp_path / "s.zarr")
    assert metadata_problem(store) is None
    group = open_group(store, "r+")
    group.attrs["runs_json"] = json.dumps([{"pid": 1}])  # changes as runs end: not covered
    assert metadata_problem(store) is None
    group.attrs["config_json"] = '{"n_eyes": 2}'
    assert "do not match the checksum" in metadata_problem(store)


def test_a_chunk_checksum_sees_its_values_and_counts_every_nan_alike():
    shape = (2, 1, 1, 1)
    part = xr.Dataset({name: (("eye", "pupil", "layout", "depth"), np.zeros(shape))
                       for name in EYE_VARIABLES})
    base = chunk_checksum(part)
    assert base == chunk_checksum(part.copy(deep=True)) and base != 0
    assert chunk_checksum(part, np.ones((2, 3))) != base
    other = part.copy(deep=True)
    other["vsotf"][0, 0, 0, 0] = np.nan
    negative_nan = part.copy(deep=True)
    negative_nan["vsotf"][0, 0, 0, 0] = -np.nan
    assert chunk_checksum(other) == chunk_checksum(negative_nan) != base
    with pytest.raises(KeyError):
        chunk_checksum(part.drop_vars("vsotf"))
