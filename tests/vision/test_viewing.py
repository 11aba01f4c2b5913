"""The viewing conditions (lfjax.vision.viewing.Viewing): checked when built, naming the
field and its range; traced pupils and CDPs pass (checked where they are used); a pytree
that jax transforms see through."""

from __future__ import annotations

import math

import jax
import pytest

from lfjax.base.errors import ParameterError
from lfjax.display.lenslets import ideal_display
from lfjax.vision.viewing import MAX_PUPIL_MM, Viewing


def test_defaults_and_fields():
    viewing = Viewing()
    assert (viewing.pupil_diameter_mm, viewing.cdp_D, viewing.display) == (3.0, 2.0, None)
    assert viewing.pupil_offset_mm == (0.0, 0.0)
    assert Viewing(pupil_diameter_mm=MAX_PUPIL_MM, cdp_D=0.0).pupil_diameter_mm == MAX_PUPIL_MM
    assert Viewing(display=ideal_display()).display is not None


@pytest.mark.parametrize("changes, parameter, words", [
    ({"pupil_diameter_mm": 0.0}, "pupil_diameter_mm",
     r"Viewing.pupil_diameter_mm must lie in \(0, 10\] mm"),
    ({"pupil_diameter_mm": 10.5}, "pupil_diameter_mm", r"must lie in \(0, 10\] mm, got 10.5"),
    ({"pupil_diameter_mm": math.nan}, "pupil_diameter_mm", r"must lie in \(0, 10\] mm"),
    ({"pupil_diameter_mm": "wide"}, "pupil_diameter_mm", r"got 'wide'"),
    ({"cdp_D": -1.0}, "cdp_D", r"cdp_D: every CDP must lie in the model's range \[0, 10\] D"),
    ({"cdp_D": 11.0}, "cdp_D", r"range \[0, 10\] D"),
    ({"pupil_offset_mm": (31.0, 0.0)}, "pupil_offset_mm",
     r"Viewing.pupil_offset_mm must be \(x, y\) in mm, each in \[-30, 30\] mm, got \(31.0, 0.0\)"),
    ({"pupil_offset_mm": (0.0, math.nan)}, "pupil_offset_mm", r"each in \[-30, 30\] mm"),
    ({"pupil_offset_mm": 1.0}, "pupil_offset_mm", r"must be \(x, y\) in mm"),
    ({"pupil_offset_mm": ("left", 0.0)}, "pupil_offset_mm", r"got \('left', 0.0\)"),
    ({"display": "phone"}, "display", r"Viewing.display must be lfjax.display.lenslets."
                                      r"DisplayOptics or None .*got str"),
])
def test_bad_values_are_refused_when_built_naming_the_field(changes, parameter, words):
    with pytest.raises(ParameterError, match=words) as info:
        Viewing(**changes)
    assert info.value.parameter == parameter


def test_a_traced_pupil_and_cdp_build_a_viewing():
    def pupil_times_cdp(pupil, cdp):
        viewing = Viewing(pupil_diameter_mm=pupil, cdp_D=cdp)
        return viewing.pupil_diameter_mm * viewing.cdp_D

    grad = jax.grad(pupil_times_cdp, argnums=(0, 1))(4.0, 1.5)
    assert tuple(map(float, grad)) == (1.5, 4.0)


def test_a_traced_pupil_offset_builds_a_viewing():
    grad = jax.grad(lambda x: Viewing(pupil_offset_mm=(x, 0.0)).pupil_offset_mm[0] * 3.0)(1.0)
    assert float(grad) == 3.0


def test_a_viewing_is_a_pytree_of_its_numbers():
    leaves = jax.tree_util.tree_leaves(Viewing(pupil_diameter_mm=4.0, cdp_D=1.5,
                                               pupil_offset_mm=(0.5, -1.0)))
    assert leaves == [4.0, 1.5, 0.5, -1.0]
