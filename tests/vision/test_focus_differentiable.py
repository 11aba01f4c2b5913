"""metrics_at is differentiable in every physical parameter (float64 finite differences)."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import lfjax
from lfjax.model.layouts import Layout
from lfjax.vision.focus import metrics_at, through_focus

WAVELENGTHS = [500.0, 600.0]
SAMPLING = lfjax.Sampling(2.0)


@pytest.fixture(scope="module")
def setup():
    with jax.enable_x64(True):
        eyes = lfjax.sample_eyes(5, 1)
        spectrum = lfjax.make_spectrum(WAVELENGTHS)
    return eyes, spectrum


def _fd(f, x, h):
    return (f(x + h) - f(x - h)) / (2 * h)


def test_metrics_at_matches_through_focus():
    eyes = lfjax.sample_eyes(5, 2)
    spectrum = lfjax.make_spectrum(WAVELENGTHS)
    layout = lfjax.grid_layout(2, 3.0)
    acc = np.array([1.4, 1.8, 2.2])
    tf = through_focus(eyes, layout, [1.8], acc, spectrum=spectrum, sampling=SAMPLING)
    vs, sr = metrics_at(eyes, layout, jnp.array([1.8]), jnp.array([acc]), spectrum=spectrum,
                        sampling=SAMPLING)
    np.testing.assert_allclose(vs, tf.vsotf, rtol=2e-5, atol=2e-6)
    np.testing.assert_allclose(sr, tf.strehl, rtol=2e-5, atol=2e-6)


@pytest.mark.parametrize("which", ["accommodation", "depth", "centre_x", "diameter", "pupil"])
def test_vsotf_gradient_matches_finite_difference(setup, which):
    with jax.enable_x64(True):
        eyes, spectrum = setup
        centres = jnp.array([[-0.6, 0.2], [0.5, -0.3]])
        diameters = jnp.array([1.0, 1.1])

        def vs(x):
            acc = jnp.array([[2.3]])
            depth = jnp.array([2.5])
            c, d, pupil = centres, diameters, 3.0
            if which == "accommodation":
                acc = acc + x
            elif which == "depth":
                depth = depth + x
            elif which == "centre_x":
                c = c.at[0, 0].add(x)
            elif which == "diameter":
                d = d.at[1].add(x)
            else:
                pupil = 2.8 + x
            layout = Layout(c, d, 1.2, "test")
            v, _ = metrics_at(eyes, layout, depth, acc, pupil_diameter_mm=pupil,
                              spectrum=spectrum, sampling=SAMPLING)
            return v[0, 0, 0]

        g = jax.grad(vs)(0.0)
        fd = _fd(vs, 0.0, 1e-4)
        assert np.isfinite(g)
        assert abs(fd) > 1e-4, "derivative too small to test"
        np.testing.assert_allclose(g, fd, rtol=1e-4, atol=1e-7)


def test_no_nan_gradient_at_pupil_centre_and_zero_accommodation(setup):
    with jax.enable_x64(True):
        eyes, spectrum = setup

        def vs(params):
            layout = Layout(params["c"], params["d"], 3.0, "test")
            v, s = metrics_at(eyes, layout, jnp.array([0.0]), params["a"][None],
                              spectrum=spectrum, sampling=SAMPLING)
            return v.sum() + s.sum()

        params = dict(c=jnp.zeros((1, 2)), d=jnp.array([3.0]), a=jnp.array([0.0]))
        g = jax.grad(vs)(params)
        for leaf in jax.tree_util.tree_leaves(g):
            assert np.all(np.isfinite(leaf))
