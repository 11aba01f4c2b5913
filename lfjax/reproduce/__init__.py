"""Reproduction of Miyanishi, Sahin & Gotchev: the study, its tables, figures and report.

The study (paper §4): a 3 mm pupil, the display's central depth plane (CDP) at 2 D, natural
view plus 2×2, 3×3 and 4×4 viewpoints, points rendered from CDP − 2 D to CDP + 2 D in
0.5 D steps, through-focus on a 0.2 D accommodation grid, 400–700 nm (the paper: 10 nm
steps; here each layout's spectrum is planned for what the findings read), seeded virtual eyes (Thibos et al. 2002) plus the average eye; VSOTF and Strehl ratio.

The parts, each importing only those listed before it:

* :mod:`~lfjax.reproduce.config` — :class:`StudyConfig`, :func:`study_eyes`, the sampling plan;
* :mod:`~lfjax.reproduce.study` — :func:`run_study` returns every number as one labelled
  :class:`xarray.Dataset`; :func:`compute_examples` the data of Figs. 4, 5 and 9;
* :mod:`~lfjax.reproduce.settling` — claims whose verdict the planned spectrum's error could
  change (:func:`mark_unsettled`), and their layouts computed again at the reference
  spectrum (:func:`settle`, ``StudyConfig.settle_verdicts``);
* :mod:`~lfjax.reproduce.alternatives` — the modelling choices the paper leaves open
  (``ALTERNATIVES``) and the claims under each (:func:`run_alternatives`);
* :mod:`~lfjax.reproduce.report` — CSV tables and ``REPORT.md``;
* :mod:`~lfjax.reproduce.figures` — Figs. 3–11;
* :mod:`lfjax.vision.claims` (below this package, since the sweep's ten-eye check uses it too) —
  :func:`evaluate_claims` turns the Dataset into the paper's findings as checkable claims
  (:class:`Claim`);
* :mod:`~lfjax.reproduce.run` — :func:`reproduce` writes results file, CSV tables, figures
  and ``REPORT.md`` into a folder (staged whole: :func:`lfjax.base.files.staged_output`);
* this module re-exports the public names of the parts. ``lfjax reproduce`` is its command line (:mod:`lfjax.cli.reproduce`).
  Given a population sweep store (``--population``), the report adds "What ten eyes cannot
  tell" (:mod:`lfjax.sweep.ten_eyes`; the sweep reads the claims from :mod:`lfjax.vision.claims`,
  never from this package, so the two import in one direction).

Host-side orchestration (numpy, xarray, files); the numerics are :mod:`lfjax.vision.focus`
and :mod:`lfjax.kernel.optics`.
"""

from lfjax.vision.claim_core import Claim, dof_D
from lfjax.vision.claims import evaluate_claims
from lfjax.reproduce.alternatives import ALTERNATIVES, run_alternatives
from lfjax.reproduce.settling import mark_unsettled, settle
from lfjax.reproduce.config import LF_LAYOUTS, METRICS, StudyConfig, study_eyes
from lfjax.reproduce.figures import FIGURES, all_figures, save_figures
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
from lfjax.reproduce.study import (
    layout_through_focus,
    run_study,
    study_sampling,
    study_wavelength_rules,
)
from lfjax.reproduce.run import (
    EXAMPLES_FILE,
    MARKER_FILE,
    POPULATION_TABLE,
    RESULTS_FILE,
    OutputError,
    check_output_dir,
    check_population,
    check_reproduce,
    population_section,
    reproduce,
    write_display_outputs,
)

__all__ = [
    "ALTERNATIVES",
    "EXAMPLES_FILE",
    "FIGURES",
    "LF_LAYOUTS",
    "MARKER_FILE",
    "METRICS",
    "POPULATION_TABLE",
    "RESULTS_FILE",
    "TABLES",
    "Claim",
    "OutputError",
    "StudyConfig",
    "all_figures",
    "alternatives_table",
    "check_output_dir",
    "check_population",
    "check_reproduce",
    "claims_table",
    "compute_examples",
    "cutoff_table",
    "dof_D",
    "evaluate_claims",
    "layout_through_focus",
    "mark_unsettled",
    "population_section",
    "prediction_table",
    "reproduce",
    "run_alternatives",
    "run_study",
    "save_figures",
    "settle",
    "study_eyes",
    "study_sampling",
    "study_wavelength_rules",
    "summary_table",
    "write_display_outputs",
    "write_report",
]
