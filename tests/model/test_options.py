"""Physical parameters are data (lfjax.model.options.ModelParameters): the numeric face of every
modelling choice reproduces the string options exactly, the predicted accommodation is
differentiable in the accommodation-SA slope and the LCA constant A (checked against
central differences of re-solved peaks, float64), a numeric change reuses the compiled
program while a static choice compiles a new one, and a vmapped batch of variants equals
the variants run one by one."""

from __future__ import annotations

import contextlib

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import lfjax
from lfjax.model.options import (
    STATIC_CHOICES,
    ModelOptions,
    ModelParameters,
    stack_parameters,
)
from lfjax.vision.peaks import accommodation_peaks
from lfjax.kernel.pipeline import Accommodation, PipelineConfig, Scene
from lfjax.reproduce.alternatives import ALTERNATIVES
from lfjax.kernel.scene import sa_parameters
from lfjax.model.spectral import make_spectrum
from lfjax.vision.focus import through_focus, through_focus_variants
from lfjax.vision.peak_options import PeakOptions
from lfjax.vision.prepare import States

VARIANTS = [ModelOptions()] + [ModelOptions().replace(**c) for c in ALTERNATIVES.values()] + [
    ModelOptions(sce="off"), ModelOptions(accommodation_sa="off"),
    ModelOptions(sce_rho_scale=0.7, lca_c_nm=210.0, lca_reference_nm=560.0,
                 sa_slope_um_per_D=-0.05, sa_reference_pupil_mm=6.0),
]


@pytest.mark.parametrize("options", VARIANTS, ids=lambda o: f"{o.sce}-{o.accommodation_sa}-"
                         f"{o.wavelength_normalisation}-{o.lca_A}-{o.sce_rho_scale}")
def test_numeric_parameters_reproduce_the_string_options(options):
    """Spectrum and accommodation SA built from ModelParameters (the traced path) equal
    those built from the options on the host; the numeric forms are the documented ones."""
    wl = np.arange(400.0, 701.0, 30.0)
    host = make_spectrum(wl, options)
    traced = jax.jit(lambda p: make_spectrum(wl, options, parameters=p))(options.parameters())
    for name in ("wavelengths_nm", "weights", "lca_D", "sce_rho_per_mm2", "unit_sum"):
        np.testing.assert_allclose(np.asarray(getattr(traced, name)),
                                   np.asarray(getattr(host, name)), rtol=1e-12, atol=1e-12,
                                   err_msg=name)
    for pupil in (3.0, 4.5):
        np.testing.assert_allclose(np.asarray(sa_parameters(options.parameters(), pupil)),
                                   np.asarray(sa_parameters(options, pupil)), rtol=1e-12)
    p = options.parameters()
    assert float(p.sce_exponent) == {"amplitude": 1.0, "intensity": 0.5, "off": 0.0}[options.sce]
    assert float(p.unit_sum) == float(options.wavelength_normalisation == "unit_sum")


def test_accommodation_sa_readings_as_numbers():
    """c(4,0) per dioptre and its Zernike radius for each reading, 3 mm pupil, 5 mm reference."""
    slope = -0.0435
    expected = {"scaled": (slope * 0.6**4, 1.5), "wavefront_5mm": (slope, 2.5),
                "unscaled": (slope, 1.5), "off": (0.0, 1.5)}
    for form, (c40, radius) in expected.items():
        got = np.asarray(sa_parameters(ModelOptions(accommodation_sa=form).parameters(), 3.0))
        np.testing.assert_allclose(got, [c40, radius], rtol=1e-12, err_msg=form)


def test_bad_parameters_are_refused_by_name():
    with pytest.raises(ValueError, match="sce_rho_scale must be >= 0"):
        ModelOptions(sce_rho_scale=-1.0)
    with pytest.raises(ValueError, match=r"ModelParameters.lca_c_nm must be < 380 nm"):
        ModelOptions().parameters().replace(lca_c_nm=400.0)
    with pytest.raises(ValueError, match=r"ModelParameters.sa_reference_pupil_mm must be > 0"):
        stack_parameters([ModelOptions().parameters(),
                          ModelOptions().parameters().replace(sa_reference_pupil_mm=0.0)])
    with pytest.raises(ValueError, match="batch must be one of"):
        through_focus_variants(
            lfjax.sample_eyes(0, 1), None, States.around([2.0]), [ModelOptions()], batch="pmap"
        )


# ----------------------------------------------------------------------------- gradients

WL = [620.0]  # LCA −0.33 D here: the peak moves with A
GRID = np.round(np.arange(1.0, 3.01, 0.5), 9)  # brackets only; Newton refines
DEPTH = 2.0


def _peak_function():
    options = ModelOptions()
    layout = lfjax.open_pupil(3.0)
    spectrum = make_spectrum(WL, options)
    config = PipelineConfig.build(spectrum.wavelengths_nm, layout.window_diameter_mm, 3.0,
                                  lfjax.Sampling(1.5), options)
    scene = Scene.from_layout(layout, [DEPTH], 2.0, 3.0)
    index = np.arange(GRID.size)[None]
    eyes = lfjax.Eyes(np.asarray(lfjax.sample_eyes(2, 1).zernike_um)[:, :10], 3.0)

    def peak_of(p: ModelParameters):
        """Predicted accommodation (D, the VSOTF peak by Newton) of one aberrated eye."""
        return accommodation_peaks(
            eyes,
            scene,
            make_spectrum(WL, options, parameters=p),
            Accommodation.shared(GRID, index, p, 3.0),
            config,
            metric="vsotf",
            peaks=PeakOptions(method="newton"),
        ).accommodation_D[0, 0]

    return peak_of, options.parameters()


def test_predicted_accommodation_gradient_in_sa_slope_and_lca_A_matches_finite_differences():
    """d(peak)/d(SA slope) and d(peak)/d(LCA A) from one reverse pass through the solver
    (implicit function theorem) against central differences of re-solved peaks."""
    peak_of, p = _peak_function()
    # one compiled program gives the gradient and the re-solved peaks of the differences
    # (its value is the same forward solve): one compile instead of two
    value_and_grad = jax.jit(jax.value_and_grad(peak_of))
    grad = value_and_grad(p)[1]
    assert isinstance(grad, ModelParameters)
    for name, eps in (("sa_slope_um_per_D", 1e-3), ("lca_A", 1.0)):
        value = getattr(p, name)
        fd = (float(value_and_grad(p.replace(**{name: value + eps}))[0])
              - float(value_and_grad(p.replace(**{name: value - eps}))[0])) / (2.0 * eps)
        assert abs(fd) * eps > 1e-4, f"{name}: the peak barely moves ({fd} D per unit)"
        np.testing.assert_allclose(float(getattr(grad, name)), fd, rtol=1e-4, err_msg=name)


# ----------------------------------------------------------------------------- compilation


def test_numbers_do_not_recompile_static_choices_do():
    """Every numeric parameter and every choice with a numeric form is data: changing it
    reuses the compiled program; a static choice (the NCSF model) compiles a new one."""
    compiles = []

    def listener(event, duration, **kwargs):
        # the pipeline's program only: host-side eager ops (an integer power with a new
        # exponent) compile tiny programs of their own, as any new jnp call does
        name = str(kwargs.get("fun_name"))
        if event == "/jax/core/compile/backend_compile_duration" and "metrics_and_peaks" in name:
            compiles.append(name)

    eyes = lfjax.sample_eyes(0, 1)
    spectrum_wl = [500.0, 600.0]

    def run(options):
        tf = through_focus(
            eyes,
            None,
            States.grid([1.8, 2.0, 2.2], depths_D=[2.0]),
            spectrum=make_spectrum(spectrum_wl, options),
            sampling=lfjax.Sampling(2.0),
            options=options,
            check_aliasing=False,
        )
        return jax.block_until_ready(tf.vsotf)

    # counted compiles must be real ones: a program another test (or another worker, through
    # the session's shared disk cache) already compiled would be found, not compiled, so
    # the in-memory, persistent and exported-program caches are all out of play here
    from lfjax.base import programs

    kept_folder = programs.program_cache_folder()
    programs.enable_program_cache(None)
    programs.clear_loaded()
    jax.clear_caches()
    with _persistent_cache_off():
        first = run(ModelOptions())
        jax.monitoring.register_event_duration_secs_listener(listener)
        try:
            numeric = [ModelOptions(lca_A=640.0), ModelOptions(sa_slope_um_per_D=-0.06),
                       ModelOptions(sce="intensity"), ModelOptions(accommodation_sa="unscaled"),
                       ModelOptions(wavelength_normalisation="unit_sum"),
                       ModelOptions(sce_rho_scale=0.5, lca_c_nm=200.0)]
            values = [run(o) for o in numeric]
            assert compiles == [], f"a numeric change recompiled: {compiles}"
            assert all(not np.allclose(v, first) for v in values)
            assert "ncsf" in STATIC_CHOICES
            run(ModelOptions(ncsf="campbell_green_2004"))
            assert len(compiles) == 1, compiles
        finally:
            jax.monitoring.unregister_event_duration_listener(listener)
            programs.enable_program_cache(kept_folder)


@contextlib.contextmanager
def _persistent_cache_off():
    kept = jax.config.jax_enable_compilation_cache
    jax.config.update("jax_enable_compilation_cache", False)
    try:
        yield
    finally:
        jax.config.update("jax_enable_compilation_cache", kept)


@pytest.mark.parametrize("batch", ["vmap", "map", "loop"])
def test_batched_variants_equal_the_variants_one_by_one(batch):
    """through_focus_variants (one program over stacked parameters, vmapped or mapped) gives
    each variant's through_focus numbers, and refuses variants differing in a static choice."""
    eyes = lfjax.sample_eyes(1, 1)
    layout = lfjax.grid_layout(2, 3.0)
    options = [ModelOptions(), ModelOptions(sce="intensity", lca_A=633.46),
               ModelOptions(accommodation_sa="wavefront_5mm", wavelength_normalisation="unit_sum")]
    wl = [500.0, 600.0]
    states = lfjax.States.grid([1.6, 2.0, 2.4], [2.0, 2.4])
    viewing = lfjax.Viewing(pupil_diameter_mm=3.0, cdp_D=2.0)
    sampling = lfjax.Sampling(1.5)
    batch = through_focus_variants(eyes, layout, states, options, viewing, wavelengths_nm=wl,
                                   samplings=[sampling] * 3, batch=batch)
    for o, b in zip(options, batch):
        one = through_focus(eyes, layout, states, viewing, spectrum=make_spectrum(wl, o),
                            sampling=sampling, options=o)
        np.testing.assert_allclose(np.asarray(b.vsotf), np.asarray(one.vsotf), rtol=1e-10)
        np.testing.assert_allclose(np.asarray(b.strehl), np.asarray(one.strehl), rtol=1e-10)
        assert b.sampling == one.sampling
    assert not np.allclose(np.asarray(batch[0].vsotf), np.asarray(batch[2].vsotf))
    with pytest.raises(ValueError, match="ModelOptions.vsotf_reference must agree"):
        through_focus_variants(eyes, layout, lfjax.States.grid([1.6, 2.0, 2.4], [2.0]),
                               [ModelOptions(), ModelOptions(vsotf_reference="open_pupil")],
                               viewing)


@pytest.mark.parametrize("batch", ["vmap", "map"])
def test_batched_variants_program_is_exported_and_reloaded(tmp_path, batch):
    """The batched variants' program goes through the program cache like through_focus's: a
    later process (here: the loaded programs forgotten) calls the exported form, without
    tracing it again, and gets the same numbers (on an accelerator, where the variants are
    vmapped, tracing it cost seconds per layout in every ``lfjax reproduce``)."""
    from lfjax.base import programs
    from lfjax.vision import focus

    eyes = lfjax.sample_eyes(1, 1)
    layout = lfjax.grid_layout(2, 3.0)
    options = [ModelOptions(), ModelOptions(sce="intensity", lca_A=633.46)]
    states = lfjax.States.grid([1.6, 2.0, 2.4], [2.0, 2.4])
    kw = dict(wavelengths_nm=[500.0, 600.0], samplings=[lfjax.Sampling(1.5)] * 2, batch=batch,
              peaks=lfjax.PeakOptions(metrics=("vsotf",), method="vertex"))
    kept = programs.program_cache_folder()
    folder = programs.enable_program_cache(tmp_path / "programs")
    programs.clear_loaded()
    traced = []
    original = focus._metrics_and_peaks_variants

    def counting(*args, **kwargs):
        traced.append(1)
        return original(*args, **kwargs)

    try:
        focus._metrics_and_peaks_variants = counting
        first = through_focus_variants(eyes, layout, states, options, **kw)
        assert len(list(folder.glob("*.jaxexport"))) == 1 and traced == [1]
        programs.clear_loaded()  # a new process
        again = through_focus_variants(eyes, layout, states, options, **kw)
        assert traced == [1]  # loaded from the file, not traced
    finally:
        focus._metrics_and_peaks_variants = original
        programs.enable_program_cache(kept)
        programs.clear_loaded()
    for a, b in zip(first, again):
        np.testing.assert_array_equal(np.asarray(a.vsotf), np.asarray(b.vsotf))
        np.testing.assert_array_equal(np.asarray(a.continuous_accommodation_D()),
                                      np.asarray(b.continuous_accommodation_D()))
