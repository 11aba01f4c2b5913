"""Population viewers (lfjax.binocular.population): left eyes as sample_eyes, mirrored
fellows, anisometropia through the published prevalences, IPD statistics."""

import math

import jax.numpy as jnp
import numpy as np
import pytest

import lfjax
from lfjax.base.errors import ParameterError
from lfjax.binocular import population as P
from lfjax.binocular.viewer import binocular_statistics
from lfjax.model.eyes import thibos_statistics

N = 20000


def test_left_eyes_are_sample_eyes_and_right_eyes_their_mirror():
    v = P.sample_viewers(7, 5, anisometropia_D=0.0)
    np.testing.assert_array_equal(v.left.zernike_um, lfjax.sample_eyes(7, 5).zernike_um)
    np.testing.assert_array_equal(v.right.zernike_um, v.left.mirrored().zernike_um)


def test_fixed_anisometropia_is_the_difference_in_spherical_equivalent():
    v = P.sample_viewers(7, 5, anisometropia_D=1.0)
    per_um = P.spherical_equivalent_per_um(3.0)
    assert per_um == pytest.approx(-4 * math.sqrt(3) / 1.5**2)
    se_left = per_um * np.asarray(v.left.zernike_um[:, P.DEFOCUS_J])
    se_right = per_um * np.asarray(v.right.zernike_um[:, P.DEFOCUS_J])
    np.testing.assert_allclose(se_right - se_left, 1.0, rtol=0, atol=1e-12)
    other = np.arange(v.left.n_modes) != P.DEFOCUS_J
    np.testing.assert_array_equal(np.asarray(v.right.zernike_um)[:, other],
                                  np.asarray(v.left.mirrored().zernike_um)[:, other])


def test_anisometropia_law_passes_through_the_published_prevalences():
    k, b = P.anisometropia_weibull()
    stats = binocular_statistics()
    assert math.exp(-(1.0 / b) ** k) == pytest.approx(stats["anisometropia_1D_prevalence"])
    assert math.exp(-(2.0 / b) ** k) == pytest.approx(stats["anisometropia_2D_prevalence"])
    v = P.sample_viewers(11, N)
    per_um = P.spherical_equivalent_per_um(3.0)
    delta = per_um * np.asarray(v.right.zernike_um[:, P.DEFOCUS_J]
                                - v.left.zernike_um[:, P.DEFOCUS_J])
    for t, p in ((1.0, 0.0843), (2.0, 0.0222)):
        sd = math.sqrt(p * (1 - p) / N)
        assert abs(np.mean(np.abs(delta) >= t) - p) < 4 * sd
    assert abs(np.mean(delta > 0) - 0.5) < 4 * 0.5 / math.sqrt(N)


def test_ipd_follows_dodgson_and_stays_in_range():
    v = P.sample_viewers(12, N, anisometropia_D=0.0)
    ipd = np.asarray(v.ipd_mm)
    assert abs(ipd.mean() - 63.36) < 4 * 3.832 / math.sqrt(N)
    assert ipd.std() == pytest.approx(3.832, rel=0.03)
    assert ipd.min() >= 45.0 and ipd.max() <= 80.0


def test_fellow_correlation_keeps_each_eye_a_thibos_eye():
    v = P.sample_viewers(13, N, anisometropia_D=0.0, fellow_correlation=0.0)
    left = np.asarray(v.left.zernike_um)
    right_as_left = np.asarray(v.right.mirrored().zernike_um)
    _, cov, _ = thibos_statistics(3.0)
    j = 12  # spherical aberration: the same law, drawn independently
    assert np.var(right_as_left[:, j]) == pytest.approx(cov[j, j], rel=0.05)
    assert abs(np.corrcoef(left[:, j], right_as_left[:, j])[0, 1]) < 4 / math.sqrt(N)
    np.testing.assert_array_equal(right_as_left[:, P.DEFOCUS_J], left[:, P.DEFOCUS_J])
    half = P.sample_viewers(13, N, anisometropia_D=0.0, fellow_correlation=0.5)
    r = np.corrcoef(left[:, j], np.asarray(half.right.mirrored().zernike_um)[:, j])[0, 1]
    assert r == pytest.approx(0.5, abs=4 / math.sqrt(N))


@pytest.mark.parametrize("kw, match", [
    (dict(n_viewers=0), "n_viewers must be an integer >= 1"),
    (dict(fellow_correlation=1.5), r"fellow_correlation must lie in \[0, 1\]"),
    (dict(anisometropia_D="some"), "anisometropia_D must be 'population' or a number"),
    (dict(anisometropia_D=9.0), r"\[-5, 5\] D"),
    (dict(ipd_mean_mm=20.0), r"ipd_mean_mm must lie in \[45, 80\] mm"),
    (dict(ipd_sd_mm=-1.0), r"ipd_sd_mm must lie in \[0, 10\] mm"),
])
def test_bad_sampling_arguments_are_refused(kw, match):
    args = dict(n_viewers=3) | kw
    n = args.pop("n_viewers")
    with pytest.raises(ParameterError, match=match):
        P.sample_viewers(0, n, **args)
