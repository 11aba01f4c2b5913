"""Binocular options (lfjax.binocular.options): defaults and refusals."""

import pytest

from lfjax.base.errors import ParameterError
from lfjax.binocular.options import BinocularOptions


def test_defaults_switch_the_cross_link_off():
    o = BinocularOptions()
    assert (o.combination, o.ca_c_D_per_prism_D, o.comfort_zone) == ("mean_vsotf", 0.0,
                                                                     "shibata2011")
    assert o.replace(combination="better_eye").combination == "better_eye"
    assert o.as_dict()["dominant_eye"] == "right"


@pytest.mark.parametrize("changes, match", [
    (dict(combination="max"), r"BinocularOptions\.combination must be one of"),
    (dict(dominant_eye="both"), r"BinocularOptions\.dominant_eye"),
    (dict(ca_c_D_per_prism_D=0.5), r"ca_c_D_per_prism_D must lie in \[0, 0\.2\] D per prism"),
    (dict(ca_c_D_per_prism_D=-0.1), r"ca_c_D_per_prism_D"),
    (dict(blur_loop_gain=-1.0), r"blur_loop_gain must lie in \[0, 1000\]"),
    (dict(comfort_zone="banks"), r"comfort_zone"),
])
def test_bad_choices_are_refused(changes, match):
    with pytest.raises(ParameterError, match=match):
        BinocularOptions(**changes)
