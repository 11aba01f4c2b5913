"""OSA/ANSI Zernike polynomials (lfjax.base.zernike) and the defocus conversion (lfjax.base.units)."""

import math
from functools import partial

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import reference as R
from lfjax.base import units
from lfjax.base import zernike


N_POINTS = 768  # every basis evaluation below uses this many points: one compile
_basis66 = jax.jit(partial(zernike.zernike_basis, 66))


def _points(seed, lo=-1.0, hi=1.0):
    """N_POINTS seeded uniform (x, y) samples (jax.random), as numpy arrays."""
    xy = jax.random.uniform(jax.random.key(seed), (2, N_POINTS), minval=lo, maxval=hi)
    xy = np.array(xy)
    return xy[0], xy[1]


def test_ansi_index_table_and_roundtrip():
    expected = [(0, 0), (1, -1), (1, 1), (2, -2), (2, 0), (2, 2), (3, -3), (3, -1), (3, 1),
                (3, 3), (4, -4), (4, -2), (4, 0), (4, 2), (4, 4)]
    assert [zernike.nm_from_ansi(j) for j in range(15)] == expected
    n_max = zernike.MAX_RADIAL_ORDER
    for j in range(zernike.n_modes_for_order(n_max)):
        n, m = zernike.nm_from_ansi(j)
        assert (n, m) == R.nm_from_j(j)
        assert zernike.ansi_from_nm(n, m) == j
    assert zernike.n_modes_for_order(4) == 15
    assert zernike.n_modes_for_order(10) == 66


def _disk_quadrature(n_r=16, n_t=48):
    """Gauss-Legendre in r (weight r dr) x uniform in theta, normalised to the disk mean.

    Exact for products of Zernike modes up to radial order 10: the radial integrand is a
    polynomial of degree <= 21 (2 n_r - 1 = 31) and the angular one a trigonometric
    polynomial of order <= 20 (< n_t)."""
    x, w = np.polynomial.legendre.leggauss(n_r)
    r = 0.5 * (x + 1.0)
    t = np.arange(n_t) * 2 * np.pi / n_t
    rr, tt = np.meshgrid(r, t, indexing="ij")
    weights = (0.5 * w * r)[:, None] * np.full(n_t, 2 * np.pi / n_t)[None, :] / np.pi
    return rr * np.cos(tt), rr * np.sin(tt), weights


def test_orthonormality_to_order_10():
    """<Z_i Z_j> over the unit disk = δ_ij for all 66 modes of radial order <= 10."""
    x, y, w = _disk_quadrature()
    assert x.size == N_POINTS
    basis = np.asarray(_basis66(jnp.asarray(x.ravel()), jnp.asarray(y.ravel())))
    gram = np.einsum("ai,bi,i->ab", basis, basis, w.ravel())
    assert np.abs(gram - np.eye(66)).max() < 1e-10


def test_modes_match_polar_reference():
    """Cartesian Horner evaluation equals the factorial/arctan2 form of tests/reference.py,
    inside and outside the unit disk (no masking): all modes to order 10, and the highest
    supported order (20) for a few modes."""
    x, y = _points(0, -1.2, 1.2)
    x[0] = y[0] = 0.0
    rho, theta = np.hypot(x, y), np.arctan2(y, x)
    got = np.asarray(_basis66(jnp.asarray(x), jnp.asarray(y)))
    want = np.stack([R.zernike_j(j, rho, theta) for j in range(66)])
    assert np.abs(got - want).max() < 1e-11 * max(1.0, np.abs(want).max())
    inside = rho <= 1.0
    for j in (zernike.ansi_from_nm(20, 0), zernike.ansi_from_nm(20, -20),
              zernike.ansi_from_nm(19, 7)):
        g = np.asarray(zernike.zernike_mode(j, jnp.asarray(x), jnp.asarray(y)))
        w = R.zernike_j(j, rho, theta)
        # order-20 radial polynomials have coefficients up to ~1e5: absolute error inside
        assert np.abs(g - w)[inside].max() < 1e-8, j
        assert np.abs(g - w)[~inside].max() < 1e-12 * np.abs(w[~inside]).max(), j


def test_known_low_order_forms():
    x, y = _points(3)
    xj, yj = jnp.asarray(x), jnp.asarray(y)
    z = np.asarray(_basis66(xj, yj))
    r2 = x * x + y * y
    np.testing.assert_allclose(z[2], 2 * x, atol=1e-15)  # Z(1,1)
    np.testing.assert_allclose(z[1], 2 * y, atol=1e-15)  # Z(1,-1)
    np.testing.assert_allclose(z[4], math.sqrt(3) * (2 * r2 - 1), atol=1e-14)  # Z(2,0)
    np.testing.assert_allclose(z[3], math.sqrt(6) * 2 * x * y, atol=1e-14)  # √6 ρ² sin 2θ
    np.testing.assert_allclose(z[12], math.sqrt(5) * (6 * r2**2 - 6 * r2 + 1), atol=1e-14)
    np.testing.assert_allclose(z[0], 1.0, atol=0)


def test_gradients_finite_and_exact_at_pupil_centre():
    """No arctan2 / sqrt: every mode to order 6 has finite derivatives at ρ = 0, and odd
    modes have their exact slope there."""
    @jax.jit
    @jax.grad
    def grad_sum(xy, weights):
        return jnp.sum(weights * zernike.zernike_basis(28, xy[0], xy[1]))

    origin = jnp.zeros(2)
    g_all = grad_sum(origin, jnp.ones(28))
    assert bool(jnp.all(jnp.isfinite(g_all)))
    e2 = jnp.zeros(28).at[2].set(1.0)  # Z(1,1) = 2x
    np.testing.assert_allclose(grad_sum(origin, e2), [2.0, 0.0], atol=1e-15)
    e7 = jnp.zeros(28).at[7].set(1.0)  # Z(3,-1) = √8 (3ρ³ − 2ρ) sin θ: d/dy at 0 = −2√8
    np.testing.assert_allclose(grad_sum(origin, e7), [0.0, -2 * math.sqrt(8)],
                               atol=1e-14)


def test_wavefront_is_coefficient_sum():
    c = np.asarray(jax.random.normal(jax.random.key(1), (15,)))
    x, y = (jnp.asarray(a) for a in _points(1))
    w = jax.jit(zernike.wavefront_um)(jnp.asarray(c), x, y)
    direct = np.einsum("j,ji->i", c, np.asarray(_basis66(x, y))[:15])
    np.testing.assert_allclose(w, direct, rtol=1e-12, atol=1e-12)


def test_mirror_sign_vector_flips_x():
    """Z_j(−x, y) = s_j Z_j(x, y); the first 15 signs are those of the Thibos data files."""
    s = zernike.mirror_sign_vector(66)
    np.testing.assert_array_equal(
        s[:15], [1, 1, -1, -1, 1, 1, 1, 1, -1, -1, -1, -1, 1, 1, 1])
    x, y = (jnp.asarray(a) for a in _points(2))
    a = np.asarray(_basis66(-x, y))
    b = np.asarray(_basis66(x, y)) * s[:, None]
    np.testing.assert_allclose(a, b, atol=1e-12)


def test_bad_orders_raise():
    with pytest.raises(ValueError, match="radial order"):
        zernike.nm_from_ansi(10**6)
    with pytest.raises(ValueError, match="ansi_j"):
        zernike.nm_from_ansi(-1)
    with pytest.raises(ValueError, match="invalid Zernike mode"):
        zernike.ansi_from_nm(2, 1)
    with pytest.raises(ValueError, match="exceeds"):
        zernike.ansi_from_nm(22, 0)
    with pytest.raises(ValueError, match="n_modes"):
        zernike.zernike_basis(0, jnp.zeros(3), jnp.zeros(3))
    with pytest.raises(ValueError, match="radial order"):
        zernike.zernike_mode(zernike.n_modes_for_order(zernike.MAX_RADIAL_ORDER), 0.0, 0.0)


def test_defocus_coefficient_formula():
    """c(2,0) = d² D / (16√3) (paper eq:diopter2um): 1 D on a 3 mm pupil is 0.3248 µm."""
    assert units.dioptres_to_c20_um(1.0, 3.0) == pytest.approx(9 / (16 * math.sqrt(3)),
                                                               rel=1e-15)
    assert units.dioptres_to_c20_um(1.0, 3.0) == pytest.approx(0.32476, abs=1e-5)
    assert units.c20_um_to_dioptres(units.dioptres_to_c20_um(-2.7, 4.5), 4.5) == \
        pytest.approx(-2.7, rel=1e-14)
    # the defocus wavefront c Z(2,0) has curvature D: W(r) − W(0) = D r²/2 (µm, r mm, D 1/m)
    d, D, r = 3.0, 1.7, 0.9
    c = units.dioptres_to_c20_um(D, d)
    w = lambda rr: c * math.sqrt(3) * (2 * (rr / (d / 2)) ** 2 - 1)  # noqa: E731
    assert w(r) - w(0.0) == pytest.approx(D * r**2 / 2, rel=1e-13)


def test_monomial_form_is_exact_to_order_10():
    """monomial_coefficients rebuilds every mode exactly (float64, against the polar
    reference's Cartesian twin), and wavefront_on_grid evaluates it on a separable grid."""
    x = np.linspace(-1.1, 1.1, 23)
    y = np.linspace(-1.05, 1.1, 19)
    xx, yy = np.meshgrid(x, y)
    n_modes = zernike.n_modes_for_order(10)
    m = zernike.monomial_coefficients(n_modes)
    assert m.shape == (n_modes, 11, 11)
    direct = np.asarray(_basis66(jnp.asarray(xx.ravel()), jnp.asarray(yy.ravel())))
    monomial = np.einsum("jpq,pi,qi->ji", m, xx.ravel()[None] ** np.arange(11)[:, None],
                         yy.ravel()[None] ** np.arange(11)[:, None])
    np.testing.assert_allclose(monomial, direct, rtol=0, atol=5e-10)
    c = np.asarray(jax.random.normal(jax.random.key(2), (n_modes,)))
    grid = zernike.wavefront_on_grid(jnp.asarray(np.tensordot(c, m, 1)), jnp.asarray(x), jnp.asarray(y))
    np.testing.assert_allclose(np.asarray(grid).ravel(), c @ direct, rtol=0, atol=1e-9)


def test_pipeline_wavefront_separable_and_high_order_paths_agree_with_the_polynomials():
    """The pipeline's per-state wavefront on each view's window (monomial form moved to the
    window's centre up to order 10, the polynomials themselves beyond) equals eye +
    c20·Z(2,0) + c40·Z(4,0) evaluated mode by mode at the samples, float32."""
    from lfjax.kernel.optics import SEPARABLE_MAX_ORDER, _state_wavefronts_um

    offsets = jnp.asarray(np.linspace(-1.5, 1.5, 31), jnp.float32)
    centres = jnp.asarray([[0.25, -0.4], [-0.6, 0.1]], jnp.float32)  # two views' windows
    xx = np.asarray(centres[:, 0], float)[:, None, None] + np.asarray(offsets, float)[None, None, :]
    yy = np.asarray(centres[:, 1], float)[:, None, None] + np.asarray(offsets, float)[None, :, None]
    xx, yy = np.broadcast_arrays(xx, yy)
    c20, c40 = np.array([0.3, -0.8]), np.array([0.05, 0.1])
    pupil, sa_radius, measured = 3.0, 2.5, 3.5
    for order in (4, SEPARABLE_MAX_ORDER, SEPARABLE_MAX_ORDER + 2):
        n_modes = zernike.n_modes_for_order(order)
        c = 0.1 * np.asarray(jax.random.normal(jax.random.key(order), (n_modes,)))
        w = _state_wavefronts_um(jnp.asarray(c, jnp.float32), jnp.asarray(c20, jnp.float32),
                                 jnp.asarray(c40, jnp.float32), centres, offsets, pupil,
                                 sa_radius, measured)
        eye = sum(c[j] * np.asarray(zernike.zernike_mode(j, xx / (measured / 2), yy / (measured / 2)))
                  for j in range(n_modes))
        z20 = np.asarray(zernike.zernike_mode(4, xx / (pupil / 2), yy / (pupil / 2)))
        z40 = np.asarray(zernike.zernike_mode(12, xx / sa_radius, yy / sa_radius))
        expected = eye[None] + c20[:, None, None, None] * z20[None] + c40[:, None, None, None] * z40[None]
        inside = xx**2 + yy**2 <= (pupil / 2) ** 2
        assert w.shape == (2, 2, 31, 31)
        np.testing.assert_allclose(np.asarray(w)[:, inside], expected[:, inside], rtol=0, atol=2e-4)


def test_host_modes_equal_the_jax_modes_in_float64():
    """The host guards' NumPy modes are the traced modes, without JAX dispatch: equal to
    float32 rounding on and beyond the unit disk, in float64, for every mode to order 10."""
    x, y = _points(11, -1.2, 1.2)
    host = zernike.zernike_basis_host(66, x, y)
    assert host.dtype == np.float64 and host.shape == (66, N_POINTS)
    np.testing.assert_allclose(host, np.asarray(_basis66(x, y)), rtol=1e-5, atol=1e-4)
    np.testing.assert_array_equal(zernike.zernike_mode_host(12, x, y), host[12])
    with pytest.raises(ValueError, match="n_modes"):
        zernike.zernike_basis_host(0, x, y)
