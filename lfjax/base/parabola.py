"""The vertex of the parabola through three neighbouring grid points: one implementation for
the pipeline's continuous peaks (:mod:`lfjax.vision.peaks`, traced), the planner's peak
shifts (:mod:`lfjax.planner.proxy`, NumPy) and the study's sub-grid peaks
(:mod:`lfjax.reproduce.study`, NumPy).
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np


def _array_module(*arrays):
    """numpy when every input is a NumPy array or scalar (host work compiles nothing), else jax."""
    if all(isinstance(a, (np.ndarray, float, int, np.floating, np.integer)) for a in arrays):
        return np
    return jnp


def parabola_vertex(states_D, values, index, step_D=None):
    """Vertex of the parabola through grid points index−1, index, index+1 (D), clipped to
    ±half a step; the grid point itself at the grid's ends or where the curve is not concave.

    states_D (…, n) increasing, values (…, n), index (…) int → (…) D. The step is half the
    distance between the two neighbours, or ``step_D`` (D) for a uniform grid. NumPy arrays
    in give NumPy out; anything else is evaluated with jax (traceable).
    """
    xp = _array_module(states_D, values, index)
    n = states_D.shape[-1]
    lo, hi = xp.clip(index - 1, 0, n - 1), xp.clip(index + 1, 0, n - 1)

    def take(x, i):
        return xp.take_along_axis(x, i[..., None], axis=-1)[..., 0]

    y0, y1, y2 = take(values, lo), take(values, index), take(values, hi)
    a0, a1, a2 = take(states_D, lo), take(states_D, index), take(states_D, hi)
    denom = y0 - 2 * y1 + y2
    ok = (lo != index) & (hi != index) & (denom < 0) & xp.isfinite(y0 + y2)
    step = 0.5 * (a2 - a0) if step_D is None else step_D
    shift = xp.where(ok, 0.5 * (y0 - y2) / xp.where(ok, denom, -1.0), 0.0)
    return a1 + xp.clip(shift, -0.5, 0.5) * step


__all__ = ["parabola_vertex"]
