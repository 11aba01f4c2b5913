"""Population sampling of viewers: pairs of eyes and their interpupillary distances.

A viewer's left eye is the eye :func:`lfjax.sample_eyes` draws from Thibos et al. (2002)
for the same key (bit for bit); the right eye is that eye mirrored (x → −x: the modes odd
in x change sign, the enantiomorphism Porter et al. 2001 and Thibos et al. 2002 describe),
optionally decorrelated from it, plus a difference in spherical equivalent (anisometropia).
The interpupillary distance is drawn from the adult statistics Dodgson (2004) gathered.
Every published number comes from ``lfjax/data/binocular_statistics.csv``.
"""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np

from lfjax.base.errors import ParameterError
from lfjax.base.types import FULL
from lfjax.base.zernike import ansi_from_nm
from lfjax.binocular.viewer import Viewer, binocular_statistics, ipd_range_mm
from lfjax.model.eyes import Eyes, sample_eyes, thibos_statistics

DEFOCUS_J = ansi_from_nm(2, 0)
"""OSA/ANSI index of defocus Z(2, 0)."""


def spherical_equivalent_per_um(measured_pupil_mm: float) -> float:
    """Spherical equivalent (D) of 1 µm of Zernike defocus c(2,0) on a pupil of diameter
    ``measured_pupil_mm``: M = −4√3 c(2,0) / r², r the pupil radius in mm (the power-vector
    refraction of Thibos, Hong, Bradley & Applegate 2004, J Vis 4(4):329–351; positive
    c(2,0) is myopic: such an eye accommodates less for the same point)."""
    radius = 0.5 * float(measured_pupil_mm)
    return -4.0 * math.sqrt(3.0) / radius**2


def anisometropia_weibull() -> tuple[float, float]:
    """Shape k and scale b (D) of the Weibull law P(|ΔM| ≥ t) = exp(−(t/b)^k) of the
    between-eye difference in spherical equivalent, passed exactly through the two published
    adult prevalences (≥ 1 D: 8.43 %, ≥ 2 D: 2.22 %, KNHANES 2010; lfjax/data/README.md).

    Two points fix two parameters; the law is the choice (a normal law through the first
    point would put 0.06 % beyond 2 D, forty times fewer than were found)."""
    stats = binocular_statistics()
    l1 = -math.log(stats["anisometropia_1D_prevalence"])
    l2 = -math.log(stats["anisometropia_2D_prevalence"])
    k = math.log(l2 / l1) / math.log(2.0)
    b = l1 ** (-1.0 / k)
    return k, b


def _check_sampling(n_viewers, fellow_correlation, ipd_mean_mm, ipd_sd_mm, anisometropia_D):
    if isinstance(n_viewers, bool) or int(n_viewers) != n_viewers or n_viewers < 1:
        raise ParameterError("n_viewers", "{n_viewers} must be an integer >= 1, got {got}",
                             got=n_viewers)
    if not (0.0 <= float(fellow_correlation) <= 1.0):
        raise ParameterError("fellow_correlation", "{fellow_correlation} must lie in [0, 1] "
                             "(unitless), got {got}", got=fellow_correlation)
    low, high = ipd_range_mm()
    if not (low <= float(ipd_mean_mm) <= high):
        raise ParameterError("ipd_mean_mm", "{ipd_mean_mm} must lie in [{low:g}, {high:g}] mm, "
                             "got {got}", low=low, high=high, got=ipd_mean_mm)
    if not (0.0 <= float(ipd_sd_mm) <= 10.0):
        raise ParameterError("ipd_sd_mm", "{ipd_sd_mm} must lie in [0, 10] mm, got {got}",
                             got=ipd_sd_mm)
    if anisometropia_D != "population" and not (
            isinstance(anisometropia_D, (int, float)) and abs(float(anisometropia_D)) <= 5.0):
        raise ParameterError("anisometropia_D", "{anisometropia_D} must be 'population' or a "
                             "number of dioptres in [-5, 5] D, got {got!r}", got=anisometropia_D)


def sample_viewers(
    key,
    n_viewers: int,
    measured_pupil_mm: float = 3.0,
    *,
    anisometropia_D: float | str = "population",
    fellow_correlation: float = 1.0,
    ipd_mean_mm: float | None = None,
    ipd_sd_mm: float | None = None,
) -> Viewer:
    """Seeded viewers drawn from the population statistics.

    Parameters
    ----------
    key : jax PRNG key or int seed in [0, 2**32)
    n_viewers : int, >= 1
    measured_pupil_mm : 3.0, 4.5, 6.0 or 7.5 (the Thibos et al. 2002 fits)
    anisometropia_D : ``"population"`` (default): the right eye's spherical equivalent minus
        the left eye's, ΔM, is drawn from :func:`anisometropia_weibull` with a random sign;
        a number: that ΔM (D) for every viewer (0: isometropic pairs). It is added to the
        right eye's defocus c(2,0) (:func:`spherical_equivalent_per_um`), so the left eye
        stays the :func:`lfjax.sample_eyes` draw.
    fellow_correlation : ρ in [0, 1], unitless: every mode but defocus of the right eye is
        mirror(μ + ρ (left − μ) + √(1−ρ²) L z'), μ and L the Thibos mean and Cholesky factor
        and z' standard normal, so each eye keeps the population's statistics. Default 1:
        exact mirror images (Thibos et al. 2002 give no fellow-eye covariance; Porter et al.
        2001 found fellow eyes' aberrations strongly mirror-symmetric — 1 is that
        idealisation, not a measured value). The right eye's defocus is the mirrored left
        defocus plus the anisometropia, whatever ρ.
    ipd_mean_mm, ipd_sd_mm : normal law of the interpupillary distance, mm; default the
        adult values of Dodgson (2004) (63.36 mm, 3.832 mm); draws are clipped to the
        accepted range 45–80 mm (about 5 SD from the mean).

    Returns
    -------
    :class:`~lfjax.binocular.viewer.Viewer` of ``n_viewers``. The left eyes are
    ``sample_eyes(key, n_viewers, measured_pupil_mm)``; the other draws use keys folded from
    ``key`` (1: IPD, 2: anisometropia, 3: fellow-eye decorrelation).
    """
    stats = binocular_statistics()
    ipd_mean_mm = stats["ipd_mean_mm"] if ipd_mean_mm is None else ipd_mean_mm
    ipd_sd_mm = stats["ipd_sd_mm"] if ipd_sd_mm is None else ipd_sd_mm
    _check_sampling(n_viewers, fellow_correlation, ipd_mean_mm, ipd_sd_mm, anisometropia_D)
    if isinstance(key, (int, np.integer)) and not isinstance(key, bool):
        if not 0 <= int(key) < 2**32:
            raise ParameterError("key", "{key} (seed) must be in [0, 2**32), got {got}", got=key)
        key = jax.random.key(int(key))
    n = int(n_viewers)
    left = sample_eyes(key, n, measured_pupil_mm)
    z_left = left.zernike_um
    mean, cov, _ = thibos_statistics(measured_pupil_mm)
    rho = float(fellow_correlation)
    if rho < 1.0:
        chol = jnp.asarray(np.linalg.cholesky(cov))
        z = jax.random.normal(jax.random.fold_in(key, 3), (n, mean.size), jnp.float32)
        fresh = jnp.matmul(z.astype(z_left.dtype), chol.T, precision=FULL)
        fellow = jnp.asarray(mean) + rho * (z_left - jnp.asarray(mean)) + math.sqrt(
            1.0 - rho * rho) * fresh
        fellow = fellow.at[:, :3].set(0.0).at[:, DEFOCUS_J].set(z_left[:, DEFOCUS_J])
    else:
        fellow = z_left
    right = Eyes(fellow, left.measured_pupil_mm, "left").mirrored()
    delta_se = _anisometropia(key, n, anisometropia_D, z_left.dtype)
    delta_c20 = delta_se / spherical_equivalent_per_um(measured_pupil_mm)
    right = Eyes(right.zernike_um.at[:, DEFOCUS_J].add(delta_c20), left.measured_pupil_mm,
                 "right")
    ipd = ipd_mean_mm + ipd_sd_mm * jax.random.normal(jax.random.fold_in(key, 1), (n,),
                                                      jnp.float32).astype(z_left.dtype)
    low, high = ipd_range_mm()
    return Viewer(left, right, jnp.clip(ipd, low, high))


def _anisometropia(key, n: int, anisometropia_D, dtype):
    """ΔM (D), shape (n,): the fixed value, or Weibull magnitudes with random signs."""
    if anisometropia_D != "population":
        return jnp.full((n,), float(anisometropia_D), dtype)
    k, b = anisometropia_weibull()
    u_key, s_key = jax.random.split(jax.random.fold_in(key, 2))
    u = jax.random.uniform(u_key, (n,), jnp.float32, minval=1e-7, maxval=1.0).astype(dtype)
    magnitude = b * (-jnp.log(u)) ** (1.0 / k)
    sign = jnp.where(jax.random.bernoulli(s_key, 0.5, (n,)), 1.0, -1.0).astype(dtype)
    return sign * magnitude


__all__ = ["sample_viewers", "anisometropia_weibull", "spherical_equivalent_per_um",
           "DEFOCUS_J"]
