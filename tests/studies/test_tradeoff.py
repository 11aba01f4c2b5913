"""lfjax.studies.tradeoff: a panel's views per pupil against perceivable resolution and
accommodation error, through the population sweep."""

from __future__ import annotations

import math

import numpy as np
import pytest

from lfjax.studies import tradeoff as to
from lfjax.model.layout_files import load_layout_json
from lfjax.display.panel import near_eye_microdisplay, phone_panel, sampling_limit_cpd

ARCMIN = 180.0 * 60.0 / math.pi


def test_panel_for_views_by_hand():
    """Near-eye preset (z_m = 30 mm, CDP 1.5 D): M = 1/(1 − 30·1.5/1000) = 1/0.955, so 2×2
    tangent views need Δu = 3/(2·M) = 1.4325 mm; the eye box E of the preset,
    1·(1 + 30/z_0), is kept by z_0 = 30·Δu/(E − Δu); the pixel then subtends
    p/(z_0·M). Every count keeps the CDP and the eye box and puts exactly n views across."""
    template = near_eye_microdisplay()
    box = float(template.eye_box_mm())
    assert box == pytest.approx(1.0 * (1.0 + 30.0 / float(template.gap_mm)), rel=1e-6)
    p2 = to.panel_for_views(template, 2)
    pitch = 3.0 * 0.955 / 2.0
    gap = 30.0 * pitch / (box - pitch)
    assert float(p2.lenslet_pitch_mm) == pytest.approx(pitch, rel=1e-5)
    assert float(p2.gap_mm) == pytest.approx(gap, rel=1e-5)
    assert float(p2.pixel_arcmin()) == pytest.approx(
        float(template.pixel_pitch_mm) * 0.955 / gap * ARCMIN, rel=1e-5)
    angles = []
    for n in range(1, 7):
        p = to.panel_for_views(template, n)
        assert p.n_views_per_side() == n
        assert float(p.views_across) == pytest.approx(n, rel=1e-5)
        assert float(p.cdp_D) == pytest.approx(1.5, abs=1e-4)
        assert float(p.eye_box_mm()) == pytest.approx(box, rel=1e-5)
        assert float(p.fill) == 1.0 and float(p.pixel_pitch_mm) == float(template.pixel_pitch_mm)
        angles.append(float(p.pixel_arcmin()))
    # at a fixed eye box the gap shrinks with the lenslets: the pixel angle grows with n
    assert np.all(np.diff(angles) > 0)


def test_panel_for_views_refusals_name_the_limit():
    # the phone's 55.2 µm pixels at M = 10/3: 3/(n·M) >= p up to n = 16
    with pytest.raises(ValueError, match=r"n_per_side must be in \[1, 16\]"):
        to.panel_for_views(phone_panel(), 17)
    with pytest.raises(ValueError, match="n_per_side must be an integer >= 1"):
        to.panel_for_views(phone_panel(), 0)
    with pytest.raises(ValueError, match="eye_box_mm must exceed the lenslet pitch"):
        to.panel_for_views(near_eye_microdisplay(), 1, eye_box_mm=2.0)


def test_views_wholly_outside_the_pupil_are_left_out():
    """Tangent 0.5 mm views on a 6×6 grid: the corners' centres lie 2.5·0.5·√2 = 1.77 mm
    out, their discs start 1.52 mm out, beyond the 1.5 mm pupil radius; 5×5's corners
    (1.2·√2 − 0.3 = 1.40 mm) still reach it."""
    template = near_eye_microdisplay()
    six = to.views_in_pupil(to.panel_for_views(template, 6), 6)
    assert six.n_subapertures == 32
    c = np.asarray(six.centres_mm)
    assert np.max(np.linalg.norm(c, axis=1)) < 2.5 * 0.5 * math.sqrt(2) - 1e-3
    assert to.views_in_pupil(to.panel_for_views(template, 5), 5).n_subapertures == 25


def test_sweep_config_carries_the_panels_optics(tmp_path):
    (part,) = to.plan_tradeoff(phone_panel(), tmp_path, to.TradeoffConfig(counts=(3,), n_eyes=3))
    panel, config = part.panel, part.sweep
    layout, record = load_layout_json(config.layouts[0])
    assert layout.n_subapertures == 9 and record["panel"]["gap_mm"] == pytest.approx(float(panel.gap_mm))
    assert not part.store.exists()  # planning computes nothing
    optics, mine = config.display_optics(), panel.optics()
    assert float(optics.fresnel_distance_mm) == pytest.approx(float(mine.fresnel_distance_mm), rel=1e-4)
    assert float(optics.pixel_width_arcmin) == pytest.approx(float(mine.pixel_width_arcmin), rel=1e-6)
    assert optics.diffraction == mine.diffraction and config.cdp_D == pytest.approx(2.0, abs=1e-4)
    assert not config.average_eye and config.n_eyes == 3
    # the grid reaches the highest depth's window: 2 + 1 + 1.5 D
    assert config.accommodation_max_D == pytest.approx(4.5)


@pytest.mark.parametrize("changes, message", [
    (dict(counts=(0, 2)), "counts must be integers"),
    (dict(depth_offsets_D=(-1.0, 1.0)), "must include 0"),
    (dict(n_eyes=0), "n_eyes must be >= 1"),
    (dict(accommodation_tolerance_D=0.0), "accommodation_tolerance_D"),
])
def test_config_refuses(changes, message):
    with pytest.raises(ValueError, match=message):
        to.TradeoffConfig(**changes)


def _row(n, cpd, rmse, depth=None, success=1.0):
    return {"n_per_side": n, "views": f"{n}x{n}", "depth_D": depth, "perceivable_cpd_median": cpd,
            "display_error_rmse_D": rmse, "peak_success_fraction": success}


def test_optimum_is_the_sharpest_count_within_the_tolerance():
    rows = [_row(1, 9.0, 0.0), _row(2, 5.0, 0.1), _row(3, 6.0, 0.2), _row(4, 7.0, 0.4),
            _row(5, 8.0, 0.1, success=0.4), _row(3, 99.0, 0.0, depth=1.0)]
    best = to.optimum(rows, 0.25)
    assert best["n_per_side"] == 3
    # 4x4 is sharper but beyond the tolerance, 5x5 too but its peaks sit on window edges
    assert to.optimum(rows, 0.5)["n_per_side"] == 4
    assert to.optimum(rows, 0.5, min_peak_success=0.3)["n_per_side"] == 5
    # none qualifies: no optimum; 1x1 never is one
    assert to.optimum([_row(1, 9.0, 0.0), _row(2, 5.0, 0.6), _row(3, 6.0, 0.5)], 0.25) is None


def test_a_tiny_tradeoff_end_to_end(tmp_path):
    """One eye, 2×2 on the near-eye panel, two depths, through run_sweep: the perceivable
    resolution is the optical cut-off capped at the panel's sampling limit, the display's
    share of the error is zero on the CDP, and a second call reuses the finished store."""
    config = to.TradeoffConfig(counts=(2,), n_eyes=1, depth_offsets_D=(-0.5, 0.0), window_D=0.5,
                               accommodation_step_D=0.25, wavelengths_nm=(550.0, 550.0, 10.0),
                               chunk_size=1)
    template = near_eye_microdisplay()
    (part,) = to.run_tradeoff(template, tmp_path, config)
    assert part.store.exists() and len(part.chunk_seconds) == 1 and "2x2" in part.estimate
    v = to.part_values(part)
    assert v["depths_D"] == pytest.approx([1.0, 1.5], abs=1e-3)
    limit = np.asarray(sampling_limit_cpd(part.panel, v["depths_D"]))
    assert v["sampling_limit_cpd"] == pytest.approx(limit, rel=1e-6)
    assert np.array_equal(v["perceivable_cpd"], np.minimum(v["optical_cutoff_cpd"], limit[None]))
    assert np.all(v["perceivable_cpd"] > 0) and np.all(np.isfinite(v["accommodation_D"]))
    assert v["error_D"] == pytest.approx(v["accommodation_D"] - v["depths_D"][None])
    assert v["display_error_D"][:, 1] == pytest.approx([0.0])
    assert np.all((v["modulation"] > 0) & (v["modulation"] <= 1))
    rows = to.tradeoff_table([part])
    assert [r["depth_D"] for r in rows] == pytest.approx([1.0, 1.5, None])
    pooled = rows[-1]
    assert pooled["n_eyes"] == 1 and pooled["views"] == "2x2"
    assert pooled["perceivable_cpd_median"] <= max(limit) + 1e-9
    text = to.markdown_table(rows, to.optimum(rows))
    assert "**2x2**" in text and "cpd @ 1.5 D" in text
    fig = to.fig_tradeoff({"near-eye": rows})
    assert len(fig.axes) >= 2
    (again,) = to.run_tradeoff(template, tmp_path, config)
    assert again.chunk_seconds == []  # complete: nothing computed
