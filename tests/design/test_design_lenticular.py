"""lfjax.design.lenticular and ``lfjax design --lenticular``: 1xN lenticular (HPO) designs."""

from __future__ import annotations

import json
import math

import jax.numpy as jnp
import numpy as np
import pytest

from lfjax import cli
from lfjax.design import lenticular as dl
from lfjax.design.fit import DesignConstraints, design_panel
from lfjax.display.lenslets import DisplayOptics, pixel_transfer
from lfjax.display.lenticular import LenticularPanel
from lfjax.model.eyes import sample_eyes


@pytest.mark.parametrize("preset, cdp", [("phone", 2.0), ("near-eye", 1.5)])
def test_the_design_rule_tiles_the_pupil_keeps_the_cdp_and_takes_the_longest_gap(preset, cdp):
    """n strips D/n wide fill the pupil, the CDP (along x) is the one asked, the gap is at
    the bound the eye box or the f-number sets, and the y defocus is CDP − 1000/(z_m + z_0)."""
    template = design_panel(preset, cdp)
    c = DesignConstraints(min_eye_box_mm=10.0, max_f_number=8.0)
    for n in (2, 3, 4):
        lens = dl.lenticular_panel(template, n, cdp, c)
        assert float(lens.view_pitch_mm) == pytest.approx(3.0 / n, rel=1e-5)
        assert float(lens.view_width_mm) == pytest.approx(3.0 / n, rel=1e-5)
        assert float(lens.cdp_D) == pytest.approx(cdp, abs=1e-5)
        assert lens.layout(3.0).n_subapertures == n
        f_number = float(lens.focal_length_mm) / float(lens.lens_pitch_mm)
        eye_box = float(lens.eye_box_mm())
        assert f_number <= 8.0 * (1 + 1e-5) and eye_box >= 10.0 * (1 - 1e-5)
        assert f_number == pytest.approx(8.0, rel=1e-5) or eye_box == pytest.approx(10.0, rel=1e-5)
        zm, z0 = float(lens.distance_mm), float(lens.gap_mm)
        assert float(lens.y_defocus_D) == pytest.approx(cdp - 1000.0 / (zm + z0), abs=1e-4)
        # a longer gap at the same pitch and CDP would shrink the eye box or slow the lens
        # past its bound; it would only shrink the pixel's angle and |Δ|
        longer = LenticularPanel.with_cdp(cdp, pixel_pitch_mm=float(lens.pixel_pitch_mm),
                                          lens_pitch_mm=float(lens.lens_pitch_mm),
                                          focal_length_mm=1.01 * float(lens.focal_length_mm),
                                          distance_mm=zm)
        assert float(longer.pixel_arcmin()) < float(lens.pixel_arcmin())
        assert abs(float(longer.y_defocus_D)) < abs(float(lens.y_defocus_D))
        assert (float(longer.focal_length_mm) / float(longer.lens_pitch_mm) > 8.0
                or float(longer.eye_box_mm()) < 10.0)


def test_a_lenticular_pixel_is_its_image_along_x_and_itself_along_y():
    """The lenticule magnifies the pixel along x only: its emitter transfer is
    sinc(a_x f_x)·sinc(a_y f_y) with a_x = p/(z_0 M) and a_y = p/(z_m + z_0); a square
    pixel (DisplayOptics) keeps one width on both axes."""
    lens = dl.lenticular_panel(design_panel("phone", 2.0), 3, 2.0, DesignConstraints())
    optics = lens.optics(lens.layout(3.0))
    p, zm, z0 = (float(v) for v in (lens.pixel_pitch_mm, lens.distance_mm, lens.gap_mm))
    a_x = p / (z0 * float(lens.magnification))
    a_y = p / (zm + z0)
    assert float(optics.pixel_width_rad) == pytest.approx(a_x, rel=1e-5)
    assert float(optics.pixel_height_rad) == pytest.approx(a_y, rel=1e-5)
    f = jnp.asarray([0.0, 100.0, 3000.0])  # cycles/rad
    t = np.asarray(pixel_transfer(f, f, optics))
    assert np.allclose(t, np.sinc(a_y * np.asarray(f))[:, None] * np.sinc(a_x * np.asarray(f))[None, :],
                       rtol=1e-5, atol=1e-7)
    square = DisplayOptics(pixel_width_arcmin=5.0)
    assert float(square.pixel_height_rad) == float(square.pixel_width_rad) > 0


TINY = ["design", "--lenticular", "--depths", "1.5", "2.5", "--n-depths", "2", "--views", "1", "2",
        "--test-eyes", "1", "--report-accuracy", "fit", "--freq-step", "0.7", "--diffraction", "off"]


def test_cli_lenticular_design_tiny_case(capsys, tmp_path, monkeypatch):
    """The report says the design is HPO, names the strips' width and the y defocus, and
    gives the x and y answers; horizontal structure (the y band) focuses near the panel's
    y focus whatever the rendered depth."""
    monkeypatch.setattr(cli.cache, "enable_compilation_cache", lambda folder=None: None)
    out = tmp_path / "hpo"
    code = cli.main([*TINY, "--out", str(out)])
    captured = capsys.readouterr()
    assert code in (0, 1), captured.err[-2000:]
    text = captured.out
    assert text.startswith("plan: lenticular (horizontal parallax only) 1xN, N in [1, 2]")
    assert "design (lenticular, horizontal parallax only): CDP 2 D" in text
    assert "1x1  refused: one strip fills the pupil" in text
    assert "strips 1.5 mm wide" in text and "y defocus -0.8" in text
    assert "x / vertical structure" in text and "y / horizontal structure" in text
    assert "perceivable cpd median x" in text and ", y " in text
    record = json.loads((out / "design.json").read_text())
    assert record["format"] == dl.LENTICULAR_FORMAT and record["parallax"].startswith("horizontal")
    two = record["designs"][1]
    spec, score = two["specification"], two["scores"]
    assert spec["strip_width_mm"]["value"] == pytest.approx(1.5, rel=1e-5)
    assert spec["y_defocus_D"]["unit"].startswith("D")
    panel_D = spec["panel_D"]["value"]
    assert abs(score["gain_y_median"]["value"]) < 0.3
    assert all(abs(v - panel_D) < 0.75 for v in score["peak_y_D_by_depth"]["value"])
    assert score["perceivable_y_cpd_median"]["value"] <= score["sampling_limit_y_cpd"]["value"] + 1e-9
    assert (code == 0) == (record["chosen_views"] == "1x2")
    assert (out / "design.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


@pytest.mark.parametrize("args, message", [
    (["--steps", "3"], "--steps sets the gradient fit of NxN designs; a --lenticular design"),
    (["--distance-range", "300", "400"], "--distance-range is not for a lenticular design"),
    (["--lens-form", "biconvex"], "--lens-form is not for a lenticular design"),
    (["--views", "9"], "--views must be integers in [1, 8] (the n of 1xn lenticular views)"),
])
def test_cli_lenticular_refuses_what_a_lenticular_design_cannot_honour(capsys, tmp_path, args, message):
    code = cli.main(["design", "--lenticular", "--depths", "1", "3", *args, "--out", str(tmp_path / "x")])
    err = capsys.readouterr().err
    assert code == 2 and message in err and len(err.strip().splitlines()) == 1, err
    assert not (tmp_path / "x").exists()


def test_finished_counts_are_kept_and_resumed(tmp_path, monkeypatch):
    """Each finished count is kept in counts_dir by the one runner; the same inputs load it
    (the score functions are replaced by counters: this tests the keeping, not the optics)."""
    calls = []

    def fake_score(lens, eyes, depths, cdp, **kw):
        calls.append(float(lens.lens_pitch_mm))
        return {"relative_accommodation_rmse_D": 0.1, "image_at_peak": 0.5 + len(calls)}

    monkeypatch.setattr(dl, "score_lenticular", fake_score)
    monkeypatch.setattr(dl, "natural_peaks_D", lambda *a, **k: np.zeros(1))
    target = dl.lenticular_target((1.0, 3.0), views=(1, 2, 3))
    kw = dict(counts_dir=tmp_path / "kept")
    said = []
    first = dl.fit_lenticular_design(design_panel("phone", 2.0), target, sample_eyes(0, 1),
                                     progress=said.append, **kw)
    assert len(calls) == 2 and first.best.n_views == 3
    assert said[0].startswith("plan: lenticular") and said[1].startswith("design 1x1: refused: one strip")
    assert sorted(p.name for p in (tmp_path / "kept").iterdir()) == ["lenticular-2.json", "lenticular-3.json"]
    said.clear()
    second = dl.fit_lenticular_design(design_panel("phone", 2.0), target, sample_eyes(0, 1),
                                      progress=said.append, **kw)
    assert len(calls) == 2 and [line.split(":")[0] for line in said[1:]] == [
        "design 1x1", "design 1x2", "design 1x3"]
    assert all("resumed" in line for line in said[2:])
    assert [f.score for f in second.fits] == [f.score for f in first.fits]
    assert math.isclose(float(second.fits[2].panel.gap_mm), float(first.fits[2].panel.gap_mm))
    dl.fit_lenticular_design(design_panel("phone", 2.0), target, sample_eyes(0, 1),
                             tolerance_D=0.2, **kw)  # other inputs
    assert len(calls) == 4
