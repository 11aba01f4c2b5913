"""The vertex of the parabola through three grid points (lfjax.base.parabola): exact on a
sampled parabola, clipped to half a step, the grid point itself at the ends or where the
curve is not concave, NumPy in → NumPy out and the same numbers through jax."""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np
import pytest

from lfjax.base.parabola import parabola_vertex

STATES = np.linspace(0.0, 2.0, 11)  # 0.2 D steps


def _curve(vertex_D, curvature=-3.0):
    return curvature * (STATES - vertex_D) ** 2 + 1.0


@pytest.mark.parametrize("vertex_D", [0.9, 1.0, 1.07, 1.099])
def test_vertex_of_a_sampled_parabola_is_exact(vertex_D):
    values = _curve(vertex_D)
    index = np.argmax(values)
    got = parabola_vertex(STATES, values, np.asarray(index))
    assert isinstance(got, (np.ndarray, np.generic))  # host work compiles nothing
    assert got == pytest.approx(vertex_D, abs=1e-12)
    # the step given for a uniform grid gives the same
    uniform = parabola_vertex(STATES, values, np.asarray(index), 0.2)
    assert uniform == pytest.approx(vertex_D, abs=1e-12)


def test_shift_is_clipped_to_half_a_step():
    # a vertex 0.3 D from the chosen point (1.0 D) is moved by at most 0.1 D
    values = _curve(1.3)
    assert parabola_vertex(STATES, values, np.asarray(5)) == pytest.approx(1.1, abs=1e-12)


@pytest.mark.parametrize("index, why", [(0, "first point"), (10, "last point")])
def test_the_grid_ends_give_the_grid_point(index, why):
    assert parabola_vertex(STATES, _curve(1.0), np.asarray(index)) == STATES[index], why


def test_a_convex_or_flat_curve_gives_the_grid_point():
    assert parabola_vertex(STATES, _curve(1.05, +3.0), np.asarray(5)) == STATES[5]
    assert parabola_vertex(STATES, np.ones_like(STATES), np.asarray(5)) == STATES[5]


def test_batched_and_traced_inputs_agree_with_numpy():
    values = np.stack([_curve(v) for v in (0.45, 1.02, 1.61)])
    index = np.argmax(values, axis=-1)
    states = np.broadcast_to(STATES, values.shape)
    host = parabola_vertex(states, values, index)
    traced = parabola_vertex(jnp.asarray(states), jnp.asarray(values), jnp.asarray(index))
    assert isinstance(traced, jnp.ndarray) and not isinstance(traced, np.ndarray)
    np.testing.assert_allclose(host, [0.45, 1.02, 1.61], atol=1e-12)
    np.testing.assert_allclose(np.asarray(traced), host, atol=1e-12)
