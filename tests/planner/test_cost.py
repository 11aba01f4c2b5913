"""The planner's cost model (lfjax.planner.cost): the FFT work by hand, and the modelled
seconds linear in the views and states, growing with the window, and cheaper for the MFT
path where its matrix products are small."""

from __future__ import annotations

import math

import pytest

from lfjax.base.sampling import Sampling
from lfjax.planner.cost import cost_s, fft_work


def test_fft_work_by_hand():
    # 4 views, one band of 2 wavelengths at n = 64: per wavelength a complex fft2 per view
    # (5 n² log2 n), per band one rfft2 (2.5 n² log2 n)
    n = 64
    want = 4 * n * n * math.log2(n) * (5.0 * 2 + 2.5)
    assert fft_work(((0, 2, n),), 4) == pytest.approx(want, rel=1e-15)
    assert fft_work(((0, 2, 64), (2, 5, 32)), 4) == pytest.approx(
        fft_work(((0, 2, 64),), 4) + fft_work(((0, 3, 32),), 4), rel=1e-15)


def test_cost_is_linear_in_views_and_states_and_grows_with_the_window():
    sampling = Sampling(1.0)
    bands = ((0, 3, 96),)
    one = cost_s(bands, 1, 1, 15, sampling)
    assert one > 0
    assert cost_s(bands, 4, 5, 15, sampling) == pytest.approx(20 * one, rel=1e-12)
    assert cost_s(((0, 3, 192),), 1, 1, 15, sampling) > one
    assert cost_s(((0, 2, 96), (2, 3, 64)), 1, 1, 15, sampling) < one


def test_the_mft_path_is_costed_by_its_pupil_samples():
    bands = ((0, 3, 256),)
    small = cost_s(bands, 4, 5, 15, Sampling(1.0, transform="mft", mft_pupil_samples=16))
    large = cost_s(bands, 4, 5, 15, Sampling(1.0, transform="mft", mft_pupil_samples=128))
    assert small < large
    assert small < cost_s(bands, 4, 5, 15, Sampling(1.0))
