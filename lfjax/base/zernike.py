"""OSA/ANSI Zernike polynomials (ANSI Z80.28), RMS-normalised, any radial order.

Index bookkeeping (``ansi_j`` ↔ ``(n, m)``) happens on the host with Python ints. The basis
is evaluated from Cartesian coordinates without ``arctan2``: ``ρ^|m| cos(mθ)`` is
``Re((X + iY)^|m|)``, a polynomial in X and Y, so values and gradients are finite everywhere,
including the pupil centre.
"""

from __future__ import annotations

import math
from functools import lru_cache

import jax.numpy as jnp
import numpy as np

from lfjax.base.types import FULL

MAX_RADIAL_ORDER = 20
"""Largest radial order accepted (the Thibos data go to order 10)."""


def nm_from_ansi(ansi_j: int) -> tuple[int, int]:
    """Radial order n and azimuthal frequency m of OSA/ANSI single index j (j = 0 is piston)."""
    ansi_j = int(ansi_j)
    if ansi_j < 0:
        raise ValueError(f"ansi_j must be >= 0, got {ansi_j}")
    n = int(math.ceil((-3.0 + math.sqrt(9.0 + 8.0 * ansi_j)) / 2.0))
    m = 2 * ansi_j - n * (n + 2)
    if n > MAX_RADIAL_ORDER:
        raise ValueError(
            f"ansi_j={ansi_j} has radial order n={n}; lfjax supports n <= {MAX_RADIAL_ORDER}"
        )
    return n, m


def ansi_from_nm(n: int, m: int) -> int:
    """OSA/ANSI single index j = (n(n+2)+m)/2 of Zernike mode (n, m)."""
    n, m = int(n), int(m)
    if n < 0 or abs(m) > n or (n - m) % 2:
        raise ValueError(f"invalid Zernike mode (n={n}, m={m}): need n >= |m| and n - m even")
    if n > MAX_RADIAL_ORDER:
        raise ValueError(f"radial order n={n} exceeds the supported {MAX_RADIAL_ORDER}")
    return (n * (n + 2) + m) // 2


def n_modes_for_order(max_radial_order: int) -> int:
    """Number of modes j = 0 … J−1 that complete radial order ``max_radial_order``."""
    return (max_radial_order + 1) * (max_radial_order + 2) // 2


def normalisation(n: int, m: int) -> float:
    """RMS normalisation sqrt(2(n+1)/(1+δ_m0))."""
    return math.sqrt(2.0 * (n + 1) / (1.0 + (m == 0)))


@lru_cache(maxsize=None)
def _radial_coefficients(n: int, m_abs: int) -> tuple[float, ...]:
    """Coefficients of R_n^m(ρ)/ρ^m as a polynomial in ρ², lowest power first."""
    k_max = (n - m_abs) // 2
    coeffs = [0.0] * (k_max + 1)
    for s in range(k_max + 1):
        value = (
            (-1) ** s
            * math.factorial(n - s)
            / (
                math.factorial(s)
                * math.factorial((n + m_abs) // 2 - s)
                * math.factorial((n - m_abs) // 2 - s)
            )
        )
        coeffs[k_max - s] = float(value)  # ρ^(n-2s) = ρ^m (ρ²)^(k_max - s)
    return tuple(coeffs)


def zernike_mode(ansi_j: int, x, y):
    """Zernike mode j at normalised pupil coordinates (x, y) = (X, Y)/R; any shape.

    Returns the RMS-normalised polynomial (unitless); it is not masked to the unit disk,
    so callers can evaluate the phase on every sample an anti-aliased edge touches.
    """
    return _zernike_mode(jnp, ansi_j, x, y)


def zernike_mode_host(ansi_j: int, x, y) -> np.ndarray:
    """:func:`zernike_mode` in float64 NumPy, for sizes worked out on the host before any
    program runs: eager JAX would dispatch (and compile) every operation of the
    polynomial one by one, about 80 ms a mode on a 65 × 65 grid against 0.1 ms here."""
    return _zernike_mode(np, ansi_j, np.asarray(x, np.float64), np.asarray(y, np.float64))


def _zernike_mode(xp, ansi_j: int, x, y):
    """:func:`zernike_mode` with the array namespace ``xp`` (``jax.numpy`` or ``numpy``)."""
    n, m = nm_from_ansi(ansi_j)
    m_abs = abs(m)
    rho2 = x * x + y * y
    radial = xp.zeros_like(rho2)
    for c in reversed(_radial_coefficients(n, m_abs)):  # Horner in ρ²
        radial = radial * rho2 + c
    if m_abs == 0:
        angular = xp.ones_like(rho2)
    else:
        z = (x + 1j * y) ** m_abs if m_abs > 1 else (x + 1j * y)
        angular = xp.real(z) if m > 0 else xp.imag(z)
    return normalisation(n, m) * radial * angular


def zernike_basis(n_modes: int, x, y):
    """Stack of modes j = 0 … n_modes−1 at normalised coordinates; shape (n_modes, *x.shape)."""
    if n_modes < 1:
        raise ValueError(f"n_modes must be >= 1, got {n_modes}")
    nm_from_ansi(n_modes - 1)  # validates the order
    return jnp.stack([zernike_mode(j, x, y) for j in range(n_modes)])


def zernike_basis_host(n_modes: int, x, y) -> np.ndarray:
    """:func:`zernike_basis` in float64 NumPy (:func:`zernike_mode_host`): for the host-side
    guards and plans, which size programs before any runs."""
    if n_modes < 1:
        raise ValueError(f"n_modes must be >= 1, got {n_modes}")
    nm_from_ansi(n_modes - 1)  # validates the order
    return np.stack([zernike_mode_host(j, x, y) for j in range(n_modes)])


def wavefront_um(coefficients_um, x, y):
    """Wavefront Σ_j c_j Z_j(x, y) in µm at normalised coordinates.

    ``coefficients_um`` has shape (n_modes,); x and y any (equal) shape.
    """
    n_modes = coefficients_um.shape[-1]
    basis = zernike_basis(n_modes, x, y)
    return jnp.tensordot(coefficients_um, basis, axes=([-1], [0]), precision=FULL)


@lru_cache(maxsize=None)
def monomial_coefficients(n_modes: int) -> np.ndarray:
    """Modes j = 0 … n_modes−1 as polynomials in x and y: array M of shape
    (n_modes, N+1, N+1), N the largest radial order, with Z_j(x, y) = Σ_pq M[j, p, q] x^p y^q.

    Built exactly (float64) from ``R_n^m(ρ)/ρ^m`` (a polynomial in ρ² = x² + y²) times
    ``Re``/``Im (x + iy)^|m|``. A polynomial on a rectangular sample grid is separable,
    ``W = Yᵀ A X`` with X[p, k] = x_k^p, which :func:`wavefront_on_grid` uses.
    """
    if n_modes < 1:
        raise ValueError(f"n_modes must be >= 1, got {n_modes}")
    order = nm_from_ansi(n_modes - 1)[0]
    out = np.zeros((n_modes, order + 1, order + 1))
    for j in range(n_modes):
        n, m = nm_from_ansi(j)
        m_abs = abs(m)
        radial = np.zeros((order + 1, order + 1))  # Σ_k c_k (x² + y²)^k
        for k, c in enumerate(_radial_coefficients(n, m_abs)):
            for i in range(k + 1):  # binomial expansion of (x² + y²)^k
                radial[2 * i, 2 * (k - i)] += c * math.comb(k, i)
        angular = np.zeros((order + 1, order + 1))  # Re or Im of (x + iy)^|m|
        for i in range(m_abs + 1):  # term C(m, i) x^(m−i) (iy)^i
            power = (1j) ** i * math.comb(m_abs, i)
            value = power.real if m >= 0 else power.imag
            angular[m_abs - i, i] += value
        product = np.zeros((order + 1, order + 1))
        for (p1, q1) in zip(*np.nonzero(radial)):
            for (p2, q2) in zip(*np.nonzero(angular)):
                product[p1 + p2, q1 + q2] += radial[p1, q1] * angular[p2, q2]
        out[j] = normalisation(n, m) * product
    return out


def powers_of(x, n: int):
    """x⁰ … x^(n−1) stacked on a new axis −2 (integer powers: exact signs, finite gradients)."""
    return jnp.stack([jnp.ones_like(x)] + [x**k for k in range(1, n)], axis=-2)


def wavefront_on_grid(monomials, x, y):
    """Σ_pq A[…, p, q] x^p y^q on the grid y × x: shape (…, len(y), len(x)).

    ``monomials`` (…, N+1, N+1) as from :func:`monomial_coefficients` contracted with
    coefficients; ``x`` (…, n_x) and ``y`` (…, n_y) 1-D coordinates (broadcast with the
    leading axes). Two small matrix products instead of N² polynomial terms per sample:
    the reverse pass then costs matrix products too (benchmarks/RESULTS.md §8).
    """
    x_pow = powers_of(x, monomials.shape[-1])  # (…, N+1, n_x)
    y_pow = powers_of(y, monomials.shape[-1])  # (…, N+1, n_y)
    return jnp.einsum("...qy,...pq,...px->...yx", y_pow, monomials, x_pow, precision=FULL)


def mirror_sign_vector(n_modes: int) -> np.ndarray:
    """Signs that mirror a coefficient vector x → −x (left eye ↔ right eye).

    Modes odd under x → −x (m > 0 with m odd, m < 0 with m even) change sign.
    """
    signs = np.ones(n_modes)
    for j in range(n_modes):
        _, m = nm_from_ansi(j)
        if (m > 0 and m % 2 == 1) or (m < 0 and m % 2 == 0):
            signs[j] = -1.0
    return signs


__all__ = [
    "MAX_RADIAL_ORDER",
    "nm_from_ansi",
    "ansi_from_nm",
    "n_modes_for_order",
    "normalisation",
    "zernike_mode",
    "zernike_mode_host",
    "zernike_basis",
    "zernike_basis_host",
    "wavefront_um",
    "monomial_coefficients",
    "wavefront_on_grid",
    "mirror_sign_vector",
]
