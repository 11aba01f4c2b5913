"""The sampling planner: which pupil, frequency and wavelength steps answer a question.

:mod:`~lfjax.planner.plan` chooses the steps from a cheap numpy proxy of the optics and
a cost model; :mod:`~lfjax.planner.cache` remembers plans by the value of every input.
"""

from lfjax.planner import cache, plan
from lfjax.planner.plan import Plan, plan_sampling

__all__ = ["cache", "plan", "Plan", "plan_sampling"]
