"""Virtual eyes: Zernike coefficient vectors drawn from Thibos et al. (2002) statistics.

An :class:`Eyes` is a pytree with a leading batch axis (``zernike_um`` has shape
``(n_eyes, n_modes)``); the pupil diameter the coefficients were measured on travels with it.
"""

from __future__ import annotations

import math
from functools import lru_cache
from importlib import resources
from io import BytesIO

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from lfjax.base.errors import ParameterError
from lfjax.base.types import FULL, as_real_array, is_concrete
from lfjax.base.zernike import mirror_sign_vector, nm_from_ansi

THIBOS_PUPILS_MM = (3.0, 4.5, 6.0, 7.5)
"""Pupil diameters (mm) over which the Thibos et al. (2002) statistics were fitted."""

MAX_REFRACTION_D = 40.0
"""Largest refractive error (D, either sign) whose defocus coefficient bounds every Zernike
coefficient of an eye (:func:`max_coefficient_um`). The strongest refractive errors measured
in human eyes are about 30 D (pathological myopia); 40 D leaves margin. A real eye's
higher-order coefficients are far smaller than its defocus, so a coefficient beyond this is
a unit or data error (nm or mm for µm), not an eye: it would ask the field guard for an FFT
no machine holds."""


def max_coefficient_um(measured_pupil_mm: float) -> float:
    """The bound on |c_j| of any Zernike coefficient of an eye, µm: the defocus coefficient
    c(2,0) = D·R²/(4√3) of :data:`MAX_REFRACTION_D` dioptres on the measured pupil of radius
    R = ``measured_pupil_mm``/2 (mm): 13 µm on a 3 mm pupil, 81 µm on 7.5 mm."""
    radius = 0.5 * float(measured_pupil_mm)
    return MAX_REFRACTION_D * radius * radius / (4.0 * math.sqrt(3.0))


def check_coefficients(zernike_um, measured_pupil_mm: float) -> None:
    """Host check of concrete Zernike coefficients (µm, (n_eyes, n_modes)) on the measured
    pupil (mm): every one finite with |c| ≤ :func:`max_coefficient_um`; a
    :class:`~lfjax.base.errors.ParameterError` naming ``zernike_um``, its unit and range
    otherwise. Traced coefficients pass (checked where they are concrete)."""
    if not is_concrete(zernike_um):
        return
    z = np.asarray(zernike_um).reshape(-1, np.shape(zernike_um)[-1])
    bound = max_coefficient_um(measured_pupil_mm)
    infinite = ~np.isfinite(z)
    bad = infinite | (np.abs(z) > bound)
    if np.any(bad):
        eye, j = (int(i) for i in np.argwhere(infinite if np.any(infinite) else bad)[0])
        what = ("contains non-finite values (NaN or inf)" if np.any(infinite)
                else "has a coefficient beyond any human eye")
        raise ParameterError(
            "zernike_um", "{zernike_um} %s: got {got!r} µm at eye {eye}, ANSI j = {j} ({n} "
            "coefficient(s) outside); each must be finite with |c| <= {bound:.3g} µm on the "
            "{pupil:g} mm measured pupil (the defocus coefficient of a {refraction:g} D "
            "refractive error)" % what,
            bound=bound, pupil=float(measured_pupil_mm), refraction=MAX_REFRACTION_D,
            got=float(z[eye, j]), eye=eye, j=j, n=int(bad.sum()))


class Eyes(eqx.Module):
    """A batch of eyes.

    Attributes
    ----------
    zernike_um : array, shape (n_eyes, n_modes), µm
        OSA/ANSI RMS-normalised Zernike coefficients, j = 0 … n_modes−1.
    measured_pupil_mm : float
        Diameter (mm) of the pupil the coefficients are defined on (static).
    orientation : str
        ``"left"`` or ``"right"`` eye coordinates (static; x right, y up, seen from the eye).
    """

    zernike_um: jnp.ndarray = eqx.field(converter=as_real_array)
    measured_pupil_mm: float = eqx.field(static=True, converter=float)
    orientation: str = eqx.field(static=True, default="left")

    def __check_init__(self):
        if self.zernike_um.ndim != 2:
            raise ValueError(
                f"Eyes.zernike_um must have shape (n_eyes, n_modes), got {self.zernike_um.shape}"
            )
        if self.zernike_um.shape[0] < 1:
            raise ValueError(
                f"Eyes.zernike_um must hold at least one eye (a row), got shape "
                f"{self.zernike_um.shape}"
            )
        nm_from_ansi(self.zernike_um.shape[1] - 1)  # raises for unsupported orders
        if not (math.isfinite(self.measured_pupil_mm) and self.measured_pupil_mm > 0):
            raise ParameterError("measured_pupil_mm", "{measured_pupil_mm} must be finite and > 0 "
                                 "mm, got {got!r}", owner="Eyes", got=self.measured_pupil_mm)
        if self.orientation not in ("left", "right"):
            raise ValueError(f"orientation must be 'left' or 'right', got {self.orientation!r}")
        check_coefficients(self.zernike_um, self.measured_pupil_mm)

    @property
    def n_eyes(self) -> int:
        return int(self.zernike_um.shape[0])

    @property
    def n_modes(self) -> int:
        return int(self.zernike_um.shape[1])

    def __getitem__(self, index) -> Eyes:
        """Sub-batch (keeps the batch axis: ``eyes[3]`` has one eye)."""
        z = self.zernike_um[index]
        if z.ndim == 1:
            z = z[None]
        return Eyes(z, self.measured_pupil_mm, self.orientation)

    def mirrored(self) -> Eyes:
        """The same eyes in the other orientation (left ↔ right, x → −x)."""
        signs = jnp.asarray(mirror_sign_vector(self.n_modes), self.zernike_um.dtype)
        other = "right" if self.orientation == "left" else "left"
        return Eyes(self.zernike_um * signs, self.measured_pupil_mm, other)

    def without_piston_tilt(self) -> Eyes:
        """Copy with j = 0, 1, 2 set to zero."""
        return Eyes(
            self.zernike_um.at[:, :3].set(0.0), self.measured_pupil_mm, self.orientation
        )


def check_eyes(eyes, name: str = "eyes") -> Eyes:
    """``eyes`` if it is an :class:`Eyes`; a clear TypeError otherwise (a plain list or array
    of coefficients does not say which pupil it was measured on)."""
    if not isinstance(eyes, Eyes):
        raise TypeError(
            f"{name} must be an lfjax.Eyes, got {type(eyes).__name__}: build one with "
            f"lfjax.sample_eyes(seed, n_eyes), lfjax.average_eye() or "
            f"lfjax.model.eyes.make_eyes(coefficients_um, measured_pupil_mm)"
        )
    return eyes


MAX_SAMPLED_EYES = 2**26
"""Most eyes one :func:`sample_eyes` call draws (67 million; 45 float64 coefficients each
are 24 GiB): a larger population is drawn in parts (seeds) or chunks."""


def make_eyes(zernike_um, measured_pupil_mm: float, orientation: str = "left") -> Eyes:
    """Eyes from coefficients, µm, shape (n_modes,) or (n_eyes, n_modes), measured on a pupil
    of ``measured_pupil_mm`` (mm); each coefficient finite and within
    :func:`max_coefficient_um` (checked on the host, before any tracing)."""
    z = np.asarray(zernike_um, dtype=float)
    if z.ndim == 1:
        z = z[None]
    check_coefficients(z, measured_pupil_mm)  # float64, before float32 rounds 1e39 to inf
    return Eyes(jnp.asarray(z), float(measured_pupil_mm), orientation)


def aberration_free_eye(measured_pupil_mm: float = 3.0, n_modes: int = 15) -> Eyes:
    """One eye with every coefficient zero (diffraction-limited apart from SA, LCA and SCE)."""
    return Eyes(jnp.zeros((1, n_modes)), float(measured_pupil_mm))


@lru_cache(maxsize=1)
def _thibos_npz() -> dict:
    raw = resources.files("lfjax").joinpath("data/thibos2002_statistics.npz").read_bytes()
    with np.load(BytesIO(raw)) as f:
        return {k: f[k] for k in f.files}


def _check_thibos_pupil(measured_pupil_mm: float) -> str:
    for p in THIBOS_PUPILS_MM:
        if abs(float(measured_pupil_mm) - p) < 1e-9:
            return f"{p:.1f}"
    raise ValueError(
        f"measured_pupil_mm must be one of {THIBOS_PUPILS_MM} (the Thibos et al. 2002 fits), "
        f"got {measured_pupil_mm}"
    )


def thibos_statistics(measured_pupil_mm: float = 3.0) -> tuple[np.ndarray, np.ndarray, int]:
    """Mean (µm), covariance (µm²) and eye count of Thibos et al. (2002), left-eye orientation.

    Reference: Thibos, Bradley & Hong (2002), Ophthalmic Physiol Opt 22:427–433 (Indiana
    Aberration Study; data as distributed with ISETBio). Research-use licence: see
    ``lfjax/data/README.md``.
    """
    key = _check_thibos_pupil(measured_pupil_mm)
    data = _thibos_npz()
    return (
        data[f"mean_um_{key}mm"].copy(),
        data[f"covariance_um2_{key}mm"].copy(),
        int(data[f"n_eyes_{key}mm"]),
    )


def average_eye(
    measured_pupil_mm: float = 3.0, orientation: str = "left", zero_piston_tilt: bool = True
) -> Eyes:
    """The population-mean eye of Thibos et al. (2002) as a batch of one.

    Examples
    --------
    >>> import lfjax
    >>> lfjax.average_eye(3.0).zernike_um.shape  # one eye, 15 OSA/ANSI modes, µm
    (1, 15)
    """
    mean, _, _ = thibos_statistics(measured_pupil_mm)
    eyes = make_eyes(mean, measured_pupil_mm)
    if zero_piston_tilt:
        eyes = eyes.without_piston_tilt()
    return eyes.mirrored() if orientation == "right" else eyes


def append_average_eye(eyes: Eyes) -> Eyes:
    """``eyes`` with the Thibos et al. (2002) average eye of their measured pupil appended
    as the last eye (the batch the reproduction and population sweeps evaluate)."""
    avg = average_eye(eyes.measured_pupil_mm)
    return Eyes(jnp.concatenate([eyes.zernike_um, avg.zernike_um.astype(eyes.zernike_um.dtype)]),
                eyes.measured_pupil_mm, eyes.orientation)


def sample_eyes(
    key,
    n_eyes: int,
    measured_pupil_mm: float = 3.0,
    orientation: str = "left",
    zero_piston_tilt: bool = True,
) -> Eyes:
    """Seeded virtual eyes drawn from the multivariate normal model of Thibos et al. (2002).

    Parameters
    ----------
    key : jax PRNG key or int seed
    n_eyes : int, >= 1
    measured_pupil_mm : 3.0, 4.5, 6.0 or 7.5
        Which fit to sample (the coefficients are defined over this pupil).
    orientation : "left" (the data's orientation) or "right" (mirrored).
    zero_piston_tilt : bool
        Zero j = 0, 1, 2 after sampling (they do not change image quality).

    The draw is ``mean + L z`` with ``L`` the Cholesky factor of the covariance (computed
    in float64 on the host) and ``z`` standard normal from ``key`` (drawn in float32): same
    key, same eyes, in float32 and float64 alike.

    Examples
    --------
    >>> import lfjax
    >>> eyes = lfjax.sample_eyes(0, 10, measured_pupil_mm=3.0)
    >>> eyes.zernike_um.shape  # 10 eyes, 15 OSA/ANSI modes, µm on the 3 mm pupil
    (10, 15)
    >>> bool((lfjax.sample_eyes(0, 10).zernike_um == eyes.zernike_um).all())  # same seed
    True
    """
    if isinstance(n_eyes, bool) or int(n_eyes) != n_eyes or n_eyes < 1:
        raise ValueError(f"n_eyes must be an integer >= 1, got {n_eyes}")
    if n_eyes > MAX_SAMPLED_EYES:
        raise ValueError(
            f"n_eyes must be <= {MAX_SAMPLED_EYES} per call (their coefficients alone would "
            f"take {int(n_eyes) * 45 * 8 / 2**30:.3g} GiB in float64), got {n_eyes}"
        )
    if isinstance(key, (int, np.integer)) and not isinstance(key, bool):
        # jax.random.key folds an int seed modulo 2**32 (-1 draws the eyes of 2**32 - 1),
        # so only [0, 2**32) names a draw uniquely, as the command line's --seed does
        if not 0 <= int(key) < 2**32:
            raise ValueError(f"seed (key) must be in [0, 2**32), got {key}")
        key = jax.random.key(int(key))
    mean, cov, _ = thibos_statistics(measured_pupil_mm)
    chol = np.linalg.cholesky(cov)
    # Draw in float32 whatever the precision, so a seed gives the same eyes with and without
    # jax_enable_x64 (float64 draws would be different random numbers).
    z = jax.random.normal(key, (int(n_eyes), mean.size), dtype=jnp.float32)
    z = z.astype(jnp.result_type(float))
    coeffs = jnp.asarray(mean) + jnp.matmul(z, jnp.asarray(chol).T, precision=FULL)
    eyes = Eyes(coeffs, float(measured_pupil_mm))
    if zero_piston_tilt:
        eyes = eyes.without_piston_tilt()
    return eyes.mirrored() if orientation == "right" else eyes


__all__ = [
    "THIBOS_PUPILS_MM",
    "Eyes",
    "MAX_SAMPLED_EYES",
    "MAX_REFRACTION_D",
    "max_coefficient_um",
    "check_coefficients",
    "check_eyes",
    "make_eyes",
    "aberration_free_eye",
    "thibos_statistics",
    "average_eye",
    "append_average_eye",
    "sample_eyes",
]
