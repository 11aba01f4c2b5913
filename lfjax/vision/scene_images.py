"""Retinal images of a scene with depth, through a light-field display or in natural viewing.

A scene is a stack of fronto-parallel layers at depths (D), nearest first, each a colour
image per display primary (R, G, B) with a coverage ``alpha`` in [0, 1]; an image with a
depth map is cut into such layers (:func:`layers_from_depth_map`). Every layer is seen
through its own polychromatic PSF per primary — the display's rendering of that depth
(:func:`lfjax.vision.scene_blur.display_otfs`) or a real surface at that depth
(:func:`lfjax.vision.scene_blur.natural_otfs`) — and the blurred layers are composited front
to back (:func:`composite_layers`)::

    R_c = Σ_k T_k · (h_kc ∗ α_k I_kc),   T_0 = 1,   T_{k+1} = T_k · (1 − h_kc ∗ α_k)

**The layered approximation and what it leaves out.** Each layer's coverage is blurred with
the layer's own PSF and attenuates everything behind it (the "blur, then composite over"
rule of layered depth-of-field rendering). At an occluding edge the true optics differ:
light from a background point next to the edge passes the occluder through part of the
pupil only, so its PSF is the pupil *vignetted* by the occluder's shadow (partial occlusion:
the background is seen a little around the edge, and its blur there is narrower and
shifted), whereas the layers multiply the full background blur by a blurred transmission.
The light-field display has the same gap in a different form: each view shows its own
perspective, so it reveals background the single image and depth map do not hold
(disocclusions), which no input here provides. Away from occluding edges (within about one
blur radius of them) the layered image is exact for the model's PSFs; within one layer a
depth map's depths are quantised to the layer's depth (at most half the layer spacing, D).

Everything from the layers and the OTFs on is ``jax.numpy``: differentiable in the scene
(layers, coverage) and, through :func:`scene_otfs`, in the display's parameters (layout
centres and diameters, CDP).
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass

import jax
import jax.numpy as jnp
import numpy as np

from lfjax.base.errors import ParameterError
from lfjax.base.units import check_dioptres
from lfjax.base.sampling import Sampling
from lfjax.display.lenslets import DisplayOptics
from lfjax.display.panel import Panel
from lfjax.display.spectra import DisplayPrimaries, display_spectrum
from lfjax.model.eyes import Eyes
from lfjax.model.layouts import Layout
from lfjax.model.options import ModelOptions
from lfjax.vision.focus import through_focus
from lfjax.vision.images import kernel_half_width, retinal_image
from lfjax.vision.viewing import Viewing
from lfjax.vision.scene_blur import (
    single_eye,
    channel_spectra,
    common_sampling,
    display_otfs,
    embed_otf,
)
from lfjax.vision.peak_options import PeakOptions
from lfjax.vision.prepare import States

BYTES_PER_PIXEL_LAYER = 4 * 2 * 4 + 4
"""Working memory per padded pixel, layer and channel, bytes: float32 colour and coverage,
each with its complex spectrum and the OTF on the scene grid, and the host's float32 layers
(measured on the demo scene, 3 layers, 1 arcmin pixels: 2.5 GB above the process's own at
3072², under this bound's 3.1 GB). The scene is padded on every side by the
kernel's half width (:func:`lfjax.vision.images.kernel_half_width`: the PSF's field in
scene pixels), known once the OTFs' sampling is."""


SEARCH_OFFSETS_D = tuple(np.round(np.arange(-3.0, 1.0 + 1e-9, 0.2), 6))
"""Accommodation states searched by :func:`predicted_accommodation`, relative to the
fixated depth, D."""


def default_memory_limit_bytes() -> int:
    """Half of this machine's physical memory (the scene's working set must fit in it)."""
    try:
        return int(os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES") // 2)
    except (ValueError, OSError, AttributeError):
        return 8 * 2**30


def _real_numbers(name: str, x) -> np.ndarray:
    """``x`` as an array of real numbers (a luminance, a coverage, a depth), unconverted:
    complex, text or object arrays are a ``ParameterError`` naming ``name``."""
    a = np.asarray(x)
    if a.dtype.kind not in "biuf":
        what = "complex" if a.dtype.kind == "c" else f"of dtype {a.dtype}"
        raise ParameterError(name, "{" + name + "} must be real numbers (a luminance is real "
                             "and >= 0), got an array {what}", what=what)
    return a


def _finite_image(name: str, x, ndim: tuple[int, ...]) -> np.ndarray:
    """``x`` checked (real, finite, >= 0) as float32, the precision of the images (no
    float64 copy of a large image)."""
    a = _real_numbers(name, x).astype(np.float32, copy=False)
    if a.ndim not in ndim:
        raise ParameterError(name, "{" + name + "} must have {dims} dimensions, got shape {got}",
                             dims=" or ".join(map(str, ndim)), got=a.shape)
    if not np.all(np.isfinite(a)):
        raise ParameterError(name, "{" + name + "} contains NaN or infinite values")
    if np.any(a < 0):
        raise ParameterError(name, "{" + name + "} must be non-negative (luminance), min {got:g}",
                             got=float(a.min()))
    return a


def check_depths(name: str, depths) -> np.ndarray:
    """Finite depths in the model's range [0, 10] D, or a ``ParameterError`` naming ``name``."""
    d = _real_numbers(name, depths).astype(float)
    if np.any(np.isnan(d)):
        raise ParameterError(name, "{" + name + "} contains NaN")
    if np.any(~np.isfinite(d)) or np.any(d < 0) or np.any(d > 10):
        raise ParameterError(name, "{" + name + "} must be depths in [0, 10] D (0 D: infinity; "
                             "negative depths are not real points), got min {lo:g}, max {hi:g}",
                             lo=float(np.min(d)), hi=float(np.max(d)))
    return d


def layers_from_depth_map(image, depth_map_D, n_layers: int = 8, *,
                          memory_limit_bytes: int | None = None):
    """Cut an image with a depth map into layers, nearest first.

    Parameters
    ----------
    image : (n_channel, H, W) or (H, W) non-negative luminance per primary
    depth_map_D : (H, W) depth of every pixel, D, in [0, 10]
    n_layers : int >= 1; the layers are evenly spaced in dioptres from the nearest to the
        farthest depth present (fewer when the map has fewer distinct depths)
    memory_limit_bytes : refuse (:func:`check_scene_memory`) an image whose retinal image
        would not fit in it, before the layers are made (default half the RAM)

    Returns
    -------
    (layers (n_layers, n_channel, H, W) premultiplied α·I, alpha (n_layers, H, W) in {0, 1},
    depths_D (n_layers,) decreasing). Each pixel goes to the layer nearest its depth in D.
    """
    if int(n_layers) != n_layers or n_layers < 1:
        raise ParameterError("n_layers", "{n_layers} must be an integer >= 1, got {got}",
                             got=n_layers)
    # the bound of one layer before any copy (a huge image is refused at once), the bound
    # of the layers the depth map gives before they are made
    check_scene_memory(np.shape(image)[-2:], 1, memory_limit_bytes)
    img = _finite_image("image", image, (2, 3))
    if img.ndim == 2:
        img = img[None]
    depth = check_depths("depth_map_D", depth_map_D)
    if depth.shape != img.shape[-2:]:
        raise ParameterError("depth_map_D", "{depth_map_D} must have the image's shape {want}, "
                             "got {got}", want=img.shape[-2:], got=depth.shape)
    distinct = np.unique(depth)
    check_scene_memory(img.shape[-2:], min(distinct.size, int(n_layers)), memory_limit_bytes)
    if distinct.size <= n_layers:
        depths = distinct[::-1].copy()
    else:
        depths = np.linspace(depth.max(), depth.min(), int(n_layers))
    index = np.argmin(np.abs(depth[None] - depths[:, None, None]), axis=0)
    alpha = (index[None] == np.arange(depths.size)[:, None, None]).astype(np.float32)
    layers = img[None] * alpha[:, None]
    return layers.astype(np.float32), alpha, depths


def check_layers(layers, alpha, depths_D):
    """Host checks of a layer stack (:func:`composite_layers`' inputs); returns NumPy arrays."""
    lay = _finite_image("layers", layers, (4,))
    a = _real_numbers("alpha", alpha).astype(np.float32, copy=False)
    if a.shape != (lay.shape[0],) + lay.shape[-2:]:
        raise ParameterError("alpha", "{alpha} must have shape (n_layers, H, W) = {want}, got {got}",
                             want=(lay.shape[0],) + lay.shape[-2:], got=a.shape)
    if not np.all(np.isfinite(a)) or np.any(a < 0) or np.any(a > 1):
        raise ParameterError("alpha", "{alpha} must be coverage in [0, 1]")
    d = check_depths("depths_D", depths_D)
    if d.shape != (lay.shape[0],):
        raise ParameterError("depths_D", "{depths_D} must have one depth per layer ({want}), got "
                             "shape {got}", want=lay.shape[0], got=d.shape)
    if d.size > 1 and np.any(np.diff(d) >= 0):
        raise ParameterError("depths_D", "{depths_D} must be strictly decreasing: layers are given "
                             "nearest first (front to back), got {got}", got=d.tolist())
    return lay, a, d


def working_bytes(shape, n_layers: int, n_channel: int, pad: int) -> int:
    """Estimated working memory of :func:`composite_layers`, bytes, for (H, W) pixels padded
    by ``pad`` pixels on every side."""
    h, w = shape
    return int(BYTES_PER_PIXEL_LAYER * n_layers * n_channel * (h + 2 * pad) * (w + 2 * pad))


def check_scene_memory(shape, n_layers: int, memory_limit_bytes: int | None = None, *,
                       pad: int = 0, parameter: str = "image") -> int:
    """The working memory (bytes) of the retinal image of an (H, W) scene of ``n_layers``
    layers, 3 primaries, padded by ``pad`` pixels (:data:`BYTES_PER_PIXEL_LAYER`); over
    ``memory_limit_bytes`` (default half the RAM) a ``ParameterError`` naming ``parameter``
    with the estimate and the limit. It needs only the sizes: call it before allocating."""
    if len(tuple(shape)) < 2:
        return 0  # not an image: its own check says so
    h, w = (int(v) for v in tuple(shape)[-2:])
    need = working_bytes((h, w), int(n_layers), 3, int(pad))
    limit = default_memory_limit_bytes() if memory_limit_bytes is None else int(memory_limit_bytes)
    if need > limit:
        padded = f", padded by {pad} pixels a side (the PSF's field)" if pad else ""
        raise ParameterError(parameter, "{" + parameter + "}: the scene needs about {need:.2f} "
                             "GB of working memory "
                             "({n} layers × 3 primaries × {h}×{w} pixels{padded}), over the "
                             "limit of {limit:.2f} GB: use fewer layers, a smaller image or "
                             "larger pixels", need=need / 1e9, n=n_layers, h=h, w=w,
                             padded=padded, limit=limit / 1e9)
    return need


def composite_layers(layers, alpha, otf, freq_step_cpd: float, pixel_arcmin: float, *,
                     occlusion: bool = True, boundary: str = "edge"):
    """Blur every layer with its OTF and composite front to back (module docstring).

    Parameters
    ----------
    layers : (n_layers, n_channel, H, W) premultiplied colour α·I, nearest layer first
    alpha : (n_layers, H, W) coverage in [0, 1]
    otf : (n_channel, n_layers, L, L//2+1) half-plane OTFs, OTF(0) = 1
    freq_step_cpd : the OTFs' frequency step, cpd
    pixel_arcmin : the scene's pixel, arcmin
    occlusion : False: the layers add (every layer's light reaches the eye)
    boundary : as :func:`lfjax.vision.images.retinal_image`

    Returns
    -------
    (n_channel, H, W) retinal image per primary.
    """
    otf_lc = jnp.swapaxes(jnp.asarray(otf), 0, 1)  # (n_layers, n_channel, L, Lh)
    colour = retinal_image(layers, pixel_arcmin, otf_lc, freq_step_cpd, boundary=boundary)
    if not occlusion:
        return jnp.sum(colour, axis=0)
    cover = jnp.broadcast_to(jnp.asarray(alpha)[:, None], jnp.shape(layers))
    blurred = retinal_image(cover, pixel_arcmin, otf_lc, freq_step_cpd, boundary=boundary,
                            constant=0.0)
    transmit = jnp.cumprod(1.0 - blurred, axis=0)
    before = jnp.concatenate([jnp.ones_like(transmit[:1]), transmit[:-1]], axis=0)
    return jnp.sum(before * colour, axis=0)


def resolve_display(display, viewing: Viewing):
    """(layout or None, DisplayOptics or None, cdp_D, pupil_diameter_mm) of a display seen
    under ``viewing``.

    ``display`` is ``"natural"``/None (real surfaces: no layout, no display optics), a
    :class:`~lfjax.model.layouts.Layout` (``viewing``'s CDP, pupil and display optics: None
    for the paper's ideal display) or a :class:`~lfjax.display.panel.Panel`. A panel fixes
    its own CDP, pupil and optics (its central views, lenslet diffraction and pixels): they
    replace ``viewing``'s CDP and pupil, and ``viewing.display`` must be None there, as it
    must be for natural viewing (a ``ParameterError`` naming ``viewing`` otherwise)."""
    natural = display is None or (isinstance(display, str) and display == "natural")
    if not isinstance(viewing, Viewing):
        raise ParameterError("viewing", "{viewing} must be lfjax.vision.viewing.Viewing, got "
                             "{got}", got=type(viewing).__name__)
    if (natural or isinstance(display, Panel)) and viewing.display is not None:
        raise ParameterError("viewing", "{viewing}.display must be None with display={got}: "
                             "natural viewing has no display optics and a Panel brings its own",
                             got="'natural'" if natural else "a Panel")
    if natural:
        return None, None, viewing.cdp_D, viewing.pupil_diameter_mm
    if isinstance(display, Layout):
        return display, viewing.display, viewing.cdp_D, viewing.pupil_diameter_mm
    if isinstance(display, Panel):
        return (display.layout(), display.optics(), float(display.cdp_D),
                float(display.pupil_diameter_mm))
    raise ParameterError("display", "{display} must be 'natural', a Layout or a Panel, got {got}",
                         got=type(display).__name__)


def predicted_accommodation(eye: Eyes, layout: Layout | None, fixation_D: float,
                            primaries: DisplayPrimaries | str = "oled", *,
                            pupil_diameter_mm: float = 3.0, cdp_D: float = 2.0,
                            options: ModelOptions = ModelOptions(),
                            display: DisplayOptics | None = None) -> float:
    """The eye's predicted accommodation (continuous VSOTF peak, D) for a point rendered at
    ``fixation_D`` by ``layout`` (None: a real point there), in the display's white."""
    white = display_spectrum(primaries, "white", options)
    if layout is None:  # the open pupil shows its point at its CDP, whatever the depth
        cdp_D = float(fixation_D)
    # from 3 D farther than the fixated depth (past the CDP, where a display whose views
    # drive accommodation weakly leaves the eye) to 1 D nearer, in 0.2 D states
    tf = through_focus(
        single_eye(eye),
        layout,
        States.around([float(fixation_D)], SEARCH_OFFSETS_D),
        Viewing(pupil_diameter_mm=pupil_diameter_mm, cdp_D=cdp_D, display=display),
        spectrum=white,
        options=options,
        peaks=PeakOptions(metrics=("vsotf",)),
    )
    a = float(tf.continuous_accommodation_D()[0, 0])
    if not math.isfinite(a):
        a = float(tf.predicted_accommodation_D()[0, 0])
    return a


def scene_otfs(eye: Eyes, layout: Layout | None, accommodation_D: float, depths_D,
               primaries: DisplayPrimaries | str = "oled", *, pupil_diameter_mm: float = 3.0,
               cdp_D: float = 2.0, options: ModelOptions = ModelOptions(),
               display: DisplayOptics | None = None, sampling: Sampling | None = None):
    """(otf (n_channel, n_layers, L, L//2+1), freq_step_cpd) of every layer depth, per primary."""
    spectra = channel_spectra(primaries, options)
    if sampling is None:
        sampling = common_sampling(eye, [layout], float(accommodation_D), depths_D, spectra,
                                   pupil_diameter_mm=pupil_diameter_mm, cdp_D=cdp_D,
                                   options=options, display=display)
    otf = display_otfs(eye, layout, accommodation_D, depths_D, spectra, sampling,
                       pupil_diameter_mm=pupil_diameter_mm, cdp_D=cdp_D, options=options,
                       display=display)
    return embed_otf(otf, max(int(otf.shape[-2]), sampling.n_fft or 0)), sampling.freq_step_cpd


@dataclass(frozen=True, eq=False)
class LayeredScene:
    """A scene with depth: fronto-parallel layers at depths, nearest first, checked when built.

    Attributes
    ----------
    layers : (n_layers, n_channel, H, W) premultiplied colour α·I per primary (n_channel 1:
        grey, or 3: R, G, B), non-negative luminance
    alpha : (n_layers, H, W) coverage in [0, 1]
    depths_D : (n_layers,) strictly decreasing depths, D, in [0, 10] (nearest first)
    pixel_arcmin : one scene pixel's visual angle, arcmin, > 0

    Build one with :meth:`from_depth_map` (an image cut into layers by its depth map) or
    :meth:`from_layers`; the arrays are kept as given (NumPy, host side).
    """

    layers: np.ndarray
    alpha: np.ndarray
    depths_D: np.ndarray
    pixel_arcmin: float

    def __post_init__(self):
        try:
            pixel = float(self.pixel_arcmin)
        except (TypeError, ValueError):
            pixel = math.nan
        if not (pixel > 0 and math.isfinite(pixel)):
            raise ParameterError("pixel_arcmin", "{pixel_arcmin} must be > 0 arcmin, got {got}",
                                 got=self.pixel_arcmin)
        lay, _, _ = check_layers(self.layers, self.alpha, self.depths_D)
        if lay.shape[1] not in (1, 3):
            raise ParameterError("image", "{image} must have 1 or 3 channels (R, G, B), got {got}",
                                 got=lay.shape[1])
        object.__setattr__(self, "pixel_arcmin", pixel)

    @classmethod
    def from_depth_map(cls, image, depth_map_D, pixel_arcmin: float, n_layers: int = 8, *,
                       memory_limit_bytes: int | None = None) -> LayeredScene:
        """An image with a depth map cut into layers (:func:`layers_from_depth_map`).

        image : (n_channel, H, W) or (H, W) non-negative luminance per primary;
        depth_map_D : (H, W) depths, D, in [0, 10]; pixel_arcmin : arcmin per pixel;
        n_layers : layers cut from the depth map, >= 1; memory_limit_bytes : as
        :func:`layers_from_depth_map`."""
        return cls(*layers_from_depth_map(image, depth_map_D, n_layers,
                                          memory_limit_bytes=memory_limit_bytes), pixel_arcmin)

    @classmethod
    def from_layers(cls, layers, alpha, depths_D, pixel_arcmin: float) -> LayeredScene:
        """Layers given as arrays (the attributes' shapes and units), converted to float."""
        return cls(*check_layers(layers, alpha, depths_D), pixel_arcmin)

    @property
    def shape(self) -> tuple[int, int]:
        """(H, W), pixels."""
        return tuple(np.shape(self.alpha)[-2:])

    def pinhole_view(self) -> np.ndarray:
        """(3, H, W) the layers composited front to back without blur (seen through a
        pinhole): for a scene cut from a depth map, the image itself (grey repeated per
        primary)."""
        alpha = np.asarray(self.alpha, float)[:, None]
        behind = np.cumprod(np.concatenate([np.ones_like(alpha[:1]), 1 - alpha[:-1]]), axis=0)
        shown = np.sum(behind * np.asarray(self.layers, float), axis=0)
        return shown if shown.shape[0] == 3 else np.repeat(shown, 3, axis=0)


def retinal_scene(eye: Eyes, scene: LayeredScene, *, viewing: Viewing = Viewing(),
                  display="natural", primaries: DisplayPrimaries | str = "oled",
                  accommodation_D: float | None = None, fixation_D: float | None = None,
                  options: ModelOptions = ModelOptions(), occlusion: bool = True,
                  boundary: str = "edge", memory_limit_bytes: int | None = None,
                  progress=None) -> dict:
    """The retinal image of a scene with depth (module docstring), per display primary.

    Parameters
    ----------
    eye : one eye (``Eyes`` of one member: ``average_eye(3.0)``, ``sample_eyes(...)[i:i+1]``)
    scene : the :class:`LayeredScene` (its layers, depths and pixel size)
    viewing : the calculation pupil and the CDP of a layout
        (:class:`~lfjax.vision.viewing.Viewing`; its ``display`` optics for a Layout);
        see :func:`resolve_display` for how it combines with ``display``
    display : ``"natural"`` (real surfaces), a :class:`~lfjax.model.layouts.Layout` (the
        display at ``viewing.cdp_D``) or a :class:`~lfjax.display.panel.Panel` (its own CDP,
        pupil and optics replace ``viewing``'s)
    primaries : the display's primaries (a built-in name or ``DisplayPrimaries``)
    accommodation_D : where the eye focuses, D; default its predicted accommodation
        (:func:`predicted_accommodation`) for the depth at ``fixation_D``
    fixation_D : the fixated depth, D; default the depth at the image centre
    occlusion : composite with occlusion (default) or add the layers
    boundary : as :func:`lfjax.vision.images.retinal_image`
    memory_limit_bytes : refuse scenes whose working set exceeds it (default half the RAM):
        checked from the sizes before any optics, and again with the padding of the PSF's
        field once the OTFs' sampling is known, before the images are made
    progress : None, or a callable taking one line: told before each stage (the predicted
        accommodation, the layers' OTFs), which compile on a first run

    Returns
    -------
    dict: ``retina`` (n_channel, H, W), ``accommodation_D``, ``fixation_D``, ``depths_D``
    of the layers, ``freq_step_cpd``, ``otf``.
    """
    if not isinstance(scene, LayeredScene):
        raise ParameterError("scene", "{scene} must be a LayeredScene (LayeredScene.from_depth_map "
                             "or .from_layers), got {got}", got=type(scene).__name__)
    eye = single_eye(eye)
    lay, a, d = scene.layers, scene.alpha, scene.depths_D
    layout, optics, cdp, pupil = resolve_display(display, viewing)
    if fixation_D is not None:
        fixation_D = float(check_dioptres("fixation_D", fixation_D, "fixated depth"))
    if accommodation_D is not None:
        accommodation_D = float(check_dioptres("accommodation_D", accommodation_D,
                                               "accommodation state"))
    h, w = lay.shape[-2:]
    check_scene_memory((h, w), lay.shape[0], memory_limit_bytes)  # unpadded: a lower bound
    if fixation_D is None:
        depth_centre = d[np.argmax(a[:, h // 2, w // 2])] if np.any(a[:, h // 2, w // 2] > 0) else d[0]
        fixation_D = float(depth_centre)
    say = progress if callable(progress) else (lambda line: None)
    if accommodation_D is None:
        say(f"predicting the eye's accommodation for the fixated depth {fixation_D:g} D "
            f"(through focus; the first run compiles)")
        accommodation_D = predicted_accommodation(eye, layout, fixation_D, primaries,
                                                  pupil_diameter_mm=pupil, cdp_D=cdp,
                                                  options=options, display=optics)
    sampling = common_sampling(eye, [layout], float(accommodation_D), d,
                               channel_spectra(primaries, options), pupil_diameter_mm=pupil,
                               cdp_D=cdp, options=options, display=optics)
    check_scene_memory((h, w), lay.shape[0], memory_limit_bytes,
                       pad=kernel_half_width(sampling.freq_step_cpd, scene.pixel_arcmin))
    say(f"the {len(d)} layers' OTFs at {float(accommodation_D):.3f} D, per primary, and the "
        f"compositing")
    otf, df = scene_otfs(eye, layout, accommodation_D, d, primaries, pupil_diameter_mm=pupil,
                         cdp_D=cdp, options=options, display=optics, sampling=sampling)
    colour = jnp.asarray(lay if lay.shape[1] == 3 else np.repeat(lay, 3, axis=1))
    retina = composite_layers(colour, jnp.asarray(a), otf, df, scene.pixel_arcmin,
                              occlusion=occlusion, boundary=boundary)
    return dict(retina=retina, accommodation_D=float(accommodation_D), fixation_D=float(fixation_D),
                depths_D=d, freq_step_cpd=float(df), otf=otf)


def demo_scene(n_pixels: int = 128, depths_D=(4.0, 2.0, 0.5)):
    """A synthetic scene of three depths for figures and tests: (image (3, n, n), depth map).

    A far (last depth) coloured checkerboard background, a mid-depth grating bar and a
    near letter-like block, each with sharp edges."""
    n = int(n_pixels)
    y, x = np.mgrid[0:n, 0:n] / n
    near, mid, far = depths_D
    depth = np.full((n, n), far, float)
    check = ((np.floor(x * 8) + np.floor(y * 8)) % 2).astype(float)
    img = np.stack([0.2 + 0.8 * check, 0.2 + 0.5 * check, 0.2 + 0.8 * (1 - check)])
    bar = (np.abs(y - 0.5) < 0.18) & (x > 0.05) & (x < 0.6)
    grating = 0.5 + 0.5 * np.sign(np.sin(2 * np.pi * x * 16))
    img[:, bar] = np.stack([grating, grating, grating])[:, bar]
    depth[bar] = mid
    block = (np.abs(x - 0.7) < 0.12) & (np.abs(y - 0.55) < 0.25) & ~(
        (np.abs(x - 0.7) < 0.04) & (y > 0.5))
    img[:, block] = np.array([1.0, 0.9, 0.2])[:, None]
    depth[block] = near
    return img.astype(np.float32), depth


__all__ = [
    "layers_from_depth_map",
    "check_layers",
    "check_depths",
    "composite_layers",
    "resolve_display",
    "predicted_accommodation",
    "scene_otfs",
    "retinal_scene",
    "LayeredScene",
    "working_bytes",
    "check_scene_memory",
    "default_memory_limit_bytes",
    "demo_scene",
]
