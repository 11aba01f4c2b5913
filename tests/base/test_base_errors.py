"""ParameterError (lfjax.base.errors): the message names the library's parameter, renders
with other names for the parameters it names, keeps its values, and pickles whole.

(Named test_base_errors.py: tests/test_errors.py holds the bad-input checks of every entry
point.)"""

from __future__ import annotations

import pickle

from lfjax.base.errors import ParameterError


def test_the_message_names_the_parameter_and_is_a_value_error():
    err = ParameterError("n_depths", "{n_depths} must be >= 2 for a depth range, got {got}", got=1)
    assert isinstance(err, ValueError)
    assert str(err) == "n_depths must be >= 2 for a depth range, got 1"
    assert err.parameter == "n_depths" and err.values == {"got": 1}


def test_naming_renders_other_names_and_keeps_the_rest():
    err = ParameterError("front", "{front} needs held-out eyes ({test_eyes} >= 1), got {n:d}",
                         n=0)
    assert err.parameters == ("front", "test_eyes")
    assert err.naming({"front": "--front"}) == "--front needs held-out eyes (test_eyes >= 1), got 0"
    assert err.naming({"front": "--front", "test_eyes": "--test-eyes"}) == (
        "--front needs held-out eyes (--test-eyes >= 1), got 0")


def test_owner_is_written_before_library_names_only():
    err = ParameterError("fill", "{fill} must be in (0, 1], got {got:g}", owner="Panel", got=1.5)
    assert str(err) == "Panel.fill must be in (0, 1], got 1.5"
    assert err.naming({"fill": "--fill"}) == "--fill must be in (0, 1], got 1.5"


def test_a_parameter_missing_from_the_template_still_comes_first():
    err = ParameterError("x", "{y} must be below {x}")
    assert err.parameters == ("x", "y")


def test_pickles_with_its_keywords():
    err = ParameterError("fill", "{fill} must be in (0, 1], got {got}", owner="Panel", got=2)
    again = pickle.loads(pickle.dumps(err))
    assert type(again) is ParameterError and str(again) == str(err)
    assert (again.parameter, again.owner, again.values) == ("fill", "Panel", {"got": 2})

