"""metrics_at is differentiable in every physical parameter (float64 finite differences)."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import lfjax
from lfjax.model.layouts import Layout
from lfjax.vision.focus import metrics_at, through_focus
from lfjax.vision.prepare import States
from lfjax.vision.viewing import Viewing

WAVELENGTHS = [500.0, 600.0]
SAMPLING = lfjax.Sampling(2.0)


@pytest.fixture(scope="module")
def setup():
    with jax.enable_x64(True):
        eyes = lfjax.sample_eyes(5, 1)
        spectrum = lfjax.make_spectrum(WAVELENGTHS)
    return eyes, spectrum


def test_metrics_at_matches_through_focus():
    eyes = lfjax.sample_eyes(5, 2)
    spectrum = lfjax.make_spectrum(WAVELENGTHS)
    layout = lfjax.grid_layout(2, 3.0)
    acc = np.array([1.4, 1.8, 2.2])
    tf = through_focus(
        eyes, layout, States.grid(acc, depths_D=[1.8]), spectrum=spectrum, sampling=SAMPLING
    )
    vs, sr = metrics_at(eyes, layout, jnp.array([1.8]), jnp.array([acc]), spectrum=spectrum,
                        sampling=SAMPLING)
    np.testing.assert_allclose(vs, tf.vsotf, rtol=2e-5, atol=2e-6)
    np.testing.assert_allclose(sr, tf.strehl, rtol=2e-5, atol=2e-6)


PARAMETERS = ["accommodation", "depth", "centre_x", "diameter", "pupil"]


def test_vsotf_gradient_matches_finite_difference(setup):
    """d VSOTF / d(accommodation, depth, a subaperture's x centre, another's diameter, the
    pupil diameter), each against its own central difference. One compiled program (the
    VSOTF and its gradient in all five at once) serves the gradient and every
    finite-difference evaluation: one compile instead of a forward and a reverse program
    per parameter."""
    with jax.enable_x64(True):
        eyes, spectrum = setup
        centres = jnp.array([[-0.6, 0.2], [0.5, -0.3]])
        diameters = jnp.array([1.0, 1.1])

        def vs(x):
            acc = jnp.array([[2.3]]) + x["accommodation"]
            depth = jnp.array([2.5]) + x["depth"]
            c = centres.at[0, 0].add(x["centre_x"])
            d = diameters.at[1].add(x["diameter"])
            pupil = 2.8 + x["pupil"]
            layout = Layout(c, d, 1.2, "test")
            v, _ = metrics_at(
                eyes,
                layout,
                depth,
                acc,
                Viewing(pupil_diameter_mm=pupil),
                spectrum=spectrum,
                sampling=SAMPLING,
            )
            return v[0, 0, 0]

        value_and_grad = jax.jit(jax.value_and_grad(vs))
        x0 = {name: jnp.asarray(0.0) for name in PARAMETERS}
        _, g = value_and_grad(x0)
        h = 1e-4
        for name in PARAMETERS:
            plus = value_and_grad({**x0, name: jnp.asarray(h)})[0]
            minus = value_and_grad({**x0, name: jnp.asarray(-h)})[0]
            fd = float(plus - minus) / (2 * h)
            assert np.isfinite(g[name]), name
            assert abs(fd) > 1e-4, f"{name}: derivative too small to test"
            np.testing.assert_allclose(g[name], fd, rtol=1e-4, atol=1e-7, err_msg=name)


def test_no_nan_gradient_at_pupil_centre_and_zero_accommodation(setup):
    with jax.enable_x64(True):
        eyes, _ = setup
        # one wavelength (one band, half the program to compile): the singular points
        # (r = 0 at the view's centre, a = 0) do not depend on the wavelength count
        spectrum = lfjax.make_spectrum(WAVELENGTHS[:1])

        def vs(params):
            layout = Layout(params["c"], params["d"], 3.0, "test")
            v, s = metrics_at(
                eyes,
                layout,
                jnp.array([0.0]),
                params["a"][None],
                spectrum=spectrum,
                sampling=SAMPLING,
            )
            return v.sum() + s.sum()

        params = dict(c=jnp.zeros((1, 2)), d=jnp.array([3.0]), a=jnp.array([0.0]))
        g = jax.grad(vs)(params)
        for leaf in jax.tree_util.tree_leaves(g):
            assert np.all(np.isfinite(leaf))
