"""Display design: a panel fitted to a population of eyes.

The work is in :mod:`~lfjax.design.fit`; its main calls are offered here.
"""

from lfjax.design import fit
from lfjax.design.fit import (
    DesignConstraints,
    DesignResult,
    fig_design,
    fit_design,
    panel_specification,
    save_design,
)

__all__ = ["fit", "DesignConstraints", "DesignResult", "fig_design", "fit_design",
           "panel_specification", "save_design"]
