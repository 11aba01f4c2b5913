"""A fitted design's report: the perceivable resolution at each eye's predicted
accommodation, each count's verdict (:class:`DesignFit`: ok, refused or failing a
requirement), the result and its choice (:class:`DesignResult`), and the order in which the
held-out report scores the counts (:func:`report_counts_in_order`)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from lfjax.design.box import with_display
from lfjax.design.plan import SCREEN_MARGIN
from lfjax.design.settings import DesignConstraints
from lfjax.design.write import design_record, fig_design
from lfjax.display.panel import Panel
from lfjax.kernel.pipeline import retinal_metrics
from lfjax.kernel.scene import Accommodation
from lfjax.layout_opt import Objective
from lfjax.vision.resolution import perceivable_cutoff_cpd


# ----------------------------------------------------------------------------- evaluation


@eqx.filter_jit
def _mtf_at(layout, problem, accommodation_D):
    acc = Accommodation.per_depth(accommodation_D, problem.options, problem.pupil_diameter_mm)
    return retinal_metrics(problem.eyes, problem.scene(layout), problem.spectrum, acc,
                           problem.config, problem.reference).radial_mtf[0, :, 0, :]


def perceivable_resolution(panel: Panel, n_per_side: int, problem, predicted_D,
                           constraints: DesignConstraints | None = None) -> np.ndarray:
    """Perceivable cut-off (cpd, (n_eyes, n_depth)) of every eye of ``problem`` at its own
    predicted accommodation ``predicted_D`` (n_eyes, n_depth) D:
    :func:`lfjax.vision.resolution.perceivable_cutoff_cpd` of the radial MTF there, with the panel's
    optics (and its lenslets' aberration when ``constraints`` names a lens form). One eye
    per call (each eye has its own states)."""
    problem = with_display(problem, panel, constraints)
    layout = panel.layout(n_per_side)
    depths = np.asarray(problem.depths_D, float)
    out = []
    freq = None
    for i in range(problem.eyes.n_eyes):
        eye = problem.with_eyes(problem.eyes[i:i + 1])
        acc = np.maximum(np.asarray(predicted_D[i], float), 0.0)[:, None]
        mtf = _mtf_at(layout, eye, jnp.asarray(acc))
        if freq is None:
            freq = np.arange(mtf.shape[-1]) * problem.config.freq_step_cpd
        out.append(np.asarray(perceivable_cutoff_cpd(mtf, freq, panel, depths)))
    return np.stack(out)


def summary_numbers(evaluation: dict, resolution: np.ndarray) -> dict:
    keys = ("image_at_peak", "relative_accommodation_rmse_D", "accommodation_rmse_D",
            "accommodation_gain", "peak_success_fraction", "loss", "penalty", "n_eyes")
    out = {k: evaluation[k] for k in keys}
    out["perceivable_cpd_median"] = float(np.median(resolution))
    out["perceivable_cpd_p05"], out["perceivable_cpd_p95"] = (float(v) for v in np.percentile(resolution, [5, 95]))
    out["perceivable_cpd_by_depth"] = np.median(resolution, axis=0).tolist()
    return out


class CountVerdict:
    """The verdict of one count's design, from its ``refused``, ``failed`` and ``score``
    fields (shared by :class:`DesignFit` and the lenticular design's count), what
    :func:`report_counts_in_order` reads."""

    refused: str | None
    failed: str | None
    score: dict | None

    @property
    def ok(self) -> bool:
        """Buildable, a light field, scored, and within every requirement: a count that
        may be chosen."""
        return self.refused is None and self.failed is None and self.score is not None

    @property
    def status(self) -> str:
        """``"ok"``, ``"refused: <why>"`` or ``"fails: <which requirement, by how much>"``."""
        if self.refused is not None:
            return f"refused: {self.refused}"
        if self.failed is not None:
            return f"fails: {self.failed}"
        return "ok" if self.score is not None else "not scored"

    @property
    def training_loss(self) -> float | None:
        """The fit's last loss on the training eyes (None: not fitted by gradient)."""
        return None


@dataclass
class DesignFit(CountVerdict):
    """One views-per-pupil count's design.

    Attributes
    ----------
    n_per_side : views per side in the pupil
    panel, start : the fitted and the starting :class:`~lfjax.display.panel.Panel` (None when
        infeasible)
    refused : why the design is not buildable or not a light field (None when it is)
    failed : the requirement the fitted design breaks on the report's eyes (None when it
        meets them all): its accommodation error above the objective's tolerance, or a score
        that is not finite (:func:`design_failure`)
    history : loss per solver step (training eyes)
    train, test : held-out/training scores of ``panel`` (``image_at_peak`` VSOTF,
        ``relative_accommodation_rmse_D`` D, ``perceivable_cpd_median`` cpd, …)
    start_test : the same scores of the starting panel (held-out eyes, or the training
        eyes without them)
    notes : where the fitted panel leaves what the model assumes (:func:`design_notes`)
    time_s : seconds the fit and its report took
    unreported : why the held-out report did not score this fitted count (None when it did,
        or when the count is refused): its training loss ranks it behind a count that
        passes the report by more than :data:`SCREEN_MARGIN` (``report_counts="chosen"``)
    """

    n_per_side: int
    panel: Panel | None = None
    start: Panel | None = None
    refused: str | None = None
    failed: str | None = None
    history: list = field(default_factory=list)
    train: dict | None = None
    test: dict | None = None
    start_test: dict | None = None
    time_s: float = 0.0
    notes: list = field(default_factory=list)
    unreported: str | None = None

    @property
    def score(self) -> dict | None:
        return self.test if self.test is not None else self.train

    @property
    def training_loss(self) -> float | None:
        """The fit's last loss on the training eyes (objective units; None without steps)."""
        return float(self.history[-1]) if self.history else None

    @property
    def status(self) -> str:
        if self.refused is None and self.failed is None and self.unreported is not None:
            return f"not reported: {self.unreported}"
        return CountVerdict.status.fget(self)



def design_failure(score: dict, objective: Objective, eyes: str = "held-out") -> str | None:
    """The requirement a fitted design breaks on its report's ``score`` (None when none):
    a score that is not finite, or the display's accommodation RMSE
    (``relative_accommodation_rmse_D``) above ``objective.accommodation_tolerance_D`` (the
    constraint the fit was asked to keep; none without one). ``eyes`` names the report's
    eyes in the message."""
    names = ("image_at_peak", "relative_accommodation_rmse_D", "perceivable_cpd_median", "loss")
    bad = [k for k in names if not math.isfinite(float(score[k]))]
    if bad:
        return f"its {', '.join(bad)} on the {eyes} eyes are not finite"
    tol = objective.accommodation_tolerance_D
    rmse = float(score["relative_accommodation_rmse_D"])
    if tol is not None and rmse > tol:
        return (f"the display's accommodation RMSE {rmse:.3f} D on the {eyes} eyes exceeds the "
                f"tolerance accommodation_tolerance_D = {tol:g} D")
    return None


@dataclass
class DesignResult:
    """Every count's :class:`DesignFit` and the chosen one (the lowest held-out loss among
    those :attr:`DesignFit.ok`, neither refused nor failing a requirement; None when none
    is)."""

    fits: list
    cdp_D: float
    depths_D: list
    constraints: DesignConstraints
    objective: Objective
    provenance: dict

    @property
    def best(self) -> DesignFit | None:
        ok = [f for f in self.fits if f.ok]
        return min(ok, key=lambda f: f.score["loss"]) if ok else None

    def summary(self) -> str:
        where = "held-out" if any(f.test is not None for f in self.fits) else "training"
        lines = [f"design: CDP {self.cdp_D:g} D, depths {self.depths_D} D; {self.objective.name}; "
                 f"scores on the {where} eyes (start: lenslets_for_layout's tangent array, f/3)",
                 "  views  VSOTF@peak (start)  display's acc. RMSE D (start)  "
                 "perceivable cpd median [5-95 %]  status"]
        for f in self.fits:
            s = f.score
            if s is None:
                lines.append(f"  {f.n_per_side}x{f.n_per_side}    {f.status}")
                continue
            st = f.start_test or {}
            status = f.status
            start_img = f" ({st['image_at_peak']:.4f})" if st else ""
            start_acc = f" ({st['relative_accommodation_rmse_D']:.3f})" if st else ""
            lines.append(f"  {f.n_per_side}x{f.n_per_side}    {s['image_at_peak']:.4f}{start_img}   "
                         f"{s['relative_accommodation_rmse_D']:.3f}{start_acc}                  "
                         f"{s['perceivable_cpd_median']:.2f} [{s['perceivable_cpd_p05']:.2f}, "
                         f"{s['perceivable_cpd_p95']:.2f}]    {status}")
        for f in self.fits:
            lines += [f"  note ({f.n_per_side}x{f.n_per_side}): {note}" for note in f.notes]
        best = self.best
        lines.append(f"  chosen: {best.n_per_side}x{best.n_per_side}" if best else
                     "  chosen: none (no count is ok)")
        return "\n".join(lines)

    def record(self, command: str | None = None) -> dict:
        """``design.json``'s record (:func:`lfjax.design.write.design_record`)."""
        return design_record(self, command)

    def figure(self):
        """``design.png``: the chosen count's array and views (the first with a panel when
        none is chosen; :func:`lfjax.design.write.fig_design`), or None without a panel."""
        chosen = self.best or next((f for f in self.fits if f.panel is not None), None)
        return None if chosen is None else fig_design(chosen.panel, chosen.n_per_side)


def design_notes(panel: Panel, depth_range_D, wavelength_nm: float = 550.0) -> list[str]:
    """Sentences on where ``panel`` leaves what the pipeline's n×n views assume: a depth
    step (:meth:`~lfjax.display.panel.Panel.depth_step_D`) beyond half the depth range (whole-pixel
    rendering cannot part neighbouring views across it), an emitter sweep beyond half a
    view (the pixel blur's single footprint does not hold) and a Fresnel number below 1
    (each view spreads over much of the pupil). Empty when none applies."""
    lo, hi = (float(v) for v in depth_range_D)
    notes = []
    step = float(panel.depth_step_D())
    if step > 0.5 * (hi - lo):
        notes.append(f"depth step {step:.3g} D exceeds half the depth range ({0.5 * (hi - lo):.3g} D): "
                     f"whole-pixel rendering parts neighbouring views by one pixel per {step:.3g} D, "
                     f"so depths within the range rely on spreading points over pixels")
    sweep = float(panel.emitter_sweep_mm()) / float(panel.view_diameter_mm)
    if sweep > 0.5:
        notes.append(f"one emitter sweeps its beam over {sweep:.3g} view widths at the eye: the "
                     f"pixel blur (one footprint per view) does not describe it (lfjax.studies.array_views)")
    fresnel = float(panel.fresnel_number(wavelength_nm))
    if fresnel < 1.0:
        notes.append(f"Fresnel number {fresnel:.3g} < 1: each view's beam spreads over much of the pupil")
    return notes



def report_counts_in_order(fits: list, report, report_counts: str = "chosen",
                           margin: float = SCREEN_MARGIN) -> None:
    """Score the fitted counts of ``fits`` (:class:`DesignFit`, neither refused nor scored
    yet) by calling ``report(fit)``, which fills its scores and verdict.

    ``report_counts="all"``: every one. ``"chosen"``: in order of training loss (a count
    without one first), until one passes (:attr:`DesignFit.ok`), then every later one whose
    training loss exceeds that count's by at most ``margin`` of its magnitude; the others
    are marked :attr:`DesignFit.unreported`. A count that fails its report does not stop
    the search: the next in order is reported."""
    fitted = [f for f in fits if f.panel is not None and f.refused is None]
    if report_counts == "all":
        order = fitted
    else:
        order = sorted(fitted, key=lambda f: -math.inf if f.training_loss is None else f.training_loss)
    leader = None  # the first count in that order to pass its report
    for fit in order:
        if fit.score is None:  # a count kept by an earlier call may be scored already
            loss, lead = fit.training_loss, None if leader is None else leader.training_loss
            if (report_counts == "chosen" and loss is not None and lead is not None
                    and loss > lead + margin * abs(lead)):
                fit.unreported = (
                    f"its training loss {loss:.4g} trails the {leader.n_per_side}x"
                    f"{leader.n_per_side}'s {lead:.4g} by more than {margin:.0%} "
                    f"(report_counts='all' scores it)")
                continue
            report(fit)
        if leader is None and fit.ok:
            leader = fit


