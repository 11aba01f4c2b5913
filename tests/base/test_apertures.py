"""The declared aperture shapes and their rules (lfjax.base.apertures): the table, the edge
distance each shape reads from it, the window rule along x, and the strip as an aperture of
DisplayOptics and LensletArray like the others (lfjax.display.lenslets)."""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np
import pytest

from lfjax.base.apertures import APERTURES, CIRCLE, SQUARE, STRIP, aperture_edge_distance, aperture_shape
from lfjax.display.lenslets import APERTURE_SHAPES, SPHERICAL_APERTURE_SHAPES, DisplayOptics, LensletArray


def test_every_shape_is_declared_once_and_only_the_strip_spans_the_pupil_height():
    assert tuple(APERTURES) == ("circle", "square", "strip") == APERTURE_SHAPES
    assert SPHERICAL_APERTURE_SHAPES == ("circle", "square")
    assert [a.spans_pupil_height for a in (CIRCLE, SQUARE, STRIP)] == [False, False, True]
    assert aperture_shape("strip") is STRIP
    with pytest.raises(ValueError, match=r"aperture='hexagon'; allowed: circle, square, strip"):
        aperture_shape("hexagon")


def test_the_window_along_x_is_the_widest_strip_at_most_the_pupil():
    """A strip's window: its widest view along x (clipped to the pupil); bounded shapes and
    diffracted beams: square windows (None)."""
    assert STRIP.window_x_mm(1.2, 3.0) == 1.2 and STRIP.window_x_mm(4.0, 3.0) == 3.0
    assert CIRCLE.window_x_mm(1.2, 3.0) is None and SQUARE.window_x_mm(1.2, 3.0) is None
    assert DisplayOptics(aperture="strip").window_x_mm(1.0, 3.0) == 1.0
    assert DisplayOptics(aperture="strip", diffraction="fresnel").window_x_mm(1.0, 3.0) is None
    assert DisplayOptics().window_x_mm(1.0, 3.0) is None


def test_edge_distance_by_shape():
    """mm inside the edge: a strip's ignores y (it spans the pupil's height), a square's
    takes the nearer side."""
    dx, dy = jnp.asarray([0.1, 0.1]), jnp.asarray([0.0, 5.0])
    np.testing.assert_allclose(aperture_edge_distance(dx, dy, 1.0, 0.01, "strip"), [0.4, 0.4])
    np.testing.assert_allclose(aperture_edge_distance(dx, dy, 1.0, 0.01, "square"), [0.4, -4.5])


def test_a_strip_lenslet_array_is_a_lenticular_sheet():
    """LensletArray with strips: 1×n strips M·Δu apart along x, the panel-plane y defocus
    and the pixel's own height; spherical lenslets keep no y defocus."""
    sheet = LensletArray(0.45, 0.45, 3.0, 2.9, 350.0, "strip")
    layout = sheet.layout(3.0, 3)
    pitch = float(sheet.subaperture_pitch_mm)
    np.testing.assert_allclose(np.asarray(layout.centres_mm), [[-pitch, 0], [0, 0], [pitch, 0]], rtol=1e-6)
    assert float(sheet.y_defocus_D) == pytest.approx(float(sheet.cdp_D) - 1000.0 / 352.9, rel=1e-5)
    optics = sheet.optics(0.05)
    assert optics.strips and float(optics.y_defocus_D) == pytest.approx(float(sheet.y_defocus_D))
    assert float(optics.pixel_height_rad) == pytest.approx(0.05 / 352.9, rel=1e-5)
    lens = LensletArray(0.45, 0.45, 3.0, 2.9, 350.0)
    assert float(lens.y_defocus_D) == 0.0 and lens.optics(0.05).y_defocus_D is None
    assert lens.layout(3.0, 2).n_subapertures == 4


def test_a_panel_refuses_strips():
    """Panel's lenslets have power along both axes: a strip is a LenticularPanel's."""
    import lfjax

    with pytest.raises(ValueError, match=r"Panel.aperture='strip'; allowed: circle, square .*LenticularPanel"):
        lfjax.Panel.with_cdp(cdp_D=2.0, pixel_pitch_mm=0.0552, lenslet_pitch_mm=0.45,
                             focal_length_mm=3.0, distance_mm=350.0, aperture="strip")
