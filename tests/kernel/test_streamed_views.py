"""Views one at a time (lfjax.kernel.pipeline.rendered_otfs above ELEMENTAL_STACK_BYTES) give
the rendered OTFs, and their gradients, of all views transformed together.

Covers: lfjax.kernel.pipeline
"""

from __future__ import annotations

import functools

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import helpers as H
import lfjax
from lfjax.display.aberrations import LensletAberration
from lfjax.display.lenslets import DisplayOptics
from lfjax.kernel.pipeline import (
    ELEMENTAL_STACK_BYTES, Accommodation, PipelineConfig, Scene, rendered_otfs, streams_views,
)

SAMPLING = lfjax.Sampling(2.5, edge_width_samples=0.25)
WAVELENGTHS = [450.0, 550.0, 650.0]


def _displays():
    strips = jnp.asarray([[0.0, 1.0, 0.0], [1.0, 0.0, 1.0], [0.0, 1.0, 0.0]])
    return {
        "none": None,
        "pixels": DisplayOptics(pixel_width_arcmin=4.0),
        "diffraction": DisplayOptics("fresnel", "circle", 400.0, 1.5),
        "aberration": DisplayOptics(pixel_width_arcmin=2.0).with_aberration(
            LensletAberration(spherical_um=0.3, astigmatism_um=0.2)),
        "strips-leakage": DisplayOptics(aperture="strip", y_defocus_D=-0.5, leakage_weight=0.3,
                                        neighbours=strips),
    }


def _inputs(display_name: str, normalisation: str):
    options = lfjax.ModelOptions(wavelength_normalisation=normalisation)
    spectrum = lfjax.make_spectrum(WAVELENGTHS, options)
    display = _displays()[display_name]
    if display_name == "strips-leakage":
        centres = np.asarray([[-0.9, 0.0], [0.0, 0.0], [0.9, 0.0]])
        diameters = np.full(3, 0.9)
    else:
        centres = np.asarray([[-0.7, -0.6], [0.7, -0.6], [-0.7, 0.6], [0.7, 0.6]])
        diameters = np.asarray([0.9, 1.0, 0.8, 1.1])
    cfg = PipelineConfig.build(spectrum.wavelengths_nm, 1.1, 3.0, SAMPLING, options, display=display)
    scene = Scene(jnp.asarray(centres, jnp.float32), jnp.asarray(diameters, jnp.float32), 2.0,
                  jnp.asarray([1.5, 2.0, 2.6], jnp.float32), 3.0, display)
    states = np.asarray([1.6, 1.9, 2.2, 2.5])
    pairs = np.asarray([[0, 1], [1, 2], [2, 3]])  # states shared between depths
    acc = Accommodation.shared(states, pairs, options, 3.0)
    z = jnp.asarray(np.asarray(lfjax.sample_eyes(1, 7).zernike_um)[0]).at[:3].set(0.0)
    return z, scene, spectrum, acc, cfg


def _otfs(stack_bytes, z, scene, spectrum, acc, cfg):
    return _rendered(z, scene, spectrum, acc, cfg.bands, cfg.sampling, stack_bytes)


@functools.partial(jax.jit, static_argnums=(4, 5, 6))
def _rendered(z, scene, spectrum, acc, bands, sampling, stack_bytes):
    return rendered_otfs(z, 6.0, scene, spectrum, acc, bands, sampling, stack_bytes)


# every display under the paper's normalisation; unit_sum (the one coupling between views)
# on the displays whose pupil grids differ: plain windows, diffracted beams, strips
CASES = ([(name, "transmitted_energy") for name in _displays()]
         + [(name, "unit_sum") for name in ("none", "diffraction", "strips-leakage")])


@pytest.mark.parametrize("display_name, normalisation", CASES)
def test_views_one_at_a_time_render_what_all_views_together_do(display_name, normalisation):
    inputs = _inputs(display_name, normalisation)
    n_states, n_views = inputs[3].states_D.shape[0], inputs[1].centres_mm.shape[0]
    assert streams_views(n_states, n_views, inputs[4].n_fft, SAMPLING, 0)
    assert not streams_views(n_states, n_views, inputs[4].n_fft, SAMPLING, 2**40)
    together = np.asarray(_otfs(2**40, *inputs))
    streamed = np.asarray(_otfs(0, *inputs))
    n_fft = inputs[4].n_fft
    assert together.shape == streamed.shape == (3, 2, n_fft, n_fft // 2 + 1)
    np.testing.assert_allclose(together[..., 0, 0], 1.0, atol=1e-6)
    # sums of the same terms in another order (float32 rounding at most)
    assert np.max(np.abs(streamed - together)) < 2e-6


def test_streamed_gradients_match_and_one_view_or_the_mft_never_streams():
    """Under jax.vmap the streamed views give each eye's OTFs; the reverse pass through the streamed views (each view's transforms recomputed, not
    kept) gives the gradient of the whole stack, for the eye and for the views' geometry."""
    z, scene, spectrum, acc, cfg = _inputs("diffraction", "unit_sum")
    shape = (3, 2, cfg.n_fft, cfg.n_fft // 2 + 1)
    weights = jnp.asarray(np.random.default_rng(3).normal(size=shape), jnp.float32)

    def loss(stack_bytes, coefficients, centres, diameters):
        s = Scene(centres, diameters, scene.cdp_D, scene.depths_D, scene.pupil_diameter_mm, scene.display)
        return jnp.sum(weights * jnp.real(_otfs(stack_bytes, coefficients, s, spectrum, acc, cfg)))

    args = (z, scene.centres_mm, scene.diameters_mm)
    together = jax.jit(jax.grad(lambda *a: loss(2**40, *a), argnums=(0, 1, 2)))(*args)
    streamed = jax.jit(jax.grad(lambda *a: loss(0, *a), argnums=(0, 1, 2)))(*args)
    for a, b in zip(together, streamed):
        a, b = np.asarray(a), np.asarray(b)
        assert np.all(np.isfinite(b)) and np.max(np.abs(a)) > 0
        np.testing.assert_allclose(b, a, rtol=2e-4, atol=2e-4 * np.max(np.abs(a)))
    # vmapped from outside over eyes: each eye's streamed OTFs, as one at a time
    eyes = jnp.stack([z, 0.5 * z])
    batched = jax.vmap(lambda c: _otfs(0, c, scene, spectrum, acc, cfg))(eyes)
    for i in range(2):
        np.testing.assert_allclose(np.asarray(batched[i]), np.asarray(_otfs(2**40, eyes[i], scene, spectrum, acc, cfg)),
                                   atol=2e-6)
    assert not streams_views(10, 1, 4096, SAMPLING, 0)
    assert not streams_views(10, 9, 4096, lfjax.Sampling(2.5, transform="mft"), 0)
    assert ELEMENTAL_STACK_BYTES >= 64 * 2**20


def test_the_paper_study_and_optimise_shapes_do_not_stream():
    """The paper study's layouts at their planned FFT sizes (REPORT.md's settings table: 26
    states; 2x2 on 160, 3x3 on 120) and ``lfjax optimise``'s largest problem (20 states of
    4 views on 360) hold their stacks whole (11–40 MiB, below the threshold), so they keep
    their batched transforms; the phone design's counts (87 MB and up) stream."""
    sampling = lfjax.Sampling(1.0)
    with jax.enable_x64(False):  # the commands run in float32 (the suite in float64)
        for n_states, n_views, n_fft in ((26, 1, 240), (26, 4, 160), (26, 9, 120), (20, 4, 360)):
            assert not streams_views(n_states, n_views, n_fft, sampling)
        for n_states, n_views, n_fft in ((15, 4, 600), (16, 4, 972), (16, 16, 1440)):
            assert streams_views(n_states, n_views, n_fft, sampling)
    assert H.PLAIN is not None
