"""Every matrix product in lfjax asks for full float32 precision.

By default JAX lets float32 matrix products run at reduced precision on accelerators (TF32,
10-bit mantissa, on NVIDIA GPUs since Ampere; bfloat16 passes on TPU). lfjax's products are
not neural-network layers: the separable wavefront sums monomials that cancel, the matrix
Fourier transform sums phase factors, and the three-point peak fit differences metric values
that agree to 1e-4. Each product therefore names ``Precision.HIGHEST``. This is checked here on
the traced programs (the CPU ignores the setting, so a CPU run could not see it otherwise).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
from jax.extend import core as jcore

import lfjax
from lfjax.vision.images import psf_on_grid
from lfjax.kernel.metrics import radial_mtf
from lfjax.vision.peaks import accommodation_peaks
from lfjax.kernel.pipeline import Accommodation, PipelineConfig, Scene, retinal_metrics
from lfjax.vision.peak_options import PeakOptions

HIGHEST = (jax.lax.Precision.HIGHEST, jax.lax.Precision.HIGHEST)


def _dot_precisions(jaxpr):
    """The ``precision`` of every dot_general in a jaxpr and in the jaxprs inside it."""
    for eqn in jaxpr.eqns:
        if eqn.primitive.name == "dot_general":
            yield eqn.params["precision"]
        for value in eqn.params.values():
            for sub in value if isinstance(value, (tuple, list)) else (value,):
                if isinstance(sub, jcore.ClosedJaxpr):
                    yield from _dot_precisions(sub.jaxpr)
                elif isinstance(sub, jcore.Jaxpr):
                    yield from _dot_precisions(sub)


def _assert_full_precision(fn, *args):
    precisions = list(_dot_precisions(jax.make_jaxpr(fn)(*args).jaxpr))
    assert precisions, "no matrix product traced: the check would be vacuous"
    assert all(p == HIGHEST for p in precisions), precisions


def _scene(layout, transform="fft"):
    spectrum = lfjax.make_spectrum([450.0, 550.0, 650.0])
    sampling = lfjax.Sampling(1.5, transform=transform, mft_pupil_samples=32)
    config = PipelineConfig.build(spectrum.wavelengths_nm, layout.window_diameter_mm, 3.0,
                                  sampling, lfjax.ModelOptions())
    scene = Scene.from_layout(layout, [2.0, 2.5], 2.0, 3.0)
    grid = np.round(np.arange(8, 16) * 0.2, 9)
    index = np.broadcast_to(np.arange(grid.size), (2, grid.size))
    accommodation = Accommodation.shared(grid, index, lfjax.ModelOptions(), 3.0)
    return spectrum, config, scene, accommodation


def test_pipeline_products_are_full_precision_fft_and_mft():
    eyes = lfjax.sample_eyes(0, 2)
    for layout, transform in ((lfjax.grid_layout(2), "fft"), (lfjax.grid_layout(2), "mft"),
                              (lfjax.open_pupil(3.0), "fft")):
        spectrum, config, scene, accommodation = _scene(layout, transform)
        _assert_full_precision(
            lambda z: retinal_metrics(lfjax.Eyes(z, 6.0), scene, spectrum, accommodation,
                                      config).vsotf, eyes.zernike_um)


def test_local_peak_fit_and_radial_mtf_are_full_precision():
    eyes = lfjax.sample_eyes(0, 2)
    spectrum, config, scene, accommodation = _scene(lfjax.grid_layout(2))
    _assert_full_precision(
        lambda z: accommodation_peaks(
            lfjax.Eyes(z, 6.0),
            scene,
            spectrum,
            accommodation,
            config,
            metric="vsotf",
            peaks=PeakOptions(method="local"),
        ).accommodation_D,
        eyes.zernike_um,
    )
    # the ring average gathers and sums (O(L²) memory, no O(L³) binning matrix): it has no
    # matrix product whose precision a GPU or TPU could lower
    jaxpr = jax.make_jaxpr(lambda otf: radial_mtf(otf, 16, 1.0)[0])(
        jnp.ones((16, 9), jnp.complex64)).jaxpr
    assert not list(_dot_precisions(jaxpr))


def test_eye_draw_psf_and_pixel_psf_are_full_precision():
    _assert_full_precision(lambda key: lfjax.sample_eyes(key, 3).zernike_um, jax.random.key(0))
    z = np.asarray(lfjax.sample_eyes(0, 1).zernike_um)[0]
    _assert_full_precision(
        lambda c: lfjax.monochromatic_psf(c, 6.0, 3.0, 550.0, 0.5, 32), jnp.asarray(z))
    _assert_full_precision(lambda otf: psf_on_grid(otf, 1.0, 0.5, 16, 16),
                           jnp.ones((16, 9), jnp.complex64))
