"""PeakOptions (lfjax.vision.peak_options): checked when built, naming the field and its
range; hashable and equal by value (it is a static argument of compiled programs, so equal
options must share one program); the method each metric resolves to."""

from __future__ import annotations

import math

import numpy as np
import pytest

from lfjax.base.errors import ParameterError
from lfjax.vision.peak_options import (
    DEFAULT_TOLERANCE_D,
    METRICS,
    PEAK_METHODS,
    PeakOptions,
    check_method,
    resolved_method,
)


def test_defaults_are_grid_peaks_with_the_documented_tolerance():
    p = PeakOptions()
    assert p.metrics == () and p.method == "auto" and p.second_peaks is True
    assert p.tolerance_D == DEFAULT_TOLERANCE_D == 0.01
    assert (p.prominence, p.atol_D, p.max_steps) == (0.05, 1e-5, 32)


def test_equal_options_are_one_static_argument():
    a = PeakOptions(metrics=["vsotf"], method="local", tolerance_D=np.float32(0.02),
                    max_steps=np.int64(8))
    b = PeakOptions(metrics=("vsotf",), method="local", tolerance_D=0.019999999552965164,
                    max_steps=8)
    assert a.metrics == ("vsotf",) and type(a.max_steps) is int
    assert a == b and hash(a) == hash(b) and repr(a) == repr(b)
    assert {a: 1}[b] == 1
    assert PeakOptions(method="grid") != PeakOptions(method="vertex")
    assert a.replace(method="vertex").method == "vertex"


@pytest.mark.parametrize("field, value, message", [
    ("metrics", "vsotf", r"PeakOptions.metrics must be a tuple"),
    ("metrics", ("mtf",), r"PeakOptions.metrics must name metrics in \('vsotf', 'strehl'\)"),
    ("method", "newtonian", r"PeakOptions.method must be one of"),
    ("tolerance_D", 0.0, r"PeakOptions.tolerance_D must lie in \(0, 1\) D"),
    ("tolerance_D", math.nan, r"PeakOptions.tolerance_D"),
    ("tolerance_D", "0.01", r"PeakOptions.tolerance_D"),
    ("second_peaks", 1, r"PeakOptions.second_peaks must be True or False"),
    ("prominence", 1.0, r"PeakOptions.prominence must lie in \[0, 1\)"),
    ("atol_D", -1e-6, r"PeakOptions.atol_D must lie in \(0, 1\) D"),
    ("max_steps", 0, r"PeakOptions.max_steps must be an integer >= 1"),
    ("max_steps", 2.5, r"PeakOptions.max_steps"),
])
def test_bad_fields_are_refused_naming_the_field(field, value, message):
    with pytest.raises(ParameterError, match=message) as caught:
        PeakOptions(**{field: value})
    assert caught.value.parameter == field


def test_the_methods_each_metric_runs():
    assert set(METRICS) == {"vsotf", "strehl"}
    assert resolved_method("vsotf", "auto") == "newton"
    assert resolved_method("strehl", "auto") == "golden"
    assert resolved_method("strehl", "adaptive") == "golden"
    assert resolved_method("vsotf", "adaptive") == "adaptive"
    assert all(resolved_method("vsotf", m) == m for m in PEAK_METHODS if m not in ("auto",))
    with pytest.raises(ValueError, match="method must be one of"):
        check_method("nope")
