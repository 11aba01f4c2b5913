"""Design a light-field display a maker can build: fit a :class:`~lfjax.display.panel.Panel` to eyes.

Given a panel (its pixel pitch, count and emitters are kept), a viewing distance, a range of
depths to render and constraints, :func:`fit_design` fits, for each views-per-pupil count
n (the n×n views across the design pupil, :meth:`lfjax.display.panel.Panel.n_views_per_side`), the
continuous parameters of the lenslet array by gradient — the view pitch M·Δu (so the
lenslet pitch Δu), the lenslet fill, the gap z_0 (and with it the focal length that keeps
the CDP where it was asked) and, when a range is given, the viewing distance — with the
layout optimiser's objective (:func:`lfjax.layout_opt.layout_loss`, by default the
accommodation-aware one: image quality at each eye's own predicted accommodation, the
display's accommodation error bounded), the panel's lenslet diffraction and pixel blur in
the pipeline (:meth:`lfjax.display.panel.Panel.optics`), from the tangent array of
:func:`lfjax.display.lenslets.lenslets_for_layout` (:func:`start_box`). Each fit is then scored on
held-out eyes beside that starting array, with the perceivable resolution
(:func:`lfjax.vision.resolution.perceivable_cutoff_cpd`) at every eye's predicted accommodation, and
:func:`save_design` writes a buildable specification (JSON, every number with its unit)
and a drawing of the array and of the views in the pupil.

Feasible coordinates (every point of the box [0, 1]^k is a buildable panel, so L-BFGS-B
cannot leave the constraints):

* view pitch s = M·Δu in [D/(n + 1), D/n] (D the design pupil): n views fit across the
  pupil, none more (the top is the paper's tangent n×n grid); and Δu ≥ the pixel pitch;
* fill (aperture/pitch) in [``min_fill``, 1];
* gap z_0 up to the smaller of the slowest lenslet allowed (``max_f_number``) and the gap
  at which the eye box Δu·(1 + z_m/z_0) (:meth:`lfjax.display.panel.Panel.eye_box_mm`) shrinks to
  ``min_eye_box_mm``, and down to the larger of the fastest lenslet (``min_f_number``) and
  ``min_gap_fraction`` of that upper bound; the focal length follows from the gap and the
  CDP, 1/f = 1/z_0 − V. Without the eye-box bound a longer gap only shrinks the pixels'
  angle, so the fit would trade the viewing zone away unseen;
* the viewing distance in ``distance_range_mm`` (optional; below 1000/CDP mm).

The CDP is a design input (default the panel's own), not a fitted variable: it fixes where
the problem's accommodation window lies. It must lie within the depth range; otherwise the
design is refused before anything is traced. A fitted design whose views no longer form a
light field — their centres span less than half a view (one view: 1×1) or the predicted
accommodation follows the rendered depth with gain below 0.5
(:func:`lfjax.layout_opt.parallax_warning`) — is reported as refused, with the reason. A
fitted design that breaks a requirement on the report's eyes — the display's accommodation
RMSE above the objective's ``accommodation_tolerance_D``, or a score that is not finite — is
reported as failing it (:func:`design_failure`), by how much; neither is ever "ok" or chosen.
"""

from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass, field

import jax.numpy as jnp
import numpy as np

from lfjax.base.errors import ParameterError
from lfjax.base.types import finite_scalar
from lfjax.design.box import (
    design_problem,
    eye_chunk_size,
    panel_from_box,
    report_problem,
    start_box,
    with_display,
)
from lfjax.design.plan import SCREEN_MARGIN, CountPlan, DesignPlan, count_plan
from lfjax.design.report import (
    DesignFit,
    DesignResult,
    design_failure,
    design_notes,
    perceivable_resolution,
    summary_numbers,
)
from lfjax.design.resume import (
    COUNTS_FORMAT,
    count_key,
    fit_fields,
    fit_record,
    panel_leaves,
    panel_statics,
)
from lfjax.design.runner import DesignKind, run_counts
from lfjax.design.settings import (
    DesignConstraints,
    DesignTarget,
    FitSettings,
    ReportSettings,
    cdp_within,
)
from lfjax.design.solve import solve_box
from lfjax.display.panel import PRESETS, Panel
from lfjax.layout_opt import (
    Objective,
    check_depth_range,
    evaluate_layout,
    parallax_warning,
    planning_eyes,
)
from lfjax.model.eyes import Eyes
from lfjax.sweep.guard import REFINEMENT_STATES


def design_cdp_D(depth_range_D, cdp_D: float | None = None) -> float:
    """The CDP (D) of a design rendering depths in ``depth_range_D`` (low, high), D: ``cdp_D``
    when given, else the range's dioptric middle. A
    :class:`~lfjax.base.errors.ParameterError` names ``depth_range_D`` for a range that is
    not 0 ≤ low < high, and ``cdp_D`` for a CDP outside it: depths on one side of the CDP
    only would be rendered far from it, where the views' defocus and the sampling limit are
    worst."""
    lo, hi = check_depth_range(depth_range_D)
    if cdp_D is None:
        return 0.5 * (lo + hi)
    return cdp_within(finite_scalar("cdp_D", cdp_D, 0.0), lo, hi)


def design_panel(preset: str, cdp_D: float, *, distance_mm: float | None = None,
                 pixel_pitch_mm: float | None = None, pixel_count=None,
                 diffraction: str = "fresnel") -> Panel:
    """The starting panel of a design: the preset ``preset`` of
    :data:`lfjax.display.panel.PRESETS` (``"near-eye"``, ``"phone"``) with its CDP at
    ``cdp_D`` (D; :func:`design_cdp_D`) and, when given, another viewing distance (mm),
    pixel pitch (mm) or pixel count (horizontal, vertical); lenslet diffraction
    ``diffraction``. The panel's checks name the parameter
    (:class:`~lfjax.base.errors.ParameterError`)."""
    if preset not in PRESETS:
        raise ParameterError("preset", "{preset} must be one of {allowed}, got {got!r}",
                             allowed=", ".join(PRESETS), got=preset)
    panel = PRESETS[preset](cdp_D=cdp_D, **({} if distance_mm is None else {"distance_mm": distance_mm}))
    changes = {}
    if pixel_pitch_mm is not None:
        changes["pixel_pitch_mm"] = pixel_pitch_mm
    if pixel_count is not None:
        changes["pixel_count"] = tuple(pixel_count)
    return dataclasses.replace(panel, diffraction=diffraction, **changes)


def check_design(panel: Panel, target: DesignTarget):
    """:func:`fit_design`'s checks of its panel against its target, on the host and before
    anything is traced (the option objects check themselves when made). Returns
    (depths_D, cdp_D D, counts). A refused value is a
    :class:`~lfjax.base.errors.ParameterError` naming the parameter."""
    if not isinstance(panel, Panel):
        raise ParameterError("panel", "{panel} must be lfjax.display.panel.Panel, got {got}",
                             got=type(panel).__name__)
    if not isinstance(target, DesignTarget):
        raise ParameterError("target", "{target} must be lfjax.design.DesignTarget, got {got}",
                             got=type(target).__name__)
    return target.depths_D, target.cdp_for(panel), list(target.views_per_side)


def fit_design(panel: Panel, target: DesignTarget, train_eyes: Eyes, test_eyes: Eyes | None = None,
               *, constraints: DesignConstraints = DesignConstraints(),  # noqa: B008 (frozen)
               objective=None, fit: FitSettings = FitSettings(),  # noqa: B008 (frozen)
               report: ReportSettings = ReportSettings(),  # noqa: B008 (frozen)
               sampling=None, progress=False, counts_dir=None) -> DesignResult:
    """Fit ``panel``'s lenslet array to ``train_eyes`` for each views-per-pupil count.

    Parameters
    ----------
    panel : the starting panel: its pixel pitch, count and fill, design pupil, viewing
        distance (unless ``constraints.distance_range_mm``), aperture shape and
        diffraction mode are kept
    target : :class:`~lfjax.design.settings.DesignTarget`: the rendered depth range and
        depths, the CDP (default the panel's; within the depth range), the counts n to try
        (n×n views) and the fit's wavelengths
    train_eyes, test_eyes : the fit's population and the held-out one (None: report on
        the training eyes); :class:`lfjax.layout_opt.EyeDraw` draws both
    constraints : :class:`DesignConstraints`
    objective : the layout optimiser's objective (default the accommodation-aware one)
    fit : :class:`~lfjax.design.settings.FitSettings`: L-BFGS-B steps per count, its
        tolerance on the projected gradient, and the training eyes per chunk of the gradient
    report : :class:`~lfjax.design.settings.ReportSettings`: the held-out report's setting
        (``"fast"``: 11 wavelengths, peaks at the grid vertex; ``"full"``: 31 wavelengths,
        refined peaks; ``"fit"``: :func:`~lfjax.design.box.report_problem`) and which fitted
        counts it scores (``"chosen"``: in order of training loss until one passes, and those
        within :data:`SCREEN_MARGIN` of that one, the rest marked
        :attr:`DesignFit.unreported` — the chosen count is the same as with ``"all"``, every
        count, unless two counts' training losses lie within the margin and their held-out
        losses in the other order, and then both are reported)
    sampling : a :class:`~lfjax.base.sampling.Sampling` for both settings (default: planned by
        the layout optimiser's aliasing guard for the widest pixel blur of each count's box)
    progress : False, True (print) or a callable taking one line: the plan
        (:class:`lfjax.design.plan.DesignPlan`: each count's sampling, estimated time and
        memory) before any fit, then a line per solver step and per report
    counts_dir : a folder where each finished count is kept as it finishes
        (:mod:`lfjax.design.resume`); a count already kept there by a call with the same
        inputs is loaded instead of fitted again (None: nothing kept)

    Refuses (:func:`check_design` and the option objects: a
    :class:`~lfjax.base.errors.ParameterError` naming the parameter, before anything is
    traced) a CDP outside the depth range, counts outside 1 … 8 and wavelengths the model has
    no data for. Reported refused, with the reason, without fitting: a count no panel of
    these pixels can make, and 1×1 (one view: no light field); after fitting: a design whose
    accommodation does not follow the rendered depth (gain < 0.5) or whose eye box falls short.
    """
    depths, cdp, counts = check_design(panel, target)
    chunk = eye_chunk_size(train_eyes.n_eyes, fit.eye_chunk)
    say = progress if callable(progress) else (
        (lambda line: print(line, flush=True)) if progress else None)
    objective = Objective.parse(objective) if objective is not None else Objective()
    kind = LensletKind(panel, target, cdp, constraints, objective, fit, report, sampling,
                       train_eyes, test_eyes, chunk)
    fits = run_counts(kind, counts, counts_dir, say)
    provenance = {"n_train_eyes": train_eyes.n_eyes,
                  "n_test_eyes": 0 if test_eyes is None else test_eyes.n_eyes,
                  "wavelengths_nm": list(target.wavelengths_nm), "steps": fit.steps,
                  "report_accuracy": report.accuracy, "report_counts": report.counts,
                  "eye_chunk": chunk,
                  "freq_step_cpd": None if sampling is None else float(sampling.freq_step_cpd)}
    return DesignResult(fits, cdp, depths.tolist(), constraints, objective, provenance)


ONE_LENSLET_VIEW = ("the views have collapsed into one aperture: 1x1 puts a single view in the "
                    "pupil, so the rendered depth moves nothing on the retina and the eye focuses "
                    "on the CDP (choose views_per_side >= 2)")
"""Why an n×n design refuses 1×1 (:func:`lfjax.design.runner.count_refusal`)."""


@dataclass
class LensletKind(DesignKind):
    """The n×n lenslet design as a kind of :func:`lfjax.design.runner.run_counts`: each count's
    lenslets fitted by L-BFGS-B (:func:`fit_count`) after the plan of every count's problems
    (:class:`lfjax.design.plan.DesignPlan`), then reported on the held-out eyes
    (:func:`report_count`) in order of training loss (``report.counts``). The fields are
    :func:`fit_design`'s (``cdp_D``: the design's CDP, D; ``chunk``: the training eyes per
    chunk of the gradient)."""

    panel: Panel
    target: DesignTarget
    cdp_D: float
    constraints: DesignConstraints
    objective: Objective
    fit: FitSettings
    report_settings: ReportSettings
    sampling: object
    train_eyes: Eyes
    test_eyes: Eyes | None
    chunk: int
    problems: dict = field(default_factory=dict)
    """{n: (fit problem, report problem)} of the counts planned or reported."""

    counts_format = COUNTS_FORMAT
    counts_stem = "count"
    one_view = ONE_LENSLET_VIEW

    @property
    def report_counts(self) -> str:
        return self.report_settings.counts

    @property
    def report_eyes(self) -> Eyes:
        return self.test_eyes if self.test_eyes is not None else self.train_eyes

    def key(self, n: int) -> str:
        return count_key(self.panel, n, self.target, self.cdp_D, self.constraints, self.objective,
                         self.fit, self.report_settings, self.sampling, self.train_eyes, self.test_eyes)

    def record(self, fit: DesignFit) -> dict:
        return fit_record(fit)

    def from_record(self, record: dict) -> DesignFit:
        return DesignFit(**fit_fields(record))

    def refused(self, n: int, why: str) -> DesignFit:
        return DesignFit(n, refused=why)

    def prepare(self, n: int):
        """Count ``n``'s fit problem and its report's (their sampling planned), kept."""
        if n not in self.problems:
            problem = design_problem(self.panel, n, self.train_eyes, self.target.depths_D, self.cdp_D,
                                     self.constraints, self.objective, self.target.wavelengths_nm,
                                     "fit", planning_eyes(self.train_eyes, self.test_eyes),
                                     self.sampling)
            accuracy = self.report_settings.accuracy
            self.problems[n] = problem, (
                problem if accuracy == "fit" and self.test_eyes is None else
                report_problem(problem, self.report_eyes, accuracy, self.sampling))
        return self.problems[n]

    def plan(self, counts: list, kept: set, refusals: dict, counts_dir, say) -> None:
        # every count's problems (their sampling) and what they will cost, before the first
        # fit, so that a run too long or too large is seen at once
        t_plan = time.perf_counter()
        plan = DesignPlan(train_eyes=self.train_eyes.n_eyes, report_eyes=self.report_eyes.n_eyes,
                          eye_chunk=self.chunk, steps=self.fit.steps,
                          report_accuracy=self.report_settings.accuracy,
                          report_counts=self.report_settings.counts)
        for n in counts:
            if n in kept:
                plan.counts.append(CountPlan(n, resumed=f"fitted earlier, kept in {counts_dir}"))
            elif n in refusals:
                plan.counts.append(CountPlan(n, refused=refusals[n]))
            else:
                problem, report_p = self.prepare(n)
                plan.counts.append(count_plan(n, problem, report_p, self.train_eyes.n_eyes,
                                              self.report_eyes.n_eyes, self.fit.steps, self.chunk,
                                              REFINEMENT_STATES.get(report_p.peak_method, 0)))
        if say is not None:
            say(plan.summary() + f"\n  (planned in {time.perf_counter() - t_plan:.0f} s)")

    def make(self, n: int, say) -> DesignFit:
        return fit_count(self.panel, n, self.prepare(n)[0], self.constraints, self.fit,
                         None if self.fit.eye_chunk is None else self.chunk,
                         self.target.depth_range_D, say)

    def report(self, fit: DesignFit, n: int, say) -> None:
        # a count kept by an earlier call before its report has no problems yet
        report_count(fit, self.prepare(n)[1], self.constraints, self.objective,
                     self.test_eyes is not None, say)


def fit_count(panel: Panel, n: int, problem, constraints: DesignConstraints, fit: FitSettings,
              solver_chunk: int | None, depth_range_D, say=None) -> DesignFit:
    """One count's fit on its training ``problem``: L-BFGS-B from the tangent start
    (:func:`~lfjax.design.solve.solve_box`), the fitted and starting panels on the host, and
    its verdict from the views' geometry and the eye box alone (the report adds the rest)."""
    cdp = float(problem.cdp_D)
    t0 = time.perf_counter()
    tell = None if say is None else (lambda line: say(f"design {n}x{n}: {line}"))
    x0 = jnp.asarray(start_box(panel, n, cdp, constraints), jnp.result_type(float))
    x, history = solve_box(x0, problem, panel, n, constraints, fit.steps, fit.tol, solver_chunk, tell)
    fitted = panel_from_box(np.asarray(x), panel, n, cdp, constraints)
    start = panel_from_box(np.asarray(x0), panel, n, cdp, constraints)
    out = DesignFit(n, host_panel(fitted), host_panel(start), history=history)
    out.refused = parallax_warning(out.panel.layout(n))  # the views' geometry alone
    if out.refused is None and float(out.panel.eye_box_mm()) < constraints.min_eye_box_mm * (1 - 1e-3):
        out.refused = (f"the eye box {float(out.panel.eye_box_mm()):.3g} mm is below min_eye_box_mm = "
                       f"{constraints.min_eye_box_mm:g} mm even at the fastest lenslets")
    out.notes = design_notes(out.panel, depth_range_D)
    out.time_s = time.perf_counter() - t0
    if tell is not None:
        tell(f"fitted in {out.time_s:.1f} s" + ("" if out.training_loss is None else
                                                f", training loss {out.training_loss:.5f}"))
    return out


def report_count(one: DesignFit, problem, constraints: DesignConstraints, objective: Objective,
                 held_out: bool, say=None) -> None:
    """The report of a fitted count on its report ``problem`` (held-out eyes when
    ``held_out``): its fitted and starting panels scored, its verdict completed."""
    n = one.n_per_side
    t0 = time.perf_counter()
    tell = None if say is None else (lambda line: say(f"design {n}x{n}: {line}"))
    scores = {}
    for key, candidate in (("fit", one.panel), ("start", one.start)):
        t1 = time.perf_counter()
        evaluation = evaluate_layout(candidate.layout(n), with_display(problem, candidate, constraints))
        res = perceivable_resolution(candidate, n, problem, evaluation["values"]["peak_D"], constraints)
        scores[key] = (summary_numbers(evaluation, res), evaluation)
        if tell is not None:
            tell(f"report of the {'fitted' if key == 'fit' else 'starting'} panel on "
                 f"{problem.eyes.n_eyes} eyes: {time.perf_counter() - t1:.0f} s")
    if held_out:
        one.test = scores["fit"][0]
    else:
        one.train = scores["fit"][0]
    one.start_test = scores["start"][0]
    one.refused = parallax_warning(one.panel.layout(n), scores["fit"][1])
    if one.refused is None:
        one.failed = design_failure(one.score, objective, "held-out" if held_out else "training")
    one.unreported = None
    one.time_s += time.perf_counter() - t0
    if tell is not None:
        tell(f"done in {one.time_s:.1f} s")


def host_panel(panel: Panel) -> Panel:
    """``panel`` with host floats for its numbers (a fitted panel's leaves are device arrays)."""
    return Panel(*panel_leaves(panel), **dict(panel_statics(panel), pixel_count=panel.pixel_count))


__all__ = ["SCREEN_MARGIN", "ONE_LENSLET_VIEW", "LensletKind", "design_cdp_D", "design_panel",
           "check_design", "fit_design", "fit_count", "report_count", "host_panel"]
