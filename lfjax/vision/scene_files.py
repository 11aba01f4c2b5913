"""A scene with depth on disk: its input files read into a
:class:`~lfjax.vision.scene_images.LayeredScene`, and the figure of its retinal image.

Two inputs (NumPy files, each read with :func:`numpy.load`, no pickles):

* an image with a depth map (:func:`read_depth_map_scene`): the image an ``.npy`` of
  (3, H, W) or (H, W, 3) luminance per R, G, B primary, or (H, W) grey; the depth map an
  ``.npy`` of (H, W) depths in dioptres;
* a layers file (:func:`read_layers_file`): an ``.npz`` holding ``layers`` (n, 3, H, W)
  premultiplied colour, ``alpha`` (n, H, W) coverage in [0, 1] and ``depths_D`` (n,)
  depths in D, nearest first.

A file that cannot be read or lacks an array is a
:class:`~lfjax.base.errors.ParameterError` naming the parameter the path was given as; the
arrays are then checked as :class:`~lfjax.vision.scene_images.LayeredScene` checks them.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from lfjax.base.errors import ParameterError
from lfjax.vision.scene_images import LayeredScene

LAYERS_FILE_KEYS = ("layers", "alpha", "depths_D")
"""The arrays a layers file (``.npz``) must hold."""


def load_array(path, parameter: str):
    """``numpy.load(path)`` (an array, or an ``.npz``'s arrays); a file that cannot be read
    is a ``ParameterError`` naming ``parameter``."""
    try:
        return np.load(path)
    except (OSError, ValueError) as err:
        raise ParameterError(parameter, "{" + parameter + "} {path} cannot be read: {why}",
                             path=path, why=err) from None


def read_layers_file(path, pixel_arcmin: float) -> LayeredScene:
    """The scene of a layers file (module docstring) with pixels of ``pixel_arcmin`` arcmin;
    a ``ParameterError`` naming ``layers_file`` when the file is unreadable or lacks one of
    :data:`LAYERS_FILE_KEYS`."""
    data = load_array(path, "layers_file")
    if not hasattr(data, "files"):  # one array (an .npy), not an .npz of named ones
        raise ParameterError("layers_file", "{layers_file} {path} is not an .npz of {keys}",
                             path=path, keys=", ".join(LAYERS_FILE_KEYS))
    with data:  # an .npz holds its file open until closed
        missing = [k for k in LAYERS_FILE_KEYS if k not in data]
        if missing:
            raise ParameterError("layers_file", "{layers_file} lacks {missing}",
                                 missing=", ".join(missing))
        arrays = [data[k] for k in LAYERS_FILE_KEYS]
    return LayeredScene.from_layers(*arrays, pixel_arcmin)


def read_depth_map_scene(image_path, depth_path, pixel_arcmin: float,
                         n_layers: int = 8) -> LayeredScene:
    """The scene of an image file and a depth-map file (module docstring), cut into
    ``n_layers`` layers; ``depth_path`` None is a ``ParameterError`` naming ``depth_map_D``.
    An image of (H, W, 3) (channels last, as image libraries write them) is moved to
    (3, H, W)."""
    if not depth_path:
        raise ParameterError("depth_map_D", "{depth_map_D} is required with {image}")
    image = load_array(image_path, "image")
    if image.ndim == 3 and image.shape[-1] == 3 and image.shape[0] != 3:
        image = np.moveaxis(image, -1, 0)
    return LayeredScene.from_depth_map(image, load_array(depth_path, "depth_map_D"),
                                       pixel_arcmin, n_layers)


def save_retina_figure(path, scene: LayeredScene, retina, title: str, dpi: int = 110) -> Path:
    """Write a PNG of the scene (seen through a pinhole, :meth:`LayeredScene.pinhole_view`)
    and its retinal image ``retina`` (3, H, W) side by side, both scaled by the scene's
    brightest value; returns ``path``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    shown = scene.pinhole_view()
    top = max(float(np.max(shown)), 1e-12)
    fig, ax = plt.subplots(1, 2, figsize=(8, 4.2))
    for a, im, name in ((ax[0], shown, "scene"), (ax[1], retina, "retina")):
        im = np.moveaxis(np.asarray(im), 0, -1)
        a.imshow(np.clip(im / top, 0, 1), origin="lower")
        a.set_title(name)
        a.set_xticks([]), a.set_yticks([])
    fig.suptitle(title, fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=dpi)
    plt.close(fig)
    return Path(path)


__all__ = ["LAYERS_FILE_KEYS", "load_array", "read_layers_file", "read_depth_map_scene",
           "save_retina_figure"]
