"""Virtual eyes (lfjax.model.eyes): Thibos et al. (2002) statistics, seeded sampling, mirroring."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from scipy import stats

import lfjax
import reference as R
from lfjax.model import eyes as E
from lfjax.base import zernike

N_DRAWS = 20000
N_SMALL = 6  # every small draw has this size: eager jax recompiles for each new shape


def test_statistics_match_the_published_files():
    """Spot values of the package data against the Thibos/ISETBio JSON files
    (the IASstats tables ISETBio bundles, lfjax/data/README.md: mean[4], mean[12],
    covariance[4][4], covariance[12][4], n_eyes)."""
    mean, cov, n = E.thibos_statistics(3.0)
    assert mean.shape == (15,) and cov.shape == (15, 15) and n == 200
    assert mean[4] == pytest.approx(0.00914352391617855, rel=1e-14)
    assert mean[12] == pytest.approx(0.006905749206285674, rel=1e-14)
    assert cov[4, 4] == pytest.approx(0.005615301699013611, rel=1e-14)
    assert cov[12, 4] == pytest.approx(-0.00016277441383817878, rel=1e-14)
    mean, cov, n = E.thibos_statistics(7.5)
    assert mean.shape == (66,) and cov.shape == (66, 66) and n == 140
    assert mean[4] == pytest.approx(0.6257505684352647, rel=1e-14)
    assert mean[12] == pytest.approx(0.16515595919792903, rel=1e-14)
    assert cov[4, 4] == pytest.approx(0.8046770639019539, rel=1e-14)
    assert cov[12, 4] == pytest.approx(0.057098693197524676, rel=1e-14)
    for p in E.THIBOS_PUPILS_MM:
        _, cov, _ = E.thibos_statistics(p)
        np.testing.assert_array_equal(cov, cov.T)
        assert np.linalg.eigvalsh(cov).min() > 0


@pytest.mark.parametrize("pupil", [3.0, 7.5])
def test_sampling_reproduces_mean_and_covariance(pupil):
    """20 000 draws: sample mean and covariance agree with the data within sampling error.

    Mean: N (m̂−μ)ᵀ Σ⁻¹ (m̂−μ) ~ χ²(k), required below its 0.9999 quantile, and every
    component within 4.5 standard errors sqrt(Σ_ii / N). Covariance: every entry within
    5 standard errors sqrt((Σ_ii Σ_jj + Σ_ij²) / N) (Gaussian sampling variance of S_ij;
    with 120 or 2211 entries a false alarm has probability ~1e-4 or ~1e-3 for a fresh seed;
    the seed is fixed, so the test is deterministic).
    """
    mean, cov, _ = E.thibos_statistics(pupil)
    draws = np.asarray(
        lfjax.sample_eyes(jax.random.key(20), N_DRAWS, pupil, zero_piston_tilt=False).zernike_um
    )
    assert draws.shape == (N_DRAWS, mean.size)
    k = mean.size
    m_hat = draws.mean(axis=0)
    d = m_hat - mean
    chi2 = N_DRAWS * d @ np.linalg.solve(cov, d)
    assert chi2 < stats.chi2.ppf(0.9999, k), chi2
    assert np.max(np.abs(d) / np.sqrt(np.diag(cov) / N_DRAWS)) < 4.5
    s_hat = np.cov(draws, rowvar=False)
    var = np.diag(cov)
    se = np.sqrt((var[:, None] * var[None, :] + cov**2) / N_DRAWS)
    assert np.max(np.abs(s_hat - cov) / se) < 5.0


def test_same_seed_same_eyes():
    a = lfjax.sample_eyes(7, N_SMALL)
    b = lfjax.sample_eyes(jax.random.key(7), N_SMALL)
    np.testing.assert_array_equal(a.zernike_um, b.zernike_um)
    np.testing.assert_array_equal(a.zernike_um, lfjax.sample_eyes(7, N_SMALL).zernike_um)
    c = lfjax.sample_eyes(8, N_SMALL)
    assert not np.allclose(a.zernike_um, c.zernike_um)
    assert a.measured_pupil_mm == 3.0 and a.orientation == "left" and a.n_eyes == N_SMALL


def test_piston_and_tilt_zeroed_by_default():
    z = np.asarray(lfjax.sample_eyes(3, N_SMALL).zernike_um)
    assert np.all(z[:, :3] == 0.0)
    assert np.all(z[:, 3:] != 0.0)
    raw = np.asarray(lfjax.sample_eyes(3, N_SMALL, zero_piston_tilt=False).zernike_um)
    np.testing.assert_array_equal(raw[:, 3:], z[:, 3:])


def test_right_eyes_are_mirrored_left_eyes():
    left = lfjax.sample_eyes(11, N_SMALL)
    right = lfjax.sample_eyes(11, N_SMALL, orientation="right")
    assert right.orientation == "right"
    np.testing.assert_array_equal(right.zernike_um, left.mirrored().zernike_um)
    np.testing.assert_array_equal(left.mirrored().mirrored().zernike_um, left.zernike_um)
    # mirroring is x -> −x of the wavefront (numpy Zernikes of tests/reference.py)
    x, y = np.asarray(jax.random.uniform(jax.random.key(0), (2, 64), minval=-1, maxval=1))
    basis = np.stack([R.zernike_j(j, np.hypot(x, y), np.arctan2(y, x)) for j in range(15)])
    basis_mirror = np.stack([R.zernike_j(j, np.hypot(x, y), np.arctan2(y, -x))
                             for j in range(15)])
    np.testing.assert_allclose(np.asarray(right.zernike_um) @ basis,
                               np.asarray(left.zernike_um) @ basis_mirror, atol=1e-12)
    avg = lfjax.average_eye()
    np.testing.assert_array_equal(
        lfjax.average_eye(orientation="right").zernike_um, avg.mirrored().zernike_um)


def test_average_eye_is_the_mean():
    mean, _, _ = E.thibos_statistics(4.5)
    avg = lfjax.average_eye(4.5)
    assert avg.zernike_um.shape == (1, 28) and avg.measured_pupil_mm == 4.5
    np.testing.assert_array_equal(avg.zernike_um[0, 3:], mean[3:])
    np.testing.assert_array_equal(avg.zernike_um[0, :3], 0.0)
    keep = lfjax.average_eye(4.5, zero_piston_tilt=False)
    np.testing.assert_array_equal(keep.zernike_um[0], mean)


def test_aberration_free_eye_and_indexing():
    eye = E.aberration_free_eye(6.0, 21)
    assert eye.zernike_um.shape == (1, 21) and eye.measured_pupil_mm == 6.0
    assert not np.any(np.asarray(eye.zernike_um))
    batch = lfjax.sample_eyes(1, N_SMALL)
    sub = batch[2]
    assert sub.n_eyes == 1
    np.testing.assert_array_equal(sub.zernike_um[0], batch.zernike_um[2])
    assert batch[1:4].n_eyes == 3


def test_bad_eye_inputs():
    with pytest.raises(ValueError, match="measured_pupil_mm"):
        lfjax.sample_eyes(0, 3, measured_pupil_mm=5.0)
    with pytest.raises(ValueError, match="n_eyes"):
        lfjax.sample_eyes(0, 0)
    with pytest.raises(ValueError, match="non-finite"):
        E.make_eyes([0.0, np.nan, 0.0], 3.0)
    with pytest.raises(ValueError, match="non-finite"):
        E.make_eyes([0.0, 0.0, np.inf], 3.0)
    with pytest.raises(ValueError, match="orientation"):
        E.make_eyes(np.zeros(6), 3.0, orientation="up")
    with pytest.raises(ValueError, match="measured_pupil_mm"):
        E.make_eyes(np.zeros(6), 0.0)
    with pytest.raises(ValueError, match="radial order"):
        E.Eyes(jnp.zeros((1, zernike.n_modes_for_order(21))), 3.0)
