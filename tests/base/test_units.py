"""lfjax.base.units: the model's dioptric range, checked in one place."""

from __future__ import annotations

import numpy as np
import pytest

from lfjax.base.errors import ParameterError
from lfjax.base.units import MAX_DIOPTRES_D, check_dioptres


def test_the_models_range_is_infinity_to_ten_centimetres():
    assert MAX_DIOPTRES_D == 10.0
    values = check_dioptres("depths_D", [0.0, 2.5, MAX_DIOPTRES_D])
    np.testing.assert_array_equal(values, [0.0, 2.5, 10.0])
    assert check_dioptres("cdp_D", 1.5).shape == ()


@pytest.mark.parametrize("values, shown", [
    ([2.0, 20.0], "got [20.0]"),
    (50.0, "got [50.0]"),
    ([[1.0, 10.5], [12.0, 3.0]], "got [10.5, 12.0]"),   # any shape: the values outside listed
])
def test_a_depth_beyond_the_range_is_refused_naming_parameter_range_and_values(values, shown):
    with pytest.raises(ParameterError) as err:
        check_dioptres("depths_D", values, "rendered depth")
    text = str(err.value)
    assert err.value.parameter == "depths_D"
    assert text.startswith("depths_D: every rendered depth must lie in the model's range [0, 10] D")
    assert "MAX_DIOPTRES_D" in text and text.endswith(shown)
    # the command line names its flag instead (ParameterError.naming)
    assert err.value.naming({"depths_D": "--depths"}).startswith("--depths: every rendered depth")


@pytest.mark.parametrize("value, message", [
    (-0.5, "0 D is optical infinity"), (np.nan, "must be finite"), (np.inf, "must be finite"),
    ("far", "must be numbers in D"),
])
def test_negative_non_finite_and_non_numeric_values_are_refused(value, message):
    with pytest.raises(ParameterError, match=message):
        check_dioptres("accommodation_D", value, "accommodation state")


def test_the_note_says_where_the_values_came_from():
    with pytest.raises(ParameterError, match=r"got \[11\.0\] \(cdp_D \+ each offset\)$"):
        check_dioptres("depth_offsets_D", [1.0, 11.0], note="cdp_D + each offset")
