"""Both eyes' through-focus, one accommodation, the conflict (lfjax.binocular.focus).

Tiny scenes: one wavelength, five accommodation states, 2×2 views; each compiled program
is shared by the tests of this file.
"""

from functools import lru_cache

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import lfjax
from lfjax.base.errors import ParameterError
from lfjax.binocular import (
    BinocularOptions,
    NaturalViewing,
    NearEyeDisplay,
    StereoDisplay,
    Viewer,
    binocular_through_focus,
    pair_metrics_at,
)
from lfjax.binocular.focus import consensual_accommodation
from lfjax.binocular.population import DEFOCUS_J, spherical_equivalent_per_um
from lfjax.model.eyes import aberration_free_eye
from lfjax.model.spectral import monochromatic_spectrum

OFFSETS = [-0.4, -0.2, 0.0, 0.2, 0.4]
COMBINATIONS = [BinocularOptions(combination=c, dominant_eye=e) for c, e in (
    ("mean_vsotf", "right"), ("better_eye", "right"), ("dominant_eye", "left"),
    ("dominant_eye", "right"))]


@lru_cache(maxsize=None)
def spectrum():
    return monochromatic_spectrum(550.0)


def eyes():
    avg = lfjax.average_eye(3.0)
    return lfjax.make_eyes(jnp.concatenate([avg.zernike_um, lfjax.sample_eyes(4, 1).zernike_um]),
                           3.0)


def test_two_identical_eyes_are_one_eye_bit_for_bit():
    e = eyes()
    layout = lfjax.grid_layout(2)
    depths = [1.0, 2.5]
    mono = lfjax.through_focus(e, layout, lfjax.States.around(depths, OFFSETS), spectrum=spectrum())
    r = binocular_through_focus(Viewer.identical(e), NearEyeDisplay(layout), depths,
                                offsets_D=OFFSETS, spectrum=spectrum())
    np.testing.assert_array_equal(r.left_vsotf, np.asarray(mono.vsotf))
    np.testing.assert_array_equal(r.right_vsotf, np.asarray(mono.vsotf))
    np.testing.assert_array_equal(r.conflict_D, np.asarray(depths)[None]
                                  - mono.predicted_accommodation_D())
    # every combination of two equal curves is the one eye's prediction
    for options in COMBINATIONS:
        acc, _, index = consensual_accommodation(r.left_vsotf, r.right_vsotf, r.states_D,
                                                 r.allowed, options)
        np.testing.assert_array_equal(acc, mono.predicted_accommodation_D())
        np.testing.assert_array_equal(index, mono.peak_index())
    # each eye sees its own peak VSOTF once the pair has focused
    peak = np.nanmax(np.asarray(mono.vsotf), axis=-1)
    np.testing.assert_array_equal(r.left_vsotf_at_pair, peak)
    np.testing.assert_array_equal(r.right_vsotf_at_pair, peak)


def test_stereo_display_accommodates_at_the_screen_and_natural_viewing_at_the_point():
    pair = Viewer.identical(aberration_free_eye(3.0))
    depths = np.array([0.5, 1.0, 3.0])
    stereo = binocular_through_focus(pair, StereoDisplay(1.5), depths, offsets_D=OFFSETS,
                                     spectrum=spectrum())
    np.testing.assert_array_equal(stereo.accommodation_D, [[1.5, 1.5, 1.5]])
    np.testing.assert_array_equal(stereo.conflict_D, [depths - 1.5])
    far, near = lfjax.binocular.comfort.shibata_zone(1.5)
    np.testing.assert_array_equal(stereo.inside, [(depths >= far) & (depths <= near)])
    assert stereo.inside.tolist() == [[False, True, False]]
    natural = binocular_through_focus(pair, NaturalViewing(), depths, offsets_D=OFFSETS,
                                      spectrum=spectrum())
    np.testing.assert_array_equal(natural.accommodation_D, [depths])
    np.testing.assert_array_equal(natural.conflict_D, [[0.0, 0.0, 0.0]])
    assert natural.inside.all() and natural.fraction_inside().tolist() == [1.0, 1.0, 1.0]
    twice = binocular_through_focus(pair, NaturalViewing(), [1.0, 1.0], offsets_D=OFFSETS,
                                    spectrum=spectrum())  # a repeated depth keeps its row
    np.testing.assert_array_equal(twice.accommodation_D, [[1.0, 1.0]])
    # the cross-link pulls accommodation towards vergence by CA/C · 100 p
    ipd = float(pair.ipd_mm[0])
    linked = binocular_through_focus(pair, StereoDisplay(1.5), depths, offsets_D=OFFSETS,
                                     spectrum=spectrum(),
                                     binocular=BinocularOptions(ca_c_D_per_prism_D=0.13))
    gain = 0.1 * 0.13 * ipd
    np.testing.assert_allclose(linked.conflict_D, [(1 - gain) * (depths - 1.5)], rtol=1e-12)
    np.testing.assert_array_equal(linked.blur_accommodation_D, stereo.accommodation_D)
    # Percival's zone from given limits of clear single binocular vision
    percival = binocular_through_focus(
        pair, StereoDisplay(1.5), depths, offsets_D=OFFSETS, spectrum=spectrum(),
        binocular=BinocularOptions(comfort_zone="percival"), zcsbv_MA=(0.0, 4.5))
    assert percival.inside.tolist() == [[False, False, True]]  # middle third [1.5, 3]


def test_a_panel_shows_each_eye_the_monocular_model_of_its_own_views():
    from lfjax.binocular.displays import PanelDisplay

    panel = lfjax.display.panel.phone_panel(distance_mm=700.0, cdp_D=1.0)
    display = PanelDisplay(panel)
    pair = Viewer.mirror_pair(lfjax.average_eye(3.0), 63.0)
    r = binocular_through_focus(pair, display, [1.0], offsets_D=OFFSETS, spectrum=spectrum())
    offsets = display.eye_offsets_mm([63.0])
    viewing = lfjax.Viewing(3.0, float(panel.cdp_D), panel.optics())
    for eye, side, got in ((pair.left, 0, r.left_vsotf), (pair.right, 1, r.right_vsotf)):
        mono = lfjax.through_focus(eye, panel.layout(None, (float(offsets[side, 0]), 0.0)),
                                   lfjax.States.around([1.0], OFFSETS), viewing,
                                   spectrum=spectrum())
        np.testing.assert_array_equal(got, np.asarray(mono.vsotf))
    # the mirror pair behind mirrored views sees the same image quality (to round-off)
    np.testing.assert_allclose(r.left_vsotf, r.right_vsotf, rtol=1e-9)


def test_an_anisometropic_pair_focuses_with_the_chosen_eye():
    """Right eye 0.4 D more hyperopic (ΔM = +0.4 D) and with some spherical aberration: the
    dominant eye's focus wins, the hyperopic eye's needing more accommodation; the mean of
    the two curves lies between; the better (aberration-free) eye drives under
    "better_eye"."""
    left = aberration_free_eye(3.0)
    c20 = 0.4 / spherical_equivalent_per_um(3.0)
    right = lfjax.make_eyes(jnp.zeros(15).at[DEFOCUS_J].set(c20)
                            .at[12].set(0.05), 3.0, orientation="right")
    pair = Viewer(left, right, jnp.asarray([63.0]))
    got = {}
    for options in COMBINATIONS:
        r = binocular_through_focus(pair, StereoDisplay(1.0), [1.0], offsets_D=OFFSETS,
                                    binocular=options, spectrum=spectrum())
        got[(options.combination, options.dominant_eye)] = float(r.accommodation_D[0, 0])
        if options.combination == "better_eye":
            assert int(r.driving_eye[0, 0]) == 0  # the aberration-free left eye
        if options.combination == "dominant_eye" and options.dominant_eye == "left":
            # the left eye at its peak, the hyperopic right eye defocused: it sees less
            assert float(r.left_vsotf_at_pair[0, 0]) > float(r.right_vsotf_at_pair[0, 0])
    left_peak, right_peak = got[("dominant_eye", "left")], got[("dominant_eye", "right")]
    assert left_peak == 1.0 and right_peak - left_peak >= 0.2  # the sign of M
    assert got[("better_eye", "right")] == left_peak
    assert min(left_peak, right_peak) <= got[("mean_vsotf", "right")] <= max(left_peak,
                                                                             right_peak)


@pytest.mark.slow
def test_pair_vsotf_gradient_in_both_eyes_matches_finite_differences():
    layout = lfjax.open_pupil(3.0)
    base = lfjax.average_eye(3.0).zernike_um[0, :10]  # orders 0-3 keep the compile small

    def mean_vsotf(z):
        pair = Viewer(lfjax.model.eyes.Eyes(z[:1], 3.0), lfjax.model.eyes.Eyes(
            z[1:], 3.0, "right"), jnp.asarray([63.0]))
        return jnp.sum(pair_metrics_at(pair, layout, [1.0], [[1.2]], spectrum=spectrum(),
                                       sampling=lfjax.Sampling(2.0)))

    z = jnp.stack([base, base.at[4].add(0.05)])
    g = jax.grad(mean_vsotf)(z)
    direction = jnp.zeros_like(z).at[0, 4].set(1.0).at[1, 7].set(0.5).at[1, 3].set(-0.3)
    eps = 1e-4
    fd = (float(mean_vsotf(z + eps * direction)) - float(mean_vsotf(z - eps * direction))) / (
        2 * eps)
    assert float(jnp.vdot(g, direction)) == pytest.approx(fd, rel=1e-5)
    assert float(jnp.abs(g[1]).max()) > 0 and float(jnp.abs(g[0]).max()) > 0


def test_bad_input_is_refused_before_work():
    eye = lfjax.average_eye(3.0)
    pair = Viewer.identical(eye)
    with pytest.raises(ParameterError, match="one eye is missing"):
        binocular_through_focus(eye, NaturalViewing(), [1.0])
    with pytest.raises(ParameterError, match="cannot hold both eyes"):
        binocular_through_focus(Viewer.identical(eye, 72.0), NearEyeDisplay(
            lfjax.grid_layout(2), lens_separation_mm=63.0, eye_box_mm=10.0), [1.0])
    with pytest.raises(ParameterError, match="comfort_zone='percival' needs zcsbv_MA"):
        binocular_through_focus(pair, NaturalViewing(), [1.0],
                                binocular=BinocularOptions(comfort_zone="percival"))
    with pytest.raises(ParameterError, match="binocular must be"):
        binocular_through_focus(pair, NaturalViewing(), [1.0], binocular="mean")
    with pytest.raises(ParameterError, match="display must be"):
        binocular_through_focus(pair, lfjax.grid_layout(2), [1.0])
