"""Vergence geometry and the cross-link (lfjax.binocular.geometry)."""

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from lfjax.binocular import geometry as G


def test_vergence_demand_is_the_depth_and_the_angles_follow_the_ipd():
    d = np.array([0.0, 0.5, 2.0, 4.0])
    np.testing.assert_array_equal(G.vergence_demand_MA(d), d)
    # 63 mm, 1 D: each line of sight turns atan(0.0315)
    assert float(G.vergence_angle_deg(1.0, 63.0)) == pytest.approx(
        2 * math.degrees(math.atan(0.0315)), rel=1e-12)
    assert float(G.convergence_prism_D(1.0, 63.0)) == pytest.approx(6.3, rel=1e-12)
    # the eye's own distance differs by 0.8 % at 4 D for 63 mm, 1.3 % for 80 mm (the
    # numbers the module's docstring states)
    assert 1 - float(G.eye_distance_D(4.0, 63.0)) / 4.0 == pytest.approx(0.0078, abs=5e-5)
    ratio = float(G.eye_distance_D(4.0, 80.0)) / 4.0
    assert ratio == pytest.approx(1 / math.sqrt(1 + 0.16**2), rel=1e-12)
    assert 1 - ratio == pytest.approx(0.0126, abs=5e-5)


def test_cross_link_off_is_exact_and_on_moves_towards_vergence():
    a = jnp.asarray([1.0, 2.0])
    v = jnp.asarray([3.0, 0.5])
    np.testing.assert_array_equal(G.cross_linked_accommodation_D(a, v, 63.0, 0.0), a)
    # CA/C 0.1 D/prism D at 100 mm... within range: 0.1 * 0.1 * 63 = 0.63 of the way
    got = G.cross_linked_accommodation_D(a, v, 63.0, 0.1)
    np.testing.assert_allclose(got, a + 0.63 * (v - a), rtol=1e-12)
    # a blur loop of gain G divides the pull by 1 + G
    got = G.cross_linked_accommodation_D(a, v, 63.0, 0.1, 9.0)
    np.testing.assert_allclose(got, a + 0.063 * (v - a), rtol=1e-12)
    np.testing.assert_allclose(G.conflict_D(v, got), v - got, rtol=0)


def test_conflict_gradient_in_the_ipd_matches_finite_differences():
    def conflict(ipd):
        a = G.cross_linked_accommodation_D(2.0, 3.5, ipd, 0.13)
        return G.conflict_D(3.5, a)

    g = float(jax.grad(conflict)(jnp.asarray(63.0)))
    eps = 1e-4
    fd = (float(conflict(63.0 + eps)) - float(conflict(63.0 - eps))) / (2 * eps)
    assert g == pytest.approx(fd, rel=1e-8)
    assert g == pytest.approx(-0.1 * 0.13 * 1.5, rel=1e-12)
