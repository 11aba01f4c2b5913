"""lfjax.sweep.config_keys: the checks a key declares, strip entries and the TOML values
(no JAX: plain values)."""

from pathlib import Path

import pytest

from lfjax.sweep.config_keys import (
    MAX_STRIP_VIEWS,
    Distinct,
    Key,
    OneOf,
    Range,
    SweepConfigError,
    check_layout_entries,
    check_wavelength_grid,
    strip_views,
    toml_value,
)

KEY = Key("display", "a key", name="cdp_D", unit="D")


def test_a_range_says_its_rule_and_refuses_outside_it():
    rule = Range(0, 10, lo_open=True)
    assert rule(KEY, 5.0, Path(".")) == []
    (problem,) = rule(KEY, 0.0, Path("."))
    assert problem.startswith("display.cdp_D must be") and "got 0.0" in problem


def test_one_of_and_distinct_name_the_key():
    assert OneOf(("a", "b"))(KEY, "a", Path(".")) == []
    assert "display.cdp_D" in OneOf(("a", "b"))(KEY, "c", Path("."))[0]
    assert "repeated" in Distinct()(KEY, (1.0, 1.0), Path("."))[0]


def test_strip_entries_and_layout_entries():
    assert strip_views("1x3") == 3 and strip_views("1x03") is None and strip_views("2x2") is None
    assert check_layout_entries(KEY, ("natural", "2x2", "1x3"), Path(".")) == []
    (problem,) = check_layout_entries(KEY, (f"1x{MAX_STRIP_VIEWS + 1}",), Path("."))
    assert f"1 to {MAX_STRIP_VIEWS} strips" in problem
    assert "does not exist" in check_layout_entries(KEY, ("missing.json",), Path("."))[0]


def test_the_wavelength_grid_needs_an_increasing_range_and_a_step_the_data_resolve():
    assert check_wavelength_grid(KEY, (400.0, 700.0), Path(".")) == []
    assert check_wavelength_grid(KEY, (400.0, 700.0, 10.0), Path(".")) == []
    assert "step > 0" in check_wavelength_grid(KEY, (700.0, 400.0, 10.0), Path("."))[0]
    assert ">= 1 nm" in check_wavelength_grid(KEY, (400.0, 700.0, 0.5), Path("."))[0]


def test_toml_values_and_the_error_listing_every_problem():
    assert toml_value([1.0, "a", True]) == '[1.0, "a", true]'
    err = SweepConfigError(["one", "two"], "pop.toml")
    assert err.problems == ["one", "two"] and str(err).startswith("pop.toml: 2 problem(s)")
    with pytest.raises(ValueError):
        raise err
