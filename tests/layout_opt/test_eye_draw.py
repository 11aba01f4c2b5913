"""Tests of lfjax/layout_opt/_eye_draw.py: the eyes of a fit and of its report, drawn once."""

from __future__ import annotations

import numpy as np
import pytest

import lfjax
from lfjax import layout_opt as lo
from lfjax.base.errors import ParameterError


def test_training_eyes_from_the_seed_and_held_out_eyes_from_the_next():
    draw = lo.EyeDraw(seed=4, train_eyes=2, test_eyes=3)
    np.testing.assert_array_equal(draw.train().zernike_um, lfjax.sample_eyes(4, 2).zernike_um)
    np.testing.assert_array_equal(draw.test().zernike_um, lfjax.sample_eyes(5, 3).zernike_um)
    np.testing.assert_array_equal(draw.report().zernike_um, draw.test().zernike_um)
    assert draw.provenance() == {"seed_train": 4, "n_train_eyes": 2, "seed_test": 5,
                                 "n_test_eyes": 3}
    assert tuple(draw.provenance()) == lo.EYE_DRAW_KEYS
    both = lo.planning_eyes(draw.train(), draw.test())
    assert both.n_eyes == 5


def test_without_held_out_eyes_the_report_is_on_the_training_eyes():
    draw = lo.EyeDraw(seed=0, train_eyes=2, test_eyes=0)
    assert draw.test() is None and not draw.held_out
    np.testing.assert_array_equal(draw.report().zernike_um, draw.train().zernike_um)
    assert draw.provenance()["seed_test"] is None
    assert lo.planning_eyes(draw.train(), None).n_eyes == 2


@pytest.mark.parametrize("field, value", [("seed", -1), ("seed", 2**32), ("train_eyes", 0),
                                          ("test_eyes", -1), ("train_eyes", 1.5),
                                          ("seed", True)])
def test_a_bad_draw_names_its_field(field, value):
    with pytest.raises(ParameterError) as err:
        lo.EyeDraw(**{field: value})
    assert err.value.parameter == field
