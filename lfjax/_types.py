"""Shared array conversions for the pytrees (Eyes, Layout, Spectrum, Scene, Accommodation)."""

from __future__ import annotations

import jax
import jax.numpy as jnp

FULL = jax.lax.Precision.HIGHEST
"""Precision of every matrix product in lfjax. JAX's default lets accelerators round float32
products' inputs (TF32, a 10-bit mantissa, on NVIDIA GPUs since Ampere; bfloat16 passes on
TPU): the separable wavefront's cancelling monomials, the matrix Fourier transform's phase
sums and the three-point peak fit (values that agree to 1e-4) need all of float32. The CPU
ignores it. tests/test_precision.py checks every product of the traced programs."""


def is_concrete(*xs) -> bool:
    """True when no leaf of ``xs`` is a tracer: values can be checked on the host."""
    return not any(isinstance(x, jax.core.Tracer) for x in jax.tree_util.tree_leaves(xs))


def as_real_array(x):
    """Array-like → jax array of the default real dtype (float32, or float64 under x64);
    traced values pass through with their own floating dtype.

    Concrete values are made strongly typed: a Python float becomes a *weakly* typed array,
    which ``jax.jit`` treats as a different input type from the same value given as an
    array, so a pytree built from floats and one built from arrays would compile twice."""
    if isinstance(x, jax.core.Tracer):
        return x if jnp.issubdtype(x.dtype, jnp.floating) else x.astype(jnp.result_type(float))
    x = jnp.asarray(x)
    dtype = x.dtype if jnp.issubdtype(x.dtype, jnp.floating) else jnp.result_type(float)
    return jnp.asarray(x, dtype)


def as_index_array(x):
    """Array-like → int32 jax array (index arrays)."""
    return jnp.asarray(x, jnp.int32)
