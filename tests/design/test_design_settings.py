"""Tests of lfjax/design/settings.py: the design's option objects refuse bad values by name."""

from __future__ import annotations

import numpy as np
import pytest

from lfjax.base.errors import ParameterError
from lfjax.design.settings import DesignTarget, FitSettings, ReportSettings


def test_a_target_resolves_its_depths_and_cdp():
    target = DesignTarget((1.0, 2.0), n_depths=3, views_per_side=[2, 3])
    np.testing.assert_allclose(target.depths_D, [1.0, 1.5, 2.0])
    assert target.views_per_side == (2, 3) and target.cdp_D is None


@pytest.mark.parametrize("make, field", [
    (lambda: DesignTarget((1.0, 2.0), cdp_D=3.0), "cdp_D"),
    (lambda: DesignTarget((2.0, 1.0)), "depth_range_D"),
    (lambda: DesignTarget((1.0, 2.0), views_per_side=(9,)), "views_per_side"),
    (lambda: DesignTarget((1.0, 2.0), n_depths=1), "n_depths"),
    (lambda: FitSettings(steps=-1), "steps"),
    (lambda: FitSettings(tol=0.0), "tol"),
    (lambda: FitSettings(eye_chunk=0), "eye_chunk"),
    (lambda: ReportSettings(accuracy="slow"), "report_accuracy"),
    (lambda: ReportSettings(counts="some"), "report_counts"),
])
def test_a_bad_value_names_its_field(make, field):
    with pytest.raises(ParameterError) as err:
        make()
    assert err.value.parameter == field
