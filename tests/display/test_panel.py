"""lfjax.display.panel: the display as built, its derived geometry and the perceivable resolution.

Covers: lfjax.vision.resolution
"""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from lfjax.base.errors import ParameterError
from lfjax.kernel.metrics import cutoff_frequency, diffraction_limited_mtf
from lfjax.display.panel import (
    Panel,
    gap_for_cdp_mm,
    near_eye_microdisplay,
    phone_panel,
    sampling_limit_cpd,
)
from lfjax.vision.resolution import perceivable_cutoff_cpd

ARCMIN = 180.0 * 60.0 / math.pi


def _panel(**changes):
    """The hand-computed case (mm): p = 0.01, Δu = 0.5, fill 0.8, f = 4, z_0 = 400/101,
    z_m = 100, pixel_fill 0.25, 3 mm pupil."""
    base = dict(pixel_pitch_mm=0.01, lenslet_pitch_mm=0.5, fill=0.8, focal_length_mm=4.0,
                gap_mm=400.0 / 101.0, distance_mm=100.0, pixel_fill=0.25, pixel_count=(1000, 500),
                pupil_diameter_mm=3.0)
    base.update(changes)
    return Panel(**base)


def test_derived_geometry_by_hand():
    """Thin lens: 1/v = 1/z_0 − 1/f = 101/400 − 1/4 = 1/400, so the pixels' virtual image
    (the CDP) lies v = 400 mm behind the lenslets, L = z_m + v = 500 mm from the eye: 2 D.

    Similar triangles from a CDP point through a lenslet's aperture to the pupil: the
    aperture a = 0.8·0.5 = 0.4 mm at 400 mm from the point grows to a·L/v = 0.4·1.25 =
    0.5 mm at 500 mm (M = 1.25), and neighbouring lenslets' views are Δu·M = 0.625 mm
    apart; a 3 mm pupil holds 3/0.625 = 4.8 views across, so the central 4×4 grid
    (centres ±0.3125, ±0.9375 mm). Fresnel number (a/2)²/(λ·z_m·v/L) =
    0.04/(550e-6·80) = 0.9091. A pixel's image on the CDP is p·v/z_0 = 0.01·101 =
    1.01 mm wide at 500 mm: 2.02e-3 rad = 6.944 arcmin; the emitter (side p·√0.25) half
    that. The lenslet pitch subtends 0.5/100 = 5e-3 rad (17.19 arcmin), whose Nyquist
    frequency is 1/(2·5e-3) = 100 cycles/rad = 1.745 cpd. The eye box, the chief rays from
    the edges of an elemental image Δu·(z_m + z_0)/z_m wide through the lenslet centre,
    spans Δu·(1 + z_m/z_0) = 0.5·(1 + 25.25) = 13.125 mm at the eye.
    """
    p = _panel()
    assert float(p.cdp_D) == pytest.approx(2.0, rel=1e-5)
    assert float(p.magnification) == pytest.approx(1.25, rel=1e-5)
    assert float(p.view_pitch_mm) == pytest.approx(0.625, rel=1e-5)
    assert float(p.view_diameter_mm) == pytest.approx(0.5, rel=1e-5)
    assert float(p.views_across) == pytest.approx(4.8, rel=1e-5)
    assert p.n_views_per_side() == 4
    assert float(p.fresnel_number(550.0)) == pytest.approx(0.04 / (550e-6 * 80.0), rel=1e-5)
    assert float(p.pixel_arcmin()) == pytest.approx(1.01 / 500.0 * ARCMIN, rel=1e-5)
    assert float(p.emitter_arcmin()) == pytest.approx(0.5 * 1.01 / 500.0 * ARCMIN, rel=1e-5)
    assert float(p.lenslet_arcmin()) == pytest.approx(5e-3 * ARCMIN, rel=1e-6)
    assert float(p.nyquist_cpd()) == pytest.approx(100.0 * math.pi / 180.0, rel=1e-6)
    assert float(p.eye_box_mm()) == pytest.approx(13.125, rel=1e-5)
    # neighbouring views 0.625 mm apart part by 0.625e-3 rad per dioptre: one pixel
    # (2.02e-3 rad) is 3.232 D of rendered depth
    assert float(p.depth_step_D()) == pytest.approx(1.01 / 500.0 / 0.625e-3, rel=1e-5)
    # one emitter (side 0.005 mm) sweeps a footprint by z_m·w/z_0 = 100·0.005·101/400 mm
    assert float(p.emitter_sweep_mm()) == pytest.approx(0.12625, rel=1e-5)
    assert float(p.pixels_per_lenslet()) == pytest.approx(50.0, rel=1e-6)
    assert p.active_size_mm == pytest.approx((10.0, 5.0))
    assert p.lenslet_count() == pytest.approx((20.0, 10.0))
    assert p.field_of_view_deg()[0] == pytest.approx(2 * math.degrees(math.atan(5.0 / 100.0)))
    layout = p.layout()
    c = np.asarray(layout.centres_mm)
    assert sorted(set(np.round(c[:, 0], 5))) == pytest.approx([-0.9375, -0.3125, 0.3125, 0.9375])
    assert np.allclose(np.asarray(layout.diameters_mm), 0.5, rtol=1e-5)
    # the pipeline's display optics: Fresnel distance z_m·M and the emitter's angle
    optics = p.optics()
    assert float(optics.fresnel_distance_mm) == pytest.approx(125.0, rel=1e-5)
    assert float(optics.pixel_width_arcmin) == pytest.approx(float(p.emitter_arcmin()), rel=1e-6)
    summary = p.summary()
    assert summary["views_per_side"] == 4 and summary["f_number"] == pytest.approx(10.0, rel=1e-5)


def test_with_cdp_round_trip_and_collimated():
    p = Panel.with_cdp(cdp_D=1.25, pixel_pitch_mm=0.01, lenslet_pitch_mm=0.5, focal_length_mm=3.0,
                       distance_mm=50.0)
    assert float(p.cdp_D) == pytest.approx(1.25, rel=1e-5)
    q = Panel.with_cdp(cdp_D=0.0, pixel_pitch_mm=0.01, lenslet_pitch_mm=0.5, focal_length_mm=3.0,
                       distance_mm=50.0)
    assert float(q.gap_mm) == pytest.approx(3.0) and float(q.cdp_D) == 0.0
    assert float(q.magnification) == pytest.approx(1.0)
    assert float(gap_for_cdp_mm(2.0, 4.0, 100.0)) == pytest.approx(400.0 / 101.0, rel=1e-6)


@pytest.mark.parametrize("focal_length_mm, shown", [(0.0, "0"), (-3.0, "-3"), (math.nan, "nan")])
def test_with_cdp_refuses_a_focal_length_before_dividing_by_it(focal_length_mm, shown):
    """focal_length_mm=0 raised a bare ZeroDivisionError from the gap's formula (issue #37)."""
    with pytest.raises(ParameterError) as err:
        Panel.with_cdp(cdp_D=1.5, pixel_pitch_mm=0.01, lenslet_pitch_mm=0.5,
                       focal_length_mm=focal_length_mm, distance_mm=50.0)
    assert str(err.value) == ("Panel.focal_length_mm must be in (0, inf] mm (inf: a pinhole or "
                              f"barrier array), got {shown}")
    # a pinhole array (f = inf) is allowed: the gap is then 1/V
    Panel.with_cdp(cdp_D=1.5, pixel_pitch_mm=0.01, lenslet_pitch_mm=0.5, focal_length_mm=math.inf,
                   distance_mm=50.0)


def test_with_cdp_refuses_a_cdp_beyond_the_models_range():
    """20 D (5 cm) lies behind a display at 30 mm, so with_cdp took it; the model stops at
    10 D (lfjax.base.units.MAX_DIOPTRES_D)."""
    with pytest.raises(ParameterError, match=r"^cdp_D: every CDP must lie in the model's range "
                                             r"\[0, 10\] D .*got \[20\.0\]$"):
        Panel.with_cdp(cdp_D=20.0, pixel_pitch_mm=0.01, lenslet_pitch_mm=0.3, focal_length_mm=3.0,
                       distance_mm=30.0)


@pytest.mark.parametrize("changes, words", [
    (dict(gap_mm=4.5), ["gap_mm=4.5", "in front of the display", "(0, 4]"]),
    (dict(lenslet_pitch_mm=0.005), ["lenslet_pitch_mm=0.005", "smaller than a pixel", ">= 0.01"]),
    (dict(lenslet_pitch_mm=4.0), ["no view in the pupil", "lenslet_pitch_mm", "2.4"]),
    (dict(fill=1.5), ["Panel.fill", "(0, 1]"]),
    (dict(pixel_fill=0.0), ["Panel.pixel_fill", "(0, 1]"]),
    (dict(distance_mm=-3.0), ["Panel.distance_mm", "(0, inf)"]),
    (dict(pixel_pitch_mm=float("nan")), ["Panel.pixel_pitch_mm"]),
    (dict(pixel_count=(0, 10)), ["pixel_count", "integers >= 1"]),
    (dict(aperture="hex"), ["aperture", "circle"]),
])
def test_validation_names_parameter_and_range(changes, words):
    with pytest.raises(ValueError) as err:
        _panel(**changes)
    for w in words:
        assert w in str(err.value), str(err.value)


def test_cdp_behind_the_eye_is_named():
    # f = 4, z_0 = 4.1: a real image 1/(1/4 − 1/4.1) = 164 mm in front of the lenslets,
    # beyond the eye at 100 mm
    with pytest.raises(ValueError, match="behind the eye"):
        _panel(gap_mm=4.1)


def test_with_cdp_refuses_cdp_in_front_of_the_display():
    with pytest.raises(ValueError, match=r"cdp_D must be in \[0, 10\) D"):
        Panel.with_cdp(cdp_D=12.0, pixel_pitch_mm=0.01, lenslet_pitch_mm=0.5, focal_length_mm=4.0,
                       distance_mm=100.0)


def test_leaves_are_differentiable():
    """d(views across)/d(pitch) = −D/(M·Δu²) and d(CDP)/d(gap) by finite differences."""
    p = _panel()
    g = jax.grad(lambda du: _panel(lenslet_pitch_mm=du).views_across)(0.5)
    assert float(g) == pytest.approx(-3.0 / (1.25 * 0.25), rel=1e-4)
    f = lambda gap: _panel(gap_mm=gap).cdp_D  # noqa: E731
    h = 1e-3
    fd = (float(f(p.gap_mm + h)) - float(f(p.gap_mm - h))) / (2 * h)
    assert float(jax.grad(f)(p.gap_mm)) == pytest.approx(fd, rel=1e-2)
    # traced values are not validated (no host check inside jit)
    assert float(jax.jit(lambda du: _panel(lenslet_pitch_mm=du).view_pitch_mm)(0.4)) == pytest.approx(0.5)


def test_presets_are_the_two_panel_classes():
    near, phone = near_eye_microdisplay(), phone_panel()
    assert 0.005 <= float(near.pixel_pitch_mm) <= 0.010
    assert 20.0 <= float(near.distance_mm) <= 60.0
    assert 0.050 <= float(phone.pixel_pitch_mm) <= 0.100
    assert 300.0 <= float(phone.distance_mm) <= 500.0
    for panel in (near, phone):
        assert panel.n_views_per_side() >= 2
        assert float(panel.cdp_D) < 1000.0 / float(panel.distance_mm)
    # 0.7-inch diagonal over the 1920×1080 pixels' diagonal: 8.07 µm
    assert float(near.pixel_pitch_mm) == pytest.approx(17.78 / math.hypot(1920, 1080), rel=1e-3)
    assert float(phone.pixel_pitch_mm) == pytest.approx(25.4 / 460.0, rel=1e-6)


# ----------------------------------------------------------------------------- resolution


def test_sampling_limit_by_hand_and_against_the_ray_form():
    """On the lenslet plane (10 D) the limit is the lenslets' Nyquist frequency, 100
    cycles/rad; on the CDP (2 D) the pixels': 1/(2·2.02e-3 rad) = 247.5 cycles/rad.
    Elsewhere, in lengths: a pattern of ξ cycles/mm on the plane at z mm reaches the
    lenslet plane (z_m) and the CDP (L) along a ray as x·(1 − t) + y·t, t = (z − z_m)/(L −
    z_m); Nyquist in x (Δu) and in y (the pixel image p·v/z_0 on the CDP) bound ξ, and
    β = ξ·z cycles/rad from the eye."""
    p = _panel()
    per_rad = math.pi / 180.0
    assert float(sampling_limit_cpd(p, 10.0)) == pytest.approx(100.0 * per_rad, rel=1e-5)
    assert float(sampling_limit_cpd(p, 2.0)) == pytest.approx(500.0 / (2 * 1.01) * per_rad, rel=1e-5)
    zm, big_l, du, dy = 100.0, 500.0, 0.5, 0.01 * 101.0
    for depth in (0.25, 1.0, 3.0, 6.0):
        z = 1000.0 / depth
        t = (z - zm) / (big_l - zm)
        xi = min(1.0 / (2 * du * abs(1 - t)), 1.0 / (2 * dy * abs(t)))
        assert float(sampling_limit_cpd(p, depth)) == pytest.approx(xi * z * per_rad, rel=1e-4)


def _eye_mtf():
    f = np.linspace(0.0, 120.0, 1201)
    return f, np.asarray(diffraction_limited_mtf(jnp.asarray(f), 3.0, 550.0))


def test_perceivable_cutoff_limits():
    f, mtf = _eye_mtf()
    optical = float(cutoff_frequency(jnp.asarray(mtf), jnp.asarray(f), 0.05))
    assert 80.0 < optical < 95.0
    depths = jnp.asarray([0.0, 1.0, 3.0])
    rows = jnp.broadcast_to(jnp.asarray(mtf), (3, f.size))
    # huge lenslets (2 mm at 100 mm): the sampling limit, lenslet-dominated off the CDP
    coarse = _panel(lenslet_pitch_mm=2.0, pixel_pitch_mm=0.001)
    got = np.asarray(perceivable_cutoff_cpd(rows, f, coarse, depths))
    limit = np.asarray(sampling_limit_cpd(coarse, depths))
    assert np.allclose(got, limit, rtol=1e-6) and np.all(got < 5.0)
    # tiny lenslets and pixels: the optical cut-off
    fine = _panel(lenslet_pitch_mm=0.01, pixel_pitch_mm=1e-4)
    got = np.asarray(perceivable_cutoff_cpd(rows, f, fine, depths))
    assert np.all(np.asarray(sampling_limit_cpd(fine, depths)) > 2 * optical)
    assert np.allclose(got, optical, rtol=1e-6)
    with pytest.raises(ValueError, match="threshold"):
        perceivable_cutoff_cpd(rows, f, fine, depths, threshold=1.5)


def test_perceivable_cutoff_is_differentiable_in_the_panel():
    f, mtf = _eye_mtf()

    def cut(du):
        return perceivable_cutoff_cpd(jnp.asarray(mtf), f, _panel(lenslet_pitch_mm=du, pixel_pitch_mm=0.001),
                                      jnp.asarray(0.5))

    h = 1e-3
    fd = (float(cut(2.0 + h)) - float(cut(2.0 - h))) / (2 * h)
    assert fd < 0  # larger lenslets, coarser samples
    assert float(jax.grad(cut)(2.0)) == pytest.approx(fd, rel=1e-2)
