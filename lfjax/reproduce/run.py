"""The application :func:`reproduce`: the study, its claims, the modelling alternatives, a
population section and the display effects, written with the tables, figures and
``REPORT.md`` into a result folder staged whole (:func:`lfjax.base.files.staged_output`).

The stages are named on a progress bar (:class:`StageBar`), which also times them for the
report. Host-side orchestration (numpy, xarray, files, a figure thread).
"""

from __future__ import annotations

import dataclasses
import json
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np

from lfjax.base.errors import ParameterError
from lfjax.base.files import check_output_folder, staged_output
from lfjax.base.programs import in_callers_jax_context
from lfjax.base.tables import printable
from lfjax.vision.claims import Claim, evaluate_claims
from lfjax.studies.display_effects import (
    DisplayStudyConfig,
    display_effects_markdown,
    effects_table,
    lenslet_sweep,
    run_display_study,
    save_display_figures,
    sweep_table,
)
from lfjax.model.eyes import Eyes
from lfjax.model.options import ModelOptions
from lfjax.sweep.store import open_verified_store
from lfjax.sweep.ten_eyes import check_population_store, ten_eye_claims, ten_eye_markdown, ten_eye_table
from lfjax.reproduce.alternatives import run_alternatives
from lfjax.reproduce.settling import mark_unsettled, settle
from lfjax.reproduce.config import LF_LAYOUTS, StudyConfig, study_eyes
from lfjax.reproduce.figures import save_figures
from lfjax.reproduce.report import (
    TABLES,
    alternatives_table,
    claims_table,
    cutoff_table,
    prediction_table,
    summary_table,
    write_report,
)
from lfjax.reproduce.examples import compute_examples
from lfjax.reproduce.study import run_study, study_wavelength_rules

MARKER_FILE = ".lfjax-reproduce"
"""Empty file marking a folder written by :func:`reproduce` (``--force`` replaces only these)."""

RESULTS_FILE = "results.nc"
EXAMPLES_FILE = "examples.nc"
POPULATION_TABLE = "ten_eyes.csv"
DISPLAY_TABLE = "display_effects.csv"
DISPLAY_SWEEP_TABLE = "display_lenslet_sweep.csv"


def write_display_outputs(study, sweep, folder: Path) -> list[str]:
    """The display-effects tables (CSV) and figures (PNG) in ``folder``; returns their names."""
    folder = Path(folder)
    effects_table(study).to_csv(folder / DISPLAY_TABLE, index=False, float_format="%.6g")
    sweep_table(sweep).to_csv(folder / DISPLAY_SWEEP_TABLE, index=False, float_format="%.6g")
    return [DISPLAY_TABLE, DISPLAY_SWEEP_TABLE] + save_display_figures(study, sweep, folder)


def _files_and_figures(ds, examples, config: StudyConfig, folder: Path) -> tuple[list[str], float]:
    """``results.nc``, ``examples.nc``, the tables that read only the study (predictions,
    summary, cut-offs) and every figure, written into ``folder``: (file names, seconds)."""
    t0 = time.perf_counter()
    ds.to_netcdf(folder / RESULTS_FILE, engine="h5netcdf")
    examples.to_netcdf(folder / EXAMPLES_FILE, engine="h5netcdf")
    names = [RESULTS_FILE, EXAMPLES_FILE]
    for key, make in (("predictions", prediction_table), ("summary", summary_table),
                      ("cutoff", cutoff_table)):
        printable(make(ds)).to_csv(folder / TABLES[key], index=False, float_format="%.6g")
        names.append(TABLES[key])
    names += save_figures(ds, examples, folder, config)
    return names, time.perf_counter() - t0


def _display_effects(config: StudyConfig, n_eyes: int, stage, note=None):
    """The display-effects study on the average eye and the first ``n_eyes`` study eyes:
    (study Dataset, 2×2 sweep Dataset, report markdown)."""
    eyes, labels = study_eyes(config)
    keep = list(range(n_eyes)) + [len(labels) - 1]  # the average eye is last
    subset = Eyes(eyes.zernike_um[np.asarray(keep)], eyes.measured_pupil_mm, eyes.orientation)
    names = [labels[i] for i in keep]
    offsets = tuple(d for d in config.depth_offsets_D if abs(d - round(d)) < 1e-9)
    display_config = DisplayStudyConfig(
        layouts=tuple(n for n in LF_LAYOUTS if n in config.layouts),
        pupil_diameter_mm=config.pupil_diameter_mm, cdp_D=config.cdp_D, depth_offsets_D=offsets,
        accommodation_step_D=config.accommodation_step_D, options=config.options,
        cutoff_threshold=config.cutoff_threshold,
        wavelength_step_nm=max(20.0, float(config.wavelengths_nm[2])),
    )
    if config.label == "quick":  # --quick: two sweep distances, 50 nm steps (numbers indicative)
        display_config = dataclasses.replace(display_config, wavelength_step_nm=50.0,
                                             sweep_distances_mm=(100.0, 400.0))
    stage("display effects")
    # minutes per stage: each scene is named on the stage bar as it starts
    study = run_display_study(subset, names, display_config, progress=False, on_scene=note)
    stage("display: 2x2 lenslet sweep")
    sweep = lenslet_sweep(subset, names, display_config, progress=False, on_scene=note)
    return study, sweep, display_effects_markdown(study, sweep)


# ----------------------------------------------------------------------------- output folder


class OutputError(ParameterError):
    """The output folder cannot be used (exists, not empty, not writable): a
    :class:`~lfjax.base.errors.ParameterError` naming ``out``."""


def estimated_output_bytes(config: StudyConfig) -> int:
    """Room :func:`reproduce` asks of its output folder's disk before any work, bytes: the
    figures and examples.nc (about 2.1 MB in all for ``--quick``; 8 MB allowed) and
    results.nc with the tables (0.3 MB for ``--quick``'s 3 eyes and 3 depths; 4 MB allowed
    per eye, the average eye included, which covers the default's 9 depths and 0.2 D
    states several times over)."""
    return 8 * 2**20 + (int(config.n_eyes) + 1) * 4 * 2**20


def check_output_dir(out, force: bool = False, need_bytes: int = 0) -> Path:
    """Validate ``out`` before any work: returns its absolute path or raises OutputError
    (not a folder, not empty without ``force``, not empty and not written by
    :func:`reproduce` (:data:`MARKER_FILE`) even with ``force``, not writable — a probe file
    is created — or fewer than ``need_bytes`` free on its disk)."""
    out = Path(out).expanduser().absolute()
    if force and out.is_dir() and any(out.iterdir()) and not (out / MARKER_FILE).exists():
        # force replaces the whole folder (staged_output's replace): only an earlier result
        raise OutputError(
            "out", "{out} {path} is not empty and was not written by lfjax reproduce; "
            "refusing to replace it even with {force} (choose another folder)", path=out)
    try:
        check_output_folder(out, force, need_bytes=need_bytes, parameter="out")
    except ParameterError as err:
        raise OutputError("out", err.template, **err.values) from None
    return out


def check_population(population_store, config: StudyConfig) -> float:
    """Check a population sweep store for :func:`reproduce` before any work: its metadata,
    then every complete chunk against its checksum as ``lfjax sweep --verify`` does
    (:func:`~lfjax.sweep.store.open_verified_store`: a damaged store is refused here, not
    read as complete after the study's minutes; the store is read once more by
    :func:`population_section`). Returns the pupil (mm) whose eyes are drawn — the study's
    pupil when the store has it, else the store's only pupil. Raises
    :class:`~lfjax.base.errors.ParameterError` naming the problem."""
    pupil = _population_pupil(population_store, config)
    try:
        open_verified_store(population_store, complete_only=True)
    except ValueError as err:
        raise ParameterError("population_store", "{population_store}: {problem}",
                             problem=str(err)) from None
    return pupil


def _population_pupil(population_store, config: StudyConfig) -> float:
    """The pupil (mm) :func:`check_population` returns, from the store's metadata alone."""
    try:
        return check_population_store(population_store, sample_size=config.n_eyes,
                                      prefer_pupil_mm=config.pupil_diameter_mm)
    except ValueError as err:
        raise ParameterError("population_store", "{population_store}: {problem}",
                             problem=str(err)) from None


def check_reproduce(out, config: StudyConfig = StudyConfig(), force: bool = False,  # noqa: B008
                    population_store=None, display_effects_eyes: int | None = None) -> Path:
    """:func:`reproduce`'s checks of its arguments (of the same names), before any work
    (it makes them first): the output folder (:func:`check_output_dir`), the population
    store (:func:`check_population`) and the display-effects eyes (0 … the study's eyes).
    Returns the output folder's absolute path; a refused value is a
    :class:`~lfjax.base.errors.ParameterError` naming the parameter."""
    out = check_output_dir(out, force, estimated_output_bytes(config))
    if population_store is not None:
        check_population(population_store, config)
    if display_effects_eyes is not None and not (
            isinstance(display_effects_eyes, (int, np.integer)) and not isinstance(display_effects_eyes, bool)
            and 0 <= display_effects_eyes <= config.n_eyes):
        raise ParameterError("display_effects_eyes", "{display_effects_eyes} must be in 0 ... {n} (the "
                             "study's eyes), got {got!r}", n=config.n_eyes, got=display_effects_eyes)
    return out


def population_section(population_store, config: StudyConfig, claims: list[Claim],
                       n_draws: int = 1000, progress: bool = False):
    """The report's section "What ten eyes cannot tell": samples of the study's size
    (``config.n_eyes``, the paper's 10) drawn from the sweep store, the claims checked on
    each (:func:`lfjax.sweep.ten_eyes.ten_eye_claims`, seed ``config.seed``).

    Returns (markdown text of the section's body, the per-claim table as a DataFrame,
    the result Dataset)."""

    pupil = _population_pupil(population_store, config)  # verified by check_reproduce
    try:
        ds = open_verified_store(population_store, complete_only=True)
    except ValueError as err:  # damaged since check_reproduce read it
        raise ParameterError("population_store", "{population_store}: {problem}",
                             problem=str(err)) from None
    result = ten_eye_claims(ds, n_draws=n_draws, sample_size=config.n_eyes, seed=config.seed,
                            pupil_mm=pupil, progress=progress)
    stored = json.loads(ds.attrs["config_json"])
    ours = dict(pupil_diameters_mm=config.pupil_diameter_mm, cdp_D=config.cdp_D,
                depth_offsets_D=list(config.depth_offsets_D),
                accommodation_step_D=config.accommodation_step_D,
                window_D=config.window_D, wavelengths_nm=list(config.wavelengths_nm),
                options=config.options.as_dict())
    theirs = dict(stored, pupil_diameters_mm=pupil)
    if isinstance(theirs.get("options"), dict):
        # a store written before an option existed ran with that option's default
        theirs["options"] = {**ModelOptions().as_dict(), **theirs["options"]}
    differ = [key for key, value in ours.items() if theirs.get(key) != value]
    lines = [
        f"Are this run's verdicts what any {config.n_eyes} eyes would give? The population "
        f"sweep `{population_store}` (seed {stored.get('seed')}; its own virtual eyes, not "
        f"this run's) answers with the fraction of random samples of {config.n_eyes} eyes "
        f"on which each claim holds; the last column is this run's verdict.",
        "",
    ]
    if differ:
        lines += [f"The sweep's settings differ from this run's in: {', '.join(differ)} "
                  f"(the sweep has {', '.join(f'{k} = {theirs.get(k)!r}' for k in differ)}); "
                  f"read the two against each other with that in mind.", ""]
    lines.append(ten_eye_markdown(result, this_run=claims).rstrip())
    lines += ["", f"Per claim: `{POPULATION_TABLE}`."]
    return "\n".join(lines) + "\n", ten_eye_table(result), result


def stage_names(config: StudyConfig, population_store=None,
                display_effects_eyes: int | None = None) -> list[str]:
    """The stages :func:`reproduce` goes through, in order (the progress bar's steps)."""
    layouts = list(config.layouts)
    stages = ["eyes"] + [f"through-focus {n}" for n in layouts] + ["examples: natural view"]
    if "2x2" in layouts:
        stages.append("examples: 2x2 viewpoints")
    if config.alternatives:
        stages += [f"alternatives: {n}" for n in layouts]
    if population_store is not None:
        stages.append("population: samples of the study's size")
    if display_effects_eyes is not None:
        stages += ["display effects", "display: 2x2 lenslet sweep"]
    return stages + ["tables", "figures", "report"]


class StageBar:
    """A progress bar over named stages that times each one: :meth:`stage` ends the stage
    running (its seconds into :attr:`timings`) and starts the next; :meth:`note` shows a
    line beside it (the scene or layout a long stage is on). ``progress=False``: no bar,
    the timings only."""

    def __init__(self, stages: list[str], progress: bool = True):
        from tqdm.auto import tqdm

        self.bar = tqdm(total=len(stages), unit="stage", disable=not progress,
                        dynamic_ncols=True, bar_format="{l_bar}{bar}| {n_fmt}/{total_fmt} "
                        "stages [{elapsed}<{remaining}]")
        self.timings: dict[str, float] = {}
        self._name: str | None = None
        self._t = time.perf_counter()

    def stage(self, name: str) -> None:
        now = time.perf_counter()
        if self._name is not None:
            self.timings[self._name] = now - self._t
            self.bar.update(1)
        self._name, self._t = name, now
        self.bar.set_description(name)

    def note(self, text: str) -> None:
        self.bar.set_postfix_str(text)

    def finish(self) -> None:
        """The last stage done (its time is the report's, not timed here)."""
        self.bar.update(1)

    def close(self) -> None:
        self.bar.close()


def reproduce(out, config: StudyConfig = StudyConfig(), force: bool = False,  # noqa: B008
              progress: bool = True, population_store=None,
              population_draws: int = 1000, display_effects_eyes: int | None = None) -> dict:
    """Run the study and write everything into ``out`` (staged, then moved into place when
    complete, :func:`~lfjax.base.files.staged_output`; with
    ``force`` an earlier result of :func:`reproduce` is replaced whole).

    ``population_store``: a population sweep store (``lfjax sweep``); the report then adds
    "What ten eyes cannot tell" (:func:`population_section`, ``population_draws`` samples)
    and ``ten_eyes.csv``. The store is checked before any computation.

    ``display_effects_eyes``: add "Beyond the ideal display" (:mod:`lfjax.studies.display_effects`:
    lenslet diffraction, pixels and an OLED-like spectrum one by one, and the 2×2
    lenslet-size sweep) on the average eye and the first ``display_effects_eyes`` eyes;
    None leaves it out.

    Returns a dict with ``out`` (Path), ``files`` (names), ``claims``, ``seconds``.
    """
    t_start = time.perf_counter()
    out = check_reproduce(out, config, force, population_store, display_effects_eyes)
    bar = StageBar(stage_names(config, population_store, display_effects_eyes), progress)
    figure_pool = ThreadPoolExecutor(1, thread_name_prefix="lfjax-figures")
    try:
        with staged_output(out, force, replace=True) as tmp:
            try:
                files, claims = _write_results(tmp, config, bar, figure_pool, t_start,
                                               population_store, population_draws,
                                               display_effects_eyes)
            except BaseException:
                # not waited for (an interrupt must not wait for a figure): its writes into
                # the removed folder fail in the thread, and a folder it recreates is an
                # orphan the next run removes
                figure_pool.shutdown(wait=False, cancel_futures=True)
                raise
            bar.close()
    finally:
        bar.close()
        figure_pool.shutdown(wait=False)
    return dict(out=out, files=sorted(files), claims=claims,
                seconds=time.perf_counter() - t_start, timings=bar.timings)


def _study_and_claims(config: StudyConfig, bar: StageBar):
    """The study Dataset (settled where its verdicts need it), the planned one (whose
    spectra the alternatives reuse) and the claims, or None when they are still to be
    evaluated on the study."""
    ds = run_study(config, stage=lambda n: bar.stage(f"through-focus {n}"))
    planned = ds
    claims = None
    if config.settle_verdicts and config.accuracy != "vsotf":
        # before the examples and files: they show the settled numbers
        settled, found = settle({"study": ds}, {"study": config.options}, config.reference(),
                                config.dof_fraction, stage=bar.note)
        ds, claims = settled["study"], found["study"]
    return ds, planned, claims


def _write_results(tmp: Path, config: StudyConfig, bar: StageBar, figure_pool, t_start: float,
                   population_store, population_draws: int, display_effects_eyes):
    """Every stage of :func:`reproduce`, its files written into the staging folder ``tmp``:
    (file names, claims)."""
    bar.stage("eyes")
    study_eyes(config)
    ds, planned, claims = _study_and_claims(config, bar)
    examples = compute_examples(ds, config, stage=bar.stage)
    if claims is None:
        claims = evaluate_claims(ds, config.dof_fraction)
        if config.accuracy != "vsotf":
            claims = mark_unsettled(claims, ds)
    # the Dataset files, the study's tables and the figures read only ds and examples:
    # written in a thread while the alternatives run (their compiled programs release the
    # GIL). The examples stay here: JAX calls from a second thread wait behind the
    # alternatives' programs (measured: 13 s slower in all)
    figures = figure_pool.submit(in_callers_jax_context(_files_and_figures), ds, examples,
                                 config, tmp)
    alternatives = (run_alternatives(config, stage=bar.stage,
                                     wavelength_rules=study_wavelength_rules(planned),
                                     study=planned, settle_stage=bar.note)
                    if config.alternatives else {})
    population = None
    if population_store is not None:
        bar.stage("population: samples of the study's size")
        population = population_section(population_store, config, claims, population_draws)
    display_parts = None
    if display_effects_eyes is not None:
        display_parts = _display_effects(config, display_effects_eyes, bar.stage, note=bar.note)
    bar.stage("tables")
    files = _write_claim_tables(tmp, claims, alternatives, population)
    bar.stage("figures")
    figure_files, bar.timings["files, tables and figures (in a thread)"] = figures.result()
    files += figure_files
    if display_parts is not None:
        files += write_display_outputs(display_parts[0], display_parts[1], tmp)
    bar.stage("report")
    timings_now = dict(bar.timings)
    timings_now["total"] = time.perf_counter() - t_start
    files.append("REPORT.md")
    write_report(tmp / "REPORT.md", ds, claims, alternatives, config, timings_now, sorted(files),
                 population_markdown=population[0] if population else None,
                 display_markdown=display_parts[2] if display_parts else None)
    (tmp / MARKER_FILE).write_text("")
    bar.finish()
    return files, claims


def _write_claim_tables(folder: Path, claims, alternatives: dict, population) -> list[str]:
    """The tables that read the claims (claims, alternatives, ten eyes) in ``folder``:
    their names."""
    files = []
    tables = {"claims": claims_table(claims)}
    if alternatives:
        tables["alternatives"] = alternatives_table(claims, alternatives)
    for key, table in tables.items():
        printable(table).to_csv(folder / TABLES[key], index=False, float_format="%.6g")
        files.append(TABLES[key])
    if population is not None:
        printable(population[1]).to_csv(folder / POPULATION_TABLE, index=False,
                                        float_format="%.6g")
        files.append(POPULATION_TABLE)
    return files


__all__ = [
    "DISPLAY_SWEEP_TABLE",
    "DISPLAY_TABLE",
    "EXAMPLES_FILE",
    "MARKER_FILE",
    "OutputError",
    "POPULATION_TABLE",
    "RESULTS_FILE",
    "StageBar",
    "check_output_dir",
    "check_population",
    "check_reproduce",
    "estimated_output_bytes",
    "population_section",
    "reproduce",
    "stage_names",
    "write_display_outputs",
]
