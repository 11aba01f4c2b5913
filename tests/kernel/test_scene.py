"""The scene and accommodation pytrees (lfjax.kernel.scene): the accommodation SA's numbers
for each reading of ``ModelOptions.accommodation_sa`` by hand, shapes refused naming the
field, and how states are shared by rendered depths. No optics is computed."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from lfjax.kernel.scene import Accommodation, Scene, sa_c40_um, sa_parameters
from lfjax.model.layouts import grid_layout
from lfjax.model.options import ModelOptions

SLOPE = ModelOptions().sa_slope_um_per_D  # µm/D on the 5 mm reference pupil


@pytest.mark.parametrize("form, scale, radius", [
    ("scaled", (4.0 / 5.0) ** 4, 2.0),   # Cheng's c(4,0) rescaled to the 4 mm pupil's radius
    ("wavefront_5mm", 1.0, 2.5),         # kept on the 5 mm pupil it was measured on
    ("unscaled", 1.0, 2.0),              # the 5 mm number on the 4 mm pupil
    ("off", 0.0, 2.0),
])
def test_accommodation_sa_numbers_by_hand(form, scale, radius):
    options = ModelOptions(accommodation_sa=form)
    got = np.asarray(sa_parameters(options, 4.0))
    np.testing.assert_allclose(got, [SLOPE * scale, radius], rtol=1e-12, atol=1e-15)
    assert float(sa_c40_um(2.0, 4.0, options)) == pytest.approx(2.0 * SLOPE * scale, abs=1e-15)


def test_the_sa_numbers_follow_a_traced_pupil():
    grad = jax.grad(lambda d: sa_parameters(ModelOptions(), d)[0])(4.0)
    assert float(grad) == pytest.approx(SLOPE * 4 * 4.0**3 / 5.0**4, rel=1e-12)


def test_per_depth_states_each_get_their_own_entry():
    acc = Accommodation.per_depth([[0.0, 0.5, 1.0], [1.5, 2.0, 2.5]], ModelOptions(), 4.0)
    np.testing.assert_array_equal(np.asarray(acc.states_D), [0.0, 0.5, 1.0, 1.5, 2.0, 2.5])
    np.testing.assert_array_equal(np.asarray(acc.pair_index), [[0, 1, 2], [3, 4, 5]])
    assert acc.pair_index.dtype == jnp.int32
    assert float(acc.sa_radius_mm) == 2.0


def test_shared_states_keep_their_index():
    acc = Accommodation.shared([0.0, 1.0], [[0, 1], [1, 1]], ModelOptions(), 3.0)
    np.testing.assert_array_equal(np.asarray(acc.pair_index), [[0, 1], [1, 1]])


@pytest.mark.parametrize("build, words", [
    (lambda: Accommodation.per_depth([0.0, 1.0], ModelOptions(), 3.0),
     r"accommodation_D must have shape \(n_depth, n_k\)"),
    (lambda: Accommodation([0.0], [0], -0.04, 2.0), r"Accommodation.pair_index must have shape"),
    (lambda: Scene(np.zeros(3), np.ones(3), 2.0, [2.0], 3.0), r"Scene.centres_mm must have shape"),
    (lambda: Scene(np.zeros((3, 2)), np.ones(2), 2.0, [2.0], 3.0),
     r"Scene.diameters_mm must have shape \(3,\)"),
])
def test_bad_shapes_are_refused_naming_the_field(build, words):
    with pytest.raises(ValueError, match=words):
        build()


def test_scene_from_layout_carries_the_layout_and_a_depth_axis():
    layout = grid_layout(2, 3.0)
    scene = Scene.from_layout(layout, 1.5, 2.0, 3.0)
    assert scene.n_depths == 1 and scene.depths_D.shape == (1,)
    np.testing.assert_array_equal(np.asarray(scene.centres_mm), np.asarray(layout.centres_mm))
    assert scene.display is None and scene.cdp_D.dtype == jnp.result_type(float)
