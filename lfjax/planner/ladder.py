"""The frequency-step ladder the planner moves on: df = 2^(k/8) cpd.

Steps are taken from a fixed ladder, so "one step cheaper" is well defined
(:attr:`lfjax.planner.plan.Plan.cheaper`).
"""

from __future__ import annotations

import math

STEPS_PER_OCTAVE = 8
"""Frequency-step ladder: df = 2^(k/8) cpd (9 % apart; one step ≈ 19 % of FFT work)."""


def ladder_floor(x: float) -> float:
    """Largest ladder step 2^(k/8) ≤ x."""
    k = math.floor(STEPS_PER_OCTAVE * math.log2(x) + 1e-9)
    return 2.0 ** (k / STEPS_PER_OCTAVE)


def ladder_up(x: float) -> float:
    """The next ladder step above ``x`` (one step cheaper)."""
    return ladder_floor(x) * 2.0 ** (1.0 / STEPS_PER_OCTAVE)


__all__ = ["STEPS_PER_OCTAVE", "ladder_floor", "ladder_up"]
