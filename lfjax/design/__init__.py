"""Display design: a panel fitted to a population of eyes.

The work is in :mod:`~lfjax.design.fit`; its main calls are offered here.
"""

from lfjax.design import fit, plan
from lfjax.design.fit import (
    REPORT_ACCURACIES,
    REPORT_COUNTS,
    SCREEN_MARGIN,
    DesignConstraints,
    DesignResult,
    check_design,
    design_cdp_D,
    design_panel,
    fig_design,
    fit_design,
    panel_specification,
    save_design,
)

__all__ = ["fit", "plan", "REPORT_ACCURACIES", "REPORT_COUNTS", "SCREEN_MARGIN", "DesignConstraints", "DesignResult", "check_design",
           "design_cdp_D", "design_panel", "fig_design", "fit_design", "panel_specification", "save_design"]
