"""Layout files: a subaperture layout saved as JSON, and read back validated.

The layout optimiser writes these files (:func:`lfjax.layout_opt.save_layout_json`, which
adds the fitted parameters and the objective); the population sweep and the command line
read them. Reading lives here, below both, so that the sweep needs nothing of the
optimiser to take a layout file as input.

A file holds ``format`` (:data:`LAYOUT_FORMAT`), ``name``, ``pupil_diameter_mm``,
``window_diameter_mm``, ``centres_mm`` (n_views, 2) and ``diameters_mm`` (n_views,), all in
mm, plus what its writer adds (``objective``, ``provenance``, ``parameters``).
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import jax
import numpy as np

from lfjax.base.types import finite_scalar
from lfjax.model.layouts import Layout, make_layout

LAYOUT_FORMAT = "lfjax-layout/1"
"""The ``format`` field of a layout file."""


def jsonable(x):
    """``x`` with arrays as (nested) lists, numpy scalars as Python numbers and non-finite
    floats as ``None`` (JSON has no NaN), ready for :func:`json.dumps`."""
    if isinstance(x, dict):
        return {str(k): jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [jsonable(v) for v in x]
    if isinstance(x, (np.ndarray, jax.Array)):
        return jsonable(np.asarray(x).tolist())
    if isinstance(x, (np.floating, np.integer, np.bool_)):
        return x.item()
    if isinstance(x, float) and not math.isfinite(x):
        return None
    return x


def load_layout_json(path) -> tuple[Layout, dict]:
    """Read a layout file: (validated Layout, the whole record)."""
    record = json.loads(Path(path).read_text())
    if not isinstance(record, dict) or record.get("format") != LAYOUT_FORMAT:
        raise ValueError(f"{path}: not an lfjax layout file (format {LAYOUT_FORMAT!r} expected)")
    for key in ("centres_mm", "diameters_mm", "pupil_diameter_mm"):
        if key not in record:
            raise ValueError(f"{path}: missing {key!r}")
    pupil = finite_scalar("pupil_diameter_mm", record["pupil_diameter_mm"], 0.0, None, lo_open=True)
    layout = make_layout(record["centres_mm"], record["diameters_mm"], pupil,
                         name=str(record.get("name", "custom")),
                         window_diameter_mm=record.get("window_diameter_mm"))
    return layout, record


__all__ = [
    "LAYOUT_FORMAT",
    "jsonable",
    "load_layout_json",
]
