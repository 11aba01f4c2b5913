"""The common frequency grid and its guards (lfjax.base.sampling): fast FFT sizes, window
sizes that hold the OTF's support, wavelength bands, the blur radius against its geometric
and Airy terms by hand, the aliasing guard and its retry step, the frequency axes, and the
eyes' wavefront slope against the defocus term's analytic gradient. Host only (NumPy)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from lfjax.base.errors import ParameterError
from lfjax.base.sampling import (
    AliasingError,
    Sampling,
    blur_radius_arcmin,
    check_field,
    eye_slope_rad,
    finer_step,
    frequencies_cpd,
    half_frequencies_cpd,
    next_fast_size,
    wavelength_bands,
)
from lfjax.base.units import ARCMIN_PER_RADIAN, DEGREES_PER_RADIAN


def _smooth(n):
    for p in (2, 3, 5):
        while n % p == 0:
            n //= p
    return n == 1


def test_next_fast_size_is_the_smallest_even_5_smooth_size():
    for n in range(0, 400):
        want = next(m for m in range(max(n, 2), 4 * n + 4) if m % 2 == 0 and _smooth(m))
        assert next_fast_size(n) == want, n


@pytest.mark.parametrize("changes, words", [
    ({"freq_step_cpd": 0.0}, "freq_step_cpd must be > 0 cpd"),
    ({"freq_step_cpd": math.nan}, "freq_step_cpd must be > 0 cpd"),
    ({"n_fft": 7}, "n_fft must be an integer >= 8"),
    ({"transform": "dft"}, "transform must be 'fft' or 'mft'"),
    ({"mft_pupil_samples": 8}, "mft_pupil_samples must be an integer >= 16"),
    ({"edge_width_samples": 5.0}, "edge_width_samples must be in 0.05–4"),
])
def test_bad_sampling_is_refused_naming_the_field(changes, words):
    with pytest.raises(ValueError, match=words):
        Sampling(**changes)


def test_a_bad_step_is_a_parameter_error():
    with pytest.raises(ParameterError) as info:
        Sampling(freq_step_cpd=-1.0)
    assert info.value.parameter == "freq_step_cpd"


def test_window_holds_the_otf_support_and_is_fast():
    sampling = Sampling(1.0)
    assert sampling.field_arcmin == 60.0 and sampling.pixel_arcmin(120) == 0.5
    # 3 mm at 400 nm, 1 cpd: d / (λ df) pupil samples, twice that (the OTF's support) + edges
    samples = 3.0 / (400e-6 * DEGREES_PER_RADIAN)
    needed = 2 * (samples + 2 * 6.0 * 0.25) + 1
    size = sampling.window_size(3.0, 400.0, 3.0)
    assert size >= needed and size == next_fast_size(math.ceil(needed))
    # a half-size subaperture needs a smaller window
    assert sampling.window_size(1.5, 400.0, 3.0) < size


def test_a_fixed_n_fft_too_small_is_refused_with_the_size_it_needs():
    with pytest.raises(ValueError, match=r"n_fft=64 cannot hold .* need n_fft >= 2\d\d"):
        Sampling(1.0, n_fft=64).window_size(3.0, 400.0, 3.0)


def test_wavelength_bands_partition_the_axis_and_never_cost_more_than_one_band():
    sampling = Sampling(1.0)
    wl = np.arange(400.0, 701.0, 25.0)
    bands = wavelength_bands(wl, 3.0, 3.0, sampling)
    assert 1 <= len(bands) <= 3
    assert bands[0][0] == 0 and bands[-1][1] == wl.size
    assert all(b[1] == c[0] for b, c in zip(bands[:-1], bands[1:]))
    sizes = [n for _, _, n in bands]
    assert sizes == sorted(sizes, reverse=True)  # longer wavelengths, smaller windows
    for a, b, n in bands:
        assert n == max(sampling.window_size(3.0, w, 3.0) for w in wl[a:b])

    def cost(bs):
        return sum((b - a) * n**2 * math.log2(n) for a, b, n in bs)
    one = ((0, wl.size, sampling.window_size(3.0, 400.0, 3.0)),)
    assert cost(bands) <= cost(one)
    assert wavelength_bands(wl, 3.0, 3.0, Sampling(1.0, n_fft=300)) == ((0, wl.size, 300),)


def test_blur_radius_by_hand():
    # one 1 mm subaperture at the pupil's centre, 1 D of defocus, no display shift:
    # geometric half-width |D| d/2 = 0.5 mrad, plus three Airy radii at 550 nm
    got = blur_radius_arcmin(3.0, np.zeros((1, 2)), np.array([1.0]), np.array([1.0]),
                             np.array([0.0]), 550.0)
    want = (0.5e-3 + 3 * 1.22 * 550e-6 / 1.0) * ARCMIN_PER_RADIAN
    assert got == pytest.approx(want, rel=1e-12)
    # a display shift of 2 D on a view 1 mm off centre moves its disc by 2 mrad
    shifted = blur_radius_arcmin(3.0, np.array([[1.0, 0.0]]), np.array([1.0]), np.array([0.0]),
                                 np.array([2.0]), 550.0)
    assert shifted == pytest.approx((2e-3 + 3 * 1.22 * 550e-6) * ARCMIN_PER_RADIAN, rel=1e-12)


def test_check_field_refuses_a_wrapping_blur_and_says_the_step_to_use():
    sampling = Sampling(2.0)  # field ±15 arcmin
    check_field(sampling, 15.0, "the blur")
    with pytest.raises(AliasingError, match="use freq_step_cpd <= 1.2") as info:
        check_field(sampling, 25.0, "the blur")
    err = info.value
    assert (err.freq_step_cpd, err.max_freq_step_cpd, err.radius_arcmin) == (2.0, 1.2, 25.0)
    assert finer_step(err, 2.0) == 1.2
    # rounding down to 0.05 cpd; 90 % of the current step when that would not shrink it
    assert finer_step(AliasingError("", 2.0, 0.437, 0.0), 2.0) == 0.4
    assert finer_step(AliasingError("", 2.0, 3.0, 0.0), 2.0) == 1.8


def test_frequency_axes():
    np.testing.assert_array_equal(np.asarray(frequencies_cpd(8, 2.0)),
                                  [0, 2, 4, 6, -8, -6, -4, -2])
    np.testing.assert_array_equal(np.asarray(half_frequencies_cpd(8, 2.0)), [0, 2, 4, 6, 8])


def test_eye_slope_is_the_defocus_terms_gradient_and_ignores_tilt():
    # OSA j=4: W = c √3 (2ρ² − 1), ρ = r / R_measured: |∇W| = 4 √3 c r / R², largest at
    # the calculation pupil's edge (the 48-point grid's inside points reach within one
    # step of it; central differences of a quadratic are exact)
    c_um, measured, pupil = 0.5, 6.0, 4.0
    z = np.zeros((1, 15))
    z[0, 4] = c_um
    edge = 4 * math.sqrt(3) * c_um * (pupil / 2) / (measured / 2) ** 2 * 1e-3
    got = eye_slope_rad(z, measured, pupil)
    assert 0.95 * edge <= got <= edge * (1 + 1e-12)
    tilted = z.copy()
    tilted[0, 1:3] = 3.0
    assert eye_slope_rad(tilted, measured, pupil) == got
