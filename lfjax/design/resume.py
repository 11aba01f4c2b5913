"""Finished counts of a design (:func:`lfjax.design.runner.run_counts`, both kinds) kept on
disk, so a run interrupted or failed after some counts resumes from them instead of making
them again.

Each finished count is written (whole: temporary name, then rename) to ``FOLDER/STEM-N.json``
(``count-N.json`` for an n×n design, ``lenticular-N.json`` for a lenticular one) with a
key: a BLAKE2b digest of everything the count depends on (for an n×n design
:func:`count_key`: the starting panel, the count, depths, CDP, constraints, objective,
wavelengths, steps, tolerance, report setting, sampling, eye chunk, the training and
held-out eyes' coefficients and the lfjax version). A later call with the same inputs loads it; a count
whose key differs (any input changed) is fitted again. The command line keeps the folder
beside its output folder (:func:`counts_folder`) and removes it once the outputs are
written.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
from pathlib import Path

import numpy as np

from lfjax._version import __version__
from lfjax.base.files import atomic_write_text
from lfjax.display.panel import Panel
from lfjax.model.layout_files import jsonable

COUNTS_FORMAT = "lfjax-design-count/1"


def counts_folder(out_dir) -> Path:
    """Where ``lfjax design --out DIR`` keeps its finished counts: ``.DIR.design-counts``
    beside ``DIR`` (outside it, so the output folder stays whole or absent)."""
    out = Path(out_dir).absolute()
    return out.parent / f".{out.name}.design-counts"


def panel_leaves(panel: Panel) -> list[float]:
    """The panel's numeric fields as host floats (pixel pitch, lenslet pitch, fill, focal
    length, gap, distance (mm or fractions), pixel fill), in ``Panel``'s order."""
    return [float(np.asarray(v)) for v in (panel.pixel_pitch_mm, panel.lenslet_pitch_mm,
                                           panel.fill, panel.focal_length_mm, panel.gap_mm,
                                           panel.distance_mm, panel.pixel_fill)]


def panel_statics(panel: Panel) -> dict:
    """The panel's static fields (pixel count, design pupil, aperture, diffraction, name)."""
    return dict(pixel_count=list(panel.pixel_count), pupil_diameter_mm=panel.pupil_diameter_mm,
                aperture=panel.aperture, diffraction=panel.diffraction, name=panel.name)


def _panel_record(panel: Panel | None):
    return None if panel is None else {"leaves": panel_leaves(panel),
                                       "statics": panel_statics(panel)}


def _panel_from(record):
    if record is None:
        return None
    statics = dict(record["statics"], pixel_count=tuple(record["statics"]["pixel_count"]))
    return Panel(*record["leaves"], **statics)


def _digest(array) -> str:
    a = np.ascontiguousarray(np.asarray(array, np.float64))
    return hashlib.blake2b(f"{a.shape}|".encode() + a.tobytes(), digest_size=16).hexdigest()


def count_key(panel: Panel, n_per_side: int, target, cdp_D: float, constraints, objective,
              fit, report, sampling, train_eyes, test_eyes) -> str:
    """The digest naming everything a count's fit and report depend on (hex): the starting
    ``panel``, the count, the :class:`~lfjax.design.settings.DesignTarget` (depths and
    wavelengths), the CDP (D), constraints, objective, the
    :class:`~lfjax.design.settings.FitSettings`, the report's setting
    (:class:`~lfjax.design.settings.ReportSettings`), the sampling, and the training and
    held-out eyes' coefficients (``test_eyes`` None: none)."""
    record = {
        "format": COUNTS_FORMAT, "lfjax_version": __version__, "n_per_side": int(n_per_side),
        "panel": _panel_record(panel), "depths_D": [float(d) for d in np.asarray(target.depths_D)],
        "cdp_D": float(cdp_D), "constraints": constraints.as_dict(),
        "objective": dict(objective.as_dict(), name=objective.name),
        "wavelengths_nm": [float(w) for w in target.wavelengths_nm], "steps": int(fit.steps),
        "tol": float(fit.tol), "report_accuracy": report.accuracy,
        "sampling": None if sampling is None else dataclasses.asdict(sampling),
        "eye_chunk": None if fit.eye_chunk is None else int(fit.eye_chunk),
        "train_eyes": _digest(train_eyes.zernike_um),
        "test_eyes": None if test_eyes is None else _digest(test_eyes.zernike_um),
    }
    text = json.dumps(jsonable(record), sort_keys=True)
    return hashlib.blake2b(text.encode(), digest_size=16).hexdigest()


def fit_record(fit) -> dict:
    """A :class:`~lfjax.design.fit.DesignFit` as JSON-ready data (:func:`fit_from_record`)."""
    return jsonable({
        "n_per_side": fit.n_per_side, "panel": _panel_record(fit.panel),
        "start": _panel_record(fit.start), "refused": fit.refused, "failed": fit.failed,
        "history": [float(v) for v in fit.history], "train": fit.train, "test": fit.test,
        "start_test": fit.start_test, "time_s": float(fit.time_s), "notes": list(fit.notes),
    })


def fit_fields(record: dict) -> dict:
    """Inverse of :func:`fit_record`: the keywords of a
    :class:`~lfjax.design.fit.DesignFit` (``DesignFit(**fit_fields(record))``)."""
    return dict(n_per_side=int(record["n_per_side"]), panel=_panel_from(record["panel"]),
                start=_panel_from(record["start"]), refused=record["refused"],
                failed=record.get("failed"), history=list(record["history"]), train=record["train"], test=record["test"],
                start_test=record["start_test"], time_s=float(record["time_s"]),
                notes=list(record["notes"]))


def save_count(folder, kind, key: str, n: int, fit) -> Path:
    """Keep a made count ``n`` of a design of ``kind`` (:class:`lfjax.design.runner.DesignKind`):
    ``folder/STEM-N.json`` (written whole), its record :meth:`kind.record` under ``key``."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    return atomic_write_text(folder / f"{kind.counts_stem}-{int(n)}.json",
                             json.dumps({"format": kind.counts_format, "key": key,
                                         "fit": kind.record(fit)}) + "\n")


def load_count(folder, kind, n: int, key: str):
    """The count ``n`` kept in ``folder`` for a design of ``kind`` if its key is ``key`` (same
    inputs), as :meth:`kind.from_record`, else None (none kept, another run's, or unreadable:
    it is then made again)."""
    path = Path(folder) / f"{kind.counts_stem}-{int(n)}.json"
    try:
        record = json.loads(path.read_text())
        if record.get("format") != kind.counts_format or record.get("key") != key:
            return None
        return kind.from_record(record["fit"])
    except (OSError, ValueError, KeyError, TypeError):
        return None


__all__ = ["COUNTS_FORMAT", "count_key", "counts_folder", "fit_fields", "fit_record",
           "load_count", "save_count", "panel_leaves", "panel_statics"]
