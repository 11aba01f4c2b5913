"""The sampling planner: which pupil, frequency and wavelength steps answer a question.

:func:`~lfjax.planner.plan.plan_sampling` plans for a :class:`~lfjax.planner.scene.PlanScene`
and its :class:`~lfjax.planner.targets.Targets` (:mod:`~lfjax.planner.targets`), in steps
that share one :class:`~lfjax.planner.state.PlanningState`: the wavelength step
(:mod:`~lfjax.planner.spectral_step`) and the frequency step and transform
(:mod:`~lfjax.planner.frequency_step`, on the ladder of :mod:`~lfjax.planner.ladder`),
measuring errors on a numpy proxy of the optics (:mod:`~lfjax.planner.proxy`) and costs on a
cost model (:mod:`~lfjax.planner.cost`); :mod:`~lfjax.planner.cache` remembers plans by the
value of every input.
"""

from lfjax.planner import (cache, cost, frequency_step, ladder, plan, proxy, scene,
                           spectral_step, state, targets)
from lfjax.planner.plan import Plan, plan_sampling
from lfjax.planner.scene import PlanScene
from lfjax.planner.targets import FieldGuard, Overrides, Targets

__all__ = ["cache", "cost", "frequency_step", "ladder", "plan", "proxy", "scene",
           "spectral_step", "state", "targets", "FieldGuard", "Overrides", "Plan", "PlanScene",
           "Targets", "plan_sampling"]
