"""Layout geometry (lfjax.model.layouts): hex_layout against an independent construction of the
hexagonal lattice."""

from __future__ import annotations

import math

import numpy as np
import pytest

import lfjax


def _lattice_overlapping(pitch_mm, diameter_mm, pupil_mm):
    """Points m·a1 + n·a2 of the hexagonal lattice (a1 = (p, 0), a2 = (p/2, p√3/2)) whose
    circle of ``diameter_mm`` overlaps the open pupil, as a set of rounded (x, y) mm."""
    radius = 0.5 * pupil_mm
    reach = int(math.ceil((radius + diameter_mm) / pitch_mm)) + 2
    out = set()
    for m in range(-3 * reach, 3 * reach + 1):
        for n in range(-3 * reach, 3 * reach + 1):
            x = m * pitch_mm + 0.5 * n * pitch_mm
            y = 0.5 * math.sqrt(3.0) * n * pitch_mm
            if math.hypot(x, y) < radius + 0.5 * diameter_mm - 1e-9:
                out.add((round(x, 9), round(y, 9)))
    return out


@pytest.mark.parametrize("pitch, diameter, pupil", [(1.2, None, 3.0), (0.9, 0.6, 3.0),
                                                    (1.5, 1.0, 4.0), (0.5, 0.5, 2.0)])
def test_hex_layout_is_the_hexagonal_lattice_overlapping_the_pupil(pitch, diameter, pupil):
    """Every centre is a lattice point with one at the pupil centre; every lattice point
    whose circle overlaps the pupil is there, once; the diameters are ``diameter_mm``
    (default: the pitch, tangent circles); each centre's nearest neighbours sit one pitch
    away, six of them for a centre with all its neighbours present; the layout is
    symmetric under x → −x, y → −y."""
    layout = lfjax.hex_layout(pitch, pupil, diameter)
    d = pitch if diameter is None else diameter
    centres = np.asarray(layout.centres_mm)
    got = {(round(float(x), 9), round(float(y), 9)) for x, y in centres}
    assert len(got) == centres.shape[0]  # no duplicates
    assert got == _lattice_overlapping(pitch, d, pupil)
    assert (0.0, 0.0) in got
    np.testing.assert_allclose(np.asarray(layout.diameters_mm), d)
    dist = np.hypot(*(centres[:, None, :] - centres[None, :, :]).transpose(2, 0, 1))
    np.fill_diagonal(dist, np.inf)
    np.testing.assert_allclose(dist.min(axis=1), pitch, rtol=1e-12)
    full = np.isclose(dist, pitch, rtol=1e-9).sum(axis=1)
    assert full.max() == 6 and np.all(full <= 6)
    inner = np.hypot(centres[:, 0], centres[:, 1]) + pitch + 0.5 * d < 0.5 * pupil
    assert np.all(full[inner] == 6)
    for fx, fy in ((-1, 1), (1, -1)):
        assert {(fx * x + 0.0, fy * y + 0.0) for x, y in got} == got
    assert min(d, pupil) <= layout.window_diameter_mm <= pupil


def test_hex_layout_default_diameter_is_tangent():
    layout = lfjax.hex_layout(1.0, 3.0)
    centres = np.asarray(layout.centres_mm)
    gap = np.hypot(*(centres[:, None] - centres[None]).transpose(2, 0, 1))
    np.fill_diagonal(gap, np.inf)
    # neighbours touch: centre distance = diameter
    np.testing.assert_allclose(gap.min(axis=1), np.asarray(layout.diameters_mm), rtol=1e-12)
