"""Retinal images (lfjax.vision.images): optotype geometry, exact PSF resampling, convolution."""

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from lfjax.vision import images

# ------------------------------------------------------------------ helpers


def gaussian_otf_half(sigma_arcmin, n_fft=64, df=1.0):
    """Half-plane OTF of a circular Gaussian PSF of SD sigma (arcmin), FFT order."""
    fy = np.fft.fftfreq(n_fft, 1.0 / n_fft) * df / 60.0  # cycles per arcmin
    fx = np.fft.rfftfreq(n_fft, 1.0 / n_fft) * df / 60.0
    f2 = fx[None, :] ** 2 + fy[:, None] ** 2
    return jnp.asarray(np.exp(-2 * np.pi**2 * sigma_arcmin**2 * f2) + 0j)


def gaussian_pixel_integrals(sigma, pixel, n, centre=(0.0, 0.0)):
    """Exact pixel integrals of a unit-volume Gaussian on an n×n grid (zero at n//2)."""
    from math import erf

    edges = (np.arange(n + 1) - n // 2 - 0.5) * pixel
    def cdf(x, c):
        return np.array([0.5 * (1 + erf((v - c) / (sigma * math.sqrt(2)))) for v in x])
    py = np.diff(cdf(edges, centre[1]))
    px = np.diff(cdf(edges, centre[0]))
    return py[:, None] * px[None, :]


# ------------------------------------------------------------------ optotype


def test_snellen_e_area_and_range():
    # exact pixel coverage: the E covers 17 of its 25 stroke cells, whatever the sampling
    for letter, pixel, n in [(5.0, 1.0, 11), (5.0, 0.37, 40), (12.3, 0.5, 64)]:
        e = np.asarray(images.snellen_e(letter, pixel, n))
        coverage = (1.0 - e).sum() * pixel**2
        assert coverage == pytest.approx(17 / 25 * letter**2, rel=1e-5)
        assert e.min() >= -1e-6 and e.max() <= 1 + 1e-6


@pytest.mark.parametrize("orientation", images.ORIENTATIONS)
def test_snellen_e_opening_direction(orientation):
    e = np.asarray(images.snellen_e(5.0, 1.0, 11, orientation)) < 0.5  # dark pixels
    letter = e[3:8, 3:8]  # the 5×5 strokes, rows increasing upwards (y up)
    opening = {"right": letter[:, 4], "left": letter[:, 0],
               "up": letter[4, :], "down": letter[0, :]}[orientation]
    spine = {"right": letter[:, 0], "left": letter[:, 4],
             "up": letter[0, :], "down": letter[4, :]}[orientation]
    assert spine.all()  # the closed side is a full stroke
    assert list(opening) == [True, False, True, False, True]  # three bar ends and two gaps


def test_snellen_e_contrast_background_and_default_size():
    e = np.asarray(images.snellen_e(10.0, 0.5, contrast=0.5, background=2.0))
    assert e.shape == (40, 40)
    assert e.max() == pytest.approx(2.0) and e.min() == pytest.approx(1.0)


@pytest.mark.parametrize("kwargs, match", [
    (dict(letter_arcmin=0.0, pixel_arcmin=1.0), "letter_arcmin"),
    (dict(letter_arcmin=5.0, pixel_arcmin=-1.0), "pixel_arcmin"),
    (dict(letter_arcmin=5.0, pixel_arcmin=1.0, orientation="diagonal"), "orientation"),
    (dict(letter_arcmin=5.0, pixel_arcmin=1.0, n_pixels=4), "does not fit"),
    (dict(letter_arcmin=5.0, pixel_arcmin=1.0, n_pixels=2.5), "n_pixels"),
    (dict(letter_arcmin=5.0, pixel_arcmin=1.0, contrast=1.5), "contrast"),
    (dict(letter_arcmin=float("nan"), pixel_arcmin=1.0), "letter_arcmin"),
])
def test_snellen_e_rejects_bad_input(kwargs, match):
    with pytest.raises(ValueError, match=match):
        images.snellen_e(**kwargs)


def test_snellen_e_differentiable_in_size():
    def dark(size):
        return jnp.sum(1.0 - images.snellen_e(size, 0.5, 40))

    g = jax.grad(dark)(10.0)
    # d/ds (17/25 s² / p²) = 34/25 s / p²
    assert float(g) == pytest.approx(34 / 25 * 10.0 / 0.25, rel=1e-4)


# ------------------------------------------------------------------ PSF resampling


@pytest.mark.parametrize("pixel", [0.3, 1.0, 2.5])  # finer than, equal to, coarser than 60/(df L)
def test_psf_on_grid_matches_gaussian_pixel_integrals(pixel):
    sigma, L, df = 2.0, 64, 1.0  # PSF pixel 60/64 ≈ 0.94 arcmin, field 60 arcmin
    n = int(24 / pixel) | 1
    psf = np.asarray(images.psf_on_grid(gaussian_otf_half(sigma, L, df), df, pixel, n))
    exact = gaussian_pixel_integrals(sigma, pixel, n)
    assert np.abs(psf - exact).max() <= 2e-4 * exact.max() + 1e-7
    assert psf.sum() == pytest.approx(exact.sum(), abs=1e-4)


def test_psf_on_grid_rejects_bad_otf():
    with pytest.raises(ValueError, match="rfft2 layout"):
        images.psf_on_grid(jnp.ones((8, 8), complex), 1.0, 1.0, 9)
    with pytest.raises(ValueError, match="pixel_arcmin"):
        images.psf_on_grid(gaussian_otf_half(1.0, 16), 1.0, 0.0, 9)


# ------------------------------------------------------------------ convolution


def test_delta_scene_gives_the_psf_and_shifts_with_it():
    otf = gaussian_otf_half(1.5, 64, 1.0)
    pixel, n = 0.5, 48
    scene = jnp.zeros((n, n)).at[n // 2, n // 2].set(1.0)
    img = np.asarray(images.retinal_image(scene, pixel, otf, 1.0, boundary="constant"))
    ref = gaussian_pixel_integrals(1.5, pixel, n)
    assert np.abs(img - ref).max() < 1e-4 * ref.max() + 1e-7
    moved = jnp.zeros((n, n)).at[n // 2 + 5, n // 2 - 3].set(1.0)  # +5 rows (up), -3 columns
    img2 = np.asarray(images.retinal_image(moved, pixel, otf, 1.0, boundary="constant"))
    ref2 = gaussian_pixel_integrals(1.5, pixel, n, centre=(-3 * pixel, 5 * pixel))
    assert np.abs(img2 - ref2).max() < 1e-4 * ref.max() + 1e-7


def test_uniform_scene_and_energy_are_preserved():
    otf = gaussian_otf_half(3.0, 64, 1.0)
    flat = jnp.full((30, 40), 0.7)
    for boundary in ("edge", "periodic"):
        out = np.asarray(images.retinal_image(flat, 0.8, otf, 1.0, boundary=boundary))
        assert np.allclose(out, 0.7, atol=1e-5)
    e = images.snellen_e(8.0, 0.5, 64)
    out = np.asarray(images.retinal_image(e, 0.5, otf, 1.0, boundary="periodic"))
    assert out.mean() == pytest.approx(float(e.mean()), rel=1e-5)


# A PSF field of 24 arcmin (L = 64 samples of 2.5 cpd, 0.375 arcmin apart) and a blur wider
# than a sample: pixels from 0.01 arcmin (1/37 of a sample) to 1000 arcmin (42 fields).
FIELD_OTF = dict(sigma_arcmin=1.2, n_fft=64, df=2.5)
PIXELS_ARCMIN = (0.01, 0.03, 0.1, 0.3, 1.0, 3.0, 10.0, 30.0, 100.0, 1000.0)
FLOAT32_SUMS = 2e-6  # float32 rounding of the kernel's sums (measured: <= 8e-7)


@pytest.mark.parametrize("pixel", PIXELS_ARCMIN)
@pytest.mark.parametrize("boundary", ["edge", "periodic", "constant"])
def test_a_uniform_scene_stays_uniform_at_its_luminance_at_any_pixel_size(pixel, boundary):
    # the kernel tiles the PSF's whole field and sums to OTF(0) = 1: no pixel size, however
    # fine (a kernel of 4801 pixels on a 4-pixel scene) or coarse (the field inside one
    # pixel), loses or adds light
    otf = gaussian_otf_half(FIELD_OTF["sigma_arcmin"], FIELD_OTF["n_fft"], FIELD_OTF["df"])
    flat = jnp.full((4, 4), 2.5)
    out = np.asarray(images.retinal_image(flat, pixel, otf, FIELD_OTF["df"], boundary=boundary,
                                          constant=2.5))
    assert np.abs(out / 2.5 - 1).max() <= FLOAT32_SUMS


@pytest.mark.parametrize("pixel", (0.01, 0.3, 3.0, 30.0, 1000.0))
def test_the_light_of_any_scene_is_conserved_at_any_pixel_size(pixel):
    otf = gaussian_otf_half(FIELD_OTF["sigma_arcmin"], FIELD_OTF["n_fft"], FIELD_OTF["df"])
    scene = jnp.asarray(np.random.default_rng(7).random((6, 6)), jnp.float32)
    out = np.asarray(images.retinal_image(scene, pixel, otf, FIELD_OTF["df"],
                                          boundary="periodic"))
    assert out.sum() == pytest.approx(float(scene.sum()), rel=FLOAT32_SUMS)  # × pixel area


def test_pixels_wider_than_the_psf_field_hold_the_whole_psf():
    # a 30 arcmin pixel holds the 24 arcmin field: each retinal pixel is its scene pixel
    otf = gaussian_otf_half(FIELD_OTF["sigma_arcmin"], FIELD_OTF["n_fft"], FIELD_OTF["df"])
    scene = jnp.asarray(np.random.default_rng(8).random((5, 7)), jnp.float32)
    out = np.asarray(images.retinal_image(scene, 30.0, otf, FIELD_OTF["df"], boundary="constant"))
    np.testing.assert_allclose(out, np.asarray(scene), rtol=FLOAT32_SUMS)


def test_the_kernel_tiles_the_field_and_no_more():
    # T = 24 arcmin: 1 arcmin pixels -12…12 cover it ((12 + ½)·1 ≥ 12) and one more
    assert images.kernel_half_width(2.5, 1.0) == 13
    assert images.kernel_half_width(2.5, 1000.0) == 1
    psf = np.asarray(images.psf_on_grid(gaussian_otf_half(1.2, 64, 2.5), 2.5, 1.0, 27))
    assert psf[0].max() == 0 and psf[:, -1].max() == 0  # pixels ±13: outside the field
    assert psf.sum() == pytest.approx(1.0, abs=FLOAT32_SUMS)


def test_scene_pixel_size_is_handled():
    """A scene blurred at a fine pixel, then box-averaged, equals the same scene blurred at
    the coarse pixel: the kernel is the pixel-integrated PSF on each grid."""
    otf = gaussian_otf_half(2.0, 96, 0.75)
    fine = images.snellen_e(12.0, 0.25, 128)
    coarse = fine.reshape(32, 4, 32, 4).mean(axis=(1, 3))  # 1 arcmin pixels, same letter
    blurred_fine = images.retinal_image(fine, 0.25, otf, 0.75)
    down = np.asarray(blurred_fine).reshape(32, 4, 32, 4).mean(axis=(1, 3))
    blurred_coarse = np.asarray(images.retinal_image(coarse, 1.0, otf, 0.75))
    # equal up to the difference between box-filtering before and after the blur (small)
    assert np.abs(down - blurred_coarse).max() < 0.02


def test_psf_input_equals_otf_input():
    L, df = 64, 1.0
    otf = gaussian_otf_half(2.0, L, df)
    psf_pixel = 60.0 / (df * L)
    psf = np.fft.fftshift(np.fft.irfft2(np.asarray(otf), s=(L, L)))
    scene = images.snellen_e(10.0, 0.4, 60)
    a = np.asarray(images.retinal_image(scene, 0.4, otf, df))
    b = np.asarray(images.retinal_image(scene, 0.4, psf=psf * 7.0, psf_pixel_arcmin=psf_pixel))
    assert np.abs(a - b).max() < 1e-5


def test_batched_otfs_and_gradients():
    otf = jnp.stack([gaussian_otf_half(1.0, 32), gaussian_otf_half(3.0, 32)])
    scene = images.snellen_e(6.0, 0.5, 32)
    out = images.retinal_image(scene, 0.5, otf, 1.0)
    assert out.shape == (2, 32, 32)
    assert float(jnp.std(out[1])) < float(jnp.std(out[0]))  # more blur, less contrast

    def loss(s):
        return jnp.sum(images.retinal_image(s, 0.5, otf[0], 1.0) ** 2)

    g = jax.grad(loss)(scene)
    assert g.shape == scene.shape and bool(jnp.all(jnp.isfinite(g)))
    direction = jnp.asarray(np.random.default_rng(0).normal(size=scene.shape))
    eps = 1e-2
    fd = (loss(scene + eps * direction) - loss(scene - eps * direction)) / (2 * eps)
    assert float(jnp.sum(g * direction)) == pytest.approx(float(fd), rel=2e-3)


@pytest.mark.parametrize("call, match", [
    (lambda o: images.retinal_image(jnp.ones(5), 1.0, o, 1.0), "2-D image"),
    (lambda o: images.retinal_image(jnp.full((4, 4), jnp.nan), 1.0, o, 1.0), "non-finite"),
    (lambda o: images.retinal_image(jnp.ones((4, 4)), 0.0, o, 1.0), "pixel_arcmin"),
    (lambda o: images.retinal_image(jnp.ones((4, 4)), 1.0), "exactly one"),
    (lambda o: images.retinal_image(jnp.ones((4, 4)), 1.0, o, 1.0, psf=jnp.ones((3, 3)),
                                    psf_pixel_arcmin=1.0), "exactly one"),
    (lambda o: images.retinal_image(jnp.ones((4, 4)), 1.0, o), "freq_step_cpd"),
    (lambda o: images.retinal_image(jnp.ones((4, 4)), 1.0, o[:, :5], 1.0), "rfft2 layout"),
    (lambda o: images.retinal_image(jnp.ones((4, 4)), 1.0, psf=jnp.ones((3, 4)),
                                    psf_pixel_arcmin=1.0), "square"),
    (lambda o: images.retinal_image(jnp.ones((4, 4)), 1.0, psf=jnp.ones((3, 3))),
     "psf_pixel_arcmin"),
    (lambda o: images.retinal_image(jnp.ones((4, 4)), 1.0, o, 1.0, boundary="mirror"),
     "boundary"),
    (lambda o: images.retinal_image(jnp.ones((4, 4)) * 1j, 1.0, o, 1.0), "real"),
])
def test_retinal_image_rejects_bad_input(call, match):
    with pytest.raises(ValueError, match=match):
        call(gaussian_otf_half(1.0, 16))
