"""``lfjax retina``: bad scenes are refused in one line naming the flag, before any optics."""

import numpy as np
import pytest

from lfjax import cli


@pytest.mark.parametrize("depth, flag", [
    (np.ones((8, 9)), "--depth"),  # not the image's shape
    (np.full((8, 8), np.nan), "--depth"),
    (-np.ones((8, 8)), "--depth"),
])
def test_a_bad_depth_map_is_refused_naming_its_flag(tmp_path, capsys, depth, flag):
    np.save(tmp_path / "img.npy", np.ones((8, 8, 3)))
    np.save(tmp_path / "depth.npy", depth)
    status = cli.main(["retina", "--image", str(tmp_path / "img.npy"), "--depth",
                       str(tmp_path / "depth.npy"), "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err
    assert status == 2 and err.count("\n") == 1 and flag in err, err
    assert not (tmp_path / "out").exists()


def test_layers_out_of_order_are_refused(tmp_path, capsys):
    np.savez(tmp_path / "layers.npz", layers=np.ones((2, 3, 8, 8)), alpha=np.ones((2, 8, 8)),
             depths_D=np.array([1.0, 3.0]))
    status = cli.main(["retina", "--layers-file", str(tmp_path / "layers.npz"),
                       "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err
    assert status == 2 and "--layers-file" in err and "nearest first" in err, err
