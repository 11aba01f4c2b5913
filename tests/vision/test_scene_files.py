"""A scene with depth on disk (lfjax.vision.scene_files): the files read into the scene the
arrays make, unreadable or incomplete files refused naming their parameter, and the figure
written."""

import numpy as np
import pytest

from lfjax.base.errors import ParameterError
from lfjax.vision import scene_files as sf
from lfjax.vision.scene_images import LayeredScene, demo_scene


def test_an_image_and_depth_map_read_as_the_arrays_make_them(tmp_path):
    img, depth = demo_scene(16)
    np.save(tmp_path / "img.npy", np.moveaxis(img, 0, -1))  # channels last, as images are
    np.save(tmp_path / "depth.npy", depth)
    scene = sf.read_depth_map_scene(tmp_path / "img.npy", tmp_path / "depth.npy", 0.5, 2)
    want = LayeredScene.from_depth_map(img, depth, 0.5, 2)
    for name in ("layers", "alpha", "depths_D"):
        np.testing.assert_array_equal(getattr(scene, name), getattr(want, name))
    assert scene.pixel_arcmin == 0.5


def test_a_layers_file_reads_as_its_arrays(tmp_path):
    layers, alpha = np.ones((2, 3, 8, 8)), np.ones((2, 8, 8))
    np.savez(tmp_path / "layers.npz", layers=layers, alpha=alpha, depths_D=np.array([3.0, 1.0]))
    scene = sf.read_layers_file(tmp_path / "layers.npz", 1.0)
    np.testing.assert_array_equal(scene.layers, layers)
    assert scene.depths_D.tolist() == [3.0, 1.0]


@pytest.mark.parametrize("make, parameter, words", [
    (lambda p: sf.read_layers_file(p / "none.npz", 1.0), "layers_file", "cannot be read"),
    (lambda p: (np.savez(p / "x.npz", layers=np.ones((1, 3, 4, 4))),
                sf.read_layers_file(p / "x.npz", 1.0)), "layers_file", "lacks alpha, depths_D"),
    (lambda p: (np.save(p / "x.npy", np.ones(3)), sf.read_layers_file(p / "x.npy", 1.0)),
     "layers_file", "must be a file of type .npz"),
    (lambda p: ((p / "x.npz").write_text("layers"), sf.read_layers_file(p / "x.npz", 1.0)),
     "layers_file", "is not a NumPy .npz archive"),
    (lambda p: (np.save(p / "x.npy", np.array([{}]), allow_pickle=True),
                sf.read_depth_map_scene(p / "x.npy", p / "x.npy", 1.0)), "image",
     "cannot be read"),  # a pickle is never loaded
    (lambda p: (np.save(p / "x.npy", np.ones((4, 4))), sf.read_depth_map_scene(
        p / "x.npy", p / "x.npy", 1.0, memory_limit_bytes=100)), "image", "over the limit"),
    (lambda p: (np.savez(p / "x.npz", layers=np.ones((2, 3, 4, 4)), alpha=np.ones((2, 4, 4)),
                         depths_D=[2.0, 1.0]),
                sf.read_layers_file(p / "x.npz", 1.0, memory_limit_bytes=100)),
     "layers_file", "2 layers × 3 primaries × 4×4 pixels"),
    (lambda p: ((p / "x.jpg").write_bytes(b"\xff\xd8"), sf.read_image(p / "x.jpg")), "image",
     "must be a file of type .npy, .png"),
    (lambda p: sf.read_depth_map_scene(p / "img.npy", None, 1.0), "depth_map_D", "required"),
    (lambda p: sf.read_depth_map_scene(p / "none.npy", p / "d.npy", 1.0), "image",
     "cannot be read"),
])
def test_a_bad_file_is_refused_naming_its_parameter(tmp_path, make, parameter, words):
    with pytest.raises(ParameterError) as info:
        make(tmp_path)
    assert info.value.parameter == parameter and words in str(info.value), str(info.value)


def test_the_figure_is_written(tmp_path):
    img, depth = demo_scene(16)
    scene = LayeredScene.from_depth_map(img, depth, 1.0)
    path = sf.save_retina_figure(tmp_path / "retina.png", scene, img * 0.5, "a title")
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_a_png_is_decoded_from_srgb_to_linear_luminance(tmp_path):
    import matplotlib.image

    rgb = np.zeros((4, 6, 3))
    rgb[..., 0], rgb[..., 1], rgb[..., 2] = 1.0, 128 / 255, 0.0
    matplotlib.image.imsave(tmp_path / "x.png", rgb)
    image = sf.read_image(tmp_path / "x.png")
    assert image.shape == (4, 6, 3) and sf.array_shape(tmp_path / "x.png", "image") == (4, 6)
    # sRGB 128/255 is 21.6 % of the white's light (IEC 61966-2-1), not 50 %
    np.testing.assert_allclose(image[0, 0], [1.0, 0.2158605, 0.0], rtol=1e-5)


def test_a_png_with_transparency_is_refused(tmp_path):
    import matplotlib.image

    rgba = np.ones((4, 4, 4))
    rgba[0, 0, 3] = 0.5
    matplotlib.image.imsave(tmp_path / "x.png", rgba)
    with pytest.raises(ParameterError, match="transparent"):
        sf.read_image(tmp_path / "x.png")
