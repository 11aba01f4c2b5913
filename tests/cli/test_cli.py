"""The command line: `lfjax reproduce` end to end (quick run, outputs complete and finite),
bad input, the parameter↔flag table every subcommand names library errors through, the
notebook. Covers lfjax.cli (its main), lfjax.cli.flags (the table and argument types),
lfjax.cli.common (the one-line errors and the guard) and lfjax.cli.cache (through every run
that turns the compilation cache on).

Covers: lfjax.cli.common, lfjax.cli.flags, lfjax.cli.cache, lfjax.cli.reproduce
Covers: lfjax.reproduce, lfjax.reproduce.config
Covers: lfjax.reproduce.study, lfjax.reproduce.report, lfjax.reproduce.figures
Covers: lfjax.reproduce.examples
"""

import argparse
import dataclasses
import inspect
import os
import re
import subprocess
from pathlib import Path

import numpy as np
import pytest

from helpers import execute_notebook_tiny, percent_cells
from lfjax import cli
from lfjax import reproduce as rep
from lfjax.reproduce import run as reproduce_run
from lfjax.base.errors import ParameterError
from lfjax.base.files import staged_output
from lfjax.cli import flags

ROOT = Path(__file__).resolve().parents[2]
NOTEBOOK = ROOT / "notebooks" / "reproduce_paper.ipynb"
NOTEBOOK_TWIN = ROOT / "notebooks" / "reproduce_paper.py"


def run_main(capsys, *args):
    code = cli.main(list(args))
    out = capsys.readouterr()
    return code, out.out, out.err


# ------------------------------------------------------------------ end to end


TINY_WAVELENGTHS_NM = (550.0, 550.0, 1.0)
"""The end-to-end run's one wavelength (``--quick`` sums 400–700 nm in 30 nm steps). Each
wavelength is its own FFT band in the compiled programs, so one is what makes the run
cheap; the checks below are of the command's structure (every file, table, figure and
claim, labelled and finite), which does not depend on the spectrum. The notebook's tiny
size (``LFJAX_NOTEBOOK_SIZE=tiny``) uses the same, so it reuses these programs."""


@pytest.fixture(scope="module")
def quick_run(tmp_path_factory):
    """``lfjax reproduce --quick --out DIR`` through the command line's entry point in this
    process (the exit status, stdout and stderr as the console script would give them), with
    ``StudyConfig.quick`` on :data:`TINY_WAVELENGTHS_NM`. In float32, as the console script
    computes (this session is float64): the notebook's kernel, float32 too, then reads its
    programs from the session's caches. Returns (process result, out, its parent folder,
    the config the run used)."""
    import contextlib
    import io

    import jax

    from lfjax.base.programs import enable_program_cache
    from lfjax.planner.cache import enable_plan_cache

    parent = tmp_path_factory.mktemp("cli")
    out = parent / "results"
    quick = rep.StudyConfig.quick

    def tiny_quick(cls, *args, **changes):
        return quick(*args, **{"wavelengths_nm": TINY_WAVELENGTHS_NM, **changes})

    stdout, stderr = io.StringIO(), io.StringIO()
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(rep.StudyConfig, "quick", classmethod(tiny_quick))
        config = rep.StudyConfig.quick()
        with contextlib.redirect_stdout(stdout), contextlib.redirect_stderr(stderr), \
                jax.enable_x64(False):
            code = cli.main(["reproduce", "--quick", "--out", str(out)])
    # the command line turned on the plan and program caches: the other modules in this
    # process run with the caches as the session set them
    enable_program_cache(None)
    enable_plan_cache(None)
    proc = subprocess.CompletedProcess(["lfjax", "reproduce", "--quick"], code,
                                       stdout.getvalue(), stderr.getvalue())
    return proc, out, parent, config


def test_quick_run_succeeds_and_says_where(quick_run):
    proc, out, parent, config = quick_run
    assert config.wavelength_grid_nm.tolist() == [550.0]  # the tiny run, not the full quick
    assert proc.returncode == 0, proc.stderr[-3000:]
    last = proc.stdout.strip().splitlines()[-1]
    assert str(out) in last and last.rstrip().endswith(" s")
    assert "stages" in proc.stderr  # the progress bar
    # written through a temporary folder, nothing left beside the result
    assert sorted(p.name for p in parent.iterdir()) == ["results"]


def test_quick_run_writes_every_file(quick_run):
    _, out, _, _ = quick_run
    expected = {rep.RESULTS_FILE, rep.EXAMPLES_FILE, "REPORT.md", rep.MARKER_FILE}
    expected |= set(rep.FIGURES.values())
    expected |= {name for key, name in rep.TABLES.items() if key != "alternatives"}
    assert expected <= {p.name for p in out.iterdir()}
    for name in rep.FIGURES.values():
        data = (out / name).read_bytes()
        assert data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) > 20_000, name


def test_quick_run_tables_are_complete_and_finite(quick_run):
    import pandas as pd

    _, out, _, config = quick_run
    n_eye = config.n_eyes + 1
    n_cells = 1 + 3 * len(config.depth_offsets_D)  # natural: the CDP only
    pred = pd.read_csv(out / rep.TABLES["predictions"])
    assert len(pred) == n_eye * n_cells * 2
    assert set(pred.metric) == {"vsotf", "strehl"}
    assert set(pred.layout) == {"natural", "2x2", "3x3", "4x4"}
    assert pred.eye.nunique() == n_eye and pred.is_average.sum() == n_cells * 2
    summary = pd.read_csv(out / rep.TABLES["summary"])
    assert len(summary) == n_cells * 2
    cutoff = pd.read_csv(out / rep.TABLES["cutoff"])
    assert len(cutoff) == n_cells
    # continuous peaks are refined for VSOTF only (Strehl rows: NaN, "not computed")
    continuous = pred.predicted_accommodation_continuous_D
    assert np.all(np.isfinite(continuous[pred.metric == "vsotf"]))
    assert np.all(np.isnan(continuous[pred.metric == "strehl"]))
    assert np.all(np.abs(continuous[pred.metric == "vsotf"]
                         - pred.predicted_accommodation_D[pred.metric == "vsotf"])
                  <= config.accommodation_step_D + 1e-9)
    for table in (pred.drop(columns="predicted_accommodation_continuous_D"), summary, cutoff):
        numeric = table.select_dtypes("number").to_numpy(float)
        assert np.all(np.isfinite(numeric))
    # predictions lie on the accommodation grid, inside the evaluated window
    grid = config.accommodation_D
    assert np.all(np.min(np.abs(pred.predicted_accommodation_D.to_numpy()[:, None] - grid),
                         axis=1) < 1e-6)
    assert np.all(np.abs(pred.accommodation_error_D) <= config.window_D + 1e-9)
    assert np.all((cutoff.mean_cutoff_cpd > 0) & (cutoff.mean_cutoff_cpd < 150))
    claims = pd.read_csv(out / rep.TABLES["claims"])
    assert list(claims.id.astype(str)) == [str(i) for i in range(1, 8)]
    assert set(claims.verdict) <= {"holds", "fails"}


def test_quick_run_results_file_is_labelled(quick_run):
    import xarray as xr

    _, out, _, _ = quick_run
    with xr.open_dataset(out / rep.RESULTS_FILE, engine="h5netcdf") as ds:
        assert {"eye", "layout", "depth", "accommodation", "frequency", "metric"} <= set(ds.dims)
        assert ds.vsotf.dims == ("layout", "eye", "depth", "accommodation")
        assert ds.depth.attrs["units"] == "D" and ds.frequency.attrs["units"] == "cpd"
        assert ds.cutoff_frequency.attrs["units"] == "cpd"
        assert ds.attrs["option_sce"] == "amplitude"
        assert "model_options_json" in ds.attrs
        assert int(ds.is_average.sum()) == 1
        # the transform each layout used is recorded (4x4: the MFT, by default)
        assert rep.study_sampling(ds, "4x4").transform == "mft"
        assert rep.study_sampling(ds, "4x4").mft_pupil_samples == 48
        assert rep.study_sampling(ds, "2x2").transform == "fft"
        # VSOTF of the average eye, natural view, at its peak is close to 1 (near DL)
        nat = ds.vsotf.sel(layout="natural", eye="average", depth=2.0)
        assert 0.8 < float(nat.max()) <= 1.01
    with xr.open_dataset(out / rep.EXAMPLES_FILE, engine="h5netcdf") as ex:
        assert "fig9_retinal_image" in ex and "fig5_psf" in ex


def test_quick_run_report_states_every_claim(quick_run):
    _, out, _, _ = quick_run
    text = (out / "REPORT.md").read_text()
    for i in range(1, 8):
        assert f"\n| {i} | " in text
    assert "--quick" in text and "Modelling choices" in text
    assert "| 4x4 | 16 |" in text and "MFT (48 pupil samples)" in text
    # every layout's spectrum in words (a Gauss rule has no step: it once printed "nan")
    assert not re.search(r"\bnan\b", text, re.IGNORECASE), "a NaN reached REPORT.md"
    settings = text.split("## Settings", 1)[1].split("\n\n", 2)[1]
    rows = [r for r in settings.splitlines() if r.startswith("| ") and "layout" not in r]
    assert len(rows) == 4 and all(("Gauss rule (" in r or "nm steps (" in r) for r in rows), rows


# ------------------------------------------------------------------ bad input


def test_help_explains_every_option_with_units(capsys):
    code, out, _ = run_main(capsys, "reproduce", "--help")
    assert code == 0
    for option in ("--out", "--eyes", "--seed", "--quick", "--force", "--accuracy",
                   "--settle-verdicts"):
        assert option in out
    for unit in (" D", "cpd", "nm", "mm"):
        assert unit in out


@pytest.mark.parametrize("command", sorted(cli.SUBCOMMANDS))
def test_every_subcommands_help_names_its_guide_page(capsys, command):
    """The help ends by naming the guide page (which exists); a required flag says so."""
    code, out, _ = run_main(capsys, command, "--help")
    assert code == 0
    guide = f"docs/guides/{cli.GUIDES[command]}"
    assert guide in " ".join(out.split()) and (ROOT / guide).is_file()
    if command == "design":
        assert "required: rendered depth range" in " ".join(out.split())


@pytest.mark.parametrize("args, message", [
    (["reproduce", "--eyes", "0"], "--eyes"),
    (["reproduce", "--eyes", "-3"], "--eyes"),
    (["reproduce", "--eyes", "many"], "--eyes"),
    (["reproduce", "--seed", "-1"], "--seed"),
    (["reproduce", "--accuracy", "fast"], "--accuracy"),
    (["reproduce", "--quick", "--settle-verdicts"], "settle_verdicts needs accuracy='claims'"),
    (["reproduce", "--accuracy", "vsotf", "--settle-verdicts"], "--accuracy claims"),
    (["reproduce", "--bogus"], "unrecognized arguments"),
    (["frobnicate"], "invalid choice"),
])
def test_bad_arguments_one_line_exit_2(capsys, tmp_path, args, message):
    out = tmp_path / "never"
    code, stdout, stderr = run_main(capsys, *args, "--out", str(out)) if args[0] == "reproduce" \
        else run_main(capsys, *args)
    assert code == 2
    lines = stderr.strip().splitlines()
    assert len(lines) == 1 and message in lines[0] and "error" in lines[0]
    assert not out.exists()


def test_settle_verdicts_reaches_the_configuration(capsys, tmp_path, monkeypatch):
    import lfjax.cli.reproduce as cli_reproduce

    seen = []

    def capture(out, config, **kwargs):
        seen.append(config)
        raise KeyboardInterrupt  # stop before any work; the guard reports it

    monkeypatch.setattr(cli_reproduce, "reproduce", capture)
    monkeypatch.setattr(cli.cache, "enable_compilation_cache", lambda folder=None: None)
    for flags, want in (([], False), (["--settle-verdicts"], True)):
        run_main(capsys, "reproduce", *flags, "--out", str(tmp_path / f"o{len(seen)}"))
        assert seen[-1].settle_verdicts is want and seen[-1].accuracy == "claims"


def test_non_empty_out_without_force_is_refused(capsys, tmp_path):
    out = tmp_path / "busy"
    out.mkdir()
    (out / "keep.txt").write_text("mine")
    code, _, stderr = run_main(capsys, "reproduce", "--quick", "--out", str(out))
    assert code == 2 and len(stderr.strip().splitlines()) == 1 and "--force" in stderr
    # --force never replaces a folder that lfjax did not write
    code, _, stderr = run_main(capsys, "reproduce", "--quick", "--force", "--out", str(out))
    assert code == 2 and "not written by lfjax" in stderr
    assert [p.name for p in out.iterdir()] == ["keep.txt"]


def test_unwritable_out_is_refused(capsys, tmp_path):
    blocker = tmp_path / "a-file"
    blocker.write_text("x")
    code, _, stderr = run_main(capsys, "reproduce", "--out", str(blocker / "sub"))
    assert code == 2 and len(stderr.strip().splitlines()) == 1
    code, _, stderr = run_main(capsys, "reproduce", "--out", str(blocker))
    assert code == 2 and "not a folder" in stderr
    if os.geteuid() != 0:  # root ignores permissions
        locked = tmp_path / "locked"
        locked.mkdir()
        locked.chmod(0o555)
        try:
            code, _, stderr = run_main(capsys, "reproduce", "--out", str(locked / "new"))
            assert code == 2 and "not writable" in stderr
        finally:
            locked.chmod(0o755)


def test_failure_mid_run_leaves_nothing(capsys, tmp_path, monkeypatch):
    def boom(*args, **kwargs):
        raise RuntimeError("simulated failure\nover two lines")

    monkeypatch.setattr(reproduce_run, "compute_examples", boom)
    monkeypatch.setattr(reproduce_run, "run_study", lambda config, options=None, stage=None: None)
    monkeypatch.setattr(cli.cache, "enable_compilation_cache", lambda folder=None: None)
    out = tmp_path / "new" / "deeper"
    code, _, stderr = run_main(capsys, "reproduce", "--quick", "--no-progress", "--out", str(out))
    assert code == 1
    assert len(stderr.strip().splitlines()) == 1 and "simulated failure over two lines" in stderr
    assert list(tmp_path.iterdir()) == []  # no output, no temporary folder


def test_force_replaces_an_earlier_output(tmp_path):
    out = tmp_path / "res"
    out.mkdir()
    (out / rep.MARKER_FILE).write_text("")
    (out / "old.txt").write_text("old")
    assert rep.check_output_dir(out, force=True) == out
    with staged_output(out, force=True, replace=True) as new:  # as reproduce writes
        (new / "new.txt").write_text("new")
    assert sorted(p.name for p in out.iterdir()) == ["new.txt"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["res"]


def test_config_validation():
    with pytest.raises(ValueError, match="n_eyes"):
        rep.StudyConfig(n_eyes=0)
    with pytest.raises(ValueError, match="CDP"):
        rep.StudyConfig(depth_offsets_D=(-1.0, 1.0))
    with pytest.raises(ValueError, match=">= 0 D"):
        rep.StudyConfig(depth_offsets_D=(-3.0, 0.0))
    for bad in ((("5x5", 48),), (("4x4", 8),), (("4x4", 48.5),), (("4x4",),)):
        with pytest.raises(ValueError, match="mft_pupil_samples"):
            rep.StudyConfig(mft_pupil_samples=bad)
    for bad, match in ((dict(accuracy="fast"), "accuracy"),
                       (dict(peak_tolerance_D=0.0), "peak_tolerance_D"),
                       (dict(cutoff_tolerance_cpd=-0.25), "cutoff_tolerance_cpd"),
                       (dict(spectral_rule="gauss"), "spectral_rule"),
                       (dict(wavelength_rules=(("5x5", "uniform", 25.0),)), "wavelength_rules"),
                       (dict(wavelength_rules=(("2x2", "uniform", 0.0),)), "wavelength_rules"),
                       (dict(wavelength_rules=(("2x2", "gauss", 5.5),)), "wavelength_rules"),
                       (dict(wavelength_rules=(("2x2", "simpson", 5),)), "wavelength_rules")):
        with pytest.raises(ValueError, match=match):
            rep.StudyConfig(**bad)
    reduced = rep.StudyConfig(accuracy="vsotf").reduced()
    assert reduced.mft_pupil_samples == (("4x4", 48),)
    assert reduced.depth_offsets_D == (-2.0, -1.0, 0.0, 1.0, 2.0)
    assert reduced.wavelengths_nm[2] == 20.0 and not reduced.alternatives
    # the question's plan: the alternatives reuse the main study's planned rules
    reduced = rep.StudyConfig().reduced({"2x2": ("gauss", 6), "natural": ("uniform", 20.0)})
    assert reduced.wavelength_rules == (("2x2", "gauss", 6.0), ("natural", "uniform", 20.0))
    assert reduced.accuracy == "claims" and not reduced.alternatives


def test_accuracy_plans_the_spectrum_per_layout():
    """``accuracy="claims"`` asks the planner for each layout's spectrum (the peak and
    cut-off targets): a uniform step with ``spectral_rule="uniform"``, and with "auto" a
    Gauss rule of fewer nodes when one meets the same targets; ``"vsotf"`` keeps the fixed
    grid, and a rule fixed in ``wavelength_rules`` is used as given."""
    from lfjax.model.layouts import paper_layouts
    from lfjax.model.spectral import gauss_rule
    from lfjax.reproduce.config import planned_sampling, study_eyes

    config = rep.StudyConfig(n_eyes=1, depth_offsets_D=(-1.0, 0.0, 1.0), spectral_rule="uniform")
    eyes, _ = study_eyes(config)
    layout = paper_layouts(3.0)["4x4"]
    _, planned, weights = planned_sampling(eyes, layout, config.depths_D, config, config.options)
    step = planned[1] - planned[0]
    assert 10.0 < step < 50.0 and planned[0] == 400.0 and planned[-1] == 700.0
    assert weights is None
    _, nodes, gauss_weights = planned_sampling(eyes, layout, config.depths_D,
                                               config.replace(spectral_rule="auto"),
                                               config.options)
    if gauss_weights is not None:  # a Gauss rule was taken: fewer nodes, inside the range
        assert nodes.size < planned.size and 400.0 < nodes[0] and nodes[-1] < 700.0
        np.testing.assert_allclose(gauss_weights, gauss_rule(nodes.size, 400.0, 700.0)[1])
    _, fixed, _ = planned_sampling(eyes, layout, config.depths_D,
                                   config.replace(accuracy="vsotf"), config.options)
    np.testing.assert_allclose(fixed, config.wavelength_grid_nm)
    sampling, given, _ = planned_sampling(
        eyes, layout, config.depths_D,
        config.replace(wavelength_rules=(("4x4", "uniform", 50.0),)), config.options)
    np.testing.assert_allclose(given, [400.0, 450.0, 500.0, 550.0, 600.0, 650.0, 700.0])
    assert sampling.transform == "mft"  # the 4x4's MFT is kept under either plan
    _, given, given_weights = planned_sampling(
        eyes, layout, config.depths_D,
        config.replace(wavelength_rules=(("4x4", "gauss", 5),)), config.options)
    np.testing.assert_allclose(given, gauss_rule(5, 400.0, 700.0)[0])
    np.testing.assert_allclose(given_weights, gauss_rule(5, 400.0, 700.0)[1])


def test_dof_definition():
    rel = [-2, -1, 0, 1, 2]
    assert rep.dof_D(rel, [10, 10, 10, 10, 10], 0.8) == (4.0, True)
    d, censored = rep.dof_D(rel, [0, 5, 10, 5, 0], 0.8)
    assert not censored and d == pytest.approx(0.8)  # crossings at ±0.4 D


# ------------------------------------------------------------------ the parameter↔flag table


def _options(command: str) -> set[str]:
    """Every option string and positional metavar of a subcommand's parser."""
    parser = cli.build_parser()
    subparsers = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    names = set()
    for action in subparsers.choices[command]._actions:
        names.update(action.option_strings or [action.metavar or action.dest])
    return names


def _parameters(call) -> set[str]:
    if dataclasses.is_dataclass(call):
        return {f.name for f in dataclasses.fields(call) if f.init}
    return set(inspect.signature(call).parameters)


def _library_inputs():
    """Each subcommand's library calls that take flag values, and the parameters of those
    calls that no flag sets (everything else a check can name must be in the table)."""
    from lfjax import design, layout_opt, sweep
    from lfjax.base.files import check_output_folder
    from lfjax.base.sampling import Sampling
    from lfjax.sweep.report import sweep_report
    from lfjax.sweep.distributed import start_distributed
    from lfjax.sweep.target import check_store_target, check_store_writable
    from lfjax.vision.scene_files import read_depth_map_scene, read_layers_file
    from lfjax.vision.scene_images import LayeredScene, retinal_scene
    from lfjax.vision.viewing import Viewing

    return {
        "reproduce": ([rep.check_reproduce, rep.StudyConfig.quick],
                      {"config", "changes"}),
        "optimise": ([layout_opt.OptimisationSettings, layout_opt.optimise_and_save],
                     {"settings", "progress", "command"}),
        "sweep": ([check_store_target, check_store_writable, start_distributed, sweep.run_sweep],
                  {"config", "progress", "devices", "on_plan", "on_timeout"}),
        "sweep-report": ([sweep_report], {"sample_size", "dpi", "progress"}),
        "retina": ([retinal_scene, LayeredScene.from_depth_map, LayeredScene.from_layers,
                    read_depth_map_scene, read_layers_file, Viewing, check_output_folder],
                   {"scene", "viewing", "pupil_diameter_mm", "pupil_offset_mm", "options",
                    "boundary",
                    "memory_limit_bytes", "need_bytes", "parameter", "progress", "cls",
                    "image_path", "depth_path", "path"}),
        # ReportSettings names its accuracy and counts report_accuracy and report_counts;
        # check_design checks the target's fields (DesignTarget, above it)
        "design": ([check_output_folder, design.design_cdp_D, design.design_panel,
                    design.DesignConstraints, Sampling, design.DesignTarget, design.FitSettings,
                    design.ReportSettings, layout_opt.EyeDraw, design.check_design],
                   {"min_gap_fraction", "panel", "n_fft", "transform", "mft_pupil_samples",
                    "edge_width_samples", "need_bytes", "parameter", "accuracy", "counts",
                    "target", "tol", "eye_chunk"}),
    }


def test_the_flag_table_names_flags_that_exist():
    assert set(flags.FLAGS) == set(cli.SUBCOMMANDS)
    for command, table in flags.FLAGS.items():
        assert set(table.values()) <= _options(command), command


def test_the_flag_table_covers_every_parameter_a_check_can_name():
    """Every parameter of the library calls a subcommand makes with its flags' values is in
    its table: a library check names one of them, and the command line names the flag."""
    for command, (calls, not_flags) in _library_inputs().items():
        for call in calls:
            missing = _parameters(call) - not_flags - set(flags.FLAGS[command])
            assert not missing, f"{command}: {call.__qualname__} {sorted(missing)}"


@pytest.mark.parametrize("command, make", [
    ("optimise", lambda lo: lo.OptimisationSettings(n_views=5)),
    ("optimise", lambda lo: lo.OptimisationSettings(lattice="tri")),
    ("optimise", lambda lo: lo.OptimisationSettings(display_distance_mm=600.0)),
    ("optimise", lambda lo: lo.OptimisationSettings(display_distance_mm=-1.0)),
    ("optimise", lambda lo: lo.OptimisationSettings(spectrum="plasma")),
    ("optimise", lambda lo: lo.OptimisationSettings(pixel_width_arcmin=-1.0)),
    ("optimise", lambda lo: lo.OptimisationSettings(pupil_diameter_mm=4.0)),
    ("optimise", lambda lo: lo.OptimisationSettings(depth_range_D=(-1.0, 2.0))),
    ("optimise", lambda lo: lo.OptimisationSettings(objective={"sharpness": 1.0})),
    ("optimise", lambda lo: lo.OptimisationSettings(front=3, test_eyes=0)),
    ("optimise", lambda lo: lo.OptimisationSettings(wavelengths_nm=(380.0, 550.0))),
    ("optimise", lambda lo: lo.OptimisationSettings(freq_step_cpd=0.0)),
    ("optimise", lambda lo: lo.OptimisationSettings(max_diameter_mm=3.5)),
    ("optimise", lambda lo: lo.OptimisationSettings(depth_range_D=(0.0, 20.0))),  # model's range
    ("optimise", lambda lo: lo.OptimisationSettings(cdp_D=15.0)),
])
def test_a_refused_optimisation_names_a_parameter_of_the_table(command, make):
    from lfjax import layout_opt

    with pytest.raises(ParameterError) as err:
        make(layout_opt)
    assert set(err.value.parameters) <= set(flags.FLAGS[command]), err.value.parameters


@pytest.mark.parametrize("make", [
    lambda d: d.design_panel("near-eye", 1.5, distance_mm=800.0),
    lambda d: d.design_panel("near-eye", 1.5, distance_mm=-1.0),
    lambda d: d.design_panel("near-eye", 1.5, pixel_pitch_mm=0.0),
    lambda d: d.design_panel("near-eye", 1.5, pixel_count=(0, 5)),
    lambda d: d.design_cdp_D((1.0, 2.0), 3.0),
    lambda d: d.DesignConstraints(distance_range_mm=(100.0, 50.0)),
    lambda d: d.DesignConstraints(min_f_number=3.0, max_f_number=2.0),
    lambda d: d.design_cdp_D((0.0, 20.0)),  # beyond the model's range
    lambda d: d.check_design(d.design_panel("near-eye", 1.5),
                             d.DesignTarget((1.0, 2.0), views_per_side=(9,))),
    lambda d: d.check_design(d.design_panel("near-eye", 1.5),
                             d.DesignTarget((1.0, 2.0), wavelengths_nm=(800.0,))),
])
def test_a_refused_design_names_a_parameter_of_the_table(make):
    from lfjax import design

    with pytest.raises(ParameterError) as err:
        make(design)
    assert set(err.value.parameters) <= set(flags.FLAGS["design"]), err.value.parameters


def test_a_library_caller_reads_the_library_name_and_the_command_line_the_flag(capsys, tmp_path):
    from lfjax import layout_opt

    with pytest.raises(ValueError, match=r"^front needs held-out eyes \(test_eyes >= 1\)$"):
        layout_opt.OptimisationSettings(front=3, test_eyes=0)
    code = cli.main(["optimise", "--front", "3", "--test-eyes", "0", "--out", str(tmp_path / "x")])
    assert code == 2
    assert capsys.readouterr().err == ("lfjax optimise: error: --front needs held-out eyes "
                                       "(--test-eyes >= 1)\n")


def test_the_sweep_report_names_its_store_and_out(capsys, tmp_path):
    assert cli.main(["sweep-report", str(tmp_path / "none")]) == 2
    assert "error: STORE " in capsys.readouterr().err
    (tmp_path / "file").write_text("")
    assert cli.main(["sweep-report", str(tmp_path / "none"), "--out", str(tmp_path / "file")]) == 2
    assert "error: STORE " in capsys.readouterr().err  # the store is checked first


# ------------------------------------------------------------------ notebook


def build_notebook():
    """The .ipynb generated from the .py twin (kernel python3)."""
    import nbformat

    nb = nbformat.v4.new_notebook()
    nb.metadata["kernelspec"] = {"display_name": "Python 3 (ipykernel)", "language": "python",
                                 "name": "python3"}
    nb.metadata["language_info"] = {"name": "python"}
    for kind, src in percent_cells(NOTEBOOK_TWIN.read_text()):
        nb.cells.append(nbformat.v4.new_markdown_cell(src) if kind == "markdown"
                        else nbformat.v4.new_code_cell(src))
    return nb


def test_notebook_matches_its_script_twin():
    import nbformat

    nb = nbformat.read(NOTEBOOK, as_version=4)
    assert [(c.cell_type, c.source) for c in nb.cells] == percent_cells(NOTEBOOK_TWIN.read_text())


def test_notebook_executes(quick_run, tmp_path):
    """Top to bottom at its tiny size (the quick study on the end-to-end run's one
    wavelength: after ``quick_run`` its programs come from the session's caches)."""
    _, images, text = execute_notebook_tiny(NOTEBOOK, tmp_path)
    assert len(images) >= 10  # Figs. 3–11 and the retinal images
    assert "(1)" in text and "(7)" in text


def test_an_unforeseen_error_is_one_line_and_lfjax_debug_shows_it(monkeypatch, tmp_path, capsys):
    """An exception no check foresaw ends the command with one line on stderr (type and
    message, whitespace folded) and status 1; LFJAX_DEBUG=1 lets it through."""
    from lfjax.cli import sweep_report as command

    def broken(*args, **kwargs):
        raise RuntimeError("the\n  unexpected")

    monkeypatch.setattr(command, "sweep_report", broken)
    monkeypatch.delenv("LFJAX_DEBUG", raising=False)
    assert cli.main(["sweep-report", str(tmp_path / "store"), "--out", str(tmp_path / "r")]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert err == ["lfjax sweep-report: error: RuntimeError: the unexpected"]
    monkeypatch.setenv("LFJAX_DEBUG", "1")
    with pytest.raises(RuntimeError, match="unexpected"):
        cli.main(["sweep-report", str(tmp_path / "store"), "--out", str(tmp_path / "r")])
