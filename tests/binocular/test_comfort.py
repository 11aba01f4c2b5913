"""Zones of comfort (lfjax.binocular.comfort): Shibata et al. (2011), Percival."""

import numpy as np
import pytest

from lfjax.binocular import comfort as C


def test_shibata_boundaries_are_the_published_lines():
    p = C.shibata_parameters()
    assert p == dict(m_far=1.129, T_far=0.442, m_near=1.035, T_near=-0.626)
    f = np.array([0.0, 0.5, 2.0, 4.0])
    far, near = C.shibata_zone(f)
    # vergence = (focal − T) / m: m · V + T gives the focal distance back
    np.testing.assert_allclose(1.129 * np.asarray(far) + 0.442, f, atol=1e-15)
    np.testing.assert_allclose(1.035 * np.asarray(near) - 0.626, f, atol=1e-15)
    # the published points: at 2 D focal distance
    assert float(far[2]) == pytest.approx((2.0 - 0.442) / 1.129, rel=1e-15)
    assert float(near[2]) == pytest.approx((2.0 + 0.626) / 1.035, rel=1e-15)
    # the far boundary meets 0 MA where the focal distance is T_far
    assert float(C.shibata_zone(0.442)[0]) == 0.0
    # their findings: at far focal distances content behind the screen is tolerated less
    # than in front, at near distances the reverse
    assert -float(far[0]) < float(near[0])
    assert 4.0 - float(far[3]) > float(near[3]) - 4.0


def test_inside_is_inclusive_and_the_margin_is_signed():
    far, near = C.shibata_zone(2.0)
    v = np.array([float(far) - 0.01, float(far), 2.0, float(near), float(near) + 0.01])
    np.testing.assert_array_equal(C.inside_zone(v, (far, near)), [False, True, True, True, False])
    margin = np.asarray(C.comfort_margin_D(v, (far, near)))
    np.testing.assert_array_equal(margin >= 0, [False, True, True, True, False])


def test_percival_is_the_middle_third():
    far, near = C.percival_zone(np.array([0.5, 1.0]), np.array([3.5, 4.0]))
    np.testing.assert_allclose(far, [1.5, 2.0])
    np.testing.assert_allclose(near, [2.5, 3.0])
