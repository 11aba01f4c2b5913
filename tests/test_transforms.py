"""Every public numerical function under jax.jit, jax.vmap and jax.grad applied from outside.

Each case is a function f(x) of one array x built on a public lfjax function, with the
other inputs concrete and closed over (as a user writes it: the closure is what broke the
old pipeline under an outer jit). For each (function, transform):

* jit: ``jax.jit(f)(x) == f(x)``;
* vmap: ``jax.vmap(f)(xs)`` equals a Python loop over xs;
* grad: the directional derivative of Σ w·f(x) equals a central finite difference (float64).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import lfjax
from lfjax.kernel import metrics as M
from lfjax.kernel.pipeline import Accommodation, PipelineConfig, Scene, otf_stack, retinal_metrics
from lfjax.vision.focus import metrics_at

import helpers as H
from lfjax.vision.prepare import States
from lfjax.vision.viewing import Viewing

# n_fft fixed (120 on the 3 mm pupil: 60 on the 1.5 mm subapertures, the size the planner
# gives 520 nm): both wavelengths in one band, so each transformed program holds one copy
# of the kernel instead of one per band (compile time is most of this file's time; the
# band split itself is exercised by the other pipeline tests). One eye: the outputs read
# eye 0 only.
SAMPLING = lfjax.Sampling(2.0, n_fft=120)
OPTIONS = lfjax.ModelOptions()
SPECTRUM = lfjax.make_spectrum([520.0, 600.0], OPTIONS)
SPECTRUM_550 = lfjax.make_spectrum([550.0], OPTIONS)
LAYOUT = lfjax.grid_layout(2, 3.0)
EYES = lfjax.Eyes(np.asarray(lfjax.sample_eyes(4, 1).zernike_um)[:1, :10], 3.0)
CONFIG = PipelineConfig.build(SPECTRUM.wavelengths_nm, LAYOUT.window_diameter_mm, 3.0, SAMPLING,
                              OPTIONS)
SCENE = Scene.from_layout(LAYOUT, [2.4], 2.0, 3.0)


def _accommodation(states):
    states = jnp.atleast_1d(states)
    return Accommodation.shared(states, jnp.arange(states.shape[0])[None], OPTIONS, 3.0)


def core_vs_accommodation(a):
    """retinal_metrics (the pipeline) as a function of the accommodation state, D."""
    return retinal_metrics(EYES, SCENE, SPECTRUM, _accommodation(a), CONFIG).vsotf[0, 0, 0]


def core_vs_zernike(z):
    """retinal_metrics as a function of the eye's Zernike coefficients, µm."""
    eyes = lfjax.Eyes(z[None], 3.0)
    m = retinal_metrics(eyes, SCENE, SPECTRUM, _accommodation(jnp.asarray(2.2)), CONFIG)
    return m.vsotf[0, 0, 0] + 0.5 * m.strehl[0, 0, 0]


def otf_vs_diameters(d):
    """The polychromatic OTF stack (polychromatic_otf's compute) against subaperture diameters."""
    scene = Scene(LAYOUT.centres_mm, d, 2.0, jnp.asarray([2.4]), 3.0)
    otf = otf_stack(EYES, scene, SPECTRUM, _accommodation(jnp.asarray(2.2)), CONFIG)
    return jnp.real(otf[0, 0, 0, 1:4, 1:4]).ravel()


def metrics_at_vs_depth(depth):
    """metrics_at (eyes closed over) against the rendered depth, D."""
    vs, sr = metrics_at(EYES, LAYOUT, jnp.reshape(depth, (1,)), jnp.asarray([[2.2]]),
                        spectrum=SPECTRUM, sampling=SAMPLING, options=OPTIONS)
    return jnp.stack([vs[0, 0, 0], sr[0, 0, 0]])


def _test_otf(scale):
    n = 32
    fx, fy = M.half_plane_frequencies(n, 1.0)
    return jnp.exp(-(fx**2 + fy**2) / (2.0 * scale**2)).astype(jnp.complex128)


def metrics_vs_otf_width(scale):
    """vsotf, strehl_ratio, radial_mtf and cutoff_frequency of a Gaussian MTF of width ``scale``."""
    otf, ref = _test_otf(scale), _test_otf(jnp.asarray(9.0))
    radial, freq = M.radial_mtf(otf, 32, 1.0)
    return jnp.stack([
        M.vsotf(otf, ref, 32, 1.0), M.strehl_ratio(otf, ref, 32, 1.0),
        radial[3], M.cutoff_frequency(radial, freq, 0.3),
    ])


def ncsf_vs_frequency(f):
    """Both NCSF models at (f, f/2) cpd."""
    return jnp.stack([M.ncsf(f, 0.5 * f), M.ncsf(f, 0.5 * f, "campbell_green_2004")])


def psf_vs_wavelength(wl):
    """monochromatic_psf against the wavelength, nm (a few pixels)."""
    z = jnp.asarray(np.asarray(EYES.zernike_um)[0])
    psf = lfjax.monochromatic_psf(z, 3.0, 3.0, wl, 0.6, 24, pupil_samples=48)
    return psf[10:14, 10:14].ravel()


def _bump(a, centre):
    return jnp.exp(-0.5 * ((a - centre) / 0.4) ** 2) * (1.0 + 0.3 * (a - centre) ** 3)


def peak_vs_centre(centre):
    """refine_peak (the peak finder's solver, Newton) against the curve's centre, D."""
    from lfjax.vision.peak_refinement import refine_peak

    return refine_peak(_bump, 1.0, 1.4, 1.2, centre).accommodation_D


def fresnel_vs_distance(z_mm):
    """fresnel_propagate (lenslet diffraction) of a soft disc against the distance, mm: both
    kernel samplings (near field at 40 mm, far field at 400 mm on this grid)."""
    from lfjax.display.lenslets import fresnel_propagate
    from lfjax.kernel.optics import soft_disk

    k = (jnp.arange(32) - 16) * 0.05
    aperture = soft_disk(k[None, :] ** 2 + k[:, None] ** 2, 0.5, 0.0125)
    field = fresnel_propagate(aperture.astype(jnp.complex128), 0.05, 550e-6, z_mm)
    return jnp.stack([jnp.real(field[16, 12:20]), jnp.imag(field[16, 12:20])]).ravel()


def pixels_vs_width(width_arcmin):
    """pixel_transfer (finite emitters) against the emitter's angular width, arcmin."""
    from lfjax.display.lenslets import DisplayOptics, pixel_transfer

    f = jnp.linspace(0.0, 3000.0, 5)  # cycles/rad
    return pixel_transfer(f, f, DisplayOptics(pixel_width_arcmin=width_arcmin)).ravel()


def core_vs_fresnel_distance(z_mm):
    """retinal_metrics with lenslet diffraction and pixels against the Fresnel distance, mm."""
    from lfjax.display.lenslets import DisplayOptics

    display = DisplayOptics("fresnel", "circle", z_mm, 1.0)
    scene = Scene.from_layout(LAYOUT, [2.4], 2.0, 3.0, display)
    spectrum = SPECTRUM_550
    config = PipelineConfig.build(spectrum.wavelengths_nm, LAYOUT.window_diameter_mm, 3.0,
                                  lfjax.Sampling(1.6), OPTIONS, display=display)
    m = retinal_metrics(EYES, scene, spectrum, _accommodation(jnp.asarray(2.2)), config)
    return jnp.stack([m.vsotf[0, 0, 0], m.strehl[0, 0, 0]])


CASES = {
    "fresnel_propagate": (fresnel_vs_distance, 120.0, [40.0, 120.0, 400.0], 1e-3),
    "pixel_transfer": (pixels_vs_width, 1.5, [0.5, 1.5, 3.0], 1e-5),
    "core_display": (core_vs_fresnel_distance, 400.0, [300.0, 500.0], 1e-2),
    # name: (f, x0, batch, finite-difference step)
    "core_accommodation": (core_vs_accommodation, 2.3, [1.9, 2.3, 2.7], 1e-4),
    "core_zernike": (core_vs_zernike, np.asarray(EYES.zernike_um)[0], None, 1e-5),
    "otf_stack_diameters": (otf_vs_diameters, np.full(4, 1.45), [np.full(4, 1.3), np.full(4, 1.5)], 1e-5),
    "metrics_at_depth": (metrics_at_vs_depth, 2.4, [2.0, 2.8], 1e-4),
    "metrics": (metrics_vs_otf_width, 4.0, [3.0, 5.0], 1e-5),
    "ncsf": (ncsf_vs_frequency, 7.0, [2.0, 9.0, 20.0], 1e-5),
    "peak_finder": (peak_vs_centre, 1.23, [1.15, 1.23, 1.31], 1e-5),
    "monochromatic_psf": (psf_vs_wavelength, 560.0, [480.0, 620.0], 1e-3),
}


def _batch(x0, batch):
    if batch is not None:
        return jnp.asarray(np.asarray(batch, float))
    x0 = np.asarray(x0, float)
    return jnp.asarray(np.stack([x0, 0.8 * x0, 1.2 * x0]))


@pytest.mark.parametrize("name", sorted(CASES))
def test_jit_equals_eager(name):
    f, x0, _, _ = CASES[name]
    x = jnp.asarray(x0)
    np.testing.assert_allclose(jax.jit(f)(x), f(x), rtol=1e-9, atol=1e-12)


@pytest.mark.parametrize("name", sorted(CASES))
def test_vmap_equals_loop(name):
    f, x0, batch, _ = CASES[name]
    xs = _batch(x0, batch)
    looped = np.stack([np.asarray(f(x)) for x in xs])
    np.testing.assert_allclose(jax.vmap(f)(xs), looped, rtol=1e-9, atol=1e-12)


@pytest.mark.parametrize("name", sorted(CASES))
def test_grad_matches_finite_difference(name):
    f, x0, _, eps = CASES[name]
    x = jnp.asarray(x0, float)
    out = f(x)
    w = jax.random.normal(jax.random.key(1), jnp.shape(out))
    v = jax.random.normal(jax.random.key(2), jnp.shape(x))

    def scalar(y):
        return jnp.sum(w * f(y))

    g = jax.grad(scalar)(x)
    directional = float(jnp.vdot(g, v))
    fd = H.directional_fd(scalar, x, v, eps)
    assert np.all(np.isfinite(np.asarray(g)))
    assert abs(fd) > 1e-6, f"derivative too small to test ({fd})"
    np.testing.assert_allclose(directional, fd, rtol=2e-5, atol=1e-9)


def test_outer_jit_of_closed_over_eyes_does_not_recompile_per_value():
    """One compilation serves every accommodation value (floats are leaves, not static)."""
    f = jax.jit(core_vs_accommodation)
    values = [float(f(jnp.asarray(a))) for a in (1.8, 2.0, 2.2)]
    assert f._cache_size() == 1
    assert len(set(values)) == 3


def test_traced_nan_raises_instead_of_returning_nan():
    z = np.asarray(EYES.zernike_um)[0].copy()
    z[5] = np.nan
    with pytest.raises(Exception, match="zernike_um contains non-finite"):
        jax.block_until_ready(jax.jit(core_vs_zernike)(jnp.asarray(z)))


def test_traced_negative_pupil_raises():
    def vs(pupil):
        scene = Scene(LAYOUT.centres_mm, LAYOUT.diameters_mm, 2.0, jnp.asarray([2.4]), pupil)
        return retinal_metrics(EYES, scene, SPECTRUM, _accommodation(jnp.asarray(2.2)), CONFIG).vsotf

    with pytest.raises(Exception, match="pupil_diameter_mm must be in"):
        jax.block_until_ready(jax.jit(vs)(jnp.asarray(-1.0)))
    with pytest.raises(Exception, match="pupil_diameter_mm must be in"):
        jax.block_until_ready(jax.jit(vs)(jnp.asarray(3.5)))


def test_array_likes_are_converted_on_construction_and_default_sampling_is_planned():
    """Eyes, Layout and Spectrum built from NumPy arrays work in the pipeline (they used to
    fail deep inside with "'numpy.ndarray' object has no attribute 'at'"); with no sampling
    given, through_focus plans one with the field guard and reports it."""
    from lfjax.model.layouts import Layout
    from lfjax.kernel.optics import field_check
    from lfjax.model.spectral import Spectrum
    from lfjax.vision.focus import through_focus

    eyes = lfjax.Eyes(np.zeros((1, 15)), 3.0)
    assert isinstance(eyes.zernike_um, jax.Array)
    grid2 = lfjax.grid_layout(2, 3.0)
    layout = Layout(np.asarray(grid2.centres_mm), np.asarray(grid2.diameters_mm), 1.5, "2x2")
    s = lfjax.make_spectrum([550.0])
    spectrum = Spectrum(*(np.asarray(x) for x in (s.wavelengths_nm, s.weights, s.lca_D,
                                                   s.sce_rho_per_mm2)))
    acc = np.round(np.arange(0, 26) * 0.2, 9)
    with pytest.raises(ValueError, match="aliasing"):  # the old default refuses this scene
        through_focus(
            eyes,
            layout,
            States.grid(acc, depths_D=[0.0, 4.0]),
            Viewing(cdp_D=2.0),
            spectrum=spectrum,
            sampling=lfjax.Sampling(),
        )
    tf = through_focus(
        eyes, layout, States.grid(acc, depths_D=[0.0, 4.0]), Viewing(cdp_D=2.0), spectrum=spectrum
    )
    assert tf.sampling is not None and tf.sampling.freq_step_cpd < 1.0
    field_check(eyes.zernike_um, 3.0, 3.0, 2.0, acc, [0.0, 4.0], layout, spectrum, tf.sampling)
    assert np.all(np.isfinite(np.asarray(tf.vsotf)))
    with pytest.raises(ValueError, match="Spectrum.weights must have the shape"):
        Spectrum(np.array([500.0, 600.0]), np.array([1.0]), np.zeros(2), np.zeros(2))


def test_python_floats_and_arrays_give_one_compilation():
    """A Scene built from Python floats and one built from arrays of the same dtype are the
    same input type to jax.jit (no weak types leak into the leaves): one trace, not two."""
    import equinox as eqx

    traces = []

    @eqx.filter_jit
    def doubled_cdp(scene, accommodation):
        traces.append(None)
        return 2.0 * scene.cdp_D + accommodation.sa_radius_mm

    real = jnp.result_type(float)
    from_floats = Scene([[0.0, 0.0]], [3.0], 2.0, [1.0], 3.0)
    from_arrays = Scene(jnp.zeros((1, 2), real), jnp.full((1,), 3.0, real), jnp.asarray(2.5, real),
                        jnp.ones((1,), real), jnp.asarray(3.0, real))
    options = lfjax.ModelOptions()
    doubled_cdp(from_floats, Accommodation.shared([1.0], [[0]], options, 3.0))
    doubled_cdp(from_arrays, Accommodation.shared(jnp.ones((1,), real), [[0]], options,
                                                  jnp.asarray(3.0, real)))
    assert len(traces) == 1
