"""Retinal images of a scene with depth (lfjax.vision.scene_images): compositing invariants on
synthetic OTFs, the diffraction-limited layer against an independent PSF, gradients and
refusals of bad input before any optics."""

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from lfjax.base.errors import ParameterError
from lfjax.base.sampling import Sampling
from lfjax.kernel.metrics import diffraction_limited_mtf
from lfjax.display.panel import PRESETS
from lfjax.model.layouts import grid_layout
from lfjax.model.eyes import aberration_free_eye, average_eye
from lfjax.model.options import ModelOptions
from lfjax.model.spectral import monochromatic_spectrum
from lfjax.vision.images import retinal_image
from lfjax.vision.scene_blur import natural_otfs
from lfjax.vision.viewing import Viewing
from lfjax.vision import scene_images as si

L, DF, PIXEL = 32, 2.0, 0.5  # synthetic OTF grid: 32 samples of 2 cpd; scene pixel 0.5 arcmin


def gaussian_otf(widths_cpd):
    """Half-plane Gaussian OTFs (n, L, L//2+1), OTF(0) = 1: valid blur kernels of any width."""
    fy = np.fft.fftfreq(L, 1.0 / L) * DF
    fx = np.fft.rfftfreq(L, 1.0 / L) * DF
    f2 = fx[None, :] ** 2 + fy[:, None] ** 2
    return jnp.asarray(np.stack([np.exp(-f2 / w**2) for w in widths_cpd]), jnp.complex64)


def random_layers(n_layers=3, n=48, seed=0):
    rng = np.random.default_rng(seed)
    alpha = (rng.random((n_layers, n, n)) > 0.5).astype(np.float32)
    layers = rng.random((n_layers, 3, n, n)).astype(np.float32) * alpha[:, None]
    return layers, alpha


def test_energy_is_conserved_without_occlusion():
    layers, alpha = random_layers()
    otf = jnp.stack([gaussian_otf([10.0, 7.0, 5.0])] * 3)  # (channel, layer, L, Lh)
    out = si.composite_layers(layers, alpha, otf, DF, PIXEL, occlusion=False, boundary="periodic")
    np.testing.assert_allclose(np.asarray(out).sum(axis=(-2, -1)),
                               layers.sum(axis=(0, -2, -1)), rtol=2e-5)


def test_opaque_front_layer_hides_what_lies_behind():
    layers, alpha = random_layers()
    alpha[0] = 1.0
    layers[0] = np.random.default_rng(1).random(layers[0].shape)
    otf = jnp.stack([gaussian_otf([10.0, 7.0, 5.0])] * 3)
    other = layers.copy()
    other[1:] = np.random.default_rng(2).random(other[1:].shape) * alpha[1:, None]
    a = np.asarray(si.composite_layers(layers, alpha, otf, DF, PIXEL))
    b = np.asarray(si.composite_layers(other, alpha, otf, DF, PIXEL))
    front = np.asarray(retinal_image(layers[0], PIXEL, otf[:, 0], DF))
    assert np.max(np.abs(a - b)) < 1e-5 * np.max(a)
    np.testing.assert_allclose(a, front, atol=1e-5 * np.max(a))


def test_one_layer_at_focus_is_the_scene_convolved_with_the_diffraction_limited_psf():
    # An aberration-free eye focused on the layer, one wavelength, no Stiles-Crawford and no
    # accommodation SA. Reference: the scene convolved with the analytic diffraction-limited
    # PSF (its OTF, the circular pupil's autocorrelation) resampled onto the scene grid the
    # same exact way. The model's sampled OTF is within 3.0e-3 of the analytic one at 1 cpd
    # (soft pupil edge, pupil sampled at λ·df), which bounds the difference; an opaque
    # single layer adds nothing to it (its coverage transmits nothing behind, passes all).
    options = ModelOptions(sce="off", accommodation_sa="off")
    otf = natural_otfs(aberration_free_eye(3.0), 2.0, [2.0],
                       (monochromatic_spectrum(550.0, options),), Sampling(freq_step_cpd=1.0),
                       options=options)
    n_fft = otf.shape[-2]
    fy = np.fft.fftfreq(n_fft, 1.0 / n_fft)
    fx = np.fft.rfftfreq(n_fft, 1.0 / n_fft)
    airy = diffraction_limited_mtf(np.hypot(fx[None, :], fy[:, None]), 3.0, 550.0)
    scene = np.random.default_rng(3).random((1, 1, 40, 40)).astype(np.float32)
    out = np.asarray(si.composite_layers(scene, np.ones((1, 40, 40), np.float32), otf,
                                         1.0, PIXEL)[0])
    ref = np.asarray(retinal_image(scene[0, 0], PIXEL, airy.astype(np.complex64), 1.0))
    own = np.asarray(retinal_image(scene[0, 0], PIXEL, otf[0, 0], 1.0))
    assert np.max(np.abs(out - own)) < 1e-6 * np.max(own)  # compositing one layer is exact
    assert np.max(np.abs(out - ref)) < 3e-3 * np.max(ref)


def test_gradients_in_the_scene_match_finite_differences():
    layers, alpha = random_layers(2, 12)
    otf = jnp.stack([gaussian_otf([6.0, 3.0])] * 3)
    weight = jnp.asarray(np.random.default_rng(4).random((3, 12, 12)), jnp.float32)

    def loss(x):
        return jnp.sum(weight * si.composite_layers(x, alpha, otf, DF, PIXEL))

    g = np.asarray(jax.grad(loss)(jnp.asarray(layers)))
    step = np.zeros_like(layers)
    step[1, 0, 5, 6] = 1e-2
    fd = (float(loss(layers + step)) - float(loss(layers - step))) / 2e-2
    assert abs(g[1, 0, 5, 6] - fd) < 1e-3 * max(abs(fd), 1e-3)


def test_depth_map_layers_are_ordered_and_cover_every_pixel():
    img, depth = si.demo_scene(32)
    layers, alpha, depths = si.layers_from_depth_map(img, depth, 8)
    assert np.all(np.diff(depths) < 0)
    np.testing.assert_array_equal(alpha.sum(axis=0), 1.0)
    np.testing.assert_allclose(layers.sum(axis=0), img, rtol=1e-6)


@pytest.mark.parametrize("change, parameter", [
    (dict(depth_map_D=np.ones((8, 9))), "depth_map_D"),
    (dict(depth_map_D=np.where(np.eye(8) > 0, np.nan, 1.0)), "depth_map_D"),
    (dict(depth_map_D=-np.ones((8, 8))), "depth_map_D"),
    (dict(pixel_arcmin=0.0), "pixel_arcmin"),
    (dict(pixel_arcmin="wide"), "pixel_arcmin"),
    (dict(image=np.ones((2, 8, 8))), "image"),  # neither grey nor R, G, B
    (dict(image=np.ones((3, 8, 8)) + 1j), "image"),  # a luminance is real
    (dict(image=np.full((3, 8, 8), "bright")), "image"),
    (dict(depth_map_D=np.ones((8, 8)) * 1j), "depth_map_D"),
    (dict(memory_limit_bytes=1000), "image"),
])
def test_a_bad_scene_is_refused_when_built(change, parameter):
    kwargs = dict(image=np.ones((3, 8, 8)), depth_map_D=np.ones((8, 8)), pixel_arcmin=1.0)
    kwargs.update(change)
    with pytest.raises(ParameterError) as info:
        si.LayeredScene.from_depth_map(**kwargs)
    assert info.value.parameter == parameter


def test_layers_out_of_order_are_refused():
    layers, alpha = random_layers(2, 8)
    with pytest.raises(ParameterError, match="strictly decreasing"):
        si.LayeredScene.from_layers(layers, alpha, [1.0, 2.0], 1.0)


def test_a_scene_keeps_its_arrays_and_its_pinhole_view_is_the_image():
    img, depth = si.demo_scene(16)
    scene = si.LayeredScene.from_depth_map(img, depth, 0.5, n_layers=2)
    assert scene.layers.dtype == np.float32 and scene.depths_D.tolist() == [4.0, 0.5]
    assert scene.shape == (16, 16) and scene.pixel_arcmin == 0.5
    np.testing.assert_allclose(scene.pinhole_view(), img, rtol=1e-6)
    grey = si.LayeredScene.from_depth_map(img[0], depth, 0.5)
    np.testing.assert_allclose(grey.pinhole_view(), np.stack([img[0]] * 3), rtol=1e-6)
    with pytest.raises(dataclasses.FrozenInstanceError):
        scene.pixel_arcmin = 1.0


@pytest.mark.parametrize("change, parameter", [
    (dict(memory_limit_bytes=1000), "image"),
    (dict(scene="not a scene"), "scene"),
    (dict(display="phone"), "display"),
    (dict(viewing=Viewing(display=PRESETS["near-eye"]().optics())), "viewing"),  # natural: no display optics
    (dict(viewing=(3.0, 2.0)), "viewing"),
    (dict(fixation_D=20.0), "fixation_D"),  # the model's depths: [0, 10] D
    (dict(accommodation_D=-1.0), "accommodation_D"),
])
def test_bad_input_is_refused_before_any_optics(change, parameter):
    kwargs = dict(scene=si.LayeredScene.from_depth_map(np.ones((3, 8, 8)), np.ones((8, 8)), 1.0))
    kwargs.update(change)
    with pytest.raises(ParameterError) as info:
        si.retinal_scene(average_eye(3.0), **kwargs)
    assert info.value.parameter == parameter


def test_a_panel_brings_its_own_cdp_pupil_and_optics():
    panel = PRESETS["near-eye"]()
    layout, optics, cdp, pupil = si.resolve_display(panel, Viewing(pupil_diameter_mm=2.0,
                                                                   cdp_D=3.0))
    assert (cdp, pupil) == (float(panel.cdp_D), float(panel.pupil_diameter_mm))
    assert optics is not None and layout is not None
    layout, optics, cdp, pupil = si.resolve_display(grid_layout(2), Viewing(cdp_D=3.0))
    assert (optics, cdp, pupil) == (None, 3.0, 3.0)
    assert si.resolve_display("natural", Viewing())[:2] == (None, None)


def test_a_huge_image_is_refused_from_its_size_before_any_copy(monkeypatch):
    # a 20000² image of 3 primaries (an 8-byte-per-pixel view of a small buffer: nothing of
    # that size exists) is refused from its shape alone, before the float copy and the layers
    image = np.lib.stride_tricks.as_strided(np.ones(1, np.float32), (3, 20000, 20000), (0, 0, 0))
    monkeypatch.setattr(si, "_finite_image", lambda *a: pytest.fail("the image was copied"))
    with pytest.raises(ParameterError, match=r"about 43\.20 GB .* over the limit of 1\.00 GB"):
        si.LayeredScene.from_depth_map(image, np.ones((20000, 20000)), 1.0,
                                       memory_limit_bytes=10**9)


def test_the_psf_fields_padding_is_in_the_memory_estimate():
    # 0.001 arcmin pixels: a field of ~23 arcmin is a kernel of ~23000 pixels a side
    scene = si.LayeredScene.from_layers(np.ones((1, 3, 4, 4)), np.ones((1, 4, 4)), [2.0], 0.001)
    with pytest.raises(ParameterError, match="padded by 1[0-9]{4} pixels a side"):
        si.retinal_scene(average_eye(3.0), scene, accommodation_D=2.0,
                         memory_limit_bytes=2 * 10**9)


@pytest.fixture(scope="module")
def eye_otf():
    """The average eye's OTF per primary (OLED) focused on a real point at 2 D, its step."""
    otf, df = si.scene_otfs(average_eye(3.0), None, 2.0, [2.0])
    return np.asarray(otf[:, 0]), float(df)


def direct_retinal_image(otf_half, df, scene, cells_per_sample, cells_per_pixel):
    """An independent float64 reference: the PSF on a grid ``cells_per_sample`` times finer
    than the OTF's (the OTF zero-padded, inverse FFT), integrated over each scene pixel of
    ``cells_per_pixel`` (odd) cells by the midpoint rule over one period (half cells at its
    ends), convolved directly with the scene (zero outside it). Returns (image, pixel)."""
    from lfjax.kernel.optics import full_plane

    L = otf_half.shape[-2]
    full = np.asarray(full_plane(jnp.asarray(otf_half), L), np.complex128)
    M, T = cells_per_sample * L, 60.0 / df
    spectrum = np.zeros((M, M), complex)
    k = np.fft.fftfreq(L, 1.0 / L).astype(int) % M
    spectrum[np.ix_(k, k)] = full
    psf = np.real(np.fft.ifft2(spectrum)) * M * M / T**2  # at θ = j·T/M, periodic
    cells = np.arange(-M // 2, M // 2 + 1)
    weight = np.where(np.abs(cells) == M // 2, 0.5, 1.0) * T / M
    n = scene.shape[-1]
    offsets = np.arange(-(n - 1), n)
    P = (np.abs(cells[None, :] - offsets[:, None] * cells_per_pixel) <= cells_per_pixel // 2)
    P = P * weight[None, :]  # (2n − 1, M + 1): the cells of the pixel at each offset
    W = P @ psf[np.ix_(cells % M, cells % M)] @ P.T
    out = np.zeros(scene.shape)
    for (y, x), value in np.ndenumerate(scene):
        out += value * W[n - 1 - y: 2 * n - 1 - y, n - 1 - x: 2 * n - 1 - x]
    return out, T / M * cells_per_pixel


@pytest.mark.parametrize("cells_per_sample, cells_per_pixel", [
    (27, 9),  # pixels a third of the PSF's sample (0.071 arcmin)
    (15, 45),  # pixels three samples wide (0.64 arcmin)
])
def test_the_retinal_image_agrees_with_a_direct_float64_convolution(eye_otf, cells_per_sample,
                                                                    cells_per_pixel):
    # the reference's midpoint rule converges as 1/cells² (measured: 3e-3, 3e-4, 4e-5 of the
    # peak at 3, 9, 27 cells per sample); at these it is within 5e-5 of the exact kernel
    otf, df = eye_otf
    scene = np.random.default_rng(4).random((10, 10))
    for channel in range(3):
        ref, pixel = direct_retinal_image(otf[channel], df, scene, cells_per_sample,
                                          cells_per_pixel)
        got = np.asarray(retinal_image(jnp.asarray(scene, jnp.float32), pixel, otf[channel], df,
                                       boundary="constant"))
        assert np.abs(got - ref).max() < 1e-4 * ref.max(), channel
