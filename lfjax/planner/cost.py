"""The planner's cost model: the modelled seconds per eye of a sampling, and its FFT work.

Only the ratio of the FFT and MFT paths' costs matters (``transform="auto"`` picks the
cheaper); benchmarks/speed/speed_accuracy.py re-measures it.
"""

from __future__ import annotations

import math

from lfjax.base.sampling import Sampling
from lfjax.kernel.optics import pupil_window_size

# Cost model: seconds per eye = FFT flops / R_fft + matrix-product flops / R_mm + pupil
# samples evaluated × t_pupil. Calibrated by least squares on four warm pipeline runs on
# the 2-core reference machine (2×2 and 4×4, FFT and MFT, 31 λ, 21 states, 3 eyes; fit within
# 8 %); small transforms run well below the rate of large FFTs on this machine. Only the ratio
# of the two paths matters for the choice, and benchmarks/speed/speed_accuracy.py re-measures it.
_FFT_FLOPS_PER_S = 4.1e9
_MATMUL_FLOPS_PER_S = 92e9
_PUPIL_S_PER_SAMPLE = 17e-9


def fft_work(bands, n_sub: int) -> float:
    """Relative FFT work per eye and state: per wavelength one complex fft2 of the pupil field
    per view (5 n² log2 n), per band one real rfft2 of the band's summed PSFs (2.5 n² log2 n)."""
    return float(sum(n_sub * n**2 * math.log2(n) * (5.0 * (b - a) + 2.5) for a, b, n in bands))


def cost_s(bands, n_sub: int, n_states: int, n_modes: int, sampling: Sampling) -> float:
    """Modelled seconds per eye: transforms + pupil evaluation, per band (see module). Each
    wavelength pays its pupil field and its transform to the PSF; each band one rfft2 of its
    summed PSFs (optics._elemental_otfs_band)."""
    total = 0.0
    for start, stop, n in bands:
        n_wl = stop - start
        log = math.log2(n)
        otf_fft = 2.5 * n * n * log / _FFT_FLOPS_PER_S  # once per band
        if sampling.transform == "mft":
            m = sampling.mft_pupil_samples
            per_wavelength = 8.0 * n * m * (m + n) / _MATMUL_FLOPS_PER_S
            pupil = m * m
        else:
            per_wavelength = 5.0 * n * n * log / _FFT_FLOPS_PER_S
            pupil = pupil_window_size(n, sampling) ** 2
        per_wavelength += pupil * _PUPIL_S_PER_SAMPLE
        total += n_sub * n_states * (n_wl * per_wavelength + otf_fft)
    return total


__all__ = ["fft_work", "cost_s"]
