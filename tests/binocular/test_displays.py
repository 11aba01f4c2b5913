"""What each eye receives (lfjax.binocular.displays): runs per display and refusals."""

import numpy as np
import pytest

import lfjax
from lfjax.base.errors import ParameterError
from lfjax.binocular.displays import NaturalViewing, NearEyeDisplay, StereoDisplay, check_display
from lfjax.binocular.viewer import Viewer


def test_each_display_says_what_each_eye_computes():
    viewing = lfjax.Viewing(3.0, 1.5)
    natural = NaturalViewing().runs([0.5, 2.0], viewing)
    assert [(r[0], r[1].tolist(), float(r[2].cdp_D)) for r in natural] == [
        (None, [0.5], 0.5), (None, [2.0], 2.0)]
    (layout, depths, v, rows), = StereoDisplay(2.5).runs([0.5, 2.0], viewing)
    assert layout is None and depths.tolist() == [2.5] and float(v.cdp_D) == 2.5
    assert rows is None
    views = lfjax.grid_layout(2)
    (layout, depths, v, rows), = NearEyeDisplay(views).runs([0.5, 2.0], viewing)
    assert layout is views and depths.tolist() == [0.5, 2.0] and v is viewing


def test_bad_displays_are_refused():
    with pytest.raises(ParameterError, match="screen_D"):
        StereoDisplay(-1.0)
    with pytest.raises(ParameterError, match=r"NearEyeDisplay\.views must be lfjax\.Layout"):
        NearEyeDisplay(None)
    with pytest.raises(ParameterError, match=r"NearEyeDisplay\.eye_box_mm must lie in"):
        NearEyeDisplay(lfjax.grid_layout(2), eye_box_mm=-2.0)
    with pytest.raises(ParameterError, match="display must be"):
        check_display(lfjax.grid_layout(2))


def test_an_eye_box_that_cannot_hold_both_eyes_is_refused():
    display = NearEyeDisplay(lfjax.grid_layout(2), lens_separation_mm=63.0, eye_box_mm=8.0)
    eyes = lfjax.sample_eyes(0, 2)
    display.check_fits(Viewer.identical(eyes, [60.0, 66.0]), 3.0)  # 3 mm off: fits
    with pytest.raises(ParameterError, match=r"NearEyeDisplay\.eye_box_mm = 8 mm cannot hold "
                                             r"both eyes.*within ±5 mm of 63 mm.*\[70\.0\]"):
        display.check_fits(Viewer.identical(eyes, [63.0, 70.0]), 3.0)
    np.testing.assert_array_equal(NaturalViewing().check_fits(None, 3.0), None)


def test_a_panel_puts_each_eye_on_its_own_views():
    from lfjax.binocular.displays import PanelDisplay

    panel = lfjax.display.panel.phone_panel()
    display = PanelDisplay(panel)
    pitch = float(panel.view_pitch_mm)
    offsets = display.eye_offsets_mm([63.0, 64.0])
    # the eyes at ∓IPD/2 see the grid shifted by ±IPD/2, wrapped into half a pitch: mirrors
    np.testing.assert_allclose(offsets[0], -offsets[1], atol=1e-12)
    assert np.all(np.abs(offsets) <= pitch / 2)
    turns = (offsets[1] + np.array([31.5, 32.0])) / pitch
    np.testing.assert_allclose(turns, np.round(turns), atol=1e-9)
    runs = display.runs([1.0, 2.0], lfjax.Viewing(), [63.0, 64.0])
    assert [r[3] for r in runs] == [[0], [1], [2], [3]]
    np.testing.assert_allclose(np.asarray(runs[2][0].centres_mm)[:, 0]
                               - np.asarray(panel.layout().centres_mm)[:, 0], offsets[1, 0])
    assert float(runs[0][2].cdp_D) == pytest.approx(2.0)


def test_a_panel_whose_viewing_zone_cannot_hold_both_eyes_is_refused():
    from lfjax.binocular.displays import PanelDisplay

    panel = lfjax.display.panel.phone_panel()  # a 54 mm viewing zone at 350 mm
    assert float(panel.eye_box_mm()) == pytest.approx(54.0, abs=0.01)
    eyes = lfjax.sample_eyes(0, 2)
    with pytest.raises(ParameterError, match=r"viewing zone \(Panel\.eye_box_mm\) is 54 mm wide "
                                             r"and cannot hold both eyes.*\[63\.0, 60\.0\]"):
        PanelDisplay(panel).check_fits(Viewer.identical(eyes, [63.0, 60.0]), 3.0)
    wide = lfjax.display.panel.phone_panel(distance_mm=700.0, cdp_D=1.0)
    PanelDisplay(wide).check_fits(Viewer.identical(eyes, [63.0, 60.0]), 3.0)
