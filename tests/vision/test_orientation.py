"""Strip views against analytic diffraction and geometric optics, the HPO beam against the
open pupil, leakage 0 bit for bit, mirror symmetry of the overlap scan, and the orientation
bands of the VSOTF (lfjax.vision.orientation)."""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np
import pytest

import lfjax
from lfjax.display.lenticular import strip_display
from lfjax.kernel.optics import psf_from_otf
from lfjax.model.eyes import Eyes
from lfjax.model.layouts import grid_layout, open_pupil
from lfjax.model.strips import strip_layout
from lfjax.vision.focus import through_focus
from lfjax.vision.orientation import orientation_through_focus, orientation_windows
from lfjax.vision.prepare import States
from lfjax.vision.psf import polychromatic_otf
from lfjax.vision.viewing import Viewing

PLAIN = lfjax.ModelOptions(sce="off", accommodation_sa="off")
LAMBDA_MM = 550e-6


def _strip_psf(width_mm, y_defocus_D, eye_defocus_D, df=0.5):
    """Monochromatic (550 nm) PSF of one strip, aberration-free eye, (psf, angles rad)."""
    layout = strip_layout(1, 3.0, width_mm=width_mm)
    eye = Eyes(jnp.zeros((1, 15)), 3.0)
    stack = polychromatic_otf(
        eye,
        [2.0 + eye_defocus_D],
        Viewing(pupil_diameter_mm=3.0, cdp_D=2.0,
                display=strip_display(layout, y_defocus_D=y_defocus_D)),
        layout=layout,
        depths_D=[2.0],
        spectrum=lfjax.make_spectrum([550.0], PLAIN),
        sampling=lfjax.Sampling(df),
        options=PLAIN,
    )
    otf = stack.otf[0, 0, 0]
    n = otf.shape[0]
    psf = np.asarray(psf_from_otf(otf, n, df), float)
    theta = (np.arange(n) - n // 2) * np.deg2rad(1.0 / (df * n))
    return psf, theta


def test_a_strip_diffracts_as_a_slit_along_x_and_the_pupil_height_along_y():
    """In focus: the PSF's row through the centre is the slit's sinc²(wθ/λ) (exactly, the
    Fraunhofer pattern of the strip's chord profile), its column the pupil height's."""
    w, radius = 0.5, 1.5
    psf, theta = _strip_psf(w, 0.0, 0.0)
    c = theta.size // 2
    row, col = psf[c] / psf[c, c], psf[:, c] / psf[c, c]
    xs = np.linspace(-w / 2, w / 2, 2001)
    ys = np.linspace(-radius, radius, 20001)
    chord = 2 * np.sqrt(radius**2 - xs**2)  # the aperture's height at each x
    width = np.minimum(w, 2 * np.sqrt(np.maximum(radius**2 - ys**2, 0)))  # its width at each y

    def fraunhofer(profile, s):
        f = np.abs(np.trapezoid(profile[None] * np.exp(-2j * np.pi * s[None] * theta[:, None] / LAMBDA_MM), s, axis=1))**2
        return f / f[c]

    near = slice(c - 30, c + 31)  # ±9 arcmin: the slit's central lobe and two side lobes each way
    np.testing.assert_allclose(row[near], fraunhofer(chord, xs)[near], atol=2e-3)
    np.testing.assert_allclose(row[near], np.sinc(w * theta / LAMBDA_MM)[near] ** 2, atol=4e-3)
    np.testing.assert_allclose(col[near], fraunhofer(width, ys)[near], atol=1e-3)
    np.testing.assert_allclose(col[near], np.sinc(2 * radius * theta / LAMBDA_MM)[near] ** 2, atol=6e-3)


def _cdf(p):
    c = np.cumsum(p)
    return c / c[-1]


def test_geometric_limits_along_each_axis():
    """Defocused far beyond the diffraction limit (Fresnel numbers 11 along x, 16 along y)
    the line spreads are the strip's shadow: a top hat D_x·w wide along x, the chord profile
    D_y·height along y, with D_x = 6 D of the eye's defocus and D_y = 6 − 12 = −6 D once the
    beam's own y defocus (−12 D) is added."""
    w, radius = 2.0, 1.5
    psf, theta = _strip_psf(w, -12.0, 6.0, df=0.8)
    half = 6.0e-3 * w / 2  # rad
    expected = np.clip((theta + half) / (2 * half), 0, 1)
    # edge diffraction at N ≈ 11 still puts ~3 % of the light beyond the shadow's edges
    assert np.max(np.abs(_cdf(psf.sum(0)) - expected)) < 0.04
    ys = -theta / 6.0e-3  # pupil height (mm) each angle comes from (the sign is immaterial)
    width = np.minimum(w, 2 * np.sqrt(np.maximum(radius**2 - ys**2, 0)))
    assert np.max(np.abs(_cdf(psf.sum(1)) - _cdf(width))) < 0.03


def test_full_height_strip_with_one_view_is_the_open_pupil_along_y():
    """A strip covering the pupil (n = 1) with y defocus Δ: its OTF on the f_y axis at
    accommodation a is the open pupil's at a + Δ, on the f_x axis the open pupil's at a
    (the x² term of the astigmatic beam cancels in the autocorrelation along y)."""
    eye = lfjax.average_eye(3.0)
    spectrum = lfjax.make_spectrum([500.0, 600.0], PLAIN)
    layout = strip_layout(1, 3.0, width_mm=3.3)  # its sides beyond the pupil: the pupil's own edge
    acc = [1.5, 2.0, 2.5]
    common = dict(spectrum=spectrum, sampling=lfjax.Sampling(1.5), options=PLAIN, depths_D=[2.0])
    hpo = polychromatic_otf(eye, acc, Viewing(display=strip_display(layout, y_defocus_D=-0.5)),
                            layout=layout, **common).otf[0, 0]
    natural = polychromatic_otf(eye, acc, layout=open_pupil(3.0), **common).otf[0, 0]
    np.testing.assert_allclose(np.asarray(hpo[1, :, 0]), np.asarray(natural[0, :, 0]), atol=1e-12)
    np.testing.assert_allclose(np.asarray(hpo[1, 0, :]), np.asarray(natural[1, 0, :]), atol=1e-12)
    assert np.max(np.abs(np.asarray(hpo[1, :, 0] - natural[1, :, 0]))) > 0.05


def test_leakage_weight_zero_is_todays_display_bit_for_bit():
    eye = lfjax.average_eye(3.0)
    kw = dict(sampling=lfjax.Sampling(1.5), spectrum=lfjax.make_spectrum([550.0]))
    states = States.around([1.0, 3.0], [-0.5, 0.0])
    layout = grid_layout(2, 3.0)
    today = through_focus(eye, layout, states, **kw)
    leaky = through_focus(eye, layout, states,
                          Viewing(display=strip_display(layout, aperture="circle")), **kw)
    for name in ("vsotf", "strehl", "radial_mtf"):
        np.testing.assert_array_equal(np.asarray(getattr(leaky, name)), np.asarray(getattr(today, name)))
    more = through_focus(eye, layout, states, Viewing(display=strip_display(
        layout, aperture="circle", leakage_weight=0.4)), **kw)
    assert np.max(np.abs(np.asarray(more.vsotf) - np.asarray(today.vsotf))) > 1e-2


def _mirrored(eyes):
    """The eyes mirrored x → −x: Z_n^m times (−1)^m (m ≥ 0) or −(−1)^m (m < 0)."""
    from lfjax.base.zernike import nm_from_ansi

    signs = []
    for j in range(eyes.zernike_um.shape[-1]):
        _, m = nm_from_ansi(j)
        signs.append((-1) ** abs(m) * (1 if m >= 0 else -1))
    return Eyes(eyes.zernike_um * jnp.asarray(signs, float), eyes.measured_pupil_mm)


@pytest.mark.parametrize("ratio", [0.75, 1.25])
def test_a_symmetric_overlap_scan_is_symmetric_in_its_results(ratio):
    """Strips placed symmetrically about the pupil's centre, with gaps or overlap, with
    leakage: an eye and its mirror image see the same through-focus (views and shifts map
    onto each other)."""
    eye = lfjax.sample_eyes(3, 1, 3.0)
    layout = strip_layout(2, 3.0, width_mm=ratio * 1.5)
    kw = dict(sampling=lfjax.Sampling(1.5), spectrum=lfjax.make_spectrum([550.0]))
    states = States.grid([1.5, 2.5], [1.0, 3.0])
    viewing = Viewing(display=strip_display(layout, leakage_weight=0.3))
    a = orientation_through_focus(eye, layout, states, viewing, **kw)
    b = orientation_through_focus(_mirrored(eye), layout, states, viewing, **kw)
    # The mirrored views' samples are the same lattice points, held at other indices of
    # their windows (an even window has one more sample on one side): the sums differ by
    # float64 rounding only, ~1e-12 of VSOTF on near-cancelling (≈1e-4) values.
    np.testing.assert_allclose(np.asarray(b.vsotf), np.asarray(a.vsotf), rtol=1e-9, atol=1e-11)
    assert np.max(np.abs(np.asarray(eye.zernike_um - _mirrored(eye).zernike_um))) > 1e-3


def test_orientation_windows_and_the_whole_band_is_through_focus():
    wx, wy = orientation_windows(16, 1.0)
    np.testing.assert_allclose(np.asarray(wx + wy), 1.0)
    assert float(wx[0, 3]) == 1.0 and float(wy[3, 0]) == 1.0  # f_x axis, f_y axis
    eye = lfjax.sample_eyes(0, 2, 3.0)
    layout = strip_layout(2, 3.0)
    display = strip_display(layout, y_defocus_D=-0.5)
    kw = dict(sampling=lfjax.Sampling(1.4), spectrum=lfjax.make_spectrum([550.0]))
    states = States.grid([1.0, 2.0, 3.0], [1.0, 2.5])
    bands = orientation_through_focus(eye, layout, states, Viewing(display=display), **kw)
    whole = through_focus(eye, layout, states, Viewing(display=display), **kw)
    np.testing.assert_allclose(np.asarray(bands.vsotf[0]), np.asarray(whole.vsotf), rtol=1e-10)


def test_strips_narrow_fft_is_the_square_windows_answer():
    """Strips are transformed on windows as wide as the strip along x (fewer FFT columns,
    the same angular field): the same OTFs as on the square, pupil-wide window, which a
    user-fixed n_fft of the same size still uses."""
    from lfjax.vision.prepare import prepare

    eyes = lfjax.sample_eyes(5, 2, 3.0)
    layout = strip_layout(3, 3.0, width_mm=1.2)
    display = strip_display(layout, y_defocus_D=-0.4, leakage_weight=0.2)
    # two wavelengths: two bands of narrow windows (each its own width) against the one
    # square band; a third band is a third copy of the kernel to compile, nothing new
    spectrum = lfjax.make_spectrum([480.0, 640.0])
    common = dict(spectrum=spectrum)
    viewing = Viewing(pupil_diameter_mm=3.0, cdp_D=2.0, display=display)
    narrow_config = prepare(eyes, layout, States.grid([1.5, 2.5], [1.0, 3.0]), viewing,
                            sampling=lfjax.Sampling(0.9), **common).config
    assert len(narrow_config.bands) == 2
    assert all(len(b) == 4 and b[3] < b[2] for b in narrow_config.bands)  # fewer columns
    n_fft = narrow_config.n_fft
    states = States.grid([1.5, 2.0, 2.5], [1.0, 3.0])
    narrow = orientation_through_focus(eyes, layout, states, viewing,
                                       sampling=lfjax.Sampling(0.9), **common)
    square = orientation_through_focus(eyes, layout, states, viewing,
                                       sampling=lfjax.Sampling(0.9, n_fft=n_fft), **common)
    np.testing.assert_allclose(np.asarray(narrow.vsotf), np.asarray(square.vsotf), atol=2e-5)
    np.testing.assert_allclose(np.asarray(narrow.mtf_x), np.asarray(square.mtf_x), atol=2e-5)
    np.testing.assert_allclose(np.asarray(narrow.mtf_y), np.asarray(square.mtf_y), atol=2e-5)
    assert np.ptp(np.asarray(square.vsotf)) > 0.05
