"""Tables as written for people: floating-point round-off shown as the 0 it stands for."""

from __future__ import annotations

import numpy as np

ROUNDOFF = 1e-12
"""Magnitudes below this are round-off in every table lfjax writes (dioptres, cpd, ratios,
fractions): differences of grid values such as 2.2 − 2.0 − 0.2 = 2.8e-17."""


def printable(table, atol: float = ROUNDOFF):
    """A copy of a pandas DataFrame with every float whose magnitude is below ``atol`` set
    to exactly 0 (so CSV and markdown print ``0``, not ``5.55e-17``); NaN stays NaN."""
    out = table.copy()
    for name in out.columns:
        column = out[name]
        if column.dtype.kind == "f":
            values = column.to_numpy(copy=True)
            values[np.abs(values) < atol] = 0.0
            out[name] = values
    return out
