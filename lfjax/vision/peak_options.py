"""How continuous accommodation peaks are found: the methods, the metrics and the options
object every peak-finding entry point takes (:class:`PeakOptions`).

The methods are described in :mod:`lfjax.vision.peaks`; the solvers and the grid estimate
that carry them out live in :mod:`lfjax.vision.peak_refinement`.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from lfjax.base.errors import ParameterError

PEAK_METHODS = ("auto", "newton", "golden", "bfgs", "local", "parabola", "vertex", "grid",
                "adaptive")


METRICS = ("vsotf", "strehl")


DEFAULT_TOLERANCE_D = 0.01
"""``"adaptive"`` refines a peak whose grid estimate may be further than this from the
true maximum, D (the paper study's target for a predicted accommodation)."""


def check_method(method: str):
    if method not in PEAK_METHODS:
        raise ValueError(f"method must be one of {PEAK_METHODS}, got {method!r}")


def check_tolerance(tolerance_D) -> None:
    """Refuse a peak tolerance that is not a positive, finite number of dioptres."""
    ok = isinstance(tolerance_D, (int, float, np.floating, np.integer)) and not isinstance(
        tolerance_D, bool) and np.isfinite(tolerance_D) and 0 < float(tolerance_D) < 1
    if not ok:
        raise ParameterError("tolerance_D", "{tolerance_D} must lie in (0, 1) D (the "
                             "largest error a grid-estimated peak may keep), got {got!r}",
                             owner="PeakOptions", got=tolerance_D)


@dataclass(frozen=True)
class PeakOptions:
    """How continuous accommodation peaks are found: one frozen object, checked when built.

    Every entry point that finds peaks takes one (``through_focus(..., peaks=...)``,
    :func:`accommodation_peaks`, the sweep, the study), so a new peak option is a new field
    here, not a keyword threaded through each signature.

    Attributes
    ----------
    metrics : the metrics whose continuous peak is refined, a tuple of :data:`METRICS`;
        ``()`` (default): grid peaks only (entry points that always refine, such as
        :func:`accommodation_peaks`, take the metric on its own)
    method : the refinement, one of :data:`PEAK_METHODS` (module docstring; ``"auto"``:
        Newton for VSOTF, golden section for the Strehl ratio)
    tolerance_D : ``"adaptive"`` only: refine the peaks whose grid estimate may lie further
        than this from the true maximum, D, in (0, 1) (default :data:`DEFAULT_TOLERANCE_D`)
    second_peaks : refine second local maxima too (default); False halves the refinement's
        cost (the second peak is then located by the grid parabola and valued on the grid)
    prominence : a second local maximum is reported when it stands this fraction of its
        value above the valley between it and the global one, in [0, 1)
    atol_D : the solvers' location tolerance, D, > 0
    max_steps : the solvers' step limit, an integer ≥ 1

    Examples
    --------
    >>> from lfjax.vision.peaks import PeakOptions
    >>> PeakOptions(metrics=("vsotf",), method="vertex").method
    'vertex'
    >>> PeakOptions(method="nope")
    Traceback (most recent call last):
    ...
    lfjax.base.errors.ParameterError: PeakOptions.method must be one of ...
    """

    metrics: tuple[str, ...] = ()
    method: str = "auto"
    tolerance_D: float = DEFAULT_TOLERANCE_D
    second_peaks: bool = True
    prominence: float = 0.05
    atol_D: float = 1e-5
    max_steps: int = 32

    def __post_init__(self):
        metrics = self.metrics
        if isinstance(metrics, str) or not isinstance(metrics, (tuple, list)):
            raise ParameterError("metrics", "{metrics} must be a tuple of metric names from "
                                 "{allowed}, got {got!r}", owner="PeakOptions",
                                 allowed=METRICS, got=metrics)
        for name in metrics:
            if name not in METRICS:
                raise ParameterError("metrics", "{metrics} must name metrics in {allowed}, "
                                     "got {got!r}", owner="PeakOptions", allowed=METRICS,
                                     got=name)
        # a list would make the object unhashable (it is a static argument of jitted calls)
        object.__setattr__(self, "metrics", tuple(metrics))
        if self.method not in PEAK_METHODS:
            raise ParameterError("method", "{method} must be one of {allowed}, got {got!r}",
                                 owner="PeakOptions", allowed=PEAK_METHODS, got=self.method)
        check_tolerance(self.tolerance_D)
        if not isinstance(self.second_peaks, (bool, np.bool_)):
            raise ParameterError("second_peaks", "{second_peaks} must be True or False, got "
                                 "{got!r}", owner="PeakOptions", got=self.second_peaks)
        object.__setattr__(self, "second_peaks", bool(self.second_peaks))
        if not _real(self.prominence) or not 0 <= float(self.prominence) < 1:
            raise ParameterError("prominence", "{prominence} must lie in [0, 1), got {got!r}",
                                 owner="PeakOptions", got=self.prominence)
        if not _real(self.atol_D) or not 0 < float(self.atol_D) < 1:
            raise ParameterError("atol_D", "{atol_D} must lie in (0, 1) D, got {got!r}",
                                 owner="PeakOptions", got=self.atol_D)
        if (isinstance(self.max_steps, bool) or not isinstance(self.max_steps, (int, np.integer))
                or self.max_steps < 1):
            raise ParameterError("max_steps", "{max_steps} must be an integer >= 1, got {got!r}",
                                 owner="PeakOptions", got=self.max_steps)
        # floats and ints as Python numbers: the repr is part of the compiled program's key
        for name in ("tolerance_D", "prominence", "atol_D"):
            object.__setattr__(self, name, float(getattr(self, name)))
        object.__setattr__(self, "max_steps", int(self.max_steps))

    def replace(self, **changes) -> PeakOptions:
        """A copy with ``changes`` (checked again)."""
        return dataclasses.replace(self, **changes)


def _real(x) -> bool:
    return (isinstance(x, (int, float, np.floating, np.integer)) and not isinstance(x, bool)
            and bool(np.isfinite(x)))


def resolved_method(metric: str, method: str) -> str:
    """The refinement ``method`` runs for ``metric``: ``"auto"`` is Newton for VSOTF (smooth
    in accommodation) and golden section for the Strehl ratio; ``"adaptive"`` is itself for
    VSOTF and golden section for the Strehl ratio (its grid estimate assumes a smooth
    curve; the Strehl ratio's is piecewise smooth); any other name is itself."""
    if method == "auto":
        return "newton" if metric == "vsotf" else "golden"
    if method == "adaptive" and metric != "vsotf":
        return "golden"
    return method


__all__ = ["PEAK_METHODS", "METRICS", "DEFAULT_TOLERANCE_D", "PeakOptions", "check_method",
           "check_tolerance", "resolved_method"]
