"""Shared array conversions for the pytrees (Eyes, Layout, Spectrum, Scene, Accommodation)."""

from __future__ import annotations

import functools
import math
import os
import types
import typing

import jax
import jaxtyping
import jax.numpy as jnp

from lfjax.base.errors import ParameterError

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


# ----------------------------------------------------------------- shapes in the types
# The public numerical entry points annotate their array arguments and results with
# jaxtyping shapes ("n_depth n_acc"). The annotations are documentation everywhere, and
# checked at call time when LFJAX_SHAPE_CHECKS=1 (the test suite sets it in conftest.py
# before importing lfjax), so a wrong shape fails naming the dimension that disagrees.

SHAPE_CHECKS = os.environ.get("LFJAX_SHAPE_CHECKS", "") == "1"
"""True when :func:`shape_checked` entry points check their jaxtyping annotations."""


def _is_shape_annotation(hint) -> bool:
    """True for a jaxtyping array type, or a union / tuple that contains one."""
    if isinstance(hint, type) and issubclass(hint, jaxtyping.AbstractArray):
        return True
    return any(_is_shape_annotation(arg) for arg in typing.get_args(hint))


def shape_checked(fn):
    """Check ``fn``'s jaxtyping-annotated arguments and result at call time, when
    :data:`SHAPE_CHECKS` is on; otherwise return ``fn`` unchanged (no cost).

    Only the jaxtyping annotations are checked (by beartype, through ``jaxtyping.jaxtyped``,
    so one call's dimension names must agree across its arguments and its result); the
    other annotations stay documentation. When the arguments fail and ``fn``'s own host
    checks also refuse them, ``fn``'s error (a ``ValueError`` naming the parameter, what
    users get without the checks) is raised, with the shape error as its context.
    """
    if not SHAPE_CHECKS:
        return fn
    # Deferred: beartype is a test dependency, imported only when the checks are on.
    from beartype import BeartypeConf, beartype

    hints = typing.get_type_hints(fn, include_extras=True)
    checked = {name: hint for name, hint in hints.items() if _is_shape_annotation(hint)}
    if not checked:
        raise TypeError(f"{fn.__qualname__} has no jaxtyping annotation to check")
    # A copy of fn that carries only the shape annotations (beartype reads __annotations__).
    copy = types.FunctionType(fn.__code__, fn.__globals__, fn.__name__, fn.__defaults__,
                              fn.__closure__)
    copy.__kwdefaults__ = fn.__kwdefaults__
    copy.__qualname__ = fn.__qualname__
    copy.__module__ = fn.__module__
    copy.__annotations__ = checked
    typecheck = beartype(conf=BeartypeConf(is_pep484_tower=True))
    checking = jaxtyping.jaxtyped(typechecker=typecheck)(copy)

    @functools.wraps(fn)
    def wrapper(*args, **kwargs):
        try:
            return checking(*args, **kwargs)
        except jaxtyping.TypeCheckError as error:
            if "parameters" in str(error).split("\n", 1)[0]:
                fn(*args, **kwargs)  # fn's own host checks speak first when they refuse
            raise error from None

    wrapper.__shape_checked__ = True
    return wrapper


def finite_scalar(name: str, value, lo: float | None = None, hi: float | None = None,
                  lo_open: bool = False, *, parameter: str | None = None) -> float:
    """Host check of one scalar parameter: finite and inside [lo, hi] (or (lo, hi]); a
    :class:`~lfjax.base.errors.ParameterError` names ``name`` and the allowed range.

    ``parameter``: the parameter the value belongs to when ``name`` is a part of it
    (``finite_scalar("low end", low, 0.0, parameter="depth_range_D")``); the message then
    reads ``"depth_range_D: low end must be …"``. Default: ``name`` itself."""
    if parameter is None or parameter == name:
        parameter, subject = name, "{" + name + "}"
    else:
        subject = "{" + parameter + "}: " + name.replace("{", "{{").replace("}", "}}")
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise ParameterError(parameter, subject + " must be a number, got {value!r}",
                             value=value) from None
    bad_lo = lo is not None and (x <= lo if lo_open else x < lo)
    bad_hi = hi is not None and x > hi
    if not math.isfinite(x) or bad_lo or bad_hi:
        left = "(" if lo_open else "["
        rng = f"{left}{'-inf' if lo is None else f'{lo:g}'}, {'inf' if hi is None else f'{hi:g}'}]"
        raise ParameterError(parameter, subject + f" must be finite and in {rng}, got {{value!r}}",
                             value=value)
    return x
