"""A pupil displaced from the design position (Viewing.pupil_offset_mm, read by prepare's
moved_layout) and the eye-box map over such displacements (lfjax.vision.eye_box).

Tiny scenes: one or two wavelengths, a coarse frequency step, a few states."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import lfjax
from helpers import PLAIN, dl_eye
from lfjax.base.errors import ParameterError
from lfjax.display.panel import near_eye_microdisplay
from lfjax.model.layouts import Layout, make_layout
from lfjax.vision.eye_box import (clipping_onset_mm, eye_box_map, panel_views,
                                  views_reaching)
from lfjax.vision.focus import metrics_at, through_focus
from lfjax.vision.prepare import States, prepare
from lfjax.vision.viewing import Viewing

SAMPLING = lfjax.Sampling(1.5)
STATES = States.around([2.0], [-0.4, -0.2, 0.0, 0.2, 0.4])
LINE = make_layout([[-0.8, 0.0], [0.0, 0.0], [0.8, 0.0]], [0.8] * 3, 3.0, name="line")
"""Three 0.8 mm views on the x axis of a 3 mm pupil: the left one starts to leave a pupil
moved to +x at 1.5 − 0.8 − 0.4 = 0.3 mm."""


def _symmetric_eye():
    """An eye whose wavefront is even in x: defocus, 0° astigmatism, vertical coma, SA."""
    z = np.zeros((1, 15))
    z[0, 4], z[0, 5], z[0, 7], z[0, 12] = 0.1, 0.08, 0.06, 0.03
    return lfjax.model.eyes.make_eyes(z, 3.0)


def test_zero_offset_reproduces_todays_numbers_bit_for_bit():
    eyes, layout = lfjax.sample_eyes(2, 3), lfjax.grid_layout(2, 3.0)
    spectrum = lfjax.make_spectrum([550.0])
    runs = [through_focus(eyes, layout, STATES, viewing, spectrum=spectrum, sampling=SAMPLING)
            for viewing in (Viewing(cdp_D=1.5), Viewing(cdp_D=1.5, pupil_offset_mm=(0.0, 0.0)),
                            Viewing(cdp_D=1.5, pupil_offset_mm=jnp.zeros(2)))]
    for other in runs[1:]:
        for name in ("vsotf", "strehl", "radial_mtf"):
            np.testing.assert_array_equal(getattr(other, name), getattr(runs[0], name))


def test_a_lateral_shift_moves_every_entry_point_by_minus_the_shift():
    layout = lfjax.grid_layout(2, 2.4)  # views at (±0.6, ±0.6) mm
    prepared = prepare(lfjax.sample_eyes(1, 1), layout, STATES,
                       Viewing(cdp_D=1.5, pupil_offset_mm=(0.2, -0.1)),
                       spectrum=lfjax.make_spectrum([550.0]), sampling=SAMPLING)
    # by hand: the pupil moved 0.2 mm right and 0.1 mm down finds each view 0.2 mm further
    # left and 0.1 mm higher in its own coordinates
    hand = np.array([[-0.8, -0.5], [0.4, -0.5], [-0.8, 0.7], [0.4, 0.7]])
    np.testing.assert_allclose(np.asarray(prepared.layout.centres_mm), hand, atol=1e-6)
    np.testing.assert_array_equal(np.asarray(prepared.scene.centres_mm),
                                  np.asarray(prepared.layout.centres_mm))
    np.testing.assert_array_equal(np.asarray(prepared.scene.diameters_mm), [1.2] * 4)


def test_plus_and_minus_x_give_mirrored_answers_for_an_eye_symmetric_in_x():
    eye, layout = _symmetric_eye(), lfjax.grid_layout(2, 2.4)
    runs = [through_focus(eye, layout, STATES, Viewing(cdp_D=1.5, pupil_offset_mm=(x, 0.3)),
                          spectrum=lfjax.make_spectrum([500.0, 600.0]), sampling=SAMPLING,
                          peaks=lfjax.PeakOptions(metrics=("vsotf",)))
            for x in (0.25, -0.25)]
    # mirrored pupil windows sample the grid at mirrored points only to float32 rounding
    np.testing.assert_allclose(runs[0].vsotf, runs[1].vsotf, rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(runs[0].continuous_accommodation_D(),
                               runs[1].continuous_accommodation_D(), atol=1e-5)
    # and the displacement matters: the answer is not the centred one
    centred = through_focus(eye, layout, STATES, Viewing(cdp_D=1.5, pupil_offset_mm=(0.0, 0.3)),
                            spectrum=lfjax.make_spectrum([500.0, 600.0]), sampling=SAMPLING)
    assert np.max(np.abs(np.asarray(runs[0].vsotf) - np.asarray(centred.vsotf))) > 1e-3


def test_clipping_onset_is_the_geometry_and_the_pipeline_agrees():
    # a view on the line of motion: pupil radius − |centre| − view radius
    assert clipping_onset_mm(LINE, 3.0) == pytest.approx(1.5 - 0.8 - 0.4, abs=1e-6)
    assert clipping_onset_mm(LINE, 3.0, (-2.0, 0.0)) == pytest.approx(0.3, abs=1e-6)
    assert clipping_onset_mm(LINE, 3.0, (0.0, 1.0)) == pytest.approx(np.sqrt(1.1**2 - 0.8**2),
                                                                     abs=1e-6)
    # the near-eye panel's 2×2 views (pitch p, radius p/2) along x: |(p/2 + t, p/2)| = R − p/2
    panel = near_eye_microdisplay()
    p = float(panel.view_pitch_mm)
    hand = np.sqrt((1.5 - p / 2) ** 2 - (p / 2) ** 2) - p / 2
    assert clipping_onset_mm(panel.layout(), 3.0) == pytest.approx(hand, abs=1e-6)

    # An aberration-free eye (no SCE, LCA or SA) sees the same MTF wherever its pupil holds
    # every view whole (the views' relative displacements do not change; only a common
    # translation), and a different one once the first view is cropped.
    spectrum = lfjax.make_spectrum([550.0], PLAIN)
    states = States.grid([1.3, 1.5, 1.7], [1.5])

    def mtf(x):
        return np.asarray(through_focus(
            dl_eye(), LINE, states, Viewing(cdp_D=1.0, pupil_offset_mm=(x, 0.0)),
            spectrum=spectrum, sampling=lfjax.Sampling(2.0), options=PLAIN).radial_mtf)

    centred = mtf(0.0)
    assert np.max(np.abs(mtf(0.25) - centred)) < 1e-6
    assert np.max(np.abs(mtf(0.4) - centred)) > 3e-3


def test_a_view_wholly_outside_the_moved_pupil_is_refused_naming_the_offset():
    with pytest.raises(ParameterError, match=r"viewing.pupil_offset_mm = \(1.3, 0\) mm moves "
                       r"the 3 mm pupil off 1 of the 3 views of layout 'line' \(view 0 lies "
                       r"0.2 mm outside it\)") as info:
        prepare(dl_eye(), LINE, STATES, Viewing(cdp_D=1.5, pupil_offset_mm=(1.3, 0.0)),
                spectrum=lfjax.make_spectrum([550.0]), sampling=SAMPLING)
    assert info.value.parameter == "pupil_offset_mm"
    reaching = views_reaching(LINE, 3.0, (1.3, 0.0))
    np.testing.assert_allclose(np.asarray(reaching.centres_mm), [[0.0, 0.0], [0.8, 0.0]])
    assert views_reaching(LINE, 3.0, (1.05, 0.0)).n_subapertures == 3  # exit at 1.1 mm
    assert views_reaching(LINE, 3.0, (3.0, 0.0)) is None


def test_vsotf_is_differentiable_in_the_offset():
    with jax.enable_x64(True):
        eyes = lfjax.sample_eyes(5, 1)
        spectrum = lfjax.make_spectrum([500.0, 600.0])
        layout = Layout(jnp.array([[-0.6, -0.6], [0.6, -0.6], [-0.6, 0.6], [0.6, 0.6]]),
                        jnp.full(4, 1.2), 1.2, "2x2")

        def vs(x):
            viewing = Viewing(pupil_diameter_mm=3.0, cdp_D=1.5,
                              pupil_offset_mm=(0.2 + x[0], -0.1 + x[1]))
            v, _ = metrics_at(eyes, layout, jnp.array([2.0]), jnp.array([[2.1]]), viewing,
                              spectrum=spectrum, sampling=SAMPLING)
            return v[0, 0, 0]

        value_and_grad = jax.jit(jax.value_and_grad(vs))
        zero = jnp.zeros(2)
        _, g = value_and_grad(zero)
        h = 1e-4
        for axis in range(2):
            step = zero.at[axis].set(h)
            fd = float(value_and_grad(step)[0] - value_and_grad(-step)[0]) / (2 * h)
            assert abs(fd) > 1e-3  # the offset moves the answer
            assert float(g[axis]) == pytest.approx(fd, rel=2e-3, abs=1e-6)


def test_panel_views_cover_the_eye_box_on_the_design_grid():
    panel = near_eye_microdisplay()
    views = panel_views(panel)
    c = np.asarray(views.centres_mm)
    half_box, p = 0.5 * float(panel.eye_box_mm()), float(panel.view_pitch_mm)
    assert np.all(np.abs(c) <= half_box + 1e-6)
    # the grid's next ring would lie outside the box
    assert np.max(np.abs(c)) + p > half_box
    # the design pupil's n×n views are among them
    design = np.asarray(panel.layout().centres_mm)
    assert all(np.any(np.all(np.isclose(c, row, atol=1e-6), axis=1)) for row in design)


def test_eye_box_map_centre_and_grid():
    layout = LINE
    spectrum = lfjax.make_spectrum([550.0])
    eyes = lfjax.sample_eyes(1, 2)
    out = eye_box_map(eyes, layout, [1.5], Viewing(cdp_D=1.0), [-1.3, 0.0, 1.3],
                      spectrum=spectrum, sampling=SAMPLING)
    assert out.accommodation_D.shape == (eyes.n_eyes, 1, 1, 3)
    np.testing.assert_array_equal(out.accommodation_D[..., 0, 1], out.centred_D)
    np.testing.assert_array_equal(out.n_views, [[2, 3, 2]])
    assert out.inside[0, 1]
    direct = through_focus(eyes, views_reaching(layout, 3.0, (1.3, 0.0)), States.around([1.5]),
                           Viewing(cdp_D=1.0, pupil_offset_mm=(1.3, 0.0)), spectrum=spectrum,
                           sampling=SAMPLING, peaks=lfjax.PeakOptions(metrics=("vsotf",)))
    np.testing.assert_array_equal(out.accommodation_D[..., 0, 2],
                                  direct.continuous_accommodation_D())
    low, high = out.extent_mm("x")
    assert low <= 0.0 <= high
    with pytest.raises(ParameterError, match="offsets_x_mm must be a 1-D grid"):
        eye_box_map(eyes, layout, [1.5], Viewing(cdp_D=1.0), [0.5], spectrum=spectrum)
