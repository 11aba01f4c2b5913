"""Continuous accommodation peaks (lfjax.vision.peaks): analytic curves, implicit gradients, the
two-peaked Strehl curve, the hyperopic limit and the grid's far end, bad input, and the
golden method on brackets away from zero (its workaround of an optimistix 0.1.0 bug).

Covers: lfjax.vision.peak_refinement
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import lfjax
from lfjax.vision.peak_refinement import refine_peak
from lfjax.vision.peaks import accommodation_peaks
from lfjax.kernel.pipeline import Accommodation, PipelineConfig, Scene, retinal_metrics

import helpers as H
from lfjax.vision.peak_options import PeakOptions

SOLVERS = ("newton", "golden", "bfgs")


# ----------------------------------------------------------------------------- analytic


def _skewed_peak(a, args):
    """A smooth, asymmetric single peak at a = args[0] (D): exp(−(a−c)²/(2s²))·(1 + k(a−c)³)."""
    centre, width = args
    x = a - centre
    return jnp.exp(-0.5 * (x / width) ** 2) * (1.0 + 0.3 * x**3)


@pytest.mark.parametrize("method", SOLVERS)
@pytest.mark.parametrize("centre", [1.2345, 3.0071])
def test_analytic_peak_recovered_to_1e4_D(method, centre):
    """Maximum of x·exp(−x²/2s²)-free skewed bump: the exact location solves V'(a) = 0; the
    solvers must find it to 1e-4 D from a 0.2 D bracket that does not straddle zero."""
    args = (jnp.asarray(centre), jnp.asarray(0.4))
    # exact maximum: root of the derivative by bisection in float64 on the host
    f = lambda a: float(jax.grad(_skewed_peak)(jnp.asarray(a), args))  # noqa: E731
    lo, hi = centre - 0.2, centre + 0.2
    for _ in range(80):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if f(mid) > 0 else (lo, mid)
    exact = 0.5 * (lo + hi)
    grid_peak = round(centre / 0.2) * 0.2
    peak = refine_peak(_skewed_peak, grid_peak - 0.2, grid_peak + 0.2, grid_peak, args, method)
    assert bool(peak.success)
    assert abs(float(peak.accommodation_D) - exact) < 1e-4
    assert int(peak.result) == 0


def test_peak_on_bracket_end_is_pinned_with_zero_gradient():
    """A maximum at the hyperopic limit (bracket end 0 D): Newton returns the end itself in
    one step, and the location does not move with the curve's parameters."""
    args = (jnp.asarray(-0.3), jnp.asarray(0.5))  # true maximum beyond the limit
    peak = refine_peak(_skewed_peak, 0.0, 0.2, 0.1, args, "newton")
    assert float(peak.accommodation_D) == 0.0 and bool(peak.success)
    assert int(peak.n_steps) <= 2
    grad = jax.grad(lambda c: refine_peak(_skewed_peak, 0.0, 0.2, 0.1, (c, args[1]),
                                          "newton").accommodation_D)(args[0])
    assert float(grad) == 0.0


def test_implicit_gradient_of_analytic_peak():
    """d(peak)/d(centre) = 1 for a curve that translates with its centre."""
    for method in SOLVERS:
        g = jax.grad(lambda c: refine_peak(_skewed_peak, 1.0, 1.4, 1.2, (c, jnp.asarray(0.4)),
                                           method).accommodation_D)(jnp.asarray(1.23))
        np.testing.assert_allclose(float(g), 1.0, rtol=1e-4, err_msg=method)


# ----------------------------------------------------------------------------- pipeline


OPTIONS = lfjax.ModelOptions(accommodation_sa="off", sce="off")
SPECTRUM = lfjax.make_spectrum([550.0], OPTIONS)  # LCA = 0 at 550 nm
SAMPLING = lfjax.Sampling(1.5)
GRID = np.round(np.arange(0, 26) * 0.2, 9)


def _pipeline(layout, depths, grid=GRID, window=1.0, options=OPTIONS, spectrum=SPECTRUM,
              cdp_D=2.0):
    cfg = PipelineConfig.build(spectrum.wavelengths_nm, layout.window_diameter_mm, 3.0, SAMPLING,
                               options)
    scene = Scene.from_layout(layout, depths, cdp_D, 3.0)
    index = np.broadcast_to(np.arange(grid.size), (len(depths), grid.size))
    allowed = np.abs(grid[None] - np.asarray(depths)[:, None]) <= window + 1e-9
    return cfg, scene, Accommodation.shared(grid, index, options, 3.0), allowed


def _defocused_eye(dioptres):
    z = np.zeros((1, 15))
    z[0, 4] = dioptres * H.C20_PER_D_3MM
    return lfjax.Eyes(z, 3.0)


def test_defocused_eye_peak_is_exact_and_its_gradient_analytic(method="newton"):
    """A monochromatic, SA-free eye with +0.37 D of its own defocus (myopic) viewing a point
    on the display plane (CDP 2.5 D) through its whole pupil focuses 0.37 D short of it; the
    implicit derivative of the peak with respect to c(2,0) is −1/(0.3248 µm/D) exactly
    (docs/design.md#conventions)."""
    layout = lfjax.open_pupil(3.0)
    cfg, scene, grid, allowed = _pipeline(layout, [2.5], cdp_D=2.5)

    def peak_of(c20):
        eyes = lfjax.Eyes(jnp.zeros((1, 15)).at[0, 4].set(c20), 3.0)
        return accommodation_peaks(
            eyes,
            scene,
            SPECTRUM,
            grid,
            cfg,
            metric="vsotf",
            peaks=PeakOptions(method=method),
            allowed=allowed,
        ).accommodation_D[0, 0]

    c20 = 0.37 * H.C20_PER_D_3MM
    # the peak and its derivative from one program (value_and_grad): one compile, not two
    peak, slope = jax.value_and_grad(peak_of)(c20)
    np.testing.assert_allclose(float(peak), 2.5 - 0.37, atol=2e-4)
    np.testing.assert_allclose(float(slope), -1.0 / H.C20_PER_D_3MM, rtol=2e-3)


def test_implicit_gradient_matches_finite_difference_of_the_resolved_peak():
    """Aberrated eye, 2×2 views: d(peak)/d(eye's Zernike coefficients, subaperture centres
    and diameters, CDP) along a random direction against central differences of re-solved
    peaks (float64)."""
    layout = lfjax.grid_layout(2, 3.0)
    options = lfjax.ModelOptions()
    spectrum = lfjax.make_spectrum([550.0], options)
    cfg, scene, grid, allowed = _pipeline(layout, [1.5], options=options, spectrum=spectrum)
    params = dict(z=jnp.asarray(np.asarray(lfjax.sample_eyes(2, 1).zernike_um)[0, :10]),
                  centres=scene.centres_mm, diameters=scene.diameters_mm * 0.9,
                  cdp=jnp.asarray(2.0))

    def peak_of(p):
        s = Scene(p["centres"], p["diameters"], p["cdp"], scene.depths_D, 3.0)
        return accommodation_peaks(
            lfjax.Eyes(p["z"][None], 3.0),
            s,
            spectrum,
            grid,
            cfg,
            metric="vsotf",
            peaks=PeakOptions(method="newton"),
            allowed=allowed,
        ).accommodation_D[0, 0]

    # one compiled program serves the gradient and the re-solved peaks of the central
    # differences (its value output is the same forward solve as peak_of's own program)
    value_and_grad = jax.jit(jax.value_and_grad(peak_of))
    v = H.random_direction(jax.random.key(3), params)
    directional = H.tree_vdot(value_and_grad(params)[1], v)
    fd = H.directional_fd(lambda p: value_and_grad(p)[0], params, v, 1e-4)
    assert abs(fd) > 1e-2
    np.testing.assert_allclose(directional, fd, rtol=2e-4)


def test_two_peaked_strehl_returns_global_maximum_and_reports_the_second():
    """2×2 views, aberration-free eye, a point rendered 2 D behind the CDP (4 D): the Strehl
    ratio peaks at the CDP (four sharp but separated images) and again near the rendered
    depth. The default ("auto": golden section for Strehl) returns the global maximum of a
    0.01 D grid and reports the second peak.

    The PSF pixel is 0.25 arcmin here (n_fft 160): the sampled PSF's peak is the largest of
    its pixels, so Strehl is only piecewise smooth in accommodation (wiggles of a few % at
    0.6 arcmin pixels can move a 0.2 D grid's argmax to the wrong neighbour), and Newton,
    which trusts derivatives, lands on a piece's end (2.2 D here) — hence "auto"."""
    layout = lfjax.grid_layout(2, 3.0)
    options = lfjax.ModelOptions()
    spectrum = lfjax.make_spectrum([550.0], options)
    cfg = PipelineConfig.build(spectrum.wavelengths_nm, layout.window_diameter_mm, 3.0,
                               lfjax.Sampling(1.5, n_fft=160), options)
    scene = Scene.from_layout(layout, [4.0], 2.0, 3.0)
    index = np.arange(GRID.size)[None]
    allowed = np.abs(GRID[None] - 4.0) <= 2.6 + 1e-9
    grid = Accommodation.shared(GRID, index, options, 3.0)
    eyes = lfjax.model.eyes.aberration_free_eye()
    peaks = accommodation_peaks(
        eyes,
        scene,
        spectrum,
        grid,
        cfg,
        metric="strehl",
        peaks=PeakOptions(method="auto"),
        allowed=allowed,
    )
    main, second = float(peaks.accommodation_D[0, 0]), float(peaks.second_accommodation_D[0, 0])
    fine = np.round(np.arange(140, 501) * 0.01, 9)
    dense = np.asarray(retinal_metrics(
        eyes, scene, spectrum, Accommodation.shared(fine, np.arange(fine.size)[None], options, 3.0),
        cfg).strehl[0, 0])
    assert abs(main - fine[np.argmax(dense)]) <= 0.02
    assert float(peaks.value[0, 0]) >= dense.max() - 1e-3
    assert bool(peaks.success[0, 0])
    assert 3.5 <= second <= 4.2, f"second peak (near the rendered depth) not reported: {second}"
    assert float(peaks.second_value[0, 0]) < float(peaks.value[0, 0])
    newton = accommodation_peaks(
        eyes,
        scene,
        spectrum,
        grid,
        cfg,
        metric="strehl",
        peaks=PeakOptions(method="newton"),
        allowed=allowed,
    )
    assert abs(float(newton.accommodation_D[0, 0]) - fine[np.argmax(dense)]) > 0.05


def test_hyperopic_limit_and_far_grid_end_are_flagged():
    """An eye that wants to relax beyond infinity peaks at 0 D (flagged, successful); a peak
    beyond the last grid state is flagged and not reported as successful."""
    layout = lfjax.open_pupil(3.0)
    eyes = lfjax.Eyes(np.concatenate([_defocused_eye(0.6).zernike_um,
                                      _defocused_eye(-1.3).zernike_um]), 3.0)
    result = {}
    for depth in (0.2, 4.5):  # a point on the display plane, viewed through the whole pupil
        cfg, scene, grid, allowed = _pipeline(layout, [depth], window=1.5, cdp_D=depth)
        result[depth] = accommodation_peaks(
            eyes,
            scene,
            SPECTRUM,
            grid,
            cfg,
            metric="vsotf",
            peaks=PeakOptions(method="newton"),
            allowed=allowed,
        )
    near, far = result[0.2], result[4.5]
    # eye 0 (+0.6 D myopic) at 0.2 D: wants −0.4 D → held at 0 D
    assert float(near.accommodation_D[0, 0]) == 0.0
    assert bool(near.at_hyperopic_limit[0, 0]) and bool(near.success[0, 0])
    # eye 1 (−1.3 D hyperopic) at 4.5 D: wants 5.8 D, beyond the 5 D grid end
    assert bool(far.at_grid_edge[1, 0]) and not bool(far.success[1, 0])
    # the other two are ordinary peaks
    assert bool(near.success[1, 0]) and bool(far.success[0, 0])
    np.testing.assert_allclose(float(near.accommodation_D[1, 0]), 0.2 + 1.3, atol=2e-4)
    np.testing.assert_allclose(float(far.accommodation_D[0, 0]), 4.5 - 0.6, atol=2e-4)


# ----------------------------------------------------------------------------- bad input


def test_bad_brackets_are_refused():
    args = (jnp.asarray(1.0), jnp.asarray(0.4))
    with pytest.raises(ValueError, match="empty or one-point bracket"):
        refine_peak(_skewed_peak, 1.0, 1.0, 1.0, args)
    with pytest.raises(ValueError, match="empty or one-point bracket"):
        refine_peak(_skewed_peak, 2.0, 1.0, 1.5, args)
    with pytest.raises(ValueError, match="must be finite"):
        refine_peak(_skewed_peak, float("nan"), 1.0, 0.5, args)
    with pytest.raises(ValueError, match="method must be one of"):
        refine_peak(_skewed_peak, 0.0, 1.0, 0.5, args, "simplex")
    traced = jax.jit(lambda lo: refine_peak(_skewed_peak, lo, 1.0, 0.5, args).accommodation_D)
    with pytest.raises(Exception, match="empty or one-point bracket"):
        jax.block_until_ready(traced(jnp.asarray(1.0)))


def test_one_state_grid_is_refused():
    layout = lfjax.open_pupil(3.0)
    cfg, scene, grid, _ = _pipeline(layout, [2.0], grid=np.array([2.0]))
    with pytest.raises(ValueError, match=">= 2 accommodation states"):
        accommodation_peaks(H.dl_eye(), scene, SPECTRUM, grid, cfg)


# ----------------------------------------------------------------------------- upstream trap


@pytest.mark.parametrize("lower, upper, peak", [(2.0, 4.0, 3.0), (2.0, 4.0, 2.1),
                                                (2.0, 4.0, 3.93), (4.6, 5.0, 4.7),
                                                (0.0, 0.4, 0.33)])
def test_golden_search_honours_brackets_that_do_not_straddle_zero(lower, upper, peak):
    """optimistix 0.1.0's GoldenSearch puts its first midpoint at (upper − lower)/(φ + 1),
    not lower + …, so a bracket that does not straddle zero diverges (optimistix issue #236,
    fixed upstream by PR #237). lfjax searches the offset from the bracket centre, which is
    right with or without the upstream fix: the golden method must find the peak of a
    skewed curve anywhere inside such brackets, near either end included (< 1e-4 D), and
    report success."""
    got = refine_peak(_skewed_peak, lower, upper, 0.5 * (lower + upper), (peak, 0.3),
                      "golden")
    assert bool(got.success)
    assert abs(float(got.accommodation_D) - peak) < 1e-4, (float(got.accommodation_D), peak)


def test_local_refinement_agrees_with_the_exact_peak():
    """"local" (three points around the grid parabola's vertex, no solver loop) finds the
    analytic peak of a defocused eye (CDP − own defocus) to < 5e-4 D, where the grid
    parabola alone is off by more."""
    layout = lfjax.open_pupil(3.0)
    cfg, scene, grid, allowed = _pipeline(layout, [2.5], cdp_D=2.5)
    own = np.array([0.37, -0.61])  # two eyes: the shape of this file's other open-pupil calls
    eyes = lfjax.Eyes(np.concatenate([_defocused_eye(d).zernike_um for d in own]), 3.0)
    exact = 2.5 - own
    local = accommodation_peaks(
        eyes,
        scene,
        SPECTRUM,
        grid,
        cfg,
        metric="vsotf",
        peaks=PeakOptions(method="local"),
        allowed=allowed,
    )
    parabola = accommodation_peaks(
        eyes,
        scene,
        SPECTRUM,
        grid,
        cfg,
        metric="vsotf",
        peaks=PeakOptions(method="parabola"),
        allowed=allowed,
    )
    assert np.all(np.asarray(local.success))
    np.testing.assert_allclose(np.asarray(local.accommodation_D)[:, 0], exact, atol=5e-4)
    assert np.max(np.abs(np.asarray(parabola.accommodation_D)[:, 0] - exact)) > 1e-3
    # "vertex": the parabola's location, valued by the parabola itself (no evaluation):
    # close to the metric there, and not below the grid maximum it interpolates
    vertex = accommodation_peaks(
        eyes,
        scene,
        SPECTRUM,
        grid,
        cfg,
        metric="vsotf",
        peaks=PeakOptions(method="vertex"),
        allowed=allowed,
    )
    np.testing.assert_array_equal(np.asarray(vertex.accommodation_D),
                                  np.asarray(parabola.accommodation_D))
    np.testing.assert_allclose(np.asarray(vertex.value), np.asarray(parabola.value), rtol=2e-2)
    assert np.all(np.asarray(vertex.value) >= np.asarray(vertex.grid_value) - 1e-12)


def test_local_refinement_at_the_hyperopic_limit():
    """Near 0 D the three-point stencil moves inside the bracket instead of being clipped
    onto the limit (clipped points coincide and leave the parabola's fit singular: NaN).
    A peak 0.05 D above the limit is found; one beyond it is held at 0 D and succeeds."""
    layout = lfjax.open_pupil(3.0)
    cfg, scene, grid, allowed = _pipeline(layout, [0.3], cdp_D=0.3)
    own = np.array([0.25, 0.6])  # peaks at 0.05 D and (beyond the limit) -0.3 D
    eyes = lfjax.Eyes(np.concatenate([_defocused_eye(d).zernike_um for d in own]), 3.0)
    local = accommodation_peaks(
        eyes,
        scene,
        SPECTRUM,
        grid,
        cfg,
        metric="vsotf",
        peaks=PeakOptions(method="local"),
        allowed=allowed,
    )
    found = np.asarray(local.accommodation_D)[:, 0]
    assert np.all(np.isfinite(found)) and np.all(np.asarray(local.success))
    np.testing.assert_allclose(found, [0.05, 0.0], atol=5e-4)


def test_flat_curves_of_strongly_aberrated_eyes_are_not_reported_as_successes():
    """Strongly aberrated eyes (0.6 µm of spherical aberration; 1.5 µm of coma on a 3 mm
    pupil) have VSOTF curves that are flat (≈ 0.06, rising slowly) or tiny and symmetric
    (≈ 0.001) over ±1 D: the maximum sits on the window's edge, and every method says so
    (at_grid_edge, not successful) instead of returning a confident prediction."""
    cfg, scene, grid, allowed = _pipeline(lfjax.open_pupil(3.0), [2.0], window=1.0)
    z = np.zeros((2, 15))
    z[0, 12], z[1, 7] = 0.6, 1.5
    eyes = lfjax.Eyes(z, 3.0)
    for method in ("newton", "golden", "local"):
        peaks = accommodation_peaks(
            eyes,
            scene,
            SPECTRUM,
            grid,
            cfg,
            metric="vsotf",
            peaks=PeakOptions(method=method),
            allowed=allowed,
        )
        assert np.all(np.asarray(peaks.at_grid_edge)), method
        assert not np.any(np.asarray(peaks.success)), method
        assert np.all(np.abs(np.abs(np.asarray(peaks.accommodation_D) - 2.0) - 1.0) < 1e-3)


def test_non_smooth_peak_newton_reports_failure_golden_and_bfgs_find_it():
    """A peak with a kink (the Strehl ratio is a maximum over PSF samples, so its curve has
    corners; benchmarks/validation/peak_failure_cases.json "non_smooth_strehl"):
    V = 1 − 0.3|a − c| − 0.5(a − c)². Newton on dV/da cannot converge (the slope jumps at the peak) and must say
    so rather than return a point; golden section (``"auto"`` for the Strehl ratio) and BFGS
    find the corner."""
    def kinked(a, args):
        x = a - args[0]
        return 1.0 - 0.3 * jnp.abs(x) - 0.5 * x**2

    centre = 2.037
    args = (jnp.asarray(centre),)
    newton = refine_peak(kinked, 1.8, 2.2, 2.0, args, "newton", 1e-5, 32)
    assert not bool(newton.success) and int(newton.result) != 0
    for method in ("golden", "bfgs"):
        peak = refine_peak(kinked, 1.8, 2.2, 2.0, args, method, 1e-5, 32)
        assert bool(peak.success), method
        assert abs(float(peak.accommodation_D) - centre) < 1e-4, method


def test_peak_narrower_than_the_grid_step_is_missed_by_the_bracketing_grid():
    """The failure kind behind golden section's 19 silent Strehl peaks in 3,600
    (benchmarks/RESULTS.md §10): the global maximum is narrower than the grid step, so the
    grid's highest sample lies on a lower, broader peak, the narrow one is no grid local
    maximum (no second peak is reported) and golden section converges on the broad peak
    with success. Pinned so that a change in this behaviour is seen; a grid finer than the
    peak finds the global maximum."""
    from lfjax.vision.peaks import _local_maxima

    def two_peaks(a, args=None):  # broad peak 1.0 at 1.0 D; narrow 1.05 at 2.1 D
        return (jnp.exp(-0.5 * ((a - 1.0) / 0.5) ** 2)
                + 1.05 * jnp.exp(-0.5 * ((a - 2.1) / 0.03) ** 2))

    for step, expected in ((0.2, 1.0), (0.01, 2.1)):
        states = jnp.asarray(np.round(np.arange(0.0, 3.0 + 1e-9, step), 9))
        values = two_peaks(states)
        best, second = _local_maxima(values, jnp.ones(states.shape, bool), 0.05)
        grid_peak = float(states[int(best)])
        assert abs(grid_peak - expected) <= step / 2 + 1e-9, step
        if step == 0.2:
            assert int(second) == -1  # the narrow peak is not a grid local maximum
            peak = refine_peak(two_peaks, grid_peak - step, grid_peak + step, grid_peak, None,
                               "golden", 1e-5, 32)
            assert bool(peak.success)
            assert abs(float(peak.accommodation_D) - 1.0) < 1e-3
            assert float(peak.value) < float(two_peaks(2.1))


@pytest.mark.parametrize("method", ["local", "newton"])
def test_pairs_refined_in_batches_equal_pairs_refined_together(monkeypatch, method):
    """A kernel workspace too small for more than one (eye, depth) pair at a time refines
    the pairs one batch after another (lax.map): the same peaks as all pairs at once (to
    float64 rounding: the batched program sums in another order).
    (peaks_from_grid is called outside any jit, so the changed budget is traced afresh.)"""
    from lfjax.kernel import optics
    from lfjax.vision.peaks import peaks_from_grid
    from lfjax.kernel.pipeline import reference_normalisers

    layout = lfjax.open_pupil(3.0)
    cfg, scene, grid, allowed = _pipeline(layout, [2.0, 2.5], cdp_D=2.5)
    eyes = lfjax.Eyes(np.concatenate([_defocused_eye(d).zernike_um for d in (0.37, -0.61, 0.05)]), 3.0)
    values = retinal_metrics(eyes, scene, SPECTRUM, grid, cfg).vsotf
    reference = reference_normalisers(scene, SPECTRUM, grid, cfg)

    def peaks():
        p = peaks_from_grid(
            values,
            eyes,
            scene,
            SPECTRUM,
            grid,
            cfg,
            reference,
            metric="vsotf",
            peaks=PeakOptions(method=method),
            allowed=allowed,
        )
        return np.asarray(p.accommodation_D), np.asarray(p.value), np.asarray(p.success)

    together = peaks()
    monkeypatch.setattr(optics, "KERNEL_WORKSPACE_BYTES", optics.KERNEL_BYTES_PER_SAMPLE * cfg.n_fft**2)
    assert lfjax.vision.peak_refinement.pairs_per_batch(scene, cfg, method, 2) == 1
    batched = peaks()
    np.testing.assert_array_equal(batched[2], together[2])
    for a, b in zip(batched[:2], together[:2]):  # float64 rounding of another program only
        np.testing.assert_allclose(a, b, rtol=1e-13, atol=0)


# ------------------------------------------------------------------ "adaptive"


def test_grid_estimate_is_exact_for_a_gaussian_and_bounds_a_skewed_peak():
    """The grid estimate (quartic through the logarithms of five samples) is exact for a
    Gaussian peak, wherever it falls between grid points; on smooth skewed peaks it is
    off, and its error estimate bounds how far off (float64, analytic)."""
    from lfjax.vision.peak_refinement import ESTIMATE_RULES, grid_peak_estimate

    states = np.round(np.arange(0, 26) * 0.2, 9)
    for centre in (1.0, 1.0731, 2.4499):
        gauss = 0.4 * np.exp(-((states - centre) / 0.35) ** 2)
        est = grid_peak_estimate(states, gauss, np.argmax(gauss))
        assert abs(float(est.accommodation_D) - centre) < 1e-9
        np.testing.assert_allclose(float(est.value), 0.4, rtol=1e-9)
        # the lower order is exact too: the estimate is its rule's floor
        assert int(est.n_points) == 7
        np.testing.assert_allclose(float(est.error_D), ESTIMATE_RULES[7][1], atol=1e-9)
    # skewed, smooth: exp(−x²/2σ²)·(1 + tanh kx), maximum found on a 1e-5 D grid
    grid_fine = np.linspace(0, 5, 500001)
    errors = []
    for sigma in (0.3, 0.5):
        for k in (-2.0, -1.0, 1.0, 2.0):
            for centre in (1.0, 1.07, 2.31):
                def f(a):
                    return np.exp(-(a - centre) ** 2 / (2 * sigma**2)) * (1 + np.tanh(k * (a - centre)))
                truth = grid_fine[np.argmax(f(grid_fine))]
                values = f(states)
                est = grid_peak_estimate(states, values, np.argmax(values))
                errors.append(abs(float(est.accommodation_D) - truth))
                assert errors[-1] <= float(est.error_D), (sigma, k, centre, errors[-1])
    assert max(errors) > 1e-4, "skewed peaks the grid cannot place exactly"


def test_grid_estimate_refuses_what_the_grid_cannot_tell():
    """No estimate (error ∞, the grid maximum kept) where a neighbour is missing, the
    curve is not concave, or a value is not positive."""
    from lfjax.vision.peak_refinement import grid_peak_estimate

    states = np.round(np.arange(0, 11) * 0.2, 9)
    peak = np.exp(-((states - 1.0) / 0.4) ** 2)
    at_start = np.exp(-((states - 0.1) / 0.4) ** 2)  # grid maximum at index 0 or 1
    masked = np.where(np.arange(11) < 6, peak, -np.inf)  # index 5 maximum, index 6 masked
    masked[5] = peak[5] * 1.01
    flat = np.ones(11)
    negative = peak - 0.5
    for values in (at_start, masked, flat, negative):
        est = grid_peak_estimate(states, values, np.argmax(values))
        assert np.isinf(float(est.error_D))
        assert float(est.accommodation_D) == states[np.argmax(values)]


def test_map_flagged_evaluates_only_the_flagged_pairs():
    """Flagged pairs get fn, the others the fallback; fn never sees an unflagged pair's
    batch when a whole batch is unflagged (a counter inside fn would show it: here, fn
    returns a marker that the fallback cannot)."""
    from lfjax.vision.peak_refinement import _map_flagged

    rng = np.random.default_rng(0)
    x = jnp.asarray(rng.normal(size=(5, 7)))
    for fraction in (0.0, 0.2, 1.0):
        flagged = jnp.asarray(rng.random((5, 7)) < fraction)
        fallback = -jnp.ones((5, 7))
        for batch in (1, 3, 35):
            out = _map_flagged(lambda v: v * v + 10.0, flagged, batch, fallback, x)
            expected = np.where(np.asarray(flagged), np.asarray(x) ** 2 + 10.0, -1.0)
            np.testing.assert_allclose(np.asarray(out), expected, rtol=1e-12)


def test_adaptive_refines_exactly_where_the_estimate_exceeds_the_tolerance():
    """Aberrated eyes, 2×2 views: "adaptive" returns "local"'s peak on the pairs whose grid
    estimate may exceed the tolerance (n_steps 3; asserted to be some but not all pairs)
    and the grid estimate elsewhere (n_steps 0), each within the tolerance of "local"'s; a
    tolerance below every estimate refines everything and reproduces "local".
    (One wavelength: the choice of pairs reads only the metric's grid values, and each
    wavelength band is another copy of the kernel to compile; one tolerance with both
    kinds of pair, as each tolerance is a static number and a compile of its own.)"""
    layout = lfjax.grid_layout(2, 3.0)
    options = lfjax.ModelOptions()
    spectrum = lfjax.make_spectrum([550.0], options)
    depths = [0.0, 1.0, 2.0, 3.5]
    cfg, scene, grid, allowed = _pipeline(layout, depths, options=options, spectrum=spectrum,
                                          window=2.0)
    eyes = lfjax.sample_eyes(5, 6)
    local = accommodation_peaks(
        eyes,
        scene,
        spectrum,
        grid,
        cfg,
        metric="vsotf",
        peaks=PeakOptions(method="local", second_peaks=False),
        allowed=allowed,
    )
    tol = 0.01
    adaptive = accommodation_peaks(
        eyes,
        scene,
        spectrum,
        grid,
        cfg,
        metric="vsotf",
        peaks=PeakOptions(method="adaptive", second_peaks=False, tolerance_D=tol),
        allowed=allowed,
    )
    refined = np.asarray(adaptive.n_steps) > 0
    assert 0 < refined.sum() < refined.size, refined  # both kinds of pair are checked
    estimate = np.asarray(adaptive.grid_error_D)
    np.testing.assert_array_equal(refined, ~(estimate <= tol) | ~np.isfinite(estimate))
    a, b = np.asarray(adaptive.accommodation_D), np.asarray(local.accommodation_D)
    np.testing.assert_allclose(a[refined], b[refined], atol=1e-6)
    assert np.all(np.abs(a - b)[~refined] <= tol + 2e-4)  # "local" is itself ~1e-4 off
    np.testing.assert_array_equal(np.asarray(adaptive.success), np.asarray(local.success))
    everything = accommodation_peaks(
        eyes,
        scene,
        spectrum,
        grid,
        cfg,
        metric="vsotf",
        peaks=PeakOptions(method="adaptive", second_peaks=False, tolerance_D=1e-9),
        allowed=allowed,
    )
    assert np.all(np.asarray(everything.n_steps) == 3)
    np.testing.assert_allclose(np.asarray(everything.accommodation_D),
                               np.asarray(local.accommodation_D), atol=1e-6)


def test_adaptive_gradient_matches_finite_difference():
    """d(peak)/d(Zernike coefficients) through "adaptive", with one pair refined (depth
    0 D: its grid maximum lacks two neighbours below) and one kept from the grid (1.5 D:
    the estimate is differentiable too, checked against central differences; float64)."""
    layout = lfjax.grid_layout(2, 3.0)
    options = lfjax.ModelOptions()
    spectrum = lfjax.make_spectrum([550.0], options)
    cfg, scene, grid, allowed = _pipeline(layout, [0.0, 1.5], options=options, spectrum=spectrum)
    z0 = jnp.asarray(np.asarray(lfjax.sample_eyes(2, 1).zernike_um)[0])

    def locations(z):
        p = accommodation_peaks(
            lfjax.Eyes(z[None], 3.0),
            scene,
            spectrum,
            grid,
            cfg,
            metric="vsotf",
            peaks=PeakOptions(method="adaptive", second_peaks=False),
            allowed=allowed,
        )
        return p.accommodation_D[0], (p.accommodation_D[0], p.n_steps)

    # one compiled program: both pairs' derivatives (reverse mode, one row each), the
    # peaks and n_steps; the central differences re-solve through it too
    jacobian = jax.jit(jax.jacrev(locations, has_aux=True))
    rows, (_, n_steps) = jacobian(z0)
    np.testing.assert_array_equal(np.asarray(n_steps), [[3, 0]])
    v = H.random_direction(jax.random.key(4), z0)
    # kept from the grid: the derivative of the estimate's own location
    directional = H.tree_vdot(rows[1], v)
    fd = H.directional_fd(lambda z: jacobian(z)[1][0][1], z0, v, 1e-5)
    assert abs(fd) > 1e-3
    np.testing.assert_allclose(directional, fd, rtol=1e-3)
    # refined: "local"'s derivative (its fitted vertex's, with the stencil held), passed
    # through the gather and scatter unchanged
    local = jax.grad(
        lambda z: accommodation_peaks(
            lfjax.Eyes(z[None], 3.0),
            scene,
            spectrum,
            grid,
            cfg,
            metric="vsotf",
            peaks=PeakOptions(method="local", second_peaks=False),
            allowed=allowed,
        ).accommodation_D[0, 0]
    )(z0)
    refined = rows[0]
    assert float(jnp.max(jnp.abs(local))) > 1e-2
    np.testing.assert_allclose(np.asarray(refined), np.asarray(local), rtol=1e-9, atol=1e-12)


@pytest.mark.parametrize("tolerance", [0.0, -0.01, float("nan"), 1.5, "0.01"])
def test_adaptive_tolerance_is_checked(tolerance):
    from lfjax.base.errors import ParameterError

    layout = lfjax.open_pupil(3.0)
    cfg, scene, grid, allowed = _pipeline(layout, [2.0])
    with pytest.raises(ParameterError, match="PeakOptions.tolerance_D"):
        accommodation_peaks(
            _defocused_eye(0.1),
            scene,
            SPECTRUM,
            grid,
            cfg,
            metric="vsotf",
            peaks=PeakOptions(method="adaptive", tolerance_D=tolerance),
            allowed=allowed,
        )
