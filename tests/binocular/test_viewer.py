"""A viewer is two eyes and an IPD (lfjax.binocular.viewer): pairs, mirroring, refusals."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import lfjax
from lfjax.base import zernike
from lfjax.base.errors import ParameterError
from lfjax.binocular.viewer import Viewer, binocular_statistics, check_viewer, ipd_range_mm


def test_identical_pair_has_the_same_coefficients_and_the_mean_ipd():
    eyes = lfjax.sample_eyes(1, 3)
    v = Viewer.identical(eyes)
    np.testing.assert_array_equal(v.left.zernike_um, eyes.zernike_um)
    np.testing.assert_array_equal(v.right.zernike_um, eyes.zernike_um)
    assert (v.left.orientation, v.right.orientation) == ("left", "right")
    assert v.n_viewers == 3 and v.ipd_mm.shape == (3,)
    assert float(v.ipd_mm[0]) == binocular_statistics()["ipd_mean_mm"]
    one = v[1]
    assert one.n_viewers == 1
    np.testing.assert_array_equal(one.right.zernike_um[0], eyes.zernike_um[1])


def test_mirrored_wavefront_at_minus_x_equals_the_original():
    """The mirror negates the modes odd in x: W_mirror(−x, y) = W(x, y) everywhere."""
    eye = lfjax.sample_eyes(2, 1, measured_pupil_mm=6.0)
    pair = Viewer.mirror_pair(eye)
    x, y = np.meshgrid(np.linspace(-1, 1, 9), np.linspace(-1, 1, 7))
    w = zernike.wavefront_um(pair.left.zernike_um[0], jnp.asarray(x), jnp.asarray(y))
    w_mirror = zernike.wavefront_um(pair.right.zernike_um[0], jnp.asarray(-x), jnp.asarray(y))
    np.testing.assert_allclose(w_mirror, w, rtol=0, atol=1e-12)
    # and the signs are the modes odd in x: m > 0 odd, m < 0 even
    signs = zernike.mirror_sign_vector(eye.n_modes)
    for j in range(eye.n_modes):
        n, m = zernike.nm_from_ansi(j)
        odd = zernike.zernike_mode_host(j, -0.3, 0.7) == -zernike.zernike_mode_host(j, 0.3, 0.7)
        assert (signs[j] == -1.0) == (bool(odd) and zernike.zernike_mode_host(j, 0.3, 0.7) != 0)


def test_mirror_pair_of_a_symmetric_eye_is_two_identical_eyes():
    eye = lfjax.sample_eyes(3, 2)
    even = jnp.asarray(zernike.mirror_sign_vector(eye.n_modes) > 0, eye.zernike_um.dtype)
    symmetric = lfjax.make_eyes(eye.zernike_um * even, 3.0)
    pair = Viewer.mirror_pair(symmetric)
    np.testing.assert_array_equal(pair.right.zernike_um, pair.left.zernike_um)
    # an asymmetric eye's mirror differs
    assert np.max(np.abs(np.asarray(Viewer.mirror_pair(eye).right.zernike_um
                                    - eye.zernike_um))) > 1e-3


@pytest.mark.parametrize("ipd", [30.0, 95.0, float("nan"), [60.0, 44.0]])
def test_an_ipd_outside_the_human_range_is_refused(ipd):
    low, high = ipd_range_mm()
    assert (low, high) == (45.0, 80.0)
    eyes = lfjax.sample_eyes(0, 2)
    with pytest.raises(ParameterError, match=r"Viewer\.ipd_mm must lie in \[45, 80\] mm"):
        Viewer.identical(eyes, ipd)


def test_a_viewer_with_one_eye_missing_is_refused():
    eye = lfjax.average_eye(3.0)
    with pytest.raises(ParameterError, match=r"Viewer\.right must be lfjax\.Eyes"):
        Viewer(eye, None, jnp.asarray([63.0]))
    with pytest.raises(ParameterError, match="one eye is missing"):
        check_viewer(eye)
    with pytest.raises(ParameterError, match="one eye per viewer"):
        Viewer(eye, lfjax.sample_eyes(0, 2, orientation="right"), jnp.asarray([63.0]))
    with pytest.raises(ParameterError, match="right-eye orientation"):
        Viewer(eye, eye, jnp.asarray([63.0]))
    with pytest.raises(ParameterError, match=r"shape \(n_viewers,\)"):
        Viewer(eye, eye.mirrored(), jnp.asarray([63.0, 64.0]))


def test_a_traced_ipd_passes_and_is_differentiable():
    eye = lfjax.average_eye(3.0)

    def f(ipd):
        return jnp.sum(Viewer(eye, eye.mirrored(), ipd[None]).ipd_mm ** 2)

    assert float(jax.grad(f)(jnp.asarray(63.0))) == pytest.approx(126.0)
