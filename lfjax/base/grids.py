"""Host grids in dioptres and nanometres, built one way for every configuration.

A grid runs ``start, start + step, …`` up to and including ``stop`` (a last point within
1e-9 of a step of ``stop`` counts), and every point is rounded to 1e-9, so that a state
such as 0.6 D is the same float in every configuration, store and table that names it.
:func:`inclusive_grid` builds one and :func:`grid_size` counts its points without building
it. :class:`DepthGrid` gives a configuration its rendered depths and accommodation states
from its fields; the paper's study (:class:`lfjax.reproduce.config.StudyConfig`), the
population sweep (:class:`lfjax.sweep.config.SweepConfig`) and the display study
(:class:`lfjax.studies.display_effects.DisplayStudyConfig`) share it.
"""

from __future__ import annotations

import math

import numpy as np

DECIMALS = 9
"""Grid points are rounded to this many decimals (1e-9 D, 1e-9 nm)."""


def grid_size(start: float, stop: float, step: float) -> int:
    """Points of the grid ``start … stop`` by ``step`` (> 0), counted without building it.

    Raises what ``math.floor`` raises on an infinite or NaN count (``OverflowError``,
    ``ValueError``) and ``ZeroDivisionError`` for a zero step."""
    return int(math.floor((stop - start) / step + 1e-9)) + 1


def inclusive_grid(start: float, stop: float, step: float) -> np.ndarray:
    """The grid ``start, start + step, …, ≤ stop`` (float64, rounded to 1e-9; ``stop`` is
    included when it lies on the grid)."""
    return np.round(start + step * np.arange(grid_size(start, stop, step)), DECIMALS)


class DepthGrid:
    """Rendered depths and accommodation states of a configuration, from its fields.

    A mixin of frozen dataclasses that have the fields (or properties) ``cdp_D`` (central
    depth plane, D), ``depth_offsets_D`` (rendered depths relative to it, D),
    ``accommodation_step_D`` and ``accommodation_max_D`` (the absolute grid 0 … max, D).
    """

    @property
    def depths_D(self) -> np.ndarray:
        """Rendered depths ``cdp_D + depth_offsets_D``, D (rounded to 1e-9), shape (n_depth,)."""
        return np.round(self.cdp_D + np.asarray(self.depth_offsets_D, float), DECIMALS)

    @property
    def accommodation_D(self) -> np.ndarray:
        """Accommodation states ``0, step, …, ≤ max``, D (:func:`inclusive_grid`),
        shape (n_acc,)."""
        return inclusive_grid(0.0, self.accommodation_max_D, self.accommodation_step_D)


__all__ = ["DECIMALS", "DepthGrid", "grid_size", "inclusive_grid"]
