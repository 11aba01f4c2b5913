"""The sampling planner: which pupil, frequency and wavelength steps answer a question.

:func:`~lfjax.planner.plan.plan_sampling` plans for a :class:`~lfjax.planner.scene.PlanScene`
and its :class:`~lfjax.planner.plan.Targets` (:mod:`~lfjax.planner.plan`), measuring errors
on a numpy proxy of the optics (:mod:`~lfjax.planner.proxy`) and costs on a cost model
(:mod:`~lfjax.planner.cost`); :mod:`~lfjax.planner.cache` remembers plans by the value of
every input.
"""

from lfjax.planner import cache, cost, plan, proxy, scene
from lfjax.planner.plan import FieldGuard, Overrides, Plan, Targets, plan_sampling
from lfjax.planner.scene import PlanScene

__all__ = ["cache", "cost", "plan", "proxy", "scene", "FieldGuard", "Overrides", "Plan",
           "PlanScene", "Targets", "plan_sampling"]
