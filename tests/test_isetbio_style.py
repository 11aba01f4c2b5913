"""The ISETBio-style baseline (``isetbio_style.py`` beside this file, which
benchmarks/baselines/bench_naive.py times lfjax against): its sampling reproduces ISETBio's,
its PSF is the diffraction-limited one, and its view shifts have the right sign under
ISETBio's flipped y axis. Pure numpy, < 2 s."""

import numpy as np
import pytest

from isetbio_style import (
    ARCMIN_PER_RAD,
    IsetbioPipeline,
    IsetbioStats,
    WvfSampling,
    monochromatic_psf,
)


def test_default_sampling_is_isetbios():
    """wvfCreate defaults, 'psf' domain: PSF sample λ_m / P at every λ, pupil spacing ∝ λ."""
    s = WvfSampling()
    assert s.psf_arcmin_per_sample == pytest.approx(550e-6 / 16.212 * ARCMIN_PER_RAD)
    assert s.field_arcmin == pytest.approx(23.44, abs=0.01)
    assert s.pupil_dx_mm(400.0) == pytest.approx(16.212 * 400 / 550 / 201)
    assert s.pupil_dx_mm(700.0) / s.pupil_dx_mm(400.0) == pytest.approx(700 / 400)


@pytest.mark.parametrize("wavelength_nm", [450.0, 550.0, 650.0])
def test_aberration_free_mtf_is_the_circular_pupil_mtf(wavelength_nm):
    """At ISETBio's defaults (a hard-edged pupil about 30-45 samples across) the MTF of the
    aberration-free 3 mm pupil matches (2/π)(acos s − s√(1−s²)), s = f λ / d, within 0.005
    (measured ≈ 0.002), at every λ on the one λ-independent angular grid."""
    s = WvfSampling()
    psf, pix_arcmin = monochromatic_psf(s, [0.0], wavelength_nm)
    assert psf.shape == (201, 201) and np.isclose(psf.sum(), 1.0)
    mtf = np.abs(np.fft.fft2(np.fft.ifftshift(psf)))
    f = np.fft.fftfreq(201, 1.0 / 201) / (201 * pix_arcmin / ARCMIN_PER_RAD)  # cycles/rad
    sv = np.clip(np.abs(f) * wavelength_nm * 1e-6 / 3.0, 0.0, 1.0)
    analytic = (2 / np.pi) * (np.arccos(sv) - sv * np.sqrt(1 - sv**2))
    assert np.abs(mtf[0] - analytic).max() < 5e-3    # along f_x
    assert np.abs(mtf[:, 0] - analytic).max() < 5e-3  # along f_y


def test_views_coincide_on_the_rendered_depth():
    """Aberration-free, monochromatic, accommodated on the rendered depth: after the display
    shift (D_d − D_CDP)(p_n, q_n) every view's PSF is the same (views inside the pupil, so
    none is cropped). A wrong sign on either axis — ISETBio's PSF rows run towards −θ_y —
    leaves them ≈ 2 arcmin apart."""
    s = WvfSampling()
    centres = np.array([[-0.6, -0.6], [0.6, -0.6], [-0.6, 0.6], [0.6, 0.6]])
    diameters = np.full(4, 1.0)
    pipe = IsetbioPipeline(s, [550.0])
    spec = (np.array([550.0]), np.array([1.0]), np.array([0.0]), np.array([0.0]))
    n = s.n_samples
    for depth, cdp in ((2.5, 2.0), (1.5, 2.0)):
        psfs = pipe.elemental_psfs(np.zeros(15), depth - cdp, 0.0, spec, centres, diameters,
                                   IsetbioStats())
        otfs = pipe.elemental_otfs(psfs, IsetbioStats())
        views = [
            np.fft.irfft2(pipe.shifted_sum(otfs[k : k + 1], (depth - cdp) * centres[k : k + 1] * 1e-3),
                          s=(n, n))
            for k in range(4)
        ]
        raw = [np.fft.irfft2(o, s=(n, n)) for o in otfs]
        peak = views[0].max()
        assert max(np.abs(v - views[0]).max() for v in views) < 0.03 * peak  # measured 0.018
        assert max(np.abs(v - raw[0]).max() for v in raw) > 0.5 * peak
