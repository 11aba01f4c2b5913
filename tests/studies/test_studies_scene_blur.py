"""The scene-blur study's configuration and tables (lfjax.studies.scene_blur): display names
refused, each name read as its layout, optics and CDP, and the cue agreement and markdown
table on a synthetic result with known numbers (no optics is computed).

(Named test_studies_scene_blur.py: tests/vision/test_scene_blur.py holds the tests of
lfjax.vision.scene_blur.)"""

from __future__ import annotations

import numpy as np
import pytest

from lfjax.studies.scene_blur import DISPLAYS, SceneBlurConfig, cue_agreement, scene_blur_table


def test_an_unknown_display_is_refused_with_the_names_allowed():
    with pytest.raises(ValueError, match=r"displays must be among .*got \['3x4'\]"):
        SceneBlurConfig(displays=("natural", "3x4"))


def test_each_display_name_reads_as_its_layout_optics_and_cdp():
    config = SceneBlurConfig(cdp_D=1.5, pupil_diameter_mm=4.0)
    assert config.display("natural") == (None, None, 1.5, "natural")
    layout, optics, cdp, label = config.display("3x3")
    assert optics is None and (cdp, label) == (1.5, "3x3")
    assert layout.centres_mm.shape == (9, 2)
    assert float(layout.diameters_mm.max()) == pytest.approx(4.0 / 3.0)
    for name in set(DISPLAYS) - {"natural", "2x2", "3x3", "4x4"}:
        layout, optics, cdp, label = config.display(name)
        assert optics is not None and label.startswith(f"{name} (") and 0 <= cdp <= 10


def _result():
    # 2 displays × 3 eyes × 2 depths; eye 2 of display 1 has the cue's sign flipped
    shape = (2, 3, 2)
    cue = np.ones(shape)
    flipped = cue.copy()
    flipped[1, 2, :] = -1.0
    numbers = {k: np.full(shape, v) for k, v in (
        ("true_defocus_D", 0.5), ("equivalent_defocus_D", 0.25), ("mtf_ratio", 0.8),
        ("mtf_rms", 0.01))}
    return {"labels": ["natural", "2x2"], "depths_D": [0.0, 3.0], "cue_natural": cue,
            "cue_display": flipped, **numbers}


def test_cue_agreement_is_the_fraction_of_eyes_keeping_the_sign():
    np.testing.assert_allclose(cue_agreement(_result()), [[1.0, 1.0], [2 / 3, 2 / 3]])


def test_the_table_has_a_row_per_display_and_depth():
    rows = scene_blur_table(_result()).splitlines()
    assert len(rows) == 2 + 2 * 2
    assert rows[2].startswith("| natural | 0 | +0.50 [+0.50, +0.50] | +0.25 [+0.25, +0.25] | 0.80")
    assert rows[-1].startswith("| 2x2 | 3 |") and rows[-1].endswith("| 67% |")
