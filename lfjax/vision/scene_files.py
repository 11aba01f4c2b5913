"""A scene with depth on disk: its input files read into a
:class:`~lfjax.vision.scene_images.LayeredScene`, and the figure of its retinal image.

Two inputs, each file read by its type (never a pickle):

* an image with a depth map (:func:`read_depth_map_scene`): the image an ``.npy`` of
  (3, H, W) or (H, W, 3) luminance per R, G, B primary, or (H, W) grey, or a ``.png``
  (8 or 16 bits, grey or RGB, opaque: its sRGB-encoded values are decoded to linear
  relative luminance, 1 the white); the depth map an ``.npy`` of (H, W) depths in dioptres;
* a layers file (:func:`read_layers_file`): an ``.npz`` holding ``layers`` (n, 3, H, W)
  premultiplied colour, ``alpha`` (n, H, W) coverage in [0, 1] and ``depths_D`` (n,)
  depths in D, nearest first.

A file of another type, one that cannot be read or lacks an array is a
:class:`~lfjax.base.errors.ParameterError` naming the parameter the path was given as; the
sizes are checked against the memory the retinal image needs
(:func:`~lfjax.vision.scene_images.check_scene_memory`) from the files' headers, before
their arrays are read; the arrays are then checked as
:class:`~lfjax.vision.scene_images.LayeredScene` checks them.
"""

from __future__ import annotations

import zipfile
from pathlib import Path

import numpy as np

from lfjax.base.errors import ParameterError
from lfjax.vision.scene_images import LayeredScene, check_scene_memory

LAYERS_FILE_KEYS = ("layers", "alpha", "depths_D")
"""The arrays a layers file (``.npz``) must hold."""

IMAGE_TYPES = (".npy", ".png")
"""The image file types :func:`read_image` reads (by the name's ending, any case)."""

_MAGIC = {".npy": b"\x93NUMPY", ".npz": b"PK\x03\x04", ".png": b"\x89PNG\r\n\x1a\n"}
_WHAT = {".npy": "a NumPy .npy file", ".npz": "a NumPy .npz archive", ".png": "a PNG image"}


def _unreadable(parameter: str, path, why) -> ParameterError:
    return ParameterError(parameter, "{" + parameter + "} {path} cannot be read: {why}",
                          path=path, why=why)


def _check_type(path, parameter: str, suffix: str) -> None:
    """The file starts as files of ``suffix`` do, or a ``ParameterError`` naming
    ``parameter`` (a text file, a pickle, a renamed file)."""
    magic = _MAGIC[suffix]
    try:
        with open(path, "rb") as f:
            head = f.read(len(magic))
    except OSError as err:
        raise _unreadable(parameter, path, err) from None
    if head != magic:
        raise ParameterError(parameter, "{" + parameter + "} {path} is not {what} (its first "
                             "bytes are not the {suffix} signature)", path=path,
                             what=_WHAT[suffix], suffix=suffix)


def _suffix(path, parameter: str, accepted: tuple[str, ...]) -> str:
    suffix = Path(str(path)).suffix.lower()
    if suffix not in accepted:
        raise ParameterError(parameter, "{" + parameter + "} {path} must be a file of type "
                             "{accepted}, got {got!r}", path=path, accepted=", ".join(accepted),
                             got=suffix or "no type")
    return suffix


def _npy_header(stream):
    """(shape, dtype) from an .npy stream positioned at its start."""
    version = np.lib.format.read_magic(stream)
    read = (np.lib.format.read_array_header_1_0 if version == (1, 0)
            else np.lib.format.read_array_header_2_0)
    shape, _, dtype = read(stream)
    return shape, dtype


def array_shape(path, parameter: str) -> tuple[int, ...]:
    """The shape of the array in an ``.npy`` or ``.png`` file, from its header alone."""
    suffix = _suffix(path, parameter, IMAGE_TYPES)
    _check_type(path, parameter, suffix)
    try:
        with open(path, "rb") as f:
            if suffix == ".npy":
                return tuple(_npy_header(f)[0])
            head = f.read(26)  # the IHDR chunk: width, height (big-endian), bit depth, colour
    except (OSError, ValueError) as err:
        raise _unreadable(parameter, path, err) from None
    width, height = int.from_bytes(head[16:20], "big"), int.from_bytes(head[20:24], "big")
    return (height, width)


def read_npy(path, parameter: str) -> np.ndarray:
    """The array of an ``.npy`` file (no pickles); anything else is a ``ParameterError``
    naming ``parameter``."""
    _suffix(path, parameter, (".npy",))
    _check_type(path, parameter, ".npy")
    try:
        return np.load(path, allow_pickle=False)
    except (OSError, ValueError) as err:
        raise _unreadable(parameter, path, err) from None


def _srgb_to_linear(v: np.ndarray) -> np.ndarray:
    """IEC 61966-2-1 decoding of sRGB values in [0, 1] to linear light in [0, 1]."""
    return np.where(v <= 0.04045, v / 12.92, ((v + 0.055) / 1.055) ** 2.4)


def read_image(path, parameter: str = "image") -> np.ndarray:
    """An image file (:data:`IMAGE_TYPES`) as a luminance array: an ``.npy`` as stored, a
    ``.png`` decoded from sRGB to linear relative luminance, (H, W) grey or (H, W, 3);
    a PNG with transparency is refused (its alpha would be lost)."""
    suffix = _suffix(path, parameter, IMAGE_TYPES)
    if suffix == ".npy":
        return read_npy(path, parameter)
    _check_type(path, parameter, ".png")
    import matplotlib.image

    try:
        pixels = np.asarray(matplotlib.image.imread(path, format="png"), np.float64)
    except (OSError, ValueError, SyntaxError) as err:
        raise _unreadable(parameter, path, err) from None
    if pixels.ndim == 3 and pixels.shape[-1] in (2, 4):  # grey or RGB with alpha
        if np.any(pixels[..., -1] < 1):
            raise ParameterError(parameter, "{" + parameter + "} {path} has transparent "
                                 "pixels: give an opaque image (or the layers as a layers "
                                 "file)", path=path)
        pixels = pixels[..., :-1]
    if pixels.ndim == 3 and pixels.shape[-1] == 1:
        pixels = pixels[..., 0]
    return _srgb_to_linear(pixels).astype(np.float32)


def read_layers_file(path, pixel_arcmin: float, *,
                     memory_limit_bytes: int | None = None) -> LayeredScene:
    """The scene of a layers file (module docstring) with pixels of ``pixel_arcmin`` arcmin;
    a ``ParameterError`` naming ``layers_file`` when the file is not an ``.npz``, is
    unreadable, lacks one of :data:`LAYERS_FILE_KEYS` or its layers need more than
    ``memory_limit_bytes`` (default half the RAM; from the header, before they are read)."""
    _suffix(path, "layers_file", (".npz",))
    _check_type(path, "layers_file", ".npz")
    try:
        with zipfile.ZipFile(path) as archive:
            names = set(archive.namelist())
            missing = [k for k in LAYERS_FILE_KEYS if k + ".npy" not in names]
            if missing:
                raise ParameterError("layers_file", "{layers_file} lacks {missing}",
                                     missing=", ".join(missing))
            with archive.open("layers.npy") as member:
                shape, _ = _npy_header(member)
        check_scene_memory(shape[-2:], shape[0] if len(shape) == 4 else 1, memory_limit_bytes,
                           parameter="layers_file")
        with np.load(path, allow_pickle=False) as data:
            arrays = [data[k] for k in LAYERS_FILE_KEYS]
    except (OSError, ValueError, zipfile.BadZipFile) as err:
        if isinstance(err, ParameterError):
            raise
        raise _unreadable("layers_file", path, err) from None
    return LayeredScene.from_layers(*arrays, pixel_arcmin)


def read_depth_map_scene(image_path, depth_path, pixel_arcmin: float, n_layers: int = 8, *,
                         memory_limit_bytes: int | None = None) -> LayeredScene:
    """The scene of an image file and a depth-map file (module docstring), cut into
    ``n_layers`` layers; ``depth_path`` None is a ``ParameterError`` naming ``depth_map_D``.
    An image of (H, W, 3) (channels last, as image libraries write them) is moved to
    (3, H, W). The image's size is checked against ``memory_limit_bytes`` (default half the
    RAM) from its header, before it is read."""
    if not depth_path:
        raise ParameterError("depth_map_D", "{depth_map_D} is required with {image}")
    shape = array_shape(image_path, "image")
    if len(shape) == 3 and shape[-1] == 3 and shape[0] != 3:
        shape = shape[:2]
    check_scene_memory(shape[-2:], 1, memory_limit_bytes)
    image = read_image(image_path, "image")
    if image.ndim == 3 and image.shape[-1] == 3 and image.shape[0] != 3:
        image = np.moveaxis(image, -1, 0)
    return LayeredScene.from_depth_map(image, read_npy(depth_path, "depth_map_D"),
                                       pixel_arcmin, n_layers,
                                       memory_limit_bytes=memory_limit_bytes)


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


__all__ = ["LAYERS_FILE_KEYS", "IMAGE_TYPES", "array_shape", "read_npy", "read_image",
           "read_layers_file", "read_depth_map_scene", "save_retina_figure"]
