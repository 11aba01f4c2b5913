"""Layout parameters as JSON, and layout files with their parameters and objective (reading: :mod:`lfjax.model.layout_files`).

Part of :mod:`lfjax.layout_opt` (its public names are re-exported there)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from lfjax.base.files import atomic_write_text
from lfjax.base.types import finite_scalar
from lfjax._version import stamp
from lfjax.model.layout_files import LAYOUT_FORMAT, jsonable
from lfjax.model.layouts import Layout, make_layout
from lfjax.layout_opt._params import LatticeParams, free_params
from lfjax.layout_opt._problem import Objective


def params_to_dict(params) -> dict:
    """JSON-ready description of layout parameters."""
    if isinstance(params, LatticeParams):
        return dict(kind="lattice", lattice=params.kind, pitch_mm=float(params.pitch_mm),
                    diameter_mm=float(params.diameter_mm), rotation_rad=float(params.rotation_rad),
                    sites=[list(s) for s in params.sites])
    return dict(kind="free", centres_mm=np.asarray(params.centres_mm, float).tolist(),
                diameters_mm=np.asarray(params.diameters_mm, float).tolist())


def params_from_dict(record: dict):
    """Inverse of :func:`params_to_dict` (host-checked)."""
    kind = record.get("kind")
    if kind == "lattice":
        for key in ("pitch_mm", "diameter_mm", "rotation_rad"):
            finite_scalar(key, record[key])
        sites = tuple(tuple(float(v) for v in s) for s in record["sites"])
        return LatticeParams(record["pitch_mm"], record["diameter_mm"], record["rotation_rad"],
                             sites, record["lattice"])
    if kind == "free":
        return free_params(record["centres_mm"], record["diameters_mm"])
    raise ValueError(f"parameters kind must be 'lattice' or 'free', got {kind!r}")


def save_layout_json(path, layout: Layout, pupil_diameter_mm: float, *, objective=None,
                     provenance: dict | None = None, parameters=None) -> Path:
    """Write a layout as JSON: centres_mm, diameters_mm, pupil_diameter_mm, name, objective,
    provenance (+ parameters when given: LatticeParams/FreeParams or their dict).

    ``objective``: an :class:`Objective`, a name, or a dict (e.g. with its values).
    ``provenance`` follows the package's one stamp (:func:`lfjax._version.stamp`: version,
    commit, JAX, host, UTC time).
    """
    make_layout(layout.centres_mm, layout.diameters_mm, pupil_diameter_mm)  # validates
    if isinstance(objective, Objective):
        objective = objective.as_dict()
    elif isinstance(objective, str):
        objective = {"name": objective}
    if parameters is not None and not isinstance(parameters, dict):
        parameters = params_to_dict(parameters)
    prov = stamp(**(provenance or {}))
    record = {
        "format": LAYOUT_FORMAT,
        "name": layout.name,
        "pupil_diameter_mm": float(pupil_diameter_mm),
        "window_diameter_mm": float(layout.window_diameter_mm),
        "centres_mm": np.asarray(layout.centres_mm, float).tolist(),
        "diameters_mm": np.asarray(layout.diameters_mm, float).tolist(),
        "objective": objective,
        "provenance": prov,
    }
    if parameters is not None:
        record["parameters"] = parameters
    path = Path(path)
    atomic_write_text(path, json.dumps(jsonable(record), indent=2) + "\n")
    return path
