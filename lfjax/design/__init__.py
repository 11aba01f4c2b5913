"""Display design: a panel fitted to a population of eyes.

The runner is :mod:`~lfjax.design.fit` (:func:`fit_design`); its option objects are in
:mod:`~lfjax.design.settings`, the feasible box and its problems in :mod:`~lfjax.design.box`,
the solver in :mod:`~lfjax.design.solve`, the report in :mod:`~lfjax.design.report` and the
files in :mod:`~lfjax.design.write`. Its main calls are offered here.
"""

from lfjax.design import fit, plan
from lfjax.design.fit import SCREEN_MARGIN, check_design, design_cdp_D, design_panel, fit_design
from lfjax.design.report import DesignResult
from lfjax.design.settings import (
    REPORT_ACCURACIES,
    REPORT_COUNTS,
    DesignConstraints,
    DesignTarget,
    FitSettings,
    ReportSettings,
)
from lfjax.design.write import fig_design, panel_specification, save_design

__all__ = ["fit", "plan", "REPORT_ACCURACIES", "REPORT_COUNTS", "SCREEN_MARGIN", "DesignConstraints",
           "DesignResult", "DesignTarget", "FitSettings", "ReportSettings", "check_design",
           "design_cdp_D", "design_panel", "fig_design", "fit_design", "panel_specification",
           "save_design"]
