"""Display effects (lfjax.display.lenslets): lenslet diffraction and finite pixels against their limits,
analytic Fresnel diffraction, finite-difference gradients and bad input.

Covers: lfjax.studies.display_effects, lfjax.base.apertures
"""

from __future__ import annotations

import math
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pytest
import scipy.special

import helpers as H
import lfjax
from lfjax.planner import PlanScene, plan_sampling
from lfjax.planner.proxy import Proxy
from lfjax.display.lenslets import DisplayOptics, LensletArray, fresnel_propagate, lenslets_for_layout
from lfjax.vision.psf import polychromatic_otf
from lfjax.vision.focus import metrics_at, through_focus
from lfjax.vision.prepare import States
from lfjax.vision.viewing import Viewing

WL = [550.0]
OPTIONS = lfjax.ModelOptions()


def _soft_disc(n, dx, radius, edge):
    from lfjax.kernel.optics import soft_disk

    k = (np.arange(n) - n // 2) * dx
    xx, yy = np.meshgrid(k, k)
    return soft_disk(jnp.asarray(xx**2 + yy**2), radius, edge), k


@pytest.mark.parametrize("fresnel_number", [0.5, 1.0, 1.5, 2.5])
def test_pinhole_on_axis_matches_the_analytic_fresnel_integral(fresnel_number):
    """A circular aperture of radius R at distance z has on-axis field 1 − exp(iπR²/(λz))
    (Goodman §4.5): zero at even Fresnel numbers N = R²/(λz), a bright spot of amplitude 2
    at odd ones."""
    radius, lam = 0.5, 550e-6
    z = radius**2 / (lam * fresnel_number)
    n, dx = 256, 1.4 / 256
    aperture, _ = _soft_disc(n, dx, radius, 0.25 * dx)
    field = fresnel_propagate(aperture.astype(complex), dx, lam, z)
    expected = 1.0 - np.exp(1j * math.pi * fresnel_number)
    np.testing.assert_allclose(complex(field[n // 2, n // 2]), expected, atol=6e-3)


def test_square_aperture_matches_the_fresnel_integrals_off_axis():
    """A square (slit × slit) diffracts separably: a(x)·a(y), a(x) = ([C] + i[S])/√(2i) of the
    Fresnel integrals between the edges (scipy.special.fresnel), along a whole profile."""
    half, lam, z = 0.4, 550e-6, 250.0  # Fresnel number 1.16 per half-width
    n, dx = 256, 1.6 / 256
    k = (np.arange(n) - n // 2) * dx
    xx, yy = np.meshgrid(k, k)
    edge = 0.25 * dx
    inside = np.minimum(half - np.abs(xx), half - np.abs(yy))
    aperture = jax.nn.sigmoid(jnp.asarray(inside) / edge)
    field = np.asarray(fresnel_propagate(aperture.astype(complex), dx, lam, z))

    def slit(x):
        scale = math.sqrt(2.0 / (lam * z))
        s2, c2 = scipy.special.fresnel(scale * (half - x))
        s1, c1 = scipy.special.fresnel(scale * (-half - x))
        return ((c2 - c1) + 1j * (s2 - s1)) / np.sqrt(2j)

    central = np.abs(k) <= 0.55
    expected = slit(k[central]) * slit(0.0)
    np.testing.assert_allclose(field[n // 2, central], expected, atol=8e-3)
    # and the window keeps the energy the analytic pattern puts inside it (≈ 94.5 %: the rest
    # leaves the window and is not wrapped back in)
    inside = (np.sum(np.abs(slit(k)) ** 2) * dx / (2 * half)) ** 2
    assert inside < 0.96
    assert np.sum(np.abs(field) ** 2) / np.sum(np.abs(np.asarray(aperture)) ** 2) == pytest.approx(inside, rel=1e-2)


def _vsotf(display, layout=None, sampling=lfjax.Sampling(1.2, edge_width_samples=0.25)):
    layout = lfjax.grid_layout(2, 3.0) if layout is None else layout
    eye = lfjax.average_eye(3.0)
    acc = np.array([[0.6, 1.0, 1.4], [1.6, 2.0, 2.4]])
    return np.asarray(
        metrics_at(
            eye,
            layout,
            [1.0, 2.0],
            acc,
            Viewing(pupil_diameter_mm=3.0, cdp_D=2.0, display=display),
            spectrum=lfjax.make_spectrum(WL),
            sampling=sampling,
            options=OPTIONS,
        )[0]
    )


def test_large_ideal_lenslet_converges_to_the_geometric_subaperture():
    """As the Fresnel number grows (a nearer display for the same views), the diffracted
    views' through-focus VSOTF converges to the paper's geometric subapertures."""
    ideal = _vsotf(None)
    errors = []
    for distance in (300.0, 30.0, 3.0, 0.3):
        lenslets = lenslets_for_layout(2, 3.0, 2.0, distance)
        errors.append(np.abs(_vsotf(lenslets.optics()) - ideal).max())
    assert errors[0] > 0.01  # a desktop display at 30 cm diffracts visibly (N ≈ 1.4)
    assert all(b < a for a, b in zip(errors, errors[1:])), errors
    assert errors[-1] < 3e-3, errors


def test_diffraction_off_and_zero_pixels_change_nothing():
    """An ideal DisplayOptics (diffraction off, point emitters) is the paper's display,
    bit for bit; so is a lenslet array's optics with 0 mm pixels and diffraction off."""
    ideal = _vsotf(None)
    np.testing.assert_array_equal(_vsotf(DisplayOptics()), ideal)
    optics = lenslets_for_layout(2, 3.0, 2.0, 300.0).optics(0.0, diffraction="off")
    np.testing.assert_array_equal(_vsotf(optics), ideal)


def test_pixels_multiply_the_otf_by_the_emitter_sinc():
    """A square emitter of angular width a multiplies the rendered OTF by sinc(a f_x)·sinc(a f_y)."""
    eye = lfjax.average_eye(3.0)
    sampling = lfjax.Sampling(2.0)
    spectrum = lfjax.make_spectrum(WL)
    width_arcmin = 1.5
    base = polychromatic_otf(
        eye,
        [2.0],
        Viewing(pupil_diameter_mm=3.0, cdp_D=2.0),
        spectrum=spectrum,
        sampling=sampling,
        options=OPTIONS,
    )
    blurred = polychromatic_otf(
        eye,
        [2.0],
        Viewing(
            pupil_diameter_mm=3.0,
            cdp_D=2.0,
            display=DisplayOptics(pixel_width_arcmin=width_arcmin),
        ),
        spectrum=spectrum,
        sampling=sampling,
        options=OPTIONS,
    )
    n = base.n_fft
    a_deg = width_arcmin / 60.0
    fy = np.fft.fftfreq(n, 1.0 / n) * sampling.freq_step_cpd
    fx = np.fft.rfftfreq(n, 1.0 / n) * sampling.freq_step_cpd
    expected = np.sinc(a_deg * fy)[:, None] * np.sinc(a_deg * fx)[None, :]
    np.testing.assert_allclose(np.asarray(blurred.otf)[0, 0, 0],
                               np.asarray(base.otf)[0, 0, 0] * expected, atol=1e-12)


def test_pixels_and_diffraction_are_differentiable():
    """d VSOTF / d (Fresnel distance, pixel width) and through a LensletArray d / d (focal
    length, pitch, distance) against central finite differences (float64)."""
    eye = lfjax.average_eye(3.0)
    sampling = lfjax.Sampling(1.3)
    spectrum = lfjax.make_spectrum(WL)
    acc = jnp.array([[1.2, 1.6]])

    def from_optics(z_eff, width):
        display = DisplayOptics("fresnel", "circle", z_eff, width)
        return jnp.sum(
            metrics_at(
                eye,
                lfjax.grid_layout(2, 3.0),
                [1.4],
                acc,
                Viewing(pupil_diameter_mm=3.0, cdp_D=2.0, display=display),
                spectrum=spectrum,
                sampling=sampling,
                options=OPTIONS,
            )[0]
        )

    base = (jnp.asarray(400.0), jnp.asarray(1.0))
    grads = jax.grad(from_optics, argnums=(0, 1))(*base)
    for i, h in ((0, 1.0), (1, 1e-3)):
        plus = list(base)
        minus = list(base)
        plus[i] = plus[i] + h
        minus[i] = minus[i] - h
        fd = (from_optics(*plus) - from_optics(*minus)) / (2 * h)
        assert float(grads[i]) == pytest.approx(float(fd), rel=2e-4, abs=1e-9)
        assert abs(float(grads[i])) > 1e-6

    lenslets = lenslets_for_layout(2, 3.0, 2.0, 300.0)

    # the array's numbers and the panel's pixel size (mm) in one function: one compiled
    # gradient and one compiled forward pass serve both checks
    def from_array(array, pixel_pitch_mm):
        layout = array.layout(3.0, 2)
        display = array.optics(pixel_pitch_mm, 0.8)
        return jnp.sum(
            metrics_at(
                eye,
                layout,
                [1.4],
                acc,
                Viewing(pupil_diameter_mm=3.0, cdp_D=array.cdp_D, display=display),
                spectrum=spectrum,
                sampling=sampling,
                options=OPTIONS,
            )[0]
        )

    pitch = jnp.asarray(0.01)
    grad, grad_pitch = jax.grad(from_array, argnums=(0, 1))(lenslets, pitch)
    for name, h in (("focal_length_mm", 1e-4), ("pitch_mm", 1e-5), ("distance_mm", 1e-2)):
        value = float(getattr(lenslets, name))

        def at(v, name=name):
            return from_array(eqx_replace(lenslets, name, v), pitch)

        fd = (at(value + h) - at(value - h)) / (2 * h)
        assert float(getattr(grad, name)) == pytest.approx(float(fd), rel=1e-3, abs=1e-9), name

    h = 1e-4
    fd = (from_array(lenslets, pitch + h) - from_array(lenslets, pitch - h)) / (2 * h)
    assert float(grad_pitch) == pytest.approx(float(fd), rel=1e-3) and float(grad_pitch) < 0  # bigger pixels blur


def eqx_replace(module, name, value):
    import equinox as eqx

    return eqx.tree_at(lambda m: getattr(m, name), module, jnp.asarray(value))


def test_lenslet_geometry():
    """The array built for a layout gives back its CDP and view pitch (Eq. 1 at the CDP);
    a collimating lenslet (gap = f) puts the CDP at infinity with M = 1; a pinhole (f = ∞)
    at the panel, with pixel angle w/(z_0·M) = w/L."""
    lenslets = lenslets_for_layout(3, 3.0, 2.0, 300.0)
    assert float(lenslets.cdp_D) == pytest.approx(2.0, rel=1e-9)
    assert float(lenslets.subaperture_pitch_mm) == pytest.approx(1.0, rel=1e-9)
    assert float(lenslets.fresnel_distance_mm) == pytest.approx(300.0 * 500.0 / 200.0, rel=1e-9)
    collimating = LensletArray(0.5, 0.5, 2.0, 2.0, 30.0)
    assert float(collimating.cdp_D) == 0.0 and float(collimating.magnification) == 1.0
    assert float(collimating.pixel_width_arcmin(0.01)) == pytest.approx(0.01 / 2.0 * 60 * 180 / math.pi)
    pinhole = LensletArray(0.5, 0.1, jnp.inf, 5.0, 295.0)
    assert float(pinhole.cdp_D) == pytest.approx(1000.0 / 300.0)
    assert float(pinhole.pixel_width_arcmin(0.01)) == pytest.approx(0.01 / 300.0 * 60 * 180 / math.pi)


def test_the_field_guard_knows_the_display_blur():
    """Pixels widen the PSF by half their diagonal and diffracted beams defocus over the
    whole pupil: the planner's field guard asks for a finer step than for the ideal display."""
    layout = lfjax.grid_layout(4, 3.0)
    def plan(display=None):
        scene = PlanScene(layout, depths_D=[1.0, 3.0], wavelengths_nm=[450.0, 550.0, 650.0],
                          display=display)
        return plan_sampling(scene, estimate_accuracy=False)

    ideal = plan()
    pixels = plan(DisplayOptics(pixel_width_arcmin=10.0))
    diffracted = plan(DisplayOptics("fresnel", fresnel_distance_mm=500.0))
    assert pixels.blur_radius_arcmin == pytest.approx(ideal.blur_radius_arcmin + 10.0 / math.sqrt(2))
    assert diffracted.blur_radius_arcmin > ideal.blur_radius_arcmin
    with pytest.raises(ValueError, match="aliasing"):
        through_focus(
            lfjax.average_eye(3.0),
            layout,
            States.around([1.0, 3.0]),
            Viewing(display=DisplayOptics(pixel_width_arcmin=30.0)),
            spectrum=lfjax.make_spectrum(WL),
            sampling=lfjax.Sampling(ideal.sampling.freq_step_cpd * 0.999),
        )


@pytest.mark.parametrize("display", [
    DisplayOptics("fresnel", "circle", 400.0, 0.0),
    DisplayOptics("modulus", "square", 400.0, 2.0),
    DisplayOptics("off", "square", 1.0, 3.0),
], ids=["fresnel", "modulus-square-pixels", "square-pixels"])
def test_proxy_vsotf_equals_the_pipeline_with_display_effects(display):
    """The planner's proxy models lenslet diffraction, square apertures and pixels exactly as
    the pipeline does (aberration-free eye), so its error estimates stay the pipeline's."""
    layout = lfjax.grid_layout(2, 3.0)
    depths, states = [1.0, 3.0], np.array([0.6, 1.0, 2.6, 3.0])
    spectrum = lfjax.make_spectrum([500.0, 600.0])
    df = 1.3
    tf = through_focus(
        lfjax.model.eyes.aberration_free_eye(),
        layout,
        States.grid(states, depths_D=depths),
        Viewing(pupil_diameter_mm=3.0, display=display),
        spectrum=spectrum,
        sampling=lfjax.Sampling(df),
        check_aliasing=False,
    )
    acc, dep = np.meshgrid(states, depths)
    scene = PlanScene(layout, 3.0, 2.0, pairs=(acc.ravel(), dep.ravel()), options=OPTIONS,
                      display=display)
    ours = Proxy(scene, spectrum, 0.25).vsotf(df, (acc.ravel(), dep.ravel()))
    np.testing.assert_allclose(ours, np.asarray(tf.vsotf)[0].ravel(), atol=1e-5)


@pytest.mark.parametrize("build, match", [
    (lambda: LensletArray(0.5, 0.5, 0.0, 1.0, 300.0), "focal_length_mm"),
    (lambda: LensletArray(0.5, 0.5, -2.0, 1.0, 300.0), "focal_length_mm"),
    (lambda: LensletArray(0.5, 0.6, 2.0, 1.0, 300.0), "aperture_mm"),
    (lambda: LensletArray(0.5, 0.5, 2.0, 2.5, 300.0), "gap_mm"),
    (lambda: LensletArray(0.5, 0.5, 2.0, 1.0, 300.0).optics(0.6), "pixel_pitch_mm"),
    (lambda: LensletArray(0.5, 0.5, 2.0, 1.0, 300.0).optics(0.01, 1.5), "fill_factor"),
    (lambda: DisplayOptics("fresnel", fresnel_distance_mm=0.0), "fresnel_distance_mm"),
    (lambda: DisplayOptics(pixel_width_arcmin=-1.0), "pixel_width_arcmin"),
    (lambda: DisplayOptics("wave"), "diffraction"),
    (lambda: DisplayOptics(aperture="hexagon"), "aperture"),
    (lambda: lenslets_for_layout(2, 3.0, 4.0, 300.0), "cdp_D"),
])
def test_bad_display_input_names_the_parameter(build, match):
    with pytest.raises(ValueError, match=match):
        build()


def test_traced_bad_display_values_do_not_pass_silently():
    """Inside jit the display's values are checked with eqx.error_if, not turned into NaN."""
    eye = lfjax.average_eye(3.0)
    spectrum = lfjax.make_spectrum(WL)

    @jax.jit
    def run(z_eff):
        display = DisplayOptics("fresnel", "circle", z_eff, 0.0)
        return metrics_at(
            eye,
            lfjax.grid_layout(2, 3.0),
            [2.0],
            jnp.array([[2.0]]),
            Viewing(pupil_diameter_mm=3.0, cdp_D=2.0, display=display),
            spectrum=spectrum,
            sampling=lfjax.Sampling(1.3),
            options=OPTIONS,
        )[0]

    assert np.all(np.isfinite(np.asarray(run(400.0))))
    with pytest.raises(Exception, match="fresnel_distance_mm"):
        jax.block_until_ready(run(-1.0))


# ------------------------------------------------------------------ study, notebook, CLI

NOTEBOOK = Path(__file__).resolve().parents[2] / "notebooks" / "display_effects.ipynb"


def test_notebook_matches_its_script_twin():
    outputs = H.committed_notebook_outputs(NOTEBOOK)
    assert len([o for o in outputs if "image/png" in o.get("data", {})]) >= 3


def test_notebook_executes(tmp_path):
    """notebooks/display_effects.ipynb runs top to bottom at its tiny size (the study, the
    lenslet sweep, the report section and the figures of lfjax.studies.display_effects)."""
    _, images, text = H.execute_notebook_tiny(NOTEBOOK, tmp_path)
    assert len(images) >= 3
    assert "+diffraction" in text and "+spectrum" in text
    assert {p.name for p in tmp_path.iterdir()} >= {"display_effects.png", "display_lenslet_sweep.png"}


def test_display_study_config_rejects_what_it_cannot_model():
    from lfjax.studies.display_effects import DisplayStudyConfig

    with pytest.raises(ValueError, match="display_distance_mm must be in"):
        DisplayStudyConfig(display_distance_mm=600.0)
    with pytest.raises(ValueError, match="layouts"):
        DisplayStudyConfig(layouts=("5x5",))
    with pytest.raises(ValueError, match="fill_factor"):
        DisplayStudyConfig(fill_factor=0.0)


def test_reproduce_display_eyes_beyond_the_study_is_refused(capsys, tmp_path):
    from lfjax import cli

    out = tmp_path / "never"
    code = cli.main(["reproduce", "--quick", "--display-effects", "--display-eyes", "5",
                     "--out", str(out), "--no-progress"])
    err = capsys.readouterr().err
    assert code == 2 and "--display-eyes must be in 0 ... 2" in err
    assert not out.exists()


def test_display_optics_at_is_the_arrays_optics_for_every_lenslet_size():
    """The Fresnel distance of an array depends on its distance and CDP only."""
    from lfjax.display.lenslets import display_optics_at

    for n in (2, 3, 4):
        array = lenslets_for_layout(n, 3.0, 2.0, 300.0)
        assert float(display_optics_at(300.0, 2.0).fresnel_distance_mm) == pytest.approx(
            float(array.fresnel_distance_mm), rel=1e-12)
    with pytest.raises(ValueError, match="< 500 mm"):
        display_optics_at(500.0, 2.0)


def test_accommodative_gain_and_the_two_by_two_verdict():
    """Gain 1 when accommodation follows the rendered depth, 0 when it stays at one plane;
    the verdict names the largest lenslet at which the gain drops below 0.8."""
    import xarray as xr

    from lfjax.studies.display_effects import accommodative_gain, two_by_two_verdict

    depths = np.array([0.0, 1.0, 2.0, 3.0])
    assert accommodative_gain(depths, depths + 0.2) == pytest.approx(1.0)
    assert accommodative_gain(depths, np.full(4, 2.0)) == pytest.approx(0.0, abs=1e-12)
    follows, stuck = depths, 0.5 * depths + 1.0  # gain 1 and 0.5
    predicted = np.stack([follows, follows, stuck])[:, None, :]
    sweep = xr.Dataset(
        dict(predicted_accommodation=(("distance", "eye", "depth"), predicted),
             accommodation_error=(("distance", "eye", "depth"), predicted - depths),
             ideal_accommodation_error=(("eye", "depth"), np.zeros((1, 4)))),
        coords=dict(distance=[30.0, 300.0, 480.0], depth=depths,
                    lenslet_aperture_mm=("distance", [1.4, 0.6, 0.06]),
                    fresnel_number_550nm=("distance", [32.0, 1.4, 0.09])))
    text, smallest_kept, largest_broken = two_by_two_verdict(sweep)
    assert smallest_kept == 0.6 and largest_broken == 0.06
    assert "gain 0.50" in text and "gain 1.00" in text


def test_reproduce_display_section_studies_the_average_eye_and_the_first_eyes(monkeypatch):
    """lfjax reproduce --display-effects --display-eyes 1: the study gets the first virtual
    eye and the average eye of the reproduction, its layouts, depths (whole dioptres) and
    options (the computation itself is the notebook test's)."""
    import lfjax.reproduce.run as rp
    from lfjax.reproduce import StudyConfig, study_eyes
    from lfjax.reproduce.run import _display_effects

    seen = {}

    def fake_study(eyes, names, config, progress=True, on_scene=None):
        seen.update(eyes=eyes, names=names, config=config)
        on_scene("a study scene")
        return "study"

    def fake_sweep(eyes, names, config, progress=True, on_scene=None):
        on_scene("a sweep scene")
        return "sweep"

    # the reproduction imports these names at module level: replace them where it looks them up
    monkeypatch.setattr(rp, "run_display_study", fake_study)
    monkeypatch.setattr(rp, "lenslet_sweep", fake_sweep)
    monkeypatch.setattr(rp, "display_effects_markdown", lambda study, sweep: f"{study}+{sweep}")
    config = StudyConfig.quick(n_eyes=3, depth_offsets_D=(-2.0, -0.5, 0.0, 1.0))
    stages, notes = [], []
    study, sweep, markdown = _display_effects(config, 1, stages.append, notes.append)
    assert (study, sweep, markdown) == ("study", "sweep", "study+sweep")
    assert stages == ["display effects", "display: 2x2 lenslet sweep"]
    assert notes == ["a study scene", "a sweep scene"]  # each scene shown as it starts
    eyes, labels = study_eyes(config)
    assert seen["names"] == ["eye01", "average"]
    np.testing.assert_array_equal(np.asarray(seen["eyes"].zernike_um),
                                  np.asarray(eyes.zernike_um)[[0, len(labels) - 1]])
    assert seen["config"].layouts == ("2x2", "3x3", "4x4")
    assert seen["config"].depth_offsets_D == (-2.0, 0.0, 1.0)
    assert seen["config"].sweep_distances_mm == (100.0, 400.0)  # --quick


def _synthetic_display_results():
    """Datasets shaped as run_display_study's and lenslet_sweep's (2 layouts, 2 eyes, 3
    depths, 2 distances) with made-up values: for the code that reads them."""
    import xarray as xr

    from lfjax.studies.display_effects import STEPS, DisplayStudyConfig

    config = DisplayStudyConfig(layouts=("2x2", "3x3"), depth_offsets_D=(-1.0, 0.0, 1.0),
                                sweep_distances_mm=(100.0, 400.0))
    rng = np.random.default_rng(0)
    depths = config.depths_D
    dims = ("step", "layout", "eye", "depth")
    shape = (len(STEPS), 2, 2, depths.size)
    error = rng.normal(0.0, 0.1, shape)
    study = xr.Dataset(
        dict(predicted_accommodation=(dims, depths + error), accommodation_error=(dims, error),
             peak_vsotf=(dims, rng.uniform(0.2, 0.8, shape)), peak_success=(dims, np.ones(shape, bool)),
             cutoff_frequency=(dims, rng.uniform(5.0, 30.0, shape)),
             seconds=(("step", "layout"), np.ones(shape[:2])),
             freq_step_cpd=(("step", "layout"), np.full(shape[:2], 0.7))),
        coords=dict(step=list(STEPS), layout=["2x2", "3x3"], eye=["eye01", "average"], depth=depths,
                    lenslet_pitch_mm=("layout", [0.6, 0.4]), lenslet_aperture_mm=("layout", [0.6, 0.4]),
                    focal_length_mm=("layout", [3.0, 2.0]), fresnel_number_550nm=("layout", [1.4, 0.6]),
                    pixel_arcmin=("layout", [3.3, 4.9])),
        attrs=dict(cdp_D=config.cdp_D, spectrum_wavelengths=11, white_wavelengths=16, **config.as_attrs()))
    sweep_error = rng.normal(0.0, 0.1, (2, 2, depths.size))
    sweep = xr.Dataset(
        dict(predicted_accommodation=(("distance", "eye", "depth"), depths + sweep_error),
             accommodation_error=(("distance", "eye", "depth"), sweep_error),
             cutoff_frequency=(("distance", "eye", "depth"), rng.uniform(5.0, 30.0, (2, 2, depths.size))),
             peak_vsotf=(("distance", "eye", "depth"), rng.uniform(0.05, 0.3, (2, 2, depths.size))),
             strehl_accommodation=(("distance", "eye", "depth"), np.broadcast_to(depths, (2, 2, depths.size))),
             ideal_accommodation_error=(("eye", "depth"), np.zeros((2, depths.size))),
             ideal_cutoff_frequency=(("eye", "depth"), np.full((2, depths.size), 20.0)),
             ideal_peak_vsotf=(("eye", "depth"), np.full((2, depths.size), 0.25)),
             ideal_strehl_accommodation=(("eye", "depth"), np.broadcast_to(depths, (2, depths.size)))),
        coords=dict(distance=[100.0, 400.0], eye=["eye01", "average"], depth=depths,
                    lenslet_aperture_mm=("distance", [1.2, 0.3]),
                    fresnel_number_550nm=("distance", [8.2, 0.5])),
        attrs=dict(cdp_D=config.cdp_D, **config.as_attrs()))
    return study, sweep


def test_reproduce_writes_the_display_tables_figures_and_report_section(tmp_path):
    """What lfjax reproduce --display-effects writes from the two studies: both CSV tables
    (a row per layout × step × depth, per distance × depth), both figures and the report
    section with its tables."""
    import pandas as pd

    from lfjax.studies.display_effects import display_effects_markdown
    from lfjax.reproduce.run import DISPLAY_SWEEP_TABLE, DISPLAY_TABLE, write_display_outputs

    study, sweep = _synthetic_display_results()
    files = write_display_outputs(study, sweep, tmp_path)
    assert set(files) == {DISPLAY_TABLE, DISPLAY_SWEEP_TABLE, "display_effects.png",
                          "display_lenslet_sweep.png"}
    assert len(pd.read_csv(tmp_path / DISPLAY_TABLE)) == 4 * 2 * 3
    assert len(pd.read_csv(tmp_path / DISPLAY_SWEEP_TABLE)) == 2 * 3
    for name in ("display_effects.png", "display_lenslet_sweep.png"):
        assert (tmp_path / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    markdown = display_effects_markdown(study, sweep)
    assert "| 3x3 | +spectrum |" in markdown and "Strehl gain 1.00" in markdown


def test_display_study_names_each_scene_as_it_starts(monkeypatch):
    """The display-effects stages run minutes each: every scene is announced (on_scene)
    before it is computed, with its position among all of them."""
    from lfjax.studies import display_effects as de
    from lfjax.model.eyes import sample_eyes

    config = de.DisplayStudyConfig(layouts=("2x2", "3x3"), depth_offsets_D=(0.0, 1.0),
                                   sweep_distances_mm=(100.0, 400.0))
    events = []

    def fake_evaluate(eyes, config, layout, spectrum, display, sampling=None, window_D=None):
        events.append("computed")
        shape = (eyes.n_eyes, config.depths_D.size)
        return dict(predicted=np.zeros(shape), success=np.ones(shape, bool),
                    peak_vsotf=np.ones(shape), cutoff=np.ones(shape), df=1.0,
                    strehl_grid=np.zeros(shape))

    monkeypatch.setattr(de, "_evaluate", fake_evaluate)
    monkeypatch.setattr(de, "shared_sampling", lambda *args, **kwargs: None)
    eyes = sample_eyes(0, 1)
    de.run_display_study(eyes, ["eye01"], config, progress=False, on_scene=events.append)
    n = len(de.STEPS) * 2
    assert events[0] == f"2x2 {de.STEPS[0]} (1/{n})" and events[-2] == f"3x3 {de.STEPS[-1]} ({n}/{n})"
    assert events[1::2] == ["computed"] * n  # each announced before it is computed
    events.clear()
    de.lenslet_sweep(eyes, ["eye01"], config, progress=False, on_scene=events.append)
    assert events == ["2x2 ideal (1/3)", "computed", "2x2 lenslets at 100 mm (2/3)", "computed",
                      "2x2 lenslets at 400 mm (3/3)", "computed"]
