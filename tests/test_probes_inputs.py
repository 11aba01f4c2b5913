"""The issue's probes for inputs checked before work (#52, items 4 and 5), kept so they run on
every change: each bad input is refused with a :class:`~lfjax.base.errors.ParameterError`
naming the parameter (or the command-line flag) and its range, and the compiled function
it would have reached is replaced by one that fails the test if called, so the refusal
provably comes before any work; the probes that were crashes of valid input (one FFT size
in ``natural_otfs``) check the result against the explicit setting; the flat through-focus
curve is a :class:`~lfjax.base.errors.FlatCurveWarning`. Tiny sizes throughout; the command
line runs in-process (``lfjax.cli.main``).

Covers: lfjax.base.errors
"""

from __future__ import annotations

import contextlib
import json
import time
import warnings

import numpy as np
import pytest

import lfjax
from lfjax import cli
from lfjax.base.errors import FLAT_CURVE_RANGE, FlatCurveWarning, ParameterError
from lfjax.display.lenticular import strip_display
from lfjax.model.eyes import MAX_REFRACTION_D, make_eyes, max_coefficient_um
from lfjax.model.spectral import computed_range_nm, monochromatic_spectrum
from lfjax.model.strips import strip_layout

SPEC = monochromatic_spectrum(550.0, lfjax.ModelOptions(sce="off"))
SAMPLING = lfjax.Sampling(2.0)
STATES = lfjax.States.grid([1.8, 2.0, 2.2], [2.0])


def _never(monkeypatch, *targets):
    """Replace each ``(module, name)`` by a function that fails the test if called: the
    work a refused input must never reach."""
    for module, name in targets:
        def reached(*args, _name=f"{module.__name__}.{name}", **kwargs):
            raise AssertionError(f"{_name} was reached: the input was not checked first")
        monkeypatch.setattr(module, name, reached)


@contextlib.contextmanager
def _refused(parameter: str, *fragments: str, seconds: float = 5.0):
    """The block raises a ParameterError naming ``parameter`` and every fragment (the
    range), within ``seconds`` (host checks only: no compilation fits in that)."""
    t0 = time.perf_counter()
    with pytest.raises(ParameterError) as info:
        yield info
    assert parameter in info.value.parameters or parameter == info.value.parameter, info.value
    for fragment in (parameter, *fragments):
        assert fragment in str(info.value), (fragment, str(info.value))
    assert time.perf_counter() - t0 < seconds


# ----------------------------------------------------------------------------- eye_chunk


@pytest.mark.parametrize("chunk", [-1, 0, 1.5, True, "2"])
def test_eye_chunk_refused_before_work(monkeypatch, chunk):
    """Before: -1 was a reshape TypeError from inside jax.lax.map, 0 and 1.5 ran."""
    from lfjax.vision import focus, orientation, psf

    _never(monkeypatch, (focus, "call_cached"), (psf, "otf_stack"),
           (orientation, "_band_metrics"))
    eye = lfjax.average_eye(3.0)
    with _refused("eye_chunk", "integer >= 1", "None"):
        lfjax.through_focus(eye, lfjax.grid_layout(2), STATES, spectrum=SPEC,
                            sampling=SAMPLING, eye_chunk=chunk)
    with _refused("eye_chunk", "integer >= 1"):
        lfjax.polychromatic_otf(eye, [2.0], spectrum=SPEC, sampling=SAMPLING, eye_chunk=chunk)
    with _refused("eye_chunk", "integer >= 1"):
        orientation.orientation_through_focus(eye, lfjax.grid_layout(2), STATES, spectrum=SPEC,
                                              sampling=SAMPLING, eye_chunk=chunk)
    with _refused("eye_chunk", "integer >= 1"):
        lfjax.through_focus_variants(eye, None, STATES, [lfjax.ModelOptions(sce="off")],
                                     wavelengths_nm=[550.0], samplings=[SAMPLING],
                                     eye_chunk=chunk)


def test_eye_chunk_one_check_for_every_entry_point():
    """The layout optimiser's setting and the display design's fit settings take the same
    check (one concept, one home); a whole float is taken as its integer."""
    from lfjax.design.box import eye_chunk_size
    from lfjax.design.settings import FitSettings
    from lfjax.layout_opt import ProblemSetting
    from lfjax.vision.prepare import check_eye_chunk

    for build in (lambda c: ProblemSetting(eye_chunk=c), lambda c: FitSettings(eye_chunk=c),
                  lambda c: eye_chunk_size(4, c), check_eye_chunk):
        with _refused("eye_chunk", "integer >= 1"):
            build(0)
    assert check_eye_chunk(2.0) == 2 and isinstance(check_eye_chunk(2.0), int)
    assert check_eye_chunk(None) is None
    assert ProblemSetting(eye_chunk=3.0).eye_chunk == 3


# ----------------------------------------------------------------------------- strip display


def _mismatched():
    """A strip display built for two views, and a three-view layout."""
    return strip_display(strip_layout(2)), strip_layout(3)


def test_strip_display_for_another_layout_refused_by_every_vision_entry_point(monkeypatch):
    """Before (#52): ``ValueError: scan got values with different leading axis sizes`` from
    inside the program; #51 put the check in prepare, which these share."""
    from lfjax.vision import focus, orientation, psf, scene_images

    _never(monkeypatch, (focus, "call_cached"), (focus, "vsotf_and_strehl"),
           (psf, "otf_stack"), (orientation, "_band_metrics"), (scene_images, "scene_otfs"))
    display, layout = _mismatched()
    eye = lfjax.average_eye(3.0)
    viewing = lfjax.Viewing(display=display)
    calls = [
        lambda: lfjax.through_focus(eye, layout, STATES, viewing, spectrum=SPEC,
                                    sampling=SAMPLING),
        lambda: lfjax.through_focus_variants(eye, layout, STATES, [lfjax.ModelOptions()],
                                             viewing, wavelengths_nm=[550.0],
                                             samplings=[SAMPLING]),
        lambda: lfjax.metrics_at(eye, layout, [2.0], [[2.0]], viewing, spectrum=SPEC,
                                 sampling=SAMPLING),
        lambda: lfjax.polychromatic_otf(eye, [2.0], viewing, layout=layout, spectrum=SPEC,
                                        sampling=SAMPLING),
        lambda: orientation.orientation_through_focus(eye, layout, STATES, viewing,
                                                      spectrum=SPEC, sampling=SAMPLING),
        lambda: scene_images.retinal_scene(
            eye, scene_images.LayeredScene.from_layers(np.ones((1, 1, 8, 8)),
                                                       np.ones((1, 8, 8)), [2.0], 1.0),
            viewing=viewing, display=layout),
    ]
    for call in calls:
        with _refused("viewing", "viewing.display", "2 views", "3 views", "strip_display"):
            call()


def test_strip_display_for_another_layout_refused_by_peaks_planner_and_optimiser(monkeypatch):
    """accommodation_peaks (a Scene), the planner (a PlanScene) and the layout optimiser (its
    problem's display, the layout given later) check the same, naming their parameter."""
    from lfjax.kernel.scene import Scene
    from lfjax.layout_opt import _objectives, evaluate_layout, make_problem, optimise_layout
    from lfjax.planner.scene import PlanScene
    from lfjax.vision import peaks
    from lfjax.vision.prepare import prepare

    display, layout = _mismatched()
    eye = lfjax.average_eye(3.0)
    good = prepare(eye, strip_layout(2), STATES, lfjax.Viewing(display=display), spectrum=SPEC,
                   sampling=SAMPLING)
    scene = Scene.from_layout(layout, good.states.depths_D, 2.0, 3.0, display)
    problem = make_problem(eye, [1.0, 2.0], display=display, wavelengths_nm=(550.0,),
                           sampling=SAMPLING)
    _never(monkeypatch, (peaks, "reference_normalisers"), (_objectives, "retinal_metrics"))
    with _refused("scene", "scene.display", "2 views", "3 views"):
        peaks.accommodation_peaks(eye, scene, SPEC, good.accommodation(lfjax.ModelOptions()),
                                  good.config)
    with _refused("display", "2 views", "3 views"):
        PlanScene(layout=layout, eyes=eye, display=display, wavelengths_nm=[550.0])
    with _refused("display", "2 views", "3 views"):
        evaluate_layout(layout, problem)
    with _refused("display", "2 views", "3 views"):
        optimise_layout(layout, problem, max_steps=1, progress=False, report_problem=None)


def test_sweep_and_design_build_their_strip_displays_from_the_layout():
    """The sweep's configuration and the design take no display object: each builds its
    strip display from the layout it scores, so a mismatch cannot be given to them."""
    from lfjax.sweep.config import SweepConfig

    config = SweepConfig(layouts=("1x3",), leakage_weight=0.5)
    one = config.display_optics("1x3", strip_layout(3))
    assert np.shape(one.neighbours)[0] == 3


# ----------------------------------------------------------------------------- natural_otfs


def test_natural_otfs_without_n_fft_picks_one_size_for_every_channel():
    """Before: each primary picked its own FFT size and the stack failed after 18 s (a raw
    JAX shape error). Now one size (the bluest channel's, as common_sampling chooses) is
    used, and the result is what that explicit n_fft gives, exactly."""
    from lfjax.vision.scene_blur import channel_spectra, natural_otfs, with_channels_n_fft

    eye = lfjax.average_eye(3.0)
    spectra = channel_spectra("oled", lfjax.ModelOptions(sce="off"))
    coarse = lfjax.Sampling(4.0)
    implicit = np.asarray(natural_otfs(eye, 2.0, [1.5, 2.0], spectra, coarse,
                                       options=lfjax.ModelOptions(sce="off")))
    n_fft = with_channels_n_fft(coarse, spectra, 3.0, lfjax.ModelOptions(sce="off")).n_fft
    explicit = np.asarray(natural_otfs(eye, 2.0, [1.5, 2.0], spectra,
                                       lfjax.Sampling(4.0, n_fft=n_fft),
                                       options=lfjax.ModelOptions(sce="off")))
    assert implicit.shape == explicit.shape == (3, 2, n_fft, n_fft // 2 + 1)
    np.testing.assert_array_equal(implicit, explicit)
    assert np.allclose(implicit[..., 0, 0], 1.0, atol=1e-5)


# ----------------------------------------------------------------------------- eyes


def test_absurd_or_non_finite_eye_parameters_refused_before_tracing(monkeypatch):
    """Before: make_eyes took 1e6 µm and through_focus failed with a JAX OverflowError (an
    FFT size of 5e7 planned for the blur). Now the coefficient is refused where the eyes are
    made, naming zernike_um, µm and the bound (the defocus of MAX_REFRACTION_D)."""
    from lfjax.vision import focus

    _never(monkeypatch, (focus, "call_cached"))
    z = np.zeros(15)
    z[4] = 1e6
    bound = f"{max_coefficient_um(3.0):.3g} µm"
    with _refused("zernike_um", bound, "3 mm", f"{MAX_REFRACTION_D:g} D"):
        make_eyes(z, 3.0)
    with _refused("zernike_um", bound):
        lfjax.Eyes(z[None], 3.0)
    with _refused("zernike_um", "finite"):
        make_eyes(np.where(np.arange(15) == 6, np.nan, 0.0), 3.0)
    with _refused("measured_pupil_mm", "finite and > 0 mm"):
        lfjax.Eyes(np.zeros((1, 15)), float("inf"))
    # the bound is the physics it states: c(2,0) of 40 D on the measured pupil's radius
    assert max_coefficient_um(3.0) == pytest.approx(MAX_REFRACTION_D * 1.5**2 / (4 * 3**0.5))
    z[4] = 0.99 * max_coefficient_um(3.0)
    make_eyes(z, 3.0)  # inside the bound: accepted
    thibos = lfjax.sample_eyes(0, 200, 7.5)  # real eyes sit far inside it
    assert np.abs(np.asarray(thibos.zernike_um)).max() < 0.1 * max_coefficient_um(7.5)


# ----------------------------------------------------------------------------- flat curves


def test_flat_through_focus_curve_warns_that_its_peak_is_undetermined():
    """Before: a 0.01 mm pupil's curve (VSOTF 1 ± 1e-7 at every state) gave the grid's first
    state as the predicted accommodation without a word. The warning names the cause."""
    from lfjax.vision.focus import flat_curves

    tf = lfjax.through_focus(lfjax.average_eye(3.0), None,
                             lfjax.States.grid([1.6, 1.8, 2.0, 2.2, 2.4], [2.0]),
                             lfjax.Viewing(pupil_diameter_mm=0.01), spectrum=SPEC)
    v = np.asarray(tf.vsotf)
    assert np.ptp(v) < FLAT_CURVE_RANGE * np.abs(v).max()
    with pytest.warns(FlatCurveWarning, match="peak is undetermined"):
        tf.predicted_accommodation_D()
    # the rule itself: a curve with a peak above the threshold, or one state, is not flat
    assert flat_curves(np.array([1.0, 1.0 + 0.5 * FLAT_CURVE_RANGE, 1.0]))
    assert not flat_curves(np.array([1.0, 1.0 + 2 * FLAT_CURVE_RANGE, 1.0]))
    assert not flat_curves(np.array([1.0, -np.inf, -np.inf]))


def test_ordinary_through_focus_curve_does_not_warn():
    """A 3 mm pupil through ±0.4 D: the curve has a peak, no warning (filterwarnings=error)."""
    tf = lfjax.through_focus(lfjax.average_eye(3.0), lfjax.grid_layout(2),
                             lfjax.States.grid([1.6, 2.0, 2.4], [2.0]), spectrum=SPEC,
                             sampling=SAMPLING)
    with warnings.catch_warnings():
        warnings.simplefilter("error", FlatCurveWarning)
        tf.predicted_accommodation_D()


# ----------------------------------------------------------------------------- spectrum


def test_spectrum_refused_outside_what_the_model_computes_naming_the_range():
    """Before: make_spectrum documented 390–830 nm and failed in the Stiles–Crawford table
    (400–700 nm) after loading the LEF data. Now one range, computed_range_nm, refused at
    once with why."""
    lo, hi = computed_range_nm(lfjax.ModelOptions())
    with _refused("wavelengths_nm", f"{lo:g}–{hi:g} nm", "Stiles–Crawford", "sce='off'"):
        monochromatic_spectrum(395.0)
    lo_off, hi_off = computed_range_nm(lfjax.ModelOptions(sce="off"))
    assert lo_off < lo and hi_off > hi
    assert float(monochromatic_spectrum(395.0, lfjax.ModelOptions(sce="off"))
                 .wavelengths_nm[0]) == 395.0
    with _refused("wavelengths_nm", f"{lo_off:g}–{hi_off:g} nm", "LEF"):
        monochromatic_spectrum(900.0, lfjax.ModelOptions(sce="off"))


# ----------------------------------------------------------------------------- command line


@pytest.mark.parametrize("lenticular", [False, True])
def test_design_f_number_outside_what_a_lens_can_be_refused(monkeypatch, capsys, tmp_path,
                                                            lenticular):
    """Before: ``design --lenticular --f-number 0.1 0.2`` was accepted."""
    from lfjax.cli import design

    _never(monkeypatch, (design, "fit_design"), (design, "fit_lenticular_design"))
    argv = ["design", "--depths", "0.5", "2.5", "--f-number", "0.1", "0.2",
            "--out", str(tmp_path / "d")] + (["--lenticular"] if lenticular else [])
    assert cli.main(argv) == 2
    err = capsys.readouterr().err
    assert "--f-number" in err and "[0.5, inf]" in err and "f/0.5" in err, err
    assert not (tmp_path / "d").exists()


def test_design_views_1_writes_what_the_help_says(capsys, tmp_path):
    """Before: ``design --views 1`` wrote design.json alone while the help said design.json
    and design.png, both or neither. The 1×1 count is refused before it has a panel, so no
    figure exists: the help now says so, and the command does exactly that."""
    out = tmp_path / "d"
    code = cli.main(["design", "--depths", "0.5", "2.5", "--views", "1", "--train-eyes", "1",
                     "--test-eyes", "1", "--steps", "0", "--no-progress", "--out", str(out)])
    assert code == 1  # nothing qualifies
    assert sorted(p.name for p in out.iterdir()) == ["design.json"]
    record = json.loads((out / "design.json").read_text())
    assert "refused" in json.dumps(record)
    capsys.readouterr()
    with contextlib.suppress(SystemExit):  # argparse's help exits 0
        cli.main(["design", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert "--views 1 alone is refused before it has a panel" in text
    assert "design.json is then written alone" in text


def test_optimise_held_out_report_says_what_it_scores(monkeypatch, capsys):
    """Before: the held-out evaluation was silent for over a minute. It now says what it
    scores (how many eyes, at which setting) before it starts, and counts the eyes."""
    from types import SimpleNamespace

    from lfjax.layout_opt import _solver

    seen = []

    def evaluate(layout, problem, chunk=None, progress=None):
        seen.append(chunk)
        progress(problem.eyes.n_eyes)
        return {"loss": 0.0}

    monkeypatch.setattr(_solver, "evaluate_layout", evaluate)
    eyes = lfjax.sample_eyes(0, 5, 3.0)
    held = SimpleNamespace(eyes=eyes, accuracy="full",
                           spectrum=SimpleNamespace(n_wavelengths=31))
    problem = SimpleNamespace(eyes=lfjax.sample_eyes(1, 2, 3.0), accuracy="fit",
                              at_accuracy=lambda accuracy, eyes: held)
    scores = _solver._held_out_scores(None, None, problem, eyes, "full", progress=True)
    assert scores == {"before": {"loss": 0.0}, "after": {"loss": 0.0}}
    err = capsys.readouterr().err
    assert "held-out report" in err and "5 held-out eyes" in err and "'full' setting" in err
    assert "31 wavelengths" in err and "10/10" in err, err
    assert seen == [5, 5]
