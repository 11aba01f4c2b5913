"""Gradients of VSOTF and Strehl (float64) against central finite differences.

``lfjax.vision.focus.metrics_at`` is the differentiable public entry point (through_focus
builds its grids on the host; polychromatic_otf needs a concrete pupil diameter to size
its windows). One reverse-mode gradient of J = VSOTF + 0.7·Strehl w.r.t. every physical
input at once — Zernike coefficients, accommodation, rendered depth, pupil diameter,
subaperture centres and diameters — is compiled once and checked along random directions
of each input. The configuration contains the hazards of anti-aliased apertures
(docs/design.md#conventions): a subaperture centred
on the pupil centre, one internally tangent to the pupil edge, one clipped by it, and
0 D accommodation.
"""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import helpers as H
import lfjax
from lfjax.base import sampling
from lfjax.vision.focus import metrics_at
from lfjax.vision.viewing import Viewing

CDP = 1.0
WINDOW_MM = 1.6
SAMPLING = lfjax.Sampling(2.0)
OPTIONS = lfjax.ModelOptions()
SPECTRUM = lfjax.make_spectrum([550.0], OPTIONS)
N_MODES = 10  # orders 0-3: defocus, astigmatism, coma, trefoil (keeps the compile small)


def _base_params():
    z = np.asarray(lfjax.sample_eyes(3, 1).zernike_um)[:, :N_MODES]
    return dict(
        z=jnp.asarray(z),
        acc=jnp.zeros((1, 1)),  # 0 D accommodation (hyperopic limit)
        depth=jnp.asarray([0.4]),
        pupil=jnp.asarray(3.0, dtype=jnp.float64),
        centres=jnp.asarray([[0.0, 0.0],     # at the pupil centre
                             [0.9, 0.0],     # edge internally tangent to the pupil edge
                             [-0.6, 0.9]]),  # clipped by the pupil
        diameters=jnp.asarray([1.0, 1.2, 1.6]),
    )


def _metrics(p):
    layout = H.layout_from(p["centres"], p["diameters"], WINDOW_MM)
    vs, sr = metrics_at(
        lfjax.Eyes(p["z"], 3.0),
        layout,
        p["depth"],
        p["acc"],
        Viewing(pupil_diameter_mm=p["pupil"], cdp_D=CDP),
        spectrum=SPECTRUM,
        sampling=SAMPLING,
        options=OPTIONS,
    )
    return vs[0, 0, 0], sr[0, 0, 0]


def _objective(p, strehl_weight=0.7):
    vs, sr = _metrics(p)
    return vs + strehl_weight * sr


_pair = jax.jit(_metrics)
_weighted_gradient = jax.jit(jax.grad(_objective))  # one compile for J and VSOTF alone


def _gradient(p):
    return _weighted_gradient(p, 0.7)


def _forward(p):
    vs, sr = _pair(p)
    return vs + 0.7 * sr


def test_base_point_is_valid_and_nontrivial():
    """The configuration passes lfjax's host checks (layout geometry, aliasing guard) and
    the metrics are neither saturated nor tiny."""
    p = _base_params()
    lfjax.make_layout(np.asarray(p["centres"]), np.asarray(p["diameters"]), 3.0,
                      window_diameter_mm=WINDOW_MM)
    # the aliasing guard of the pipeline, from its public pieces (lfjax.base.sampling)
    z = np.asarray(p["z"])
    slope = sampling.eye_slope_rad(z, 3.0, 3.0)
    defocus = 0.0 - CDP + np.asarray(SPECTRUM.lca_D)  # a − CDP + LCA(λ)
    mismatch = 0.0 - np.asarray(p["depth"]) + np.asarray(SPECTRUM.lca_D)
    radius = sampling.blur_radius_arcmin(3.0, np.asarray(p["centres"]),
                                         np.asarray(p["diameters"]), defocus, mismatch, 550.0,
                                         slope)
    sampling.check_field(SAMPLING, radius, "test configuration")
    vs, sr = _pair(p)
    assert 0.2 < float(vs) < 0.95 and 0.2 < float(sr) < 0.95


@pytest.mark.parametrize("name", ["z", "acc", "depth", "pupil", "centres", "diameters"])
def test_gradient_matches_finite_differences(name):
    """jax.grad · v equals the central difference along a random direction v of one input.

    Tolerance from the finite differences themselves: with steps h = 2e-4 and h/2 the
    truncation error of FD(h/2) is ≈ |FD(h) − FD(h/2)|/3, so |∇J·v − FD(h/2)| must stay
    below |FD(h) − FD(h/2)| plus 1e-9 (round-off: 1e-16/h). Measured relative agreement at
    h = 1e-4: 9e-6 (Zernike), ≤ 2e-8 (the others); required ≤ 1e-4. The derivative along v
    must be non-negligible (> 1e-4) so the check is not vacuous."""
    p = _base_params()
    g = _gradient(p)
    v = H.random_direction(jax.random.key(len(name)), {name: p[name]})
    if name == "z":  # piston and tilt are zeroed by the model: no derivative there
        v[name] = v[name].at[:, :3].set(0.0)
    directional = H.tree_vdot({name: g[name]}, v)
    fd_h = H.directional_fd(_forward, p, {**jax.tree_util.tree_map(jnp.zeros_like, p), **v},
                            2e-4)
    fd_h2 = H.directional_fd(_forward, p, {**jax.tree_util.tree_map(jnp.zeros_like, p), **v},
                             1e-4)
    assert abs(directional) > 1e-4, directional
    assert abs(directional - fd_h2) <= abs(fd_h - fd_h2) + 1e-9 * (1 + abs(directional)), (
        directional, fd_h, fd_h2)
    assert abs(directional - fd_h2) <= 1e-4 * abs(directional)


HAZARDS = ["base", "depth_at_cdp", "centre_on_pupil_rim", "zero_depth_zero_accommodation",
           "coinciding_edges"]


def _hazard_params(case):
    p = _base_params()
    if case == "depth_at_cdp":
        p["depth"] = jnp.asarray([CDP])
    elif case == "centre_on_pupil_rim":
        p["centres"] = p["centres"].at[2].set(jnp.asarray([0.0, 1.5]))
    elif case == "zero_depth_zero_accommodation":
        p["depth"] = jnp.zeros(1)
    elif case == "coinciding_edges":  # second subaperture: centred, its edge = pupil edge
        p["centres"] = p["centres"].at[1].set(jnp.zeros(2))
        p["diameters"] = p["diameters"].at[1].set(1.6)
        p["pupil"] = jnp.asarray(1.6, dtype=jnp.float64)
        p["centres"] = p["centres"].at[2].set(jnp.asarray([0.3, 0.0]))
        p["diameters"] = p["diameters"].at[2].set(0.6)
    return p


@pytest.mark.parametrize("case", HAZARDS)
def test_no_nan_gradients_at_hazards(case):
    """Finite gradients (every input) at the pupil centre, at subaperture and pupil edges,
    at 0 D accommodation and 0 D rendered depth, and with no display shift."""
    p = _hazard_params(case)
    g = _gradient(p)
    for key, leaf in g.items():
        assert bool(jnp.all(jnp.isfinite(leaf))), (case, key, leaf)
    # the centred subaperture's centre gradient is finite and the model is symmetric in
    # nothing here, so it is generally nonzero: no spurious zeroing by the safe sqrt either
    assert float(jnp.abs(g["centres"]).sum()) > 0


def _one_sided(p, v, h, side):
    """Second-order one-sided difference of VSOTF along v: (−3V(0) + 4V(±h) − V(±2h))/(±2h),
    which evaluates V only on one side of the point (e.g. accommodation ≥ 0 D)."""
    def at(t):
        return float(_pair(jax.tree_util.tree_map(lambda a, b: a + t * b, p, v))[0])
    step = side * h
    return (-3.0 * at(0.0) + 4.0 * at(step) - at(2.0 * step)) / (2.0 * step)


KINKS = {"coinciding_edges": ("pupil", "centres", "diameters")}
"""Inputs whose derivative has a kink at the hazard: the subaperture's edge coincides with
the pupil's, and the aperture is their nearer edge (a minimum)."""


@pytest.mark.parametrize("case", HAZARDS)
def test_gradients_at_hazards_match_one_sided_differences(case):
    """jax.grad of VSOTF · v at the hazards (a subaperture centred on the pupil centre,
    one centred on the pupil rim, 0 D accommodation and 0 D rendered depth, no display
    shift, and a subaperture whose edge coincides with the pupil edge) equals the one-sided
    finite difference along a random direction v of each input, taken on the side the
    model is defined on (forward: accommodation and depth ≥ 0 D). VSOTF, not the Strehl
    ratio: the sampled PSF's peak is a maximum over samples, whose kinks where two samples
    tie would make a one-sided difference meaningless a step away.

    Smooth hazards: agreement with the forward difference at h = 1e-4 (second order) must
    be ≤ 1e-4 relative (measured ≤ 1.9e-5, along the centres: the internally tangent
    subaperture's edge meets the pupil's, where the aperture's curvature is not smooth).
    Where the derivative has a kink (the coinciding edges, along pupil, centres and
    diameters) forward and backward differences differ (measured 0.67 / 0.00, 0.41 / −0.44,
    0.77 / 0.11); the gradient must lie between them, a subgradient (jax gives their mean),
    not a spurious value beyond either, within the differences' own change from h = 2e-4
    to 1e-4."""
    p = _hazard_params(case)
    g = _weighted_gradient(p, 0.0)
    zeros = jax.tree_util.tree_map(jnp.zeros_like, p)
    for i, name in enumerate(["z", "acc", "depth", "pupil", "centres", "diameters"]):
        v = H.random_direction(jax.random.key(100 + i), {name: p[name]})
        if name == "z":
            v[name] = v[name].at[:, :3].set(0.0)
        if name in ("acc", "depth"):  # move away from 0 D on the forward side
            v[name] = jnp.abs(v[name])
        v = {**zeros, **v}
        directional = H.tree_vdot(g, v)
        forward = [_one_sided(p, v, h, +1) for h in (2e-4, 1e-4)]
        tol = abs(forward[0] - forward[1]) + 1e-9 * (1 + abs(directional))
        if name in KINKS.get(case, ()):
            backward = [_one_sided(p, v, h, -1) for h in (2e-4, 1e-4)]
            tol += abs(backward[0] - backward[1])
            lo, hi = sorted((forward[1], backward[1]))
            print(case, name, directional, forward, backward)
            assert hi - lo > 0.05 * abs(hi), (name, forward, backward)  # a real kink
            assert lo - tol <= directional <= hi + tol, (name, directional, forward, backward)
            continue
        assert abs(directional) > 1e-5, (name, directional)
        assert abs(directional - forward[1]) <= 1e-4 * abs(directional), (name, directional,
                                                                          forward)
