"""Population sweeps (lfjax.sweep): config validation, store contents against
through_focus, no recompilation per chunk, resume after SIGKILL, sharding over 4 forced CPU
devices, and two processes through jax.distributed writing one store.

Subprocesses get this session's XLA flags and float64 (``JAX_ENABLE_X64``), so their
stores are comparable with the in-process reference bit for bit.

Covers: lfjax.sweep.compute, lfjax.sweep.config, lfjax.sweep.run, lfjax.sweep.store
Covers: lfjax.cli.sweep
"""

from __future__ import annotations

import json
import os
import re
import shutil
import signal
import socket
import subprocess
import sys
import tomllib
from pathlib import Path

import numpy as np
import pytest

from lfjax.sweep import (
    SweepConfigError,
    StoreMismatchError,
    completed_chunks,
    config_from_dict,
    config_to_toml,
    load_config,
    open_store,
    run_sweep,
    study_view,
)
from lfjax._version import STAMP_KEYS
from lfjax.sweep.compute import build_tasks, population, sweep_spectrum
from lfjax.sweep.store import clean_interrupted_creations
from lfjax.sweep.store_checks import verify_store
from lfjax.sweep.store_lock import lock_path, StoreLockedError
from lfjax.vision.peak_options import PeakOptions
from lfjax.vision.prepare import States
from lfjax.vision.viewing import Viewing

TINY = {
    "population": {"n_eyes": 5, "seed": 3},
    "display": {"layouts": ["natural", "2x2"], "depth_offsets_D": [-1.0, 0.0, 1.0]},
    "accommodation": {"step_D": 0.5, "window_D": 1.0},
    # one wavelength: each is its own FFT band of the compiled chunk function, and what the
    # tests below check (store against through_focus, resume, sharding, processes) does not
    # depend on how many are summed; that the sum follows the config's spectrum is checked by
    # the laser lines of test_a_real_display_sweeps_as_through_focus_computes_it
    "spectrum": {"wavelengths_nm": [550.0, 550.0, 1.0]},
    "run": {"chunk_size": 2},
}
FLOAT_EQUAL = ("vsotf", "strehl", "peak_value", "cutoff_frequency", "mtf_at_peak",
               "predicted_accommodation_continuous", "continuous_error")


def tiny_config(**sections):
    data = {k: dict(v) for k, v in TINY.items()}
    for section, body in sections.items():
        data.setdefault(section, {}).update(body)
    return config_from_dict(data)


def write_toml(path: Path, config) -> Path:
    path.write_text(config_to_toml(config))
    return path


def subprocess_env(**extra) -> dict:
    env = dict(os.environ)
    env["JAX_ENABLE_X64"] = "1"
    env.update(extra)
    return env


@pytest.fixture(scope="module", autouse=True)
def persistent_compilation_cache():
    """The command line's compilation cache, here too: the subprocesses below compile the
    same programs as this process, and load them from it instead."""
    from lfjax.base.programs import enable_program_cache
    from lfjax.cli import enable_compilation_cache
    from lfjax.planner.cache import enable_plan_cache

    enable_compilation_cache()
    yield
    # the other modules in this process run with the caches as the session set them
    enable_program_cache(None)
    enable_plan_cache(None)


def assert_stores_equal(a, b, rtol: float = 0.0, atol: float = 0.0):
    assert set(a.data_vars) == set(b.data_vars)
    for name in a.data_vars:
        x, y = a[name].values, b[name].values
        if x.dtype.kind == "f":
            assert np.array_equal(np.isnan(x), np.isnan(y)), name
            np.testing.assert_allclose(x[~np.isnan(x)], y[~np.isnan(y)], rtol=rtol, atol=atol,
                                       err_msg=name)
        else:
            assert np.array_equal(x, y), name


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    """The tiny sweep, uninterrupted, in this process: (config, store path, SweepRun)."""
    config = tiny_config()
    path = tmp_path_factory.mktemp("sweep") / "reference.zarr"
    run = run_sweep(config, path, progress=False)
    return config, path, run


CHUNK_MARKS = ["chunk_complete", "chunk_checksum"]
"""The bookkeeping variables: a chunk's checksum covers every layout of its eyes."""


@pytest.fixture(scope="module")
def reference_2x2(reference, tmp_path_factory):
    """The reference's 2x2 layout alone, in this process: (config, store path, SweepRun).
    Its chunk function is the reference's (the same eyes, planned sampling and spectrum), so
    nothing is compiled again. The tests that start processes sweep this one: each process
    then traces one chunk function, not two."""
    _, ref_path, _ = reference
    config = tiny_config(display={"layouts": ["2x2"]})
    path = tmp_path_factory.mktemp("sweep") / "reference_2x2.zarr"
    run = run_sweep(config, path, progress=False)
    # the reference's numbers, bit for bit (the bookkeeping covers the layouts it holds)
    assert_stores_equal(open_store(path).drop_vars(CHUNK_MARKS),
                        open_store(ref_path).sel(layout=["2x2"]).drop_vars(CHUNK_MARKS))
    return config, path, run


# ----------------------------------------------------------------------------- config


def test_bad_config_lists_every_problem_before_any_compute(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text(
        '[population]\nn_eyes = 0\nseed = "x"\npupil_diameters_mm = [3.0, 8.0]\n'
        '[display]\nlayouts = ["2x2", "5x5"]\ndepth_offsets_m = [0.0]\ncdp_D = -1\n'
        '[sampling]\nfreq_step_cpd = -1\n[model]\nsce = "sideways"\n[extra]\na = 1\n'
    )
    with pytest.raises(SweepConfigError) as err:
        load_config(bad)
    text = str(err.value)
    for expected in ("population.n_eyes must be >= 1", "population.seed must be a whole number",
                     "exceed the measured pupil (7.5 mm)", "'5x5' is neither a paper layout",
                     "depth_offsets_m: unknown key (did you mean 'depth_offsets_D'?)",
                     "display.cdp_D must be >= 0 D", "sampling.freq_step_cpd must be > 0 cpd",
                     "ModelOptions.sce='sideways'", "unknown section [extra]"):
        assert expected in text, expected
    assert len(err.value.problems) >= 9


@pytest.mark.parametrize("changes, message", [
    ({"accommodation": {"window_D": 0.1}}, "must be >= step_D"),
    ({"population": {"measured_pupil_mm": 5.0}}, "must be one of [3.0, 4.5, 6.0, 7.5]"),
    ({"display": {"layouts": ["natural"], "depth_offsets_D": [1.0]}}, "must include 0"),
    ({"spectrum": {"wavelengths_nm": [380.0, 700.0, 10.0]}}, "must lie in [400, 700] nm"),
    ({"metrics": {"continuous_peaks": ["mtf"]}}, "metrics.continuous_peaks"),
    ({"sampling": {"freq_step_cpd": 1.0, "vsotf_tolerance": 1e-3}}, "not both"),
    ({"display": {"lenslet_distance_mm": 600.0}}, "display.lenslet_distance_mm must be in (0, 500) mm"),
    ({"display": {"pixel_width_arcmin": -1.0}}, "display.pixel_width_arcmin must be >= 0"),
    ({"spectrum": {"display": "plasma"}}, "spectrum.display must be one of crt, lcd, oled, laser"),
    # the model's dioptric range (lfjax.base.units.check_dioptres, shared with every entry point)
    ({"display": {"cdp_D": 20.0}}, "display.cdp_D: every CDP must lie in the model's range [0, 10] D"),
    ({"display": {"depth_offsets_D": [0.0, 9.0]}},
     "display.depth_offsets_D: every rendered depth must lie in the model's range [0, 10] D"),
    ({"accommodation": {"max_D": 50.0}},
     "accommodation.max_D: every accommodation state must lie in the model's range [0, 10] D"),
])
def test_impossible_values_are_named(changes, message):
    with pytest.raises(SweepConfigError, match=None) as err:
        tiny_config(**changes)
    assert message in str(err.value)


def test_lenslet_aberration_keys_reach_the_display_and_are_refused_out_of_range():
    """[display] lenslet_*_um keys: all 0 is the display without an aberration (None, as
    before); a value becomes the DisplayOptics' LensletAberration; out of [-100, 100] µm is
    refused, naming the key, its unit and its range."""
    assert tiny_config().display_optics() is None
    optics = tiny_config(display={"lenslet_spherical_um": 0.5, "lenslet_astigmatism_um": -0.2}).display_optics()
    assert float(optics.aberration.spherical_um) == 0.5
    assert float(optics.aberration.astigmatism_um) == -0.2 and optics.diffraction == "off"
    with pytest.raises(SweepConfigError) as err:
        tiny_config(display={"lenslet_coma_um": 150.0})
    assert "display.lenslet_coma_um must be in [-100, 100] um, got 150" in str(err.value)


@pytest.mark.parametrize("display, message", [
    ({"layouts": ["1x0"]}, "display.layouts: '1x0' must have 1 to 16 strips"),
    ({"layouts": ["1x17"]}, "display.layouts: '1x17' must have 1 to 16 strips"),
    ({"layouts": ["1x2"], "strip_width_ratio": 0.0}, "display.strip_width_ratio must be in (0, 2]"),
    ({"layouts": ["1x2"], "strip_width_ratio": 2.5}, "display.strip_width_ratio must be in (0, 2]"),
    ({"layouts": ["1x2"], "strip_y_defocus_D": -41.0},
     "display.strip_y_defocus_D must be in [-40, 40] D, got -41"),
    ({"leakage_weight": 1.5}, "display.leakage_weight must be in [0, 1], got 1.5"),
    ({"leakage_weight": -0.1}, "display.leakage_weight must be in [0, 1], got -0.1"),
    ({"strip_y_defocus_D": -0.8}, "display.strip_y_defocus_D = -0.8 shapes the 1xN strip "
                                  "layouts, but display.layouts has none"),
])
def test_strip_and_leakage_keys_are_refused_out_of_range(display, message):
    """The HPO and cross-talk keys are refused before any work, naming the key, its unit and
    its range (or, set without a strip layout, that they would change nothing)."""
    with pytest.raises(SweepConfigError) as err:
        tiny_config(display=display)
    assert message in str(err.value)


def test_strip_and_leakage_keys_reach_each_layouts_display(tmp_path):
    """A 1xN entry is N strips across each pupil (pitch pupil/N, width strip_width_ratio
    times it) with strip apertures and the y defocus; the leakage weight goes to every
    layout of several views with its neighbours; at their defaults every paper layout keeps
    the display it had (None: the ideal display). The keys round-trip through TOML; a store
    record from before them resumes while they are at their defaults."""
    from lfjax.model.strips import neighbour_matrix
    from lfjax.sweep.compute import resolve_layout
    from lfjax.sweep.config_files import config_differences, with_new_defaults

    plain = tiny_config()
    for entry in plain.layouts:
        assert plain.display_optics(entry, resolve_layout(plain, entry, 3.0)) is None
    config = tiny_config(display={"layouts": ["natural", "2x2", "1x3"], "strip_width_ratio": 1.25,
                                  "strip_y_defocus_D": -0.83, "leakage_weight": 0.25})
    strips = resolve_layout(config, "1x3", 3.0)
    np.testing.assert_allclose(np.asarray(strips.centres_mm)[:, 0], [-1.0, 0.0, 1.0])
    np.testing.assert_allclose(np.asarray(strips.diameters_mm), 1.25)
    optics = config.display_optics("1x3", strips)
    assert optics.aperture == "strip" and float(optics.y_defocus_D) == pytest.approx(-0.83)
    assert float(optics.leakage_weight) == 0.25
    np.testing.assert_array_equal(np.asarray(optics.neighbours), neighbour_matrix(strips))
    grid = config.display_optics("2x2", resolve_layout(config, "2x2", 3.0))
    assert grid.aperture == "circle" and float(grid.y_defocus_D) == 0.0
    assert float(grid.leakage_weight) == 0.25
    assert config.display_optics("natural", resolve_layout(config, "natural", 3.0)) is None
    with pytest.raises(ValueError, match="leakage_weight"):
        config.display_optics()
    again = load_config(write_toml(tmp_path / "c.toml", config))
    assert again == config and again.as_dict() == config.as_dict()
    old = {k: v for k, v in plain.as_dict().items()
           if k not in ("strip_width_ratio", "strip_y_defocus_D", "leakage_weight")}
    assert config_differences(with_new_defaults(old), plain.as_dict()) == []
    leaky = tiny_config(display={"leakage_weight": 0.25}).as_dict()
    assert config_differences(with_new_defaults(old), leaky) == [
        "leakage_weight: store has 0.0, config has 0.25"]


def test_config_round_trips_through_toml(tmp_path):
    config = tiny_config(sampling={"freq_step_cpd": 1.5}, model={"sce": "intensity"})
    again = load_config(write_toml(tmp_path / "c.toml", config))
    assert again.as_dict() == config.as_dict()
    assert again.options.sce == "intensity" and again.freq_step_cpd == 1.5


def test_a_step_less_spectrum_is_planned_for_the_peak_and_cutoff_targets():
    """``wavelengths_nm = [start, stop]`` (the default) asks the planner for each (pupil,
    layout)'s spectrum: the uniform step (``planned_wavelength_step``: the finest of each
    layout's coarsest step meeting the targets; a tighter target never gets a coarser one)
    or the Gauss rule for V(λ) when it meets the targets with fewer wavelengths. The tasks
    sum exactly the planned rule (its nodes and weights), and the guard counts it."""
    from lfjax.model.spectral import gauss_rule
    from lfjax.sweep.compute import planned_wavelength_step, spectral_plans, sweep_spectra
    from lfjax.sweep.guard import estimate

    planned = tiny_config(spectrum={"wavelengths_nm": [400.0, 700.0]},
                          display={"layouts": ["4x4"]})
    step = planned_wavelength_step(planned)
    assert 10.0 < step < 50.0
    uniform = sweep_spectrum(planned)
    np.testing.assert_allclose(np.diff(uniform.wavelengths_nm), step)
    assert uniform.wavelengths_nm[0] == 400.0 and uniform.wavelengths_nm[-1] == 700.0
    (plan,) = spectral_plans(planned).values()
    (spectrum,) = sweep_spectra(planned).values()
    assert plan.spectral_rule == "gauss" and spectrum.n_wavelengths < uniform.n_wavelengths
    nodes, weights = gauss_rule(spectrum.n_wavelengths, 400.0, 700.0)
    np.testing.assert_allclose(spectrum.wavelengths_nm, nodes, rtol=1e-12)
    np.testing.assert_allclose(spectrum.weights, weights, rtol=1e-6)
    eyes, _ = population(planned)
    (task,) = build_tasks(planned, eyes)
    assert task.spectrum is not None
    np.testing.assert_array_equal(task.spectrum.wavelengths_nm, spectrum.wavelengths_nm)
    assert task.pipeline_config.bands[-1][1] == spectrum.n_wavelengths
    assert estimate(planned).n_wavelengths == spectrum.n_wavelengths
    tight = tiny_config(spectrum={"wavelengths_nm": [400.0, 700.0]},
                        display={"layouts": ["4x4"]}, sampling={"peak_tolerance_D": 1e-4})
    assert planned_wavelength_step(tight) < step
    # a step given is a uniform grid, shared by every (pupil, layout)
    given = tiny_config(spectrum={"wavelengths_nm": [400.0, 700.0, 30.0]})
    for s in sweep_spectra(given).values():
        np.testing.assert_allclose(s.wavelengths_nm, np.arange(400.0, 701.0, 30.0))
    with pytest.raises(SweepConfigError, match="needs a step with spectrum.display"):
        tiny_config(spectrum={"wavelengths_nm": [400.0, 700.0], "display": "oled"})
    with pytest.raises(SweepConfigError, match="peak_tolerance_D"):
        tiny_config(sampling={"peak_tolerance_D": 0.0})


# ----------------------------------------------------------------------------- contents


def test_store_metadata_round_trips(reference):
    config, path, _ = reference
    ds = open_store(path)
    again = config_from_dict(tomllib.loads(ds.attrs["config_toml"]))
    assert again.as_dict() == config.as_dict()
    import json

    import lfjax

    assert json.loads(ds.attrs["model_options_json"]) == config.options.as_dict()
    assert ds.attrs["lfjax_version"] == lfjax.__version__
    assert ds.sizes["eye"] == config.n_eyes + 1 and bool(ds.is_average.values[-1])
    assert list(ds.layout.values) == ["natural", "2x2"]
    np.testing.assert_allclose(ds.depth.values, config.depths_D)
    np.testing.assert_allclose(ds.accommodation.values, config.accommodation_D)
    eyes, _ = population(config)
    np.testing.assert_array_equal(ds.zernike_um.values, np.asarray(eyes.zernike_um))
    assert ds.chunk_complete.values.all()
    assert ds.vsotf.attrs["units"] == "1" and ds.cutoff_frequency.attrs["units"] == "cpd"


def test_store_equals_through_focus_on_the_same_eyes_and_sampling(reference):
    """Each chunk's compiled function computes what lfjax.vision.focus computes for the
    whole population at once (grid curves, grid and continuous peaks, cut-off)."""
    from lfjax.vision.focus import through_focus

    config, path, _ = reference
    ds = open_store(path)
    eyes, _ = population(config)
    for task in build_tasks(config, eyes, sweep_spectrum(config)):
        tf = through_focus(
            eyes,
            task.layout,
            States.grid(config.accommodation_D, depths_D=task.depths_D, window_D=config.window_D),
            Viewing(pupil_diameter_mm=task.pupil_mm, cdp_D=config.cdp_D),
            spectrum=sweep_spectrum(config),
            sampling=task.sampling,
            options=config.options,
            peaks=PeakOptions(
                metrics=("vsotf",),
                method=config.peak_method,
                second_peaks=False,
                tolerance_D=config.peak_tolerance_D,
            ),
        )
        sub = ds.isel(pupil=task.pupil_index, layout=task.layout_index,
                      depth=list(task.depth_slots))
        np.testing.assert_allclose(sub.vsotf.values, np.asarray(tf.vsotf), rtol=1e-6, atol=1e-9)
        np.testing.assert_allclose(sub.strehl.values, np.asarray(tf.strehl), rtol=1e-6, atol=1e-9)
        for metric in ("vsotf", "strehl"):
            np.testing.assert_array_equal(
                sub.predicted_accommodation.sel(metric=metric).values,
                tf.predicted_accommodation_D(metric))
            np.testing.assert_allclose(sub.cutoff_frequency.sel(metric=metric).values,
                                       np.asarray(tf.cutoff_cpd(metric, config.cutoff_threshold)),
                                       rtol=1e-5)
        np.testing.assert_allclose(
            sub.predicted_accommodation_continuous.sel(metric="vsotf").values,
            tf.continuous_accommodation_D("vsotf"), atol=1e-6)
    # natural view is evaluated at the CDP only
    natural = ds.sel(layout="natural", pupil=3.0)
    off = natural.depth_rel_cdp.values != 0
    assert np.isnan(natural.vsotf.values[:, off]).all()
    assert np.isfinite(natural.predicted_accommodation.values[:, ~off]).all()


def test_one_compilation_per_pupil_and_layout_for_all_chunks(reference):
    config, _, run = reference
    assert config.n_chunks == 3 and run.computed_chunks == [0, 1, 2]  # last chunk padded
    # at most one trace per (pupil, layout) over three chunks (none if an earlier test in
    # this process compiled the same scene)
    assert set(run.traces) == {(0, 0), (0, 1)} and max(run.traces.values()) <= 1


def test_study_view_feeds_the_paper_claims(reference):
    from lfjax.vision.claims import evaluate_claims

    _, path, _ = reference
    view = study_view(open_store(path))
    assert view.vsotf.dims == ("layout", "eye", "depth", "accommodation")
    assert list(view.eye.values[-1:]) == ["average"]
    claims = evaluate_claims(view)
    assert [c.id for c in claims] == [str(i) for i in range(1, 8)]
    assert claims[0].holds is not None  # natural view at the CDP is present


# ----------------------------------------------------------------------------- refusals


def test_existing_store_is_refused_without_resume(reference):
    config, path, _ = reference
    with pytest.raises(FileExistsError, match="--resume"):
        run_sweep(config, path, progress=False)


def test_store_of_another_config_is_refused_with_the_differences(reference):
    config, path, _ = reference
    other = tiny_config(population={"seed": 4}, accommodation={"window_D": 1.5})
    with pytest.raises(StoreMismatchError) as err:
        run_sweep(other, path, resume=True, progress=False)
    text = str(err.value)
    assert "config.seed: store has 3, config has 4" in text
    assert "config.window_D: store has 1.0, config has 1.5" in text


def test_resume_of_a_complete_store_computes_nothing(reference):
    config, path, _ = reference
    run = run_sweep(config, path, resume=True, progress=False)
    assert run.computed_chunks == [] and run.skipped_chunks == [0, 1, 2]


# ----------------------------------------------------------------------------- interruption


@pytest.mark.parametrize("sig", [signal.SIGKILL, signal.SIGTERM], ids=["SIGKILL", "SIGTERM"])
def test_sweep_killed_mid_way_resumes_to_the_uninterrupted_store(reference_2x2, tmp_path, sig):
    """The sweep signals itself right after chunk 0 is marked complete (the test hook
    ``LFJAX_TEST_ABORT_AFTER_CHUNK``, read in lfjax.sweep.run): a deterministic kill point,
    not a poll that a loaded machine can miss. SIGKILL: nothing runs after it (the lock
    stays, stale); SIGTERM (a scheduler's preemption): the command stops as on Ctrl-C,
    releasing the lock. Resuming computes only chunks 1 and 2 and gives the uninterrupted
    store bit for bit. (The reference's 2x2 layout alone: one chunk function to trace in
    the process.)"""
    config, ref_path, _ = reference_2x2
    toml = write_toml(tmp_path / "tiny.toml", config)
    store = tmp_path / "killed.zarr"
    log = tmp_path / "killed.log"
    with open(log, "w") as log_file:
        proc = subprocess.run(
            [sys.executable, "-m", "lfjax.cli", "sweep", str(toml), "--out", str(store),
             "--no-progress"],
            env=subprocess_env(LFJAX_TEST_ABORT_AFTER_CHUNK="0",
                               LFJAX_TEST_ABORT_SIGNAL=signal.Signals(sig).name[3:]),
            stdout=log_file, stderr=log_file, timeout=600)
    finished = completed_chunks(store)
    if sig == signal.SIGKILL:
        assert proc.returncode == -signal.SIGKILL, log.read_text()[-2000:]
        assert lock_path(store).exists()  # the killed writer's lock, now stale
    else:
        assert proc.returncode == 130, log.read_text()[-2000:]
        assert "finished chunks are kept" in log.read_text()
        assert not lock_path(store).exists()
    assert finished.tolist() == [True, False, False], finished
    run = run_sweep(config, store, resume=True, progress=False)
    assert not lock_path(store).exists()
    assert run.computed_chunks == [1, 2] and run.skipped_chunks == [0]
    assert_stores_equal(open_store(store), open_store(ref_path))  # bit for bit


def test_cli_max_chunks_then_resume(reference, tmp_path, capsys):
    from lfjax.cli import main

    config, ref_path, _ = reference
    toml = write_toml(tmp_path / "tiny.toml", config)
    store = tmp_path / "tiny.zarr"
    assert main(["sweep", str(toml), "--out", str(store), "--max-chunks", "1",
                 "--no-progress"]) == 0
    assert completed_chunks(store).tolist() == [True, False, False]
    plan = capsys.readouterr().out  # the plan comes first, before the work
    assert plan.index("eyes        6 in 3 chunks of 2") < plan.index("1 chunks computed")
    assert main(["sweep", str(toml), "--out", str(store), "--no-progress"]) == 2
    assert "--resume" in capsys.readouterr().err
    assert main(["sweep", str(toml), "--out", str(store), "--resume", "--no-progress"]) == 0
    out = capsys.readouterr().out
    assert "4 eyes in 2 chunks computed" in out and "1 chunks already complete" in out
    assert_stores_equal(open_store(store), open_store(ref_path))


# ----------------------------------------------------------------------------- guarded stores


def test_store_opens_consolidated_and_records_its_provenance(reference):
    import warnings

    import jax
    import xarray as xr

    import lfjax

    _, path, _ = reference
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no "consolidated metadata not found" warning
        ds = xr.open_zarr(path)
    made = json.loads(ds.attrs["provenance_json"])
    assert made["lfjax_version"] == lfjax.__version__ and made["jax_version"] == jax.__version__
    assert made["host"] == socket.gethostname() and made["jax_devices"] == "1 x cpu"
    assert "lfjax_git_commit" in made and made["created_utc"].endswith("+00:00")
    assert list(made) == sorted(STAMP_KEYS)  # the one stamp (lfjax._version.stamp), sorted
    first = json.loads(ds.attrs["runs_json"])[0]
    assert first["chunks_computed"] == 3 and first["host"] == socket.gethostname()
    assert made["created_utc"] <= first["ended_utc"] <= ds.attrs["completed_utc"]


def test_a_second_writer_is_refused_and_a_stale_lock_taken_over(reference, tmp_path, capsys):
    from lfjax.cli import main

    config, ref_path, _ = reference
    store = tmp_path / "locked.zarr"
    shutil.copytree(ref_path, store)
    toml = write_toml(tmp_path / "locked.toml", config)
    holder = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(300)"])
    try:
        lock_path(store).write_text(json.dumps({"host": socket.gethostname(), "pid": holder.pid,
                                                "started_utc": "2026-01-02T03:04:05+00:00"}))
        with pytest.raises(StoreLockedError) as err:
            run_sweep(config, store, resume=True, progress=False)
        for part in (f"host {socket.gethostname()}", f"PID {holder.pid}",
                     "since 2026-01-02T03:04:05+00:00", str(lock_path(store))):
            assert part in str(err.value), part
        assert main(["sweep", str(toml), "--out", str(store), "--resume", "--no-progress"]) == 2
        assert f"PID {holder.pid}" in capsys.readouterr().err
    finally:
        holder.kill()
        holder.wait()
    # its process is gone: the lock is stale, taken over and released
    run_sweep(config, store, resume=True, progress=False)
    assert "took over a stale lock" in capsys.readouterr().err
    assert not lock_path(store).exists()
    # a holder on another host cannot be checked from here: refused, never broken
    lock_path(store).write_text(json.dumps({"host": "elsewhere", "pid": 1,
                                            "started_utc": "2026-01-02T03:04:05+00:00"}))
    with pytest.raises(StoreLockedError, match="host elsewhere, PID 1"):
        run_sweep(config, store, resume=True, progress=False)


def test_verify_finds_missing_and_truncated_chunks_and_resume_recomputes_them(
        reference, tmp_path, capsys):
    from lfjax.cli import main

    config, ref_path, _ = reference
    store = tmp_path / "damaged.zarr"
    shutil.copytree(ref_path, store)
    assert main(["sweep", str(store), "--verify"]) == 0
    assert "3 of 3 chunks verified, 0 corrupt" in capsys.readouterr().out
    (store / "vsotf" / "1.0.0.0.0").unlink()  # reads back as NaN without a checksum
    damaged = store / "mtf_at_peak" / "2.0.0.0.0.0"
    damaged.write_bytes(damaged.read_bytes()[:20])
    check = verify_store(store)
    assert check.ok == [0] and sorted(check.corrupt) == [1, 2], check
    assert "checksum" in check.corrupt[1] and "unreadable" in check.corrupt[2]
    assert main(["sweep", str(store), "--verify"]) == 1
    out = capsys.readouterr().out
    assert "1 of 3 chunks verified, 2 corrupt" in out and "chunk 2: unreadable" in out
    run = run_sweep(config, store, resume=True, progress=False)
    assert run.computed_chunks == [1, 2] and sorted(run.recomputed_chunks) == [1, 2]
    assert "recomputing 2 chunk(s)" in capsys.readouterr().err
    assert verify_store(store).ok == [0, 1, 2]
    assert_stores_equal(open_store(store), open_store(ref_path))  # bit for bit again


def _flip(path: Path, index: int) -> None:
    data = bytearray(path.read_bytes())
    data[index] ^= 0xFF
    path.write_bytes(bytes(data))


def test_damaged_bookkeeping_and_coefficients_are_named_and_recomputed_on_resume(
        reference, tmp_path, capsys):
    """One chunk per fault: its eyes' coefficients swapped with the next chunk's (covered
    by its checksum), a flipped byte in chunk_checksum/1 (the file no longer decodes), and
    chunk_complete/2 deleted (its checksum says it was written). --verify names each file
    and exits 1 without a traceback; open_store reads around them with a warning; --resume
    recomputes exactly those chunks, bit for bit."""
    from lfjax.cli import main

    config, ref_path, _ = reference
    store = tmp_path / "bookkeeping.zarr"
    shutil.copytree(ref_path, store)
    shutil.copyfile(store / "zernike_um" / "1.0", store / "zernike_um" / "0.0")
    _flip(store / "chunk_checksum" / "1", 5)
    (store / "chunk_complete" / "2").unlink()
    check = verify_store(store)
    assert check.ok == [] and sorted(check.corrupt) == [0, 1, 2], check
    assert "zernike_um" in check.corrupt[0]
    assert "chunk_checksum/1 is unreadable" in check.corrupt[1]
    assert "chunk_complete/2 is missing or altered" in check.corrupt[2]
    assert main(["sweep", str(store), "--verify"]) == 1
    out, err = capsys.readouterr()
    assert "0 of 3 chunks verified, 3 corrupt" in out and "Traceback" not in err
    assert "chunk 1: bookkeeping file chunk_checksum/1 is unreadable" in out
    with pytest.warns(UserWarning, match=r"chunk\(s\) \[1, 2\] counted as not computed"):
        partial = open_store(store, complete_only=True)
    assert partial.sizes["eye"] == 2  # chunk 0's eyes: their marks are intact
    run = run_sweep(config, store, resume=True, progress=False)
    assert run.computed_chunks == [0, 1, 2] and sorted(run.recomputed_chunks) == [0, 1, 2]
    assert "chunk 2: bookkeeping file chunk_complete/2" in capsys.readouterr().err
    assert verify_store(store).ok == [0, 1, 2]
    assert_stores_equal(open_store(store), open_store(ref_path))  # coefficients repaired too


def test_the_configuration_and_coordinates_are_covered_by_a_checksum(reference, tmp_path,
                                                                      capsys):
    from lfjax.cli import main
    from lfjax.sweep.store_checks import StoreDamagedError

    config, ref_path, _ = reference
    assert verify_store(ref_path).problems == []
    store = tmp_path / "config.zarr"
    shutil.copytree(ref_path, store)
    attrs = json.loads((store / ".zattrs").read_text())
    attrs["cdp_D"] = 2.5  # what the claims read; the config_json is untouched
    (store / ".zattrs").write_text(json.dumps(attrs))
    check = verify_store(store)
    assert not check.healthy and "do not match the checksum" in check.problems[0]
    assert main(["sweep", str(store), "--verify"]) == 1
    assert "store: its configuration or coordinates do not match" in capsys.readouterr().out
    with pytest.raises(StoreDamagedError, match="cannot be resumed safely"):
        run_sweep(config, store, resume=True, progress=False)
    shutil.rmtree(store)
    shutil.copytree(ref_path, store)
    import zarr

    zarr.open_group(str(store), mode="r+", zarr_format=2, use_consolidated=False)["depth"][0] = 9.0
    assert "do not match the checksum" in " ".join(verify_store(store).problems)  # a coordinate
    shutil.copyfile(store / "depth" / "0", store / "accommodation" / "0")  # unreadable: said
    assert "cannot be read (ValueError" in verify_store(store).problems[0]


def test_damaged_metadata_files_are_reported_as_damage_not_as_a_foreign_folder(
        reference, tmp_path, capsys):
    from lfjax.cli import main

    config, ref_path, _ = reference
    store = tmp_path / "metadata.zarr"
    shutil.copytree(ref_path, store)
    text = (store / ".zmetadata").read_text()
    (store / ".zmetadata").write_text(text[: len(text) // 2])  # truncated
    check = verify_store(store)
    assert check.ok == [0, 1, 2] and ".zmetadata (the consolidated metadata) is damaged" in \
        check.problems[0]
    with pytest.warns(UserWarning, match="zmetadata"):
        assert open_store(store).sizes["eye"] == 6  # read around it
    run = run_sweep(config, store, resume=True, progress=False)  # rewrites it as it ends
    assert run.computed_chunks == [] and verify_store(store).healthy
    text = (store / ".zattrs").read_text()
    (store / ".zattrs").write_text(text[: len(text) // 2])
    assert main(["sweep", str(store), "--verify"]) == 2
    err = capsys.readouterr().err
    assert "looks like an lfjax sweep store but its metadata file .zattrs is damaged" in err
    assert len(err.strip().splitlines()) == 1


def test_racing_creators_get_a_one_line_refusal(reference, tmp_path, capsys, monkeypatch):
    """The other writer's store appears between this one's check and its rename."""
    from lfjax.cli import main
    from lfjax.sweep import store as store_module

    config, ref_path, _ = reference
    toml = write_toml(tmp_path / "race.toml", config)
    store = tmp_path / "race.zarr"
    real_clean = store_module.clean_interrupted_creations

    def other_writer_wins(path):
        shutil.copytree(ref_path, path)
        return real_clean(path)

    monkeypatch.setattr(store_module, "clean_interrupted_creations", other_writer_wins)
    assert main(["sweep", str(toml), "--out", str(store), "--no-progress"]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert err[-1].startswith(f"lfjax sweep: error: {store} was created by another process "
                              f"while this one was creating it"), err
    assert "OSError" not in "\n".join(err) and "Directory not empty" not in "\n".join(err)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["race.toml", "race.zarr"]
    assert_stores_equal(open_store(store), open_store(ref_path))  # the winner's, untouched


def test_an_interrupted_store_creation_leaves_no_hidden_folder(tmp_path, capsys):
    gone = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"],
                          capture_output=True, text=True, check=True)
    host = socket.gethostname()
    left = tmp_path / f".s.zarr.creating-{host}-{int(gone.stdout)}-0123abcd"
    left.mkdir()
    (left / ".zgroup").write_text("{}")
    alive = tmp_path / f".s.zarr.creating-{host}-{os.getpid()}-0123abcd"
    alive.mkdir()
    assert clean_interrupted_creations(tmp_path / "s.zarr") == [left]
    assert not left.exists() and alive.exists()  # a live creation is left alone
    assert "removed 1 folder(s) left by an interrupted store creation" in capsys.readouterr().err


# ----------------------------------------------------------------------------- devices, hosts

SHARDED_SCRIPT = """
import sys
import jax
from lfjax.sweep import load_config, run_sweep
assert len(jax.local_devices()) == 4, jax.local_devices()
run = run_sweep(load_config(sys.argv[1]), sys.argv[2], progress=False)
assert run.traces == {(0, 0): 1}, run.traces  # a fresh process: exactly one
"""


def test_sharded_over_four_devices_equals_unsharded(reference_2x2, tmp_path):
    """The reference's 2x2 layout (its eyes, sampling and spectrum: the same plan), four
    eyes per chunk, one per device. (One layout: sharding splits the eye axis, which every
    layout's chunk function maps the same way.)"""
    _, ref_path, _ = reference_2x2
    toml = write_toml(tmp_path / "four.toml", tiny_config(run={"chunk_size": 4},
                                                          display={"layouts": ["2x2"]}))
    sharded = tmp_path / "four_devices.zarr"
    env = subprocess_env(XLA_FLAGS=os.environ.get("XLA_FLAGS", "")
                         + " --xla_force_host_platform_device_count=4")
    proc = subprocess.run([sys.executable, "-c", SHARDED_SCRIPT, str(toml), str(sharded)],
                          env=env, capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr[-3000:]
    # Each device maps its eye alone, the unsharded reference maps two per call: the same
    # float64 arithmetic up to round-off of the batch shape (stated tolerance 1e-9 relative).
    # 4-eye chunks against 2-eye chunks: their bookkeeping (and chunk axis) differs
    a, b = (open_store(path).drop_vars(CHUNK_MARKS) for path in (sharded, ref_path))
    assert list(a.layout.values) == ["2x2"]
    assert {k: n for k, n in a.sizes.items() if k != "chunk"} == \
        {k: n for k, n in b.sizes.items() if k != "chunk"}
    assert_stores_equal(a, b, rtol=1e-9, atol=1e-12)


IMPORT_SCRIPT = """
import importlib, pkgutil, socket
import jax
from jax._src import xla_bridge
import lfjax
names = ["lfjax"] + [m.name for m in pkgutil.walk_packages(lfjax.__path__, "lfjax.")]
for name in names:
    importlib.import_module(name)
    assert not xla_bridge.backends_are_initialized(), f"importing {name} started JAX's backend"
# what the backend check stands for: jax.distributed can still start after these imports
with socket.socket() as s:
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
jax.distributed.initialize(coordinator_address=f"127.0.0.1:{port}", num_processes=1,
                           process_id=0)
assert jax.process_count() == 1
jax.distributed.shutdown()
print(len(names), "modules")
"""


def test_no_module_starts_a_jax_backend_at_import():
    """``lfjax sweep --distributed`` imports lfjax before jax.distributed.initialize, which
    refuses once any JAX backend exists: no module may create a JAX array at import."""
    proc = subprocess.run([sys.executable, "-c", IMPORT_SCRIPT], env=subprocess_env(),
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert int(proc.stdout.split()[0]) > 30  # every module was imported


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_readme_two_process_distributed_command_writes_the_one_process_store(reference_2x2,
                                                                            tmp_path):
    """The README's multi-host command, as two local processes through the command line
    (coordinator on 127.0.0.1): the shared store equals the one-process run bit for bit.
    (The reference's 2x2 layout alone: one chunk function to trace in each process.)"""
    config, ref_path, _ = reference_2x2
    toml = write_toml(tmp_path / "tiny.toml", config)
    store = tmp_path / "two_processes.zarr"
    port = _free_port()
    procs = [subprocess.Popen(
        [sys.executable, "-m", "lfjax.cli", "sweep", str(toml), "--out", str(store),
         "--distributed", "--coordinator", f"127.0.0.1:{port}", "--num-processes", "2",
         "--process-id", str(pid), "--no-progress"],
        env=subprocess_env(), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        for pid in (0, 1)]
    try:
        outputs = [p.communicate(timeout=600) for p in procs]
    finally:
        for p in procs:
            if p.poll() is None:
                p.kill()
    for p, (out, err) in zip(procs, outputs):
        assert p.returncode == 0, err[-3000:]
    # process 0 computes chunks 0 and 2 (4 eyes), process 1 chunk 1 (2 eyes)
    assert "4 eyes in 2 chunks computed (process 0 of 2)" in outputs[0][0], outputs[0]
    assert "2 eyes in 1 chunks computed (process 1 of 2)" in outputs[1][0], outputs[1]
    assert_stores_equal(open_store(store), open_store(ref_path))


def test_guide_config_lists_every_key_with_its_default():
    """The population-sweeps guide's config is valid and states the defaults (it stays
    true)."""
    import re

    from lfjax.sweep import SweepConfig
    from lfjax.sweep.config import SCHEMA

    guide = Path(__file__).resolve().parents[2] / "docs" / "guides" / "population-sweeps.md"
    guide = guide.read_text()
    block = re.search(r"```toml\n(.*?)```", guide, re.S).group(1)
    data = tomllib.loads(block)
    assert config_from_dict(data).as_dict() == SweepConfig().as_dict()
    commented = set(re.findall(r"^# (\w+) =", block, re.M))
    for section, keys in SCHEMA.items():
        missing = [k for k in keys if k not in data.get(section, {}) and k not in commented]
        assert not missing, (section, missing)


def test_a_real_display_sweeps_as_through_focus_computes_it(tmp_path):
    """Lenslet diffraction, pixels and an OLED spectrum from the config reach every chunk:
    the store equals through_focus with the same display and spectrum."""
    from lfjax.vision.focus import through_focus

    config = tiny_config(population={"n_eyes": 1}, display={
        "layouts": ["2x2"], "depth_offsets_D": [0.0, 1.0], "lenslet_distance_mm": 300.0,
        "pixel_width_arcmin": 2.0}, spectrum={"display": "laser"})
    display = config.display_optics()
    assert display.diffraction == "fresnel" and float(display.fresnel_distance_mm) == pytest.approx(750.0)
    spectrum = sweep_spectrum(config)
    assert spectrum.n_wavelengths == 3  # the laser's three lines
    ds = open_store(run_sweep(config, tmp_path / "display.zarr", progress=False).store)
    eyes, _ = population(config)
    (task,) = build_tasks(config, eyes, spectrum)
    assert task.scene.display is not None
    tf = through_focus(
        eyes,
        task.layout,
        States.grid(config.accommodation_D, depths_D=task.depths_D, window_D=config.window_D),
        Viewing(pupil_diameter_mm=task.pupil_mm, cdp_D=config.cdp_D, display=display),
        spectrum=spectrum,
        sampling=task.sampling,
        options=config.options,
    )
    np.testing.assert_allclose(ds.vsotf.values[:, 0, 0], np.asarray(tf.vsotf), rtol=1e-6, atol=1e-9)
    ideal = through_focus(
        eyes,
        task.layout,
        States.grid(config.accommodation_D, depths_D=task.depths_D, window_D=config.window_D),
        Viewing(pupil_diameter_mm=task.pupil_mm, cdp_D=config.cdp_D),
        spectrum=spectrum,
        sampling=task.sampling,
        options=config.options,
    )
    assert np.nanmax(np.abs(np.asarray(ideal.vsotf) - np.asarray(tf.vsotf))) > 1e-3


def test_hpo_strips_with_leakage_sweep_as_through_focus_computes_them(tmp_path):
    """[display] 1xN strips, strip_width_ratio, strip_y_defocus_D and leakage_weight reach
    every chunk: the store equals through_focus with the same strips built directly
    (lfjax.model.strips.strip_layout, lfjax.display.lenticular.strip_display), records the
    values, and differs from the same strips without leakage."""
    from lfjax.display.lenticular import strip_display
    from lfjax.model.strips import strip_layout
    from lfjax.vision.focus import through_focus

    config = tiny_config(population={"n_eyes": 2, "average_eye": False}, display={
        "layouts": ["1x2"], "depth_offsets_D": [1.0], "strip_width_ratio": 1.25,
        "strip_y_defocus_D": -0.83, "leakage_weight": 0.5}, run={"chunk_size": 2},
        spectrum={"wavelengths_nm": [550.0, 550.0, 1.0]}, metrics={"continuous_peaks": []})
    ds = open_store(run_sweep(config, tmp_path / "strips.zarr", progress=False).store)
    recorded = json.loads(ds.attrs["display"])
    assert (recorded["strip_width_ratio"], recorded["strip_y_defocus_D"],
            recorded["leakage_weight"]) == (1.25, -0.83, 0.5)
    eyes, _ = population(config)
    spectrum = sweep_spectrum(config)
    (task,) = build_tasks(config, eyes, spectrum)
    layout = strip_layout(2, 3.0, width_mm=1.25 * 1.5)
    np.testing.assert_array_equal(np.asarray(task.layout.diameters_mm), np.asarray(layout.diameters_mm))

    def direct(**display):
        return np.asarray(
            through_focus(
                eyes,
                layout,
                States.grid(
                    config.accommodation_D, depths_D=task.depths_D, window_D=config.window_D
                ),
                Viewing(
                    pupil_diameter_mm=task.pupil_mm,
                    cdp_D=config.cdp_D,
                    display=strip_display(layout, **display),
                ),
                spectrum=spectrum,
                sampling=task.sampling,
                options=config.options,
            ).vsotf
        )

    lenticular = direct(y_defocus_D=-0.83, leakage_weight=0.5)
    np.testing.assert_allclose(ds.vsotf.values[:, 0, 0], lenticular, rtol=1e-6, atol=1e-9)
    assert np.nanmax(np.abs(lenticular - direct(y_defocus_D=-0.83))) > 1e-3
    # the report draws the strips as strips (rectangles spanning the pupil), not discs
    from matplotlib.patches import Circle, Rectangle

    from lfjax.sweep.report import fig_layouts
    (ax,) = fig_layouts({(3.0, "1x2"): task.layout}, [3.0], ["1x2"]).axes
    assert sum(isinstance(p, Rectangle) for p in ax.patches) == 4  # area and edge of each
    assert sum(isinstance(p, Circle) for p in ax.patches) == 1  # the pupil


def test_a_full_disk_keeps_the_finished_chunks_and_says_how_to_resume(reference, tmp_path,
                                                                       capsys, monkeypatch):
    import errno

    from lfjax.cli import main
    from lfjax.sweep import run as sweep_run

    config, ref_path, _ = reference
    toml = write_toml(tmp_path / "full.toml", config)
    store = tmp_path / "full.zarr"
    real_write = sweep_run.write_chunk
    calls = []

    def second_write_fails(*args):
        calls.append(args[1])
        if len(calls) == 2:
            raise OSError(errno.ENOSPC, "No space left on device")
        return real_write(*args)

    monkeypatch.setattr(sweep_run, "write_chunk", second_write_fails)
    assert main(["sweep", str(toml), "--out", str(store), "--no-progress"]) == 1
    err = capsys.readouterr().err
    assert f"the disk is full: finished chunks are kept in {store}" in err
    assert "continue with --resume" in err
    assert completed_chunks(store).tolist() == [True, False, False]
    assert not lock_path(store).exists()
    monkeypatch.setattr(sweep_run, "write_chunk", real_write)
    assert main(["sweep", str(toml), "--out", str(store), "--resume", "--no-progress"]) == 0
    assert_stores_equal(open_store(store), open_store(ref_path))


def test_progress_says_what_it_plans_and_compiles(reference, tmp_path, capsys):
    from lfjax.sweep.store import unmark_chunks

    config, ref_path, _ = reference
    store = tmp_path / "progress.zarr"
    shutil.copytree(ref_path, store)
    unmark_chunks(store, [2])
    run = run_sweep(config, store, resume=True, progress=True)
    assert run.computed_chunks == [2]
    err = capsys.readouterr().err
    said = [err.index(s) for s in (
        "drew 6 eyes; reading the stored sampling of 2 (pupil, layout) pair(s)",
        "planned in", "compiling 2 chunk function(s) with the first chunk")]
    assert said == sorted(said), err
    assert "2/2" in err  # the bar, in eyes


def test_a_store_is_created_from_one_chunk_and_equals_the_whole_template(reference,
                                                                          tmp_path):
    """Creating a store holds one chunk's template in memory and extends the eye axis on
    disk: the result reads exactly as a store written from the whole population's template."""
    from lfjax.sweep.store import create_store, stored_samplings, template

    config, ref_path, _ = reference
    eyes, is_average = population(config)
    tasks = build_tasks(config, eyes, sweep_spectrum(config), stored_samplings(ref_path))
    z = np.asarray(eyes.zernike_um)
    whole = create_store(tmp_path / "whole.zarr", template(config, tasks, z, is_average),
                         config.chunk_size)
    size = config.chunk_size
    part = create_store(tmp_path / "part.zarr", template(config, tasks, z[:size],
                                                         is_average[:size]),
                        config.chunk_size, eyes=(z, is_average))
    a, b = open_store(whole), open_store(part)
    assert a.sizes == b.sizes and b.sizes["eye"] == config.n_total_eyes
    assert_stores_equal(a, b)
    for name in a.coords:
        assert np.array_equal(a[name].values, b[name].values), name
    assert a.vsotf.attrs == b.vsotf.attrs and np.isnan(b.vsotf.values).all()
    assert not b.continuous_peak_success.values.any()
    assert (tmp_path / "part.zarr" / ".zmetadata").is_file()


def test_a_layout_file_made_for_a_larger_pupil_is_refused_before_anything_is_planned(tmp_path):
    """A layout file whose view lies outside a calculation pupil: the sweep stored VSOTF
    exactly 1.0 at every state and sweep-report showed it without a word (issue #37).
    Now the configuration names the layout, the pupil and how far outside it lies."""
    import json

    from lfjax.model.layout_files import LAYOUT_FORMAT

    path = tmp_path / "wide.json"
    path.write_text(json.dumps({"format": LAYOUT_FORMAT, "name": "wide", "pupil_diameter_mm": 6.0,
                                "centres_mm": [[0.0, 0.0], [2.5, 0.0]],
                                "diameters_mm": [1.0, 1.0]}))
    data = {k: dict(v) for k, v in TINY.items()}
    data["display"]["layouts"] = ["2x2", str(path)]
    data["population"]["pupil_diameters_mm"] = [3.0, 6.0]
    data["population"]["measured_pupil_mm"] = 6.0
    with pytest.raises(SweepConfigError) as err:
        config_from_dict(data)
    (problem,) = err.value.problems
    assert problem == (
        f"display.layouts ({path}) 'wide' has 1 of its 2 views entirely outside the 3 mm pupil "
        "(population.pupil_diameters_mm; a view must reach |centre| - diameter/2 < 1.5 mm): "
        "view 1 at (2.5, 0) mm, diameter 1 mm, 0.5 mm outside. Was it made for a larger pupil? "
        "Make it for this pupil, or give a pupil that holds it")
    data["population"]["pupil_diameters_mm"] = [6.0]  # the pupil it was made for
    assert config_from_dict(data).layouts == ("2x2", str(path))


def test_a_missing_distributed_peer_is_named_within_the_timeout(reference, tmp_path):
    """Processes missing at start-up: two of three started with one coordinator, and one
    of two started whose coordinator never did. Each stops after --distributed-timeout
    with one line naming the coordinator, the processes seen (the coordinator counts the
    processes that reached it; a peer can see only itself) and the time waited — not
    XLA's 300 s wait and SIGABRT."""
    config, _, _ = reference
    toml = write_toml(tmp_path / "alone.toml", config)
    shared, lonely = _free_port(), _free_port()
    cases = {  # name: (port, processes expected, process id, what it must say it saw)
        "coordinator": (shared, 3, 0, "2 of 3 processes connected to it (this one, process "
                                      "0, included)"),
        "peer": (shared, 3, 1, "this process (process 1 of 3) cannot see which others did"),
        "orphan": (lonely, 2, 1, "this process (process 1 of 2) cannot see which others "
                                 "did; the coordinator does not answer"),
    }
    procs = {}
    for name, (port, n, pid, _) in cases.items():
        procs[name] = subprocess.Popen(
            [sys.executable, "-m", "lfjax.cli", "sweep", str(toml), "--out",
             str(tmp_path / f"alone-{name}.zarr"), "--distributed", "--coordinator",
             f"127.0.0.1:{port}", "--num-processes", str(n), "--process-id", str(pid),
             # the peer outlives the coordinator's count
             "--distributed-timeout", "6" if name == "peer" else "3", "--no-progress"],
            env=subprocess_env(), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    for name, proc in procs.items():
        port, n, pid, saw = cases[name]
        try:
            _, err = proc.communicate(timeout=120)
        finally:
            if proc.poll() is None:
                proc.kill()
        assert proc.returncode == 1, err[-3000:]
        line = err.strip().splitlines()[-1]
        assert line.startswith(f"lfjax sweep: error: distributed start-up: not every process "
                               f"connected to the coordinator 127.0.0.1:{port}"), err[-3000:]
        assert saw in line, (name, line)
        assert re.search(r"within [3-7] s", line), line
        assert ("this process runs it" in line) == (pid == 0)
        assert "Check failure" not in err and "Aborted" not in err
    assert not any(tmp_path.glob("alone*.zarr"))
