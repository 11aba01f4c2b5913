"""The notebooks as committed: each carries its outputs (the site shows them as they are),
and the paper notebook's text states the settings the package's defaults use.

Executing the notebooks is tested beside the code they show (tests/cli/test_cli.py,
tests/display/test_lenslets.py, tests/design/test_design_fit.py, tests/layout_opt/), at a
tiny size; these tests only read the files.
"""

from __future__ import annotations

import re
from pathlib import Path

import nbformat
import pytest

from lfjax.reproduce.config import StudyConfig

ROOT = Path(__file__).resolve().parents[1]
NOTEBOOKS = sorted((ROOT / "notebooks").glob("*.ipynb"))


def test_there_are_notebooks():
    assert len(NOTEBOOKS) >= 4, [p.name for p in NOTEBOOKS]


@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.stem)
def test_notebook_is_committed_with_its_outputs(path):
    """Every code cell ran, in order, without an error, and the notebook shows a figure."""
    nb = nbformat.read(path, as_version=4)
    code = [c for c in nb.cells if c.cell_type == "code"]
    assert code, f"{path.name} has no code"
    not_run = [i for i, c in enumerate(code) if c.get("execution_count") is None]
    assert not not_run, f"{path.name}: code cells {not_run} were committed without being run"
    counts = [c.execution_count for c in code]
    assert counts == sorted(counts), f"{path.name}: cells were run out of order ({counts})"
    outputs = [o for c in code for o in c.get("outputs", [])]
    errors = [o.get("ename") for o in outputs if o.output_type == "error"]
    assert not errors, f"{path.name} was committed with errors: {errors}"
    assert any("image/png" in o.get("data", {}) for o in outputs), f"{path.name}: no figure"


def _number(pattern: str, text: str, what: str) -> float:
    match = re.search(pattern, text)
    assert match, f"the notebook no longer states {what} (pattern {pattern!r})"
    return float(match.group(1))


def paper_notebook_settings(text: str) -> tuple[dict, dict]:
    """(quick, full) settings the paper notebook's introduction states, read from its text."""
    quick_text, full_text = re.split(r"Set\s+`QUICK = False`", text, maxsplit=1)
    quick = dict(
        n_eyes=_number(r"(\d+) virtual eyes plus the average eye", quick_text, "the quick eyes"),
        accommodation_step_D=_number(r"([\d.]+) D accommodation grid", quick_text,
                                     "the quick accommodation step"),
        wavelength_step_nm=_number(r"(\d+) nm steps", quick_text, "the quick wavelength step"),
    )
    full = dict(
        n_eyes=_number(r"(\d+) virtual eyes plus the average eye", full_text, "the eyes"),
        pupil_diameter_mm=_number(r"([\d.]+) mm pupil", full_text, "the pupil"),
        cdp_D=_number(r"CDP at ([\d.]+) D", full_text, "the CDP"),
        depth_step_D=_number(r"in ([\d.]+) D steps", full_text, "the depth step"),
        accommodation_step_D=_number(r"([\d.]+) D accommodation grid", full_text,
                                     "the accommodation step"),
        peak_tolerance_D=_number(r"by more than ([\d.]+) D", full_text, "the peak target"),
        cutoff_tolerance_cpd=_number(r"by more than ([\d.]+) cpd", full_text, "the cut-off target"),
    )
    start, stop = re.search(r"(\d+)[–-](\d+) nm", full_text).groups()
    full["wavelength_range_nm"] = (float(start), float(stop))
    full["accuracy"] = re.search(r'`accuracy="(\w+)"`', full_text).group(1)
    # A fixed step is only stated for the quick size; the full study plans its own.
    full["states_a_fixed_step"] = bool(re.search(r"\d+ nm steps", full_text))
    return quick, full


def test_paper_notebook_text_states_the_defaults():
    nb = nbformat.read(ROOT / "notebooks" / "reproduce_paper.ipynb", as_version=4)
    intro = nb.cells[0].source.replace("\n", " ").replace("# ", "")
    quick, full = paper_notebook_settings(intro)
    q, d = StudyConfig.quick(), StudyConfig()
    assert quick == dict(n_eyes=q.n_eyes, accommodation_step_D=q.accommodation_step_D,
                         wavelength_step_nm=q.wavelengths_nm[2])
    depth_steps = {round(b - a, 9) for a, b in zip(d.depth_offsets_D, d.depth_offsets_D[1:])}
    assert full == dict(
        n_eyes=d.n_eyes, pupil_diameter_mm=d.pupil_diameter_mm, cdp_D=d.cdp_D,
        depth_step_D=depth_steps.pop(), accommodation_step_D=d.accommodation_step_D,
        peak_tolerance_D=d.peak_tolerance_D, cutoff_tolerance_cpd=d.cutoff_tolerance_cpd,
        wavelength_range_nm=d.wavelengths_nm[:2], accuracy=d.accuracy,
        states_a_fixed_step=d.accuracy == "vsotf",
    )
    assert not depth_steps, "the default depths are not evenly spaced: the text cannot say one step"
    # The code cell the text describes uses exactly these configurations.
    code = "\n".join(c.source for c in nb.cells if c.cell_type == "code")
    assert "StudyConfig.quick() if QUICK else reproduce.StudyConfig()" in code


def test_the_text_check_reads_a_disagreement():
    """The old introduction (10 nm steps for the full study) fails the check."""
    old = ("at the `--quick` size: 2 virtual eyes plus the average eye, 0.5 D accommodation "
           "grid, 400–700 nm in 30 nm steps. Set `QUICK = False` for the full study: 3 mm "
           "pupil, CDP at 2 D, in 0.5 D steps, 0.2 D accommodation grid, 400–700 nm in 10 nm "
           "steps, 10 virtual eyes plus the average eye, no peak moves by more than 0.01 D, "
           "by more than 0.25 cpd (`accuracy=\"claims\"`)")
    _, full = paper_notebook_settings(old)
    assert full["states_a_fixed_step"] and StudyConfig().accuracy == "claims"
