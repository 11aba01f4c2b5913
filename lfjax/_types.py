"""Shared array conversions for the pytrees (Eyes, Layout, Spectrum, Scene, Accommodation)."""

from __future__ import annotations

import jax.numpy as jnp


def as_real_array(x):
    """Array-like → jax array of the default real dtype (float32, or float64 under x64);
    traced values pass through with their own floating dtype."""
    x = jnp.asarray(x)
    if jnp.issubdtype(x.dtype, jnp.floating):
        return x
    return x.astype(jnp.result_type(float))


def as_index_array(x):
    """Array-like → int32 jax array (index arrays)."""
    return jnp.asarray(x, jnp.int32)
