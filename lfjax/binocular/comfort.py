"""Zones of comfort: which (vergence, accommodation) pairs a viewer tolerates.

Shibata, Kim, Hoffman & Banks (2011, J Vis 11(8):11) fitted the near and far boundaries of
the zone of comfort as straight lines in dioptres: the far boundary is the vergence distance
V_far = (F − T_far) / m_far and the near boundary V_near = (F − T_near) / m_near, F the
focal (accommodative) distance, with m_far = 1.129, T_far = 0.442 D, m_near = 1.035,
T_near = −0.626 D (``lfjax/data/binocular_statistics.csv``). Their zone is defined on the
stimuli; lfjax places the predicted accommodation where they had the focal distance.

Percival's zone is the middle third of the zone of clear single binocular vision (ZCSBV) at
each accommodation: the vergence range between the limits of fusion, cut in three equal
parts, the middle one comfortable. It needs the viewer's ZCSBV limits (measured by
relative vergence with a phoropter); lfjax ships no population values for them, so they are
arguments.

Pure jax functions of arrays (differentiable where the boundaries are).
"""

from __future__ import annotations

import jax.numpy as jnp

from lfjax.binocular.viewer import binocular_statistics


def shibata_parameters() -> dict[str, float]:
    """The fitted boundaries of Shibata et al. (2011): m_far, T_far (D), m_near, T_near (D)."""
    s = binocular_statistics()
    return dict(m_far=s["shibata_far_slope"], T_far=s["shibata_far_intercept_D"],
                m_near=s["shibata_near_slope"], T_near=s["shibata_near_intercept_D"])


def shibata_zone(focal_D):
    """(far, near) vergence boundaries (metre angles ≡ D) of the zone of comfort at focal
    distance ``focal_D`` (D, any shape), Shibata et al. (2011)."""
    p = shibata_parameters()
    f = jnp.asarray(focal_D)
    return (f - p["T_far"]) / p["m_far"], (f - p["T_near"]) / p["m_near"]


def percival_zone(zcsbv_far_MA, zcsbv_near_MA):
    """(far, near) boundaries of Percival's zone, metre angles: the middle third of the
    viewer's zone of clear single binocular vision, whose far and near vergence limits at
    the accommodation in question are ``zcsbv_far_MA`` < ``zcsbv_near_MA`` (any shape)."""
    far = jnp.asarray(zcsbv_far_MA)
    width = jnp.asarray(zcsbv_near_MA) - far
    return far + width / 3.0, far + 2.0 * width / 3.0


def inside_zone(vergence_MA, boundaries):
    """True where ``vergence_MA`` lies within ``boundaries`` = (far, near), inclusive."""
    far, near = boundaries
    v = jnp.asarray(vergence_MA)
    return (v >= far) & (v <= near)


def comfort_margin_D(vergence_MA, boundaries):
    """Signed distance (D) of the vergence from the nearer boundary: ≥ 0 inside the zone,
    negative outside (a differentiable companion of :func:`inside_zone`)."""
    far, near = boundaries
    v = jnp.asarray(vergence_MA)
    return jnp.minimum(v - far, near - v)


__all__ = ["shibata_parameters", "shibata_zone", "percival_zone", "inside_zone",
           "comfort_margin_D"]
