"""Shared conversions and checks (lfjax.base.types): strongly typed real arrays (one compile
for floats and arrays alike), index arrays, concreteness, the scalar check's messages, and
shape_checked refusing a function with nothing to check.

The shape checks at every public entry point are tested in tests/test_shapes.py."""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from lfjax.base.errors import ParameterError
from lfjax.base.types import (
    SHAPE_CHECKS,
    as_index_array,
    as_real_array,
    finite_scalar,
    is_concrete,
    shape_checked,
)


def test_real_arrays_are_strongly_typed_floats():
    for x in (1.5, 2, [1, 2], np.float32(1.0)):
        a = as_real_array(x)
        assert jnp.issubdtype(a.dtype, jnp.floating) and not a.weak_type, x
    assert as_real_array(2).dtype == jnp.result_type(float)
    assert as_real_array(np.float32(1.0)).dtype == jnp.float32  # its own float dtype kept


def test_a_float_and_an_array_compile_once():
    traces = []

    @jax.jit
    def f(x):
        traces.append(1)
        return 2 * x

    f(as_real_array(1.5))
    f(as_real_array(jnp.asarray(2.5)))
    assert len(traces) == 1


def test_traced_values_pass_through_as_floats():
    def f(x):
        y = as_real_array(x)
        assert isinstance(y, jax.core.Tracer) and not is_concrete(y)
        return y

    jax.jit(f)(1.0)
    assert is_concrete(1.0, np.ones(2), {"a": jnp.ones(3)})


def test_index_arrays_are_int32():
    assert as_index_array([0, 1.0]).dtype == jnp.int32


@pytest.mark.parametrize("value, kwargs, words", [
    (math.inf, {}, r"^x must be finite and in \[-inf, inf\], got inf$"),
    (-0.5, {"lo": 0.0}, r"^x must be finite and in \[0, inf\], got -0.5$"),
    (0.0, {"lo": 0.0, "lo_open": True, "hi": 1.0}, r"^x must be finite and in \(0, 1\], got 0.0$"),
    ("a", {}, r"^x must be a number, got 'a'$"),
    (-1.0, {"lo": 0.0, "parameter": "depth_range_D"},
     r"^depth_range_D: x must be finite and in \[0, inf\], got -1.0$"),
])
def test_finite_scalar_names_the_parameter_and_the_range(value, kwargs, words):
    with pytest.raises(ParameterError, match=words) as info:
        finite_scalar("x", value, **kwargs)
    assert info.value.parameter == kwargs.get("parameter", "x")


def test_finite_scalar_returns_a_float_inside_the_range():
    assert finite_scalar("x", np.float32(0.5), 0.0, 1.0) == 0.5
    assert finite_scalar("x", 1, 0.0, 1.0) == 1.0


@pytest.mark.skipif(not SHAPE_CHECKS, reason="the checks are on only in the test suite")
def test_shape_checked_refuses_a_function_without_shape_annotations():
    def plain(x: float) -> float:
        return x

    with pytest.raises(TypeError, match="has no jaxtyping annotation to check"):
        shape_checked(plain)
