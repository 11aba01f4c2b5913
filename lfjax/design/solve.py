"""The design fit's solver: SciPy's L-BFGS-B on the host, in the box [0, 1]^k, around the
compiled loss and gradient of :mod:`lfjax.design.box`."""

from __future__ import annotations

import math
import time

import jax.numpy as jnp
import numpy as np

from lfjax.design.box import design_value_and_grad, design_value_and_grad_chunked


FLAT_STEP = 1e-6
"""L-BFGS-B's ``ftol`` in the design fit: it stops after a step that lowers the loss by less
than this fraction of max(|loss|, 1), about eight float32 roundings of the loss — a change
the float32 loss cannot resolve. SciPy's default (2.2e-9) lies below that resolution: on
the phone preset's flat accommodation-penalty plateau (loss 97.66) a 1e-7 step was followed
by a second step whose line search spent 785 s on 10 eyes (RESULTS §36)."""


def solve_box(x0, problem, template, n, constraints, steps: int, tol: float,
           eye_chunk: int | None = 1, say=None):
    """L-BFGS-B (SciPy's, on the host) in the box [0, 1]^k around the compiled loss and
    gradient (:func:`design_loss_chunked`, ``eye_chunk`` eyes at a time): at most ``steps``
    iterations, stopping when the projected gradient is below ``tol`` or a step lowers the
    loss by less than :data:`FLAT_STEP` of its magnitude. ``say`` (a
    callable, or None) receives a line per iteration. Returns (x, loss history: the
    start, then each iteration's)."""
    from scipy.optimize import minimize

    x = np.asarray(x0, float)
    if steps == 0:
        return jnp.asarray(x0), []
    dtype = jnp.asarray(x0).dtype

    seen = {}  # the callback asks again for the point the solver just evaluated

    def fun(x):
        key = np.asarray(x, float).tobytes()
        if key not in seen:
            if eye_chunk is None:  # all at once: no checkpoint, no recomputation
                value, grad = design_value_and_grad(jnp.asarray(x, dtype), problem, template, n, constraints)
            else:
                value, grad = design_value_and_grad_chunked(jnp.asarray(x, dtype), problem, template, n,
                                                      constraints, eye_chunk)
            value = float(value)
            if not math.isfinite(value):
                raise FloatingPointError("the design loss is not finite")
            seen.clear()
            seen[key] = (value, np.asarray(grad, float))
        return seen[key]

    t0 = time.perf_counter()
    history = [fun(x)[0]]

    def step(xk):
        history.append(fun(xk)[0])
        if say is not None:
            say(f"step {len(history) - 1}/{steps}: loss {history[-1]:.5f} "
                f"({time.perf_counter() - t0:.0f} s)")

    if say is not None:
        say(f"start: loss {history[0]:.5f} ({time.perf_counter() - t0:.0f} s, with compilation)")
    result = minimize(fun, x, jac=True, method="L-BFGS-B", bounds=[(0.0, 1.0)] * x.size,
                      callback=step, options=dict(maxiter=steps, gtol=tol, ftol=FLAT_STEP))
    return jnp.asarray(result.x, dtype), history


