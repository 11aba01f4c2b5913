"""What every claim of the paper's study is built from: the numbers it reads, the ranges its
criterion allows, and the record of its verdict.

:class:`StudyNumbers` holds a study Dataset's numbers as NumPy arrays (layout, eye, depth,
...), read once: the verdicts (:func:`lfjax.vision.claims.evaluate_claims`), the margins
(:func:`lfjax.vision.claims.undecided_layouts`) and the ten-eye draws
(:mod:`lfjax.sweep.ten_eyes`, one :meth:`StudyNumbers.take_eyes` per sample) all read it.
:class:`Interval` is one threshold of a criterion: it answers both "does this value pass"
and "which answers can a value anywhere in this range give", so a claim states each
threshold once and its verdict and margin both follow from it. :class:`Claim` is one
claim's verdict on one study; :func:`dof_D`, :func:`all_of` and :func:`compare_bounds`
are the pieces several criteria share.

Host-side NumPy; the one xarray call (:func:`eye_mean`) keeps the Dataset's own reduction.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from lfjax.model.layouts import LF_LAYOUTS

DIMS = ("layout", "eye", "depth", "metric")
"""Axis order of every per-cell array of :class:`StudyNumbers`."""


@dataclass
class Claim:
    """One paper finding as a checkable statement, with its verdict on one study."""

    id: str
    finding: str
    criterion: str
    result: str
    holds: bool | None  # None: could not be evaluated on this data
    unsettled: tuple[str, ...] = ()
    """Layouts whose numbers, moved within the planned spectrum's error, could change the
    verdict (:func:`lfjax.vision.claims.undecided_layouts`); empty when the numbers
    settle it."""
    reference_layouts: tuple[str, ...] = ()
    """Layouts computed again at the reference spectrum to settle the verdict
    (:mod:`lfjax.reproduce.settling`)."""

    @property
    def verdict(self) -> str:
        return {True: "holds", False: "fails", None: "n/a"}[self.holds]


@dataclass(frozen=True)
class Interval:
    """The range ``lo ≤ x ≤ hi`` a criterion allows one number (in that number's unit); an
    open end excludes its own value. The one place a threshold is written: the verdict asks
    :meth:`holds`, the margin asks :meth:`possible` over the range the number may take."""

    lo: float = -math.inf
    hi: float = math.inf
    lo_open: bool = False
    hi_open: bool = False

    def holds(self, x) -> bool:
        """Whether ``x`` (a number, or an array: every element) lies in the range."""
        above = np.greater(x, self.lo) if self.lo_open else np.greater_equal(x, self.lo)
        below = np.less(x, self.hi) if self.hi_open else np.less_equal(x, self.hi)
        return bool(np.all(above & below))

    def possible(self, x_lo: float, x_hi: float) -> set[bool]:
        """The answers :meth:`holds` gives for some x in [x_lo, x_hi]: the range is convex,
        so it holds somewhere when it holds towards each end, and fails somewhere when it
        fails at an end."""
        out = set()
        if Interval(lo=self.lo, lo_open=self.lo_open).holds(x_hi) and \
                Interval(hi=self.hi, hi_open=self.hi_open).holds(x_lo):
            out.add(True)
        if not (self.holds(x_lo) and self.holds(x_hi)):
            out.add(False)
        return out


def fmt(x, digits=2) -> str:
    """A signed number for a claim's result text ("nan" when not finite)."""
    return "nan" if not np.isfinite(x) else f"{x:+.{digits}f}"


def dof_D(rel_depths, cutoffs, fraction: float) -> tuple[float, bool]:
    """Depth of field (D): length of the contiguous depth range around the best depth
    where the cut-off stays ≥ ``fraction`` × best, with linear interpolation of the
    crossings. Returns (dof, censored) where censored means the range reaches the end of
    the sampled depths on some side (the true DOF is at least the value)."""
    x = np.asarray(rel_depths, float)
    c = np.asarray(cutoffs, float)
    order = np.argsort(x)
    x, c = x[order], c[order]
    ib = int(np.nanargmax(c))
    level = fraction * c[ib]
    censored = False
    lo = x[ib]
    i = ib
    while True:
        if i == 0:
            lo, censored = x[0], True
            break
        if c[i - 1] >= level:
            i -= 1
            continue
        lo = x[i - 1] + (level - c[i - 1]) / (c[i] - c[i - 1]) * (x[i] - x[i - 1])
        break
    hi = x[ib]
    i = ib
    while True:
        if i == x.size - 1:
            hi, censored = x[-1], True
            break
        if c[i + 1] >= level:
            i += 1
            continue
        hi = x[i] + (c[i] - level) / (c[i] - c[i + 1]) * (x[i + 1] - x[i])
        break
    return float(hi - lo), censored


def all_of(verdicts) -> bool | None:
    """Conjunction of parts that may be undecided (None): False if any part fails, None if
    none fails but one is undecided, else True."""
    verdicts = list(verdicts)
    if any(v is False for v in verdicts):
        return False
    return None if any(v is None for v in verdicts) else True


def compare_bounds(a, a_censored, b, b_censored, tol, strict) -> bool | None:
    """Is the true value behind b >= a (strict: > a)? a and b are lower bounds where
    censored. True when proven (a exact), False when disproven (b exact), else None."""
    if not (math.isfinite(a) and math.isfinite(b)):
        return None
    ok = b > a + tol if strict else b >= a - tol
    if ok:
        return True if not a_censored else None
    return False if not b_censored else None


def eye_mean(values: np.ndarray) -> np.ndarray:
    """Mean over the first axis (eyes) as an xarray Dataset's ``mean("eye")`` gives it:
    NaN skipped, the same reduction, so the numbers are those of the Dataset route."""
    import xarray as xr

    dims = ("eye",) + tuple(f"axis{i}" for i in range(1, np.ndim(values)))
    return xr.Variable(dims, values).mean("eye").values


def _cells(ds, name: str, *, required: bool = True):
    """A per-cell variable in :data:`DIMS` order (trailing dims kept), or None if absent."""
    if name not in ds:
        if required:
            raise ValueError(f"ds: a study Dataset needs the variable {name!r}")
        return None
    var = ds[name]
    return np.asarray(var.transpose(*DIMS, ...).values)


class StudyNumbers:
    """A study Dataset's numbers the claims read, as NumPy arrays.

    Per-cell arrays (:data:`DIMS` order: layout, eye, depth, metric): ``pred`` grid peaks
    (D), ``error`` their accommodation errors (D), ``cont`` continuous peaks (D),
    ``success`` whether those converged, ``peak_value`` the metric at the peak,
    ``cutoff`` cut-off frequencies (cpd), ``mtf`` (..., frequency) radial MTF at the peak.
    ``vertex`` (layout, eye, depth): the VSOTF grid parabola's vertex (D; NaN when the
    Dataset lacks it); ``strehl`` (layout, eye, depth, accommodation) the through-focus
    Strehl ratio, or None (a sweep's study view has no curves). ``c20`` (eye,): Zernike
    defocus (um). ``layouts``, ``lf`` (its LF layouts in density order), ``rel`` depths
    relative to the CDP (D), ``depths`` (D), ``acc`` accommodation grid (D), ``freq``
    (cpd), ``eyes`` positions of the aberrated eyes, ``avg`` the average eye's position or
    None, ``attrs`` the Dataset's attributes.
    """

    ARRAYS = ("pred", "error", "cont", "success", "peak_value", "cutoff", "mtf", "vertex",
              "strehl", "c20")
    """The arrays with an eye axis (second, or first for ``c20``): :meth:`take_eyes`
    selects along it."""

    def __init__(self, **fields):
        self.__dict__.update(fields)

    @classmethod
    def from_dataset(cls, ds) -> StudyNumbers:
        """Read ``ds`` (a study Dataset, :func:`lfjax.reproduce.study.run_study`, or a
        sweep's study view) once."""
        metric = [str(m) for m in ds.metric.values]
        if metric[:2] != ["vsotf", "strehl"]:
            raise ValueError(f"ds: metrics must start with vsotf, strehl; got {metric}")
        pred = _cells(ds, "predicted_accommodation")
        parabolic = _cells(ds, "predicted_accommodation_parabolic", required=False)
        strehl = None
        if "strehl" in ds:
            strehl = np.asarray(ds.strehl.transpose("layout", "eye", "depth", ...).values, float)
        is_avg = np.asarray(ds.is_average.values, bool)
        return cls(
            layouts=[str(n) for n in ds.layout.values],
            rel=np.asarray(ds.depth_rel_cdp.values, float),
            depths=np.asarray(ds.depth.values, float),
            acc=(np.asarray(ds.accommodation.values, float) if "accommodation" in ds.coords
                 else np.zeros(0)),
            freq=np.asarray(ds.frequency.values, float),
            eye_labels=np.asarray(ds.eye.values),
            is_average=is_avg,
            attrs=dict(ds.attrs),
            pred=pred,
            error=_cells(ds, "accommodation_error"),
            cont=_cells(ds, "predicted_accommodation_continuous"),
            success=_cells(ds, "continuous_peak_success"),
            peak_value=_cells(ds, "peak_value"),
            cutoff=_cells(ds, "cutoff_frequency"),
            mtf=_cells(ds, "mtf_at_peak"),
            vertex=(parabolic[..., 0] if parabolic is not None
                    else np.full(pred.shape[:-1], np.nan)),
            strehl=strehl,
            c20=np.asarray(ds.zernike_um.sel(zernike_j=4).values, float),
        )

    def take_eyes(self, index) -> StudyNumbers:
        """The same study with only the eyes at positions ``index`` (1-d ints), in order."""
        index = np.asarray(index)
        fields = dict(self.__dict__)
        for name in self.ARRAYS:
            a = fields[name]
            if a is not None:
                fields[name] = a[index] if name == "c20" else a[:, index]
        fields["eye_labels"] = self.eye_labels[index]
        fields["is_average"] = self.is_average[index]
        return StudyNumbers(**fields)

    # ------------------------------------------------------------------ derived

    @property
    def lf(self) -> list[str]:
        return [n for n in LF_LAYOUTS if n in self.layouts]

    @property
    def eyes(self) -> np.ndarray:
        return np.flatnonzero(~self.is_average)

    @property
    def avg(self) -> int | None:
        found = np.flatnonzero(self.is_average)
        return int(found[0]) if found.size else None

    @property
    def cdp(self) -> float:
        return float(self.attrs["cdp_D"])

    @property
    def step(self) -> float:
        """The accommodation grid's step (D); 0 without a grid."""
        return float(self.acc[1] - self.acc[0]) if self.acc.size > 1 else 0.0

    def li(self, name: str) -> int:
        return self.layouts.index(name)

    def has_cdp_depth(self) -> bool:
        return bool(np.any(np.isclose(self.rel, 0.0)))

    def cdp_index(self) -> int:
        """The depth nearest the CDP."""
        return int(np.argmin(np.abs(self.rel)))

    def aberrated(self, values: np.ndarray) -> np.ndarray:
        """``values``' aberrated eyes (eye axis second, after layout)."""
        return values[:, self.eyes]

    def mean_cutoffs(self, name: str) -> np.ndarray:
        """(depth,) mean VSOTF cut-off of the aberrated eyes (cpd), NaN skipped."""
        return eye_mean(self.cutoff[self.li(name)][self.eyes][..., 0])

    def dof_fraction(self, override: float | None) -> float:
        return (float(self.attrs.get("config_dof_fraction", 0.8)) if override is None
                else override)


class ClaimRule:
    """One claim of the paper's study, declared once: its id, the paper's finding, the
    criterion (text, and the thresholds as :class:`Interval` fields of the subclass), and
    the three readings derived from them:

    * :meth:`evaluate`: the verdict on one study (:class:`Claim`);
    * :meth:`undecided`: the layouts whose numbers, moved within a
      :class:`~lfjax.vision.claim_margins.Resolution`, could change that verdict;
    * the population reading (:mod:`lfjax.sweep.ten_eyes`): :meth:`evaluate` on each
      sample of eyes (:meth:`StudyNumbers.take_eyes`).

    Subclasses are frozen dataclasses and implement :meth:`judge` and :meth:`undecided`;
    the registry is :data:`lfjax.vision.claims.CLAIMS`.
    """

    id: str
    finding: str
    criterion: str
    short_finding: str
    """The finding as shown when the data cannot evaluate the claim at all."""
    needs: str
    """What the claim needs, shown in place of the criterion when it cannot be evaluated."""

    def judge(self, s: StudyNumbers, dof_fraction: float) -> tuple[str, bool | None] | None:
        """(result text, holds) on ``s``; None when ``s`` lacks what the claim needs."""
        raise NotImplementedError

    def undecided(self, s: StudyNumbers, resolution, dof_fraction: float) -> set[str]:
        """Layouts whose numbers, each moved within ``resolution``
        (:class:`~lfjax.vision.claim_margins.Resolution`), can change the verdict; empty
        when none can."""
        raise NotImplementedError

    def criterion_text(self, s: StudyNumbers, dof_fraction: float) -> str:
        return self.criterion

    def evaluate(self, s: StudyNumbers, dof_fraction: float) -> Claim:
        """The claim's verdict on ``s``, with the numbers behind it."""
        found = self.judge(s, dof_fraction)
        if found is None:
            return Claim(self.id, self.short_finding, self.needs, "not evaluated", None)
        result, holds = found
        return Claim(self.id, self.finding, self.criterion_text(s, dof_fraction), result, holds)


__all__ = [
    "Claim",
    "ClaimRule",
    "DIMS",
    "Interval",
    "StudyNumbers",
    "all_of",
    "compare_bounds",
    "dof_D",
    "eye_mean",
    "fmt",
]
