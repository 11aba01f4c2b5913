"""Image-quality metrics (lfjax.kernel.metrics): NCSF models, VSOTF, Strehl, radial MTF, cut-off."""

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import helpers as H
from lfjax.kernel import metrics

# Jitted entry points: eager jax compiles every primitive separately (slow on 2 cores).
_ncsf = jax.jit(metrics.ncsf, static_argnums=2)
_cutoff = jax.jit(metrics.cutoff_frequency, static_argnums=2)
_dl_mtf = jax.jit(metrics.diffraction_limited_mtf, static_argnums=(1, 2))

# ----------------------------------------------------------------------------- NCSF


def _watson_ahumada(f):
    sech = lambda x: 1.0 / np.cosh(x)  # noqa: E731
    return 373.08 * (sech((f / 4.1726) ** 0.7786) - 0.8493 * sech(f / 1.3625))


def test_watson_ahumada_values_on_axis():
    """S(f) = 373.08 [sech((f/4.1726)^0.7786) − 0.8493 sech(f/1.3625)] (docs/design.md#modelling-choices) along
    both axes (no oblique loss at 0° and 90°); S(0) = 373.08·0.1507."""
    f = np.array([0.0, 0.5, 1.0, 2.0, 3.0, 4.0, 8.0, 16.0, 32.0, 60.0])
    want = _watson_ahumada(f)
    np.testing.assert_allclose(_ncsf(jnp.asarray(f), jnp.zeros_like(f)), want,
                               rtol=1e-13)
    np.testing.assert_allclose(_ncsf(jnp.zeros_like(f), jnp.asarray(-f)), want,
                               rtol=1e-13)
    assert float(_ncsf(0.0, 0.0)) == pytest.approx(373.08 * (1 - 0.8493), rel=1e-13)
    # band-pass: peak between 2 and 6 cpd
    g = np.linspace(0.1, 30, 600)
    assert 2.0 < g[np.argmax(_watson_ahumada(g))] < 6.0


def test_watson_ahumada_oblique_effect():
    """Above 3.481 cpd sensitivity at 45° is lower by 1 − exp(−(f − 3.481)/13.57149)
    (sin² 2θ = 1); at 22.5° by half that; at or below 3.481 cpd no orientation effect."""
    for f in (1.0, 3.0, 3.481):
        c, s = f / math.sqrt(2), f / math.sqrt(2)
        assert float(_ncsf(c, s)) == pytest.approx(float(_ncsf(f, 0.0)),
                                                          rel=1e-12)
    for f in (4.0, 10.0, 30.0):
        loss = 1 - math.exp(-(f - 3.481) / 13.57149)
        at0 = float(_ncsf(f, 0.0))
        at45 = float(_ncsf(f / math.sqrt(2), -f / math.sqrt(2)))
        at22 = float(_ncsf(f * math.cos(math.pi / 8), f * math.sin(math.pi / 8)))
        assert at45 / at0 == pytest.approx(1 - loss, rel=1e-12)
        assert at22 / at0 == pytest.approx(1 - 0.5 * loss, rel=1e-12)
        assert at45 < at22 < at0


def test_campbell_green():
    """log10 S = 2.8876e-8 f⁵ − 5.2957e-6 f⁴ + 3.5818e-4 f³ − 1.1241e-2 f² + 0.12704 f +
    1.8636, radially symmetric, zero above 64 cpd."""
    f = np.array([0.0, 1.0, 5.0, 20.0, 40.0, 64.0])
    log_s = (2.8876e-8 * f**5 - 5.2957e-6 * f**4 + 3.5818e-4 * f**3 - 1.1241e-2 * f**2
             + 0.12704 * f + 1.8636)
    got = _ncsf(jnp.asarray(f), jnp.zeros_like(f), "campbell_green_2004")
    np.testing.assert_allclose(got, 10.0**log_s, rtol=1e-12)
    diag = _ncsf(jnp.asarray(f / math.sqrt(2)), jnp.asarray(f / math.sqrt(2)),
                        "campbell_green_2004")
    np.testing.assert_allclose(diag, got, rtol=1e-12)
    above = _ncsf(jnp.asarray([64.01, 70.0, 100.0]), jnp.zeros(3), "campbell_green_2004")
    np.testing.assert_array_equal(above, 0.0)
    with pytest.raises(ValueError, match="ncsf model"):
        _ncsf(1.0, 0.0, "barten")


# ----------------------------------------------------------------------------- half plane


def _random_otf(n, seed):
    """Normalised OTF of a random non-negative real PSF: full plane and half plane."""
    psf = np.asarray(jax.random.uniform(jax.random.key(seed), (n, n))) ** 4
    full = np.fft.fft2(psf) / psf.sum()
    return full, jnp.asarray(full[:, : n // 2 + 1])


@pytest.mark.parametrize("n", [15, 16])
def test_half_plane_sums_equal_full_plane_sums(n):
    """VSOTF numerator, PSF peak and radial MTF on the rfft half plane equal the numpy
    full-plane computations (Hermitian multiplicities, odd and even L)."""
    df = 3.0
    full, half = _random_otf(n, n)
    k = H.fft_index(n) * df
    fx, fy = np.meshgrid(k, k)
    ncsf_full = np.asarray(_ncsf(jnp.asarray(fx), jnp.asarray(fy)))
    num = np.sum(ncsf_full * full.real)
    got = metrics.vsotf_numerator(half, metrics.ncsf_half_plane(n, df))
    assert float(got) == pytest.approx(num, rel=1e-12)
    # Σ Im OTF·NCSF vanishes for a symmetric NCSF (docs/design.md#the-model-stage-by-stage, stage 8)
    assert abs(np.sum(ncsf_full * full.imag)) < 1e-10 * abs(num)
    full2, half2 = _random_otf(n, n + 100)
    vs = metrics.vsotf(half, half2, n, df)
    assert float(vs) == pytest.approx(num / np.sum(ncsf_full * full2.real), rel=1e-12)
    assert float(metrics.vsotf(half, half, n, df)) == pytest.approx(1.0, abs=1e-14)
    # PSF peak: density per arcmin² = max(ifft2(OTF)) · L² (df/60)²
    peak = np.real(np.fft.ifft2(full)).max() * n * n * (df / 60) ** 2
    assert float(metrics.psf_peak(half, n, df)) == pytest.approx(peak, rel=1e-12)
    sr = metrics.strehl_ratio(half, half2, n, df)
    assert float(sr) == pytest.approx(peak / (np.real(np.fft.ifft2(full2)).max() * n * n
                                              * (df / 60) ** 2), rel=1e-12)
    # radial MTF: mean of |OTF| over full-plane samples with rint(|k|) = bin
    radial, freq = metrics.radial_mtf(half, n, df)
    r = np.rint(np.hypot(*np.meshgrid(H.fft_index(n), H.fft_index(n)))).astype(int)
    want = [np.abs(full)[r == b].mean() for b in range(n // 2 + 1)]
    np.testing.assert_allclose(radial, want, rtol=1e-12)
    np.testing.assert_allclose(freq, np.arange(n // 2 + 1) * df)
    w = np.asarray(metrics.half_plane_weights(n))
    assert w[0] == 1 and np.all(w[1:-1] == 2) and w[-1] == (1 if n % 2 == 0 else 2)


# ----------------------------------------------------------------------------- radial MTF


def test_radial_mtf_of_diffraction_limited_otf(dl_convergence):
    """Ring-averaged MTF of lfjax's aberration-free 3 mm OTF (550 nm, df 1 cpd) vs the
    analytic curve. Two error sources, bounded separately: ring binning (rint(|k|)) —
    measured exactly by ring-averaging the analytic 2-D MTF on the same grid (2.8e-3; bound
    ½ df · max slope = 6.7e-3) —
    and the OTF's own error, which the (linear) ring average cannot increase beyond its
    2-D maximum (measured 3.0e-3)."""
    otf = dl_convergence[3.0][0]
    n, df = otf.shape[0], 1.0
    half = jnp.asarray(otf[:, : n // 2 + 1])
    radial, freq = metrics.radial_mtf(half, n, df)
    radial = np.asarray(radial)
    analytic_2d = H.dl_otf_2d(n, df, 3.0, 550.0)
    ring_of_analytic, _ = metrics.radial_mtf(jnp.asarray(analytic_2d[:, : n // 2 + 1]), n, df)
    one_d = np.asarray(_dl_mtf(freq, 3.0, 550.0))
    binning = np.abs(np.asarray(ring_of_analytic) - one_d).max()
    # a ring holds radii within ±df/2 of its bin: bound by half a step times the largest
    # slope of the analytic MTF, (4/π)/f_cutoff at f = 0
    assert binning <= 0.5 * df * (4 / math.pi) / H.cutoff_cpd(3.0, 550.0)
    err_2d = np.abs(np.abs(otf) - analytic_2d).max()
    assert np.abs(radial - np.asarray(ring_of_analytic)).max() <= err_2d + 1e-15
    assert np.abs(radial - one_d).max() <= err_2d + binning
    assert radial[0] == pytest.approx(1.0, abs=1e-15)


def test_diffraction_limited_mtf_formula():
    cutoff = H.cutoff_cpd(3.0, 550.0)  # 95.2 cpd
    assert cutoff == pytest.approx(95.20, abs=0.01)
    f = jnp.asarray([0.0, 0.5 * cutoff, cutoff, 1.2 * cutoff])
    got = np.asarray(_dl_mtf(f, 3.0, 550.0))
    nu = 0.5
    mid = 2 / math.pi * (math.acos(nu) - nu * math.sqrt(1 - nu * nu))
    np.testing.assert_allclose(got, [1.0, mid, 0.0, 0.0], atol=1e-15)


# ----------------------------------------------------------------------------- cut-off


def test_cutoff_frequency_linear_interpolation():
    """First frequency where the radial MTF falls to the threshold, by linear
    interpolation between samples; the last frequency when it never does."""
    f = jnp.arange(0.0, 121.0, 2.0)
    mtf = jnp.clip(1.0 - f / 100.0, 0.0, 1.0)
    assert float(_cutoff(mtf, f)) == pytest.approx(95.0, abs=1e-12)
    assert float(_cutoff(mtf, f, 0.5)) == pytest.approx(50.0, abs=1e-12)
    # first crossing wins when the curve bounces back above the threshold
    bouncy = jnp.where(f > 60, 0.3, mtf)
    assert float(_cutoff(bouncy, f, 0.45)) == pytest.approx(55.0, abs=1e-12)
    # a crossing between samples: 0.2 → 0.0 over 2 cpd, threshold 0.05 at 3/4 of the step
    step = jnp.asarray([1.0, 0.6, 0.2, 0.0, 0.0])
    fs = jnp.arange(5.0) * 2.0
    assert float(_cutoff(step, fs)) == pytest.approx(5.5, abs=1e-12)
    # never below the threshold: the last frequency
    short = jnp.arange(0.0, 61.0, 2.0)
    assert float(_cutoff(1.0 - short / 100.0, short)) == 60.0
    # batched curves
    batch = jnp.stack([mtf, jnp.clip(1.0 - f / 50.0, 0.0, 1.0)])
    np.testing.assert_allclose(_cutoff(batch, f), [95.0, 47.5], atol=1e-12)
    for bad in (0.0, 1.0, -0.1):
        with pytest.raises(ValueError, match="threshold"):
            _cutoff(mtf, f, bad)


def test_cutoff_of_diffraction_limited_curve():
    """Analytic MTF of a 3 mm pupil at 550 nm sampled every 0.5 cpd: the 0.05 cut-off is
    where (2/π)(acos ν − ν√(1−ν²)) = 0.05, ν = 0.8592... (bisection), within the
    interpolation error of the convex curve over one step (< 0.05 cpd)."""
    lo, hi = 0.5, 1.0
    g = lambda nu: 2 / math.pi * (math.acos(nu) - nu * math.sqrt(1 - nu * nu)) - 0.05  # noqa
    for _ in range(80):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if g(mid) > 0 else (lo, mid)
    want = lo * H.cutoff_cpd(3.0, 550.0)
    f = jnp.arange(0.0, 120.0, 0.5)
    got = float(_cutoff(_dl_mtf(f, 3.0, 550.0), f))
    assert abs(got - want) < 0.05
