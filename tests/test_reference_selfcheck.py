"""Self-checks of the numpy reference (tests/reference.py) against analytic results.

These check the reference itself, not lfjax: if one fails, the reference is wrong.
"""

import math
import os
import sys

import numpy as np
import pytest

sys.path.insert(0, os.path.dirname(__file__))
import reference as R  # noqa: E402

LAM_REF = 550.0
RAD2AMIN = R.RAD_TO_ARCMIN


def _mono_kw(**over):
    """Aberration-free, monochromatic at lambda_ref, SCE off, accommodation SA off."""
    kw = dict(zernike_um=np.zeros(1), measured_pupil_mm=3.0, pupil_mm=3.0,
              wavelengths_nm=[LAM_REF], spectral_weights=[1.0], accommodation_D=2.0,
              cdp_D=2.0, rendered_depth_D=2.0, centres_mm=[[0.0, 0.0]], diameters_mm=[3.0],
              n_freq=64, freq_step_cpd=3.0, sce_rho_per_mm2=0.0, sa_slope_um_per_D=0.0)
    kw.update(over)
    return kw


# ------------------------------------------------------------------ 1. Zernike
def test_nm_from_j_table():
    expected = [(0, 0), (1, -1), (1, 1), (2, -2), (2, 0), (2, 2), (3, -3), (3, -1), (3, 1),
                (3, 3), (4, -4), (4, -2), (4, 0), (4, 2), (4, 4)]
    assert [R.nm_from_j(j) for j in range(15)] == expected
    for j in range(66):
        assert R.j_from_nm(*R.nm_from_j(j)) == j


def test_zernike_known_forms():
    rho = np.linspace(0, 1, 7)[:, None]
    th = np.linspace(-np.pi, np.pi, 9)[None, :]
    np.testing.assert_allclose(R.zernike_nm(1, 1, rho, th), 2 * rho * np.cos(th), atol=1e-14)
    np.testing.assert_allclose(R.zernike_nm(2, 0, rho, th) + 0 * th,
                               math.sqrt(3) * (2 * rho**2 - 1) + 0 * th, atol=1e-14)
    np.testing.assert_allclose(R.zernike_nm(4, 0, rho, th) + 0 * th,
                               math.sqrt(5) * (6 * rho**4 - 6 * rho**2 + 1) + 0 * th,
                               atol=1e-13)
    np.testing.assert_allclose(R.zernike_nm(3, -1, rho, th),
                               math.sqrt(8) * (3 * rho**3 - 2 * rho) * np.sin(th), atol=1e-13)


def test_zernike_orthonormality():
    # Gauss-Legendre in r (weight r dr) x uniform in theta: exact for these polynomials.
    nr, nt = 24, 64
    x, w = np.polynomial.legendre.leggauss(nr)
    r = 0.5 * (x + 1.0)
    wr = 0.5 * w * r
    th = np.arange(nt) * 2 * np.pi / nt
    wt = np.full(nt, 2 * np.pi / nt)
    rr, tt = np.meshgrid(r, th, indexing="ij")
    W = (wr[:, None] * wt[None, :]) / np.pi  # mean over the unit disk
    Z = np.stack([R.zernike_j(j, rr, tt) for j in range(21)])
    G = np.einsum("aij,bij,ij->ab", Z, Z, W)
    err = np.abs(G - np.eye(21)).max()
    assert err < 1e-3
    assert err < 1e-10  # the quadrature is exact


# ------------------------------------------------------------------ 2. diffraction limit
def test_diffraction_limited_open_pupil_mtf():
    L, df = 96, 2.0
    otf = R.reference_otf(**_mono_kw(n_freq=L, freq_step_cpd=df, supersample=8))
    assert abs(otf[0, 0] - 1.0) < 1e-12
    cutoff_cpd = 3.0 / (LAM_REF * 1e-6) / R.CPD_TO_CPR  # 95.2 cpd
    k = np.fft.fftfreq(L, 1.0 / L)
    nu = np.abs(k) * df / cutoff_cpd
    mtf = R.diffraction_limited_mtf(nu)
    err_x = np.abs(np.abs(otf[0, :]) - mtf).max()
    err_y = np.abs(np.abs(otf[:, 0]) - mtf).max()
    assert err_x <= 2e-3 and err_y <= 2e-3, (err_x, err_y)
    # aberration-free, centred, symmetric pupil: OTF real
    assert np.abs(otf.imag).max() < 1e-12


def test_airy_and_bessel():
    from scipy.special import j1
    x = np.linspace(0, 80, 2001)
    assert np.abs(R.bessel_j1(x) - j1(x)).max() < 1e-13
    lam_mm, d = LAM_REF * 1e-6, 3.0
    assert R.airy_intensity(0.0, lam_mm, d) == 1.0
    first_zero = 3.8317059702075125 * lam_mm / (math.pi * d)
    assert R.airy_intensity(first_zero, lam_mm, d) < 1e-12
    # PSF from the reference OTF (Nyquist above cut-off) vs Airy near the core
    L, df = 128, 2.0
    otf = R.reference_otf(**_mono_kw(n_freq=L, freq_step_cpd=df, supersample=8))
    psf = R.reference_psf_from_otf(otf)
    assert abs(psf.sum() - 1.0) < 1e-12
    a = R.psf_angles_arcmin(L, df)
    th = np.hypot(a[None, :], a[:, None]) / RAD2AMIN
    core = th < 3 * first_zero
    err = np.abs(psf / psf[0, 0] - R.airy_intensity(th, lam_mm, d))[core].max()
    assert err < 1e-4, err


# ------------------------------------------------------------------ 3. autocorrelation
def _tiny_pupil():
    rng = np.random.default_rng(1)
    c = 0.3 * rng.standard_normal(15)
    lam = 600.0
    h = lam * 1e-6 * 30.0 * R.CPD_TO_CPR / 2  # df = 30 cpd, s = 2 -> ~0.5 mm samples
    P, _, _ = R.pupil_function(c, 6.0, 3.0, lam, h, (0.4, -0.3), 2.2, defocus_D=0.7,
                               c40_extra_um=0.05, sce_rho_per_mm2=0.05)
    return P, h


def test_fft_autocorrelation_equals_bruteforce():
    P, h = _tiny_pupil()
    assert P.shape[0] >= 5 and np.count_nonzero(P) > 10
    for L in (8, 10):
        fast = R.elemental_otf(P, h, L, 2)
        slow = R.elemental_otf_bruteforce(P, h, L, 2)
        via_psf = R.elemental_otf_via_psf(P, h, L, 2)
        scale = np.abs(slow).max()
        assert np.abs(fast - slow).max() < 1e-12 * scale
        assert np.abs(via_psf - slow).max() < 1e-12 * scale
        # OTF(0) = int |P|^2
        assert abs(slow[0, 0] - (np.abs(P) ** 2).sum() * h**2) < 1e-12 * scale


def test_full_model_methods_agree_tiny():
    rng = np.random.default_rng(2)
    kw = dict(zernike_um=0.2 * rng.standard_normal(10), measured_pupil_mm=4.5, pupil_mm=3.0,
              wavelengths_nm=[480.0, 620.0], spectral_weights=[0.4, 1.0], accommodation_D=2.6,
              cdp_D=2.0, rendered_depth_D=1.2, centres_mm=[[0.75, 0.75], [-0.75, 0.0]],
              diameters_mm=[1.5, 1.2], n_freq=8, freq_step_cpd=30.0,
              sce_rho_per_mm2=[0.05, 0.04], supersample=2)
    a = R.reference_otf(method="fft", **kw)
    b = R.reference_otf(method="brute", **kw)
    c = R.reference_otf(method="psf", **kw)
    assert abs(a[0, 0] - 1) < 1e-12
    assert np.abs(a - b).max() < 1e-12
    assert np.abs(a - c).max() < 1e-12
    # real PSF -> Hermitian OTF: OTF(-k) = conj(OTF(k)) (skip the unpaired Nyquist index)
    L = a.shape[0]
    neg = (-np.arange(L)) % L
    keep = np.arange(L) != L // 2
    herm = (a - np.conj(a[np.ix_(neg, neg)]))[np.ix_(keep, keep)]
    assert np.abs(herm).max() < 1e-12
    # and the OTF is genuinely complex here (aberrations + display shifts)
    assert np.abs(a.imag).max() > 1e-3


# ------------------------------------------------------------------ 4. tilt sign
def test_positive_x_tilt_moves_psf_to_negative_x():
    c = np.zeros(3)
    c[2] = 0.5  # um on Z(1,1) = 2 rho cos(theta), 6 mm measurement pupil
    L, df = 96, 1.5
    otf = R.reference_otf(**_mono_kw(zernike_um=c, measured_pupil_mm=6.0, n_freq=L,
                                     freq_step_cpd=df))
    expected = -2 * c[2] / 3.0 * 1e-3 * RAD2AMIN  # -dW/dx, W slope 2 c2 / R_meas um/mm
    psf = R.reference_psf_from_otf(otf)
    cx, cy = R.psf_centroid_arcmin(psf, df)
    px, py = R.otf_phase_centroid_arcmin(otf, df)
    assert cx < 0 and px < 0
    assert abs(px / expected - 1) < 1e-6
    assert abs(cx / expected - 1) < 0.02
    assert abs(cy) < 1e-9 and abs(py) < 1e-9
    # y tilt (j = 1, Z(1,-1) = 2 rho sin(theta)) moves the PSF to -y
    c = np.zeros(3)
    c[1] = 0.5
    otf = R.reference_otf(**_mono_kw(zernike_um=c, measured_pupil_mm=6.0, n_freq=L,
                                     freq_step_cpd=df))
    px, py = R.otf_phase_centroid_arcmin(otf, df)
    assert abs(py / expected - 1) < 1e-6 and abs(px) < 1e-9


# ------------------------------------------------------------------ 5. defocus / LF sign
@pytest.mark.parametrize("centre", [(1.0, 0.0), (0.0, -1.0)])
def test_defocus_sign_and_display_shift(centre):
    L, df = 96, 1.0
    kw = _mono_kw(accommodation_D=3.0, cdp_D=2.0, centres_mm=[centre], diameters_mm=[1.0],
                  n_freq=L, freq_step_cpd=df)
    # D_total = +1 D: W = D r^2 / 2 -> local slope D * p (1e-3 rad/mm) -> theta = -D p
    exp_x = -(3.0 - 2.0) * centre[0] * 1e-3 * RAD2AMIN
    exp_y = -(3.0 - 2.0) * centre[1] * 1e-3 * RAD2AMIN
    otf = R.reference_otf(**kw)  # rendered at the CDP: no display shift
    psf = R.reference_psf_from_otf(otf)
    cx, cy = R.psf_centroid_arcmin(psf, df)  # window centred on 0
    cx2, cy2 = R.psf_centroid_arcmin(psf, df, centre_arcmin=(exp_x, exp_y))
    px, py = R.otf_phase_centroid_arcmin(otf, df)
    for got, exp in ((cx, exp_x), (cy, exp_y), (cx2, exp_x), (cy2, exp_y), (px, exp_x),
                     (py, exp_y)):
        if exp == 0:
            assert abs(got) < 1e-9
        else:
            assert abs(got / exp - 1) < 0.02, (got, exp)
    assert abs(cx2 - exp_x) + abs(cy2 - exp_y) < 1e-3 * 3.44
    assert abs(px - exp_x) + abs(py - exp_y) < 1e-4 * 3.44
    # rendered at r = a: display shift (r - cdp) * p brings the centroid back to 0
    otf_r = R.reference_otf(**{**kw, "rendered_depth_D": 3.0})
    psf_r = R.reference_psf_from_otf(otf_r)
    rx, ry = R.psf_centroid_arcmin(psf_r, df)
    qx, qy = R.otf_phase_centroid_arcmin(otf_r, df)
    assert abs(rx) < 0.01 * 3.44 and abs(ry) < 0.01 * 3.44
    assert abs(qx) < 1e-4 and abs(qy) < 1e-4
    # the shift is a pure phase ramp
    np.testing.assert_allclose(np.abs(otf_r), np.abs(otf), atol=1e-14)


def test_displaced_centroids_coincide_multi_subaperture():
    """Stage 6 invariant (docs/design.md#the-model-stage-by-stage): aberration-free, monochromatic eye accommodated at the rendered
    depth -> all displaced elemental PSFs share one centroid (here 0)."""
    L, df = 64, 1.5
    cs = [[-0.75, -0.75], [0.75, -0.75], [-0.75, 0.75], [0.75, 0.75]]
    for r in (0.5, 3.5):
        for c in cs:
            otf = R.reference_otf(**_mono_kw(accommodation_D=r, rendered_depth_D=r,
                                             centres_mm=[c], diameters_mm=[0.8], n_freq=L,
                                             freq_step_cpd=df))
            px, py = R.otf_phase_centroid_arcmin(otf, df)
            assert abs(px) < 1e-3 and abs(py) < 1e-3, (r, c, px, py)


def test_lca_and_defocus_coefficient():
    assert abs(R.lca_dioptres(550.0)) < 1e-15
    assert R.lca_dioptres(450.0) > 0 > R.lca_dioptres(650.0)  # eye myopic for blue
    assert abs(R.defocus_coefficient_um(1.0, 3.0) - 0.32476) < 1e-4


def test_extra_terms_equal_explicit_zernikes():
    """Accommodation defocus, LCA and accommodation SA are Zernike terms on the calculation
    pupil: with measured pupil = calculation pupil they equal explicit eye coefficients."""
    L, df = 32, 4.0
    a, cdp, lam = 2.7, 2.0, 480.0
    slope = -0.0435
    D_total = (a - cdp) + float(R.lca_dioptres(lam))
    c = np.zeros(13)
    c[4] = R.defocus_coefficient_um(D_total, 3.0)
    c[12] = slope * a * (3.0 / 5.0) ** 4  # -0.00564 um/D on a 3 mm pupil
    base = dict(_mono_kw(n_freq=L, freq_step_cpd=df, wavelengths_nm=[lam],
                         centres_mm=[[0.3, -0.2]], diameters_mm=[1.5]))
    implicit = R.reference_otf(**{**base, "accommodation_D": a, "cdp_D": cdp,
                                  "rendered_depth_D": cdp, "sa_slope_um_per_D": slope})
    explicit = R.reference_otf(**{**base, "zernike_um": c, "accommodation_D": cdp,
                                  "cdp_D": cdp, "rendered_depth_D": cdp, "lca_A": 0.0})
    assert np.abs(implicit - explicit).max() < 1e-12
    assert abs(slope * (3.0 / 5.0) ** 4 - (-0.0056376)) < 1e-6
