"""Shapes in the types: the public numerical entry points check their jaxtyping annotations
at call time in this suite (conftest.py sets LFJAX_SHAPE_CHECKS=1), naming the dimension
that disagrees."""

import jax.numpy as jnp
import numpy as np
import pytest
from jaxtyping import Array, Float, TypeCheckError

import lfjax
from lfjax.base import types as _types
from lfjax.vision import peaks
from lfjax.vision import psf
from lfjax.vision import focus as through_focus

# through_focus takes no arrays of its own: its depths and states arrive in a States, which
# checks their shapes when it is built (tests/vision/test_prepare.py)
ENTRY_POINTS = (
    through_focus.metrics_at,
    psf.monochromatic_psf,
    psf.polychromatic_otf,
    peaks.accommodation_peaks,
)


def test_the_suite_runs_with_shape_checks_on():
    assert _types.SHAPE_CHECKS
    for fn in ENTRY_POINTS:
        # an entry point compiled by eqx.filter_jit checks shapes inside, when it traces
        checked = fn if hasattr(fn, "__shape_checked__") else getattr(fn, "__wrapped__", fn)
        assert getattr(checked, "__shape_checked__", False), fn.__qualname__
    assert lfjax.monochromatic_psf is psf.monochromatic_psf


def test_mismatched_depth_axis_names_the_dimension():
    """accommodation_D has a row per rendered depth: 3 rows for 2 depths is refused. The
    error users see is the host check's (it names the parameter); the shape check that ran
    first, its context, names the dimension n_depth and its bound value."""
    eyes = lfjax.sample_eyes(0, 1, measured_pupil_mm=3.0)
    layout = lfjax.grid_layout(2, pupil_diameter_mm=3.0)
    with pytest.raises(ValueError, match="accommodation_D must have shape") as info:
        through_focus.metrics_at(eyes, layout, jnp.array([1.0, 3.0]),
                                 jnp.array([[1.0, 1.2], [3.0, 3.2], [2.0, 2.0]]))
    context = info.value.__context__
    assert isinstance(context, TypeCheckError)
    assert "accommodation_D" in str(context) and "n_depth=2" in str(context)


def test_batched_coefficients_name_the_mode_axis():
    with pytest.raises(ValueError, match="coefficients_um must have shape") as info:
        lfjax.monochromatic_psf(np.zeros((2, 15)), 3.0, 3.0, 550.0, 0.5, 16)
    assert isinstance(info.value.__context__, TypeCheckError)
    assert "n_modes" in str(info.value.__context__)


def test_a_shape_only_the_annotation_refuses_raises_the_shape_error():
    """Where no host check would refuse the input, the shape check's own error is raised."""
    @_types.shape_checked
    def scale(x: Float[Array, " n"], y: Float[Array, " n"]):
        return x * y[:1]

    assert scale(jnp.ones(3), jnp.ones(3)).shape == (3,)
    with pytest.raises(TypeCheckError, match="n=3"):
        scale(jnp.ones(3), jnp.ones(4))
