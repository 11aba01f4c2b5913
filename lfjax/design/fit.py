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
import datetime
import json
import itertools
import math
import time
from dataclasses import dataclass, field
from pathlib import Path

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from lfjax._version import __version__
from lfjax.display.aberrations import LENS_FORMS, panel_aberration
from lfjax.display.lenslets import DisplayOptics, lenslets_for_layout
from lfjax.model.eyes import Eyes
from lfjax.base.errors import ParameterError
from lfjax.base.types import finite_scalar
from lfjax.layout_opt import (
    Constraints,
    Objective,
    check_depth_range,
    depth_grid,
    combine,
    evaluate_layout,
    layout_loss,
    make_problem,
    objective_terms,
    parallax_warning,
)
from lfjax.model.options import ModelOptions
from lfjax.model.layout_files import jsonable
from lfjax.base.files import atomic_write_text, staged_output
from lfjax.design.plan import SCREEN_MARGIN, CountPlan, DesignPlan, count_plan
from lfjax.design.resume import count_key, load_count, save_count
from lfjax.sweep.guard import REFINEMENT_STATES
from lfjax.model.layout_plots import draw_layout
from lfjax.display.panel import PRESETS, Panel
from lfjax.model.spectral import make_spectrum
from lfjax.vision.resolution import perceivable_cutoff_cpd
from lfjax.kernel.pipeline import retinal_metrics
from lfjax.kernel.scene import Accommodation

DESIGN_FORMAT = "lfjax-design/1"


@dataclass(frozen=True)
class DesignConstraints:
    """What a buildable design must satisfy (host numbers; lengths in mm).

    Attributes
    ----------
    min_eye_box_mm : the viewing zone Δu·(1 + z_m/z_0) must be at least this wide, mm
        (default 10: a 3 mm pupil and the eye's movement in a near-eye display)
    min_fill : smallest lenslet fill (aperture/pitch), in (0, 1] (default 0.5)
    min_f_number, max_f_number : the lenslets' focal length over aperture (default 1 … 8)
    distance_range_mm : (low, high) to fit the viewing distance too, mm; None (default)
        keeps the panel's
    lens_form : None (default: aberration-free lenslets, the designs as before) or the
        lenslets' form (:data:`lfjax.display.aberrations.LENS_FORMS`): each view then carries
        its lenslet's on-axis spherical aberration, which grows as a⁴/f³, so the fit weighs
        fast, wide lenslets against their aberration
    refractive_index : the lenslets' refractive index, in (1, 4] (default 1.5; with ``lens_form``)
    min_gap_fraction : the gap's lower bound as a fraction of its upper bound, in (0, 1]
        (default 0.75; the fastest f-number still applies). At a fixed CDP and distance the
        gap changes nothing but the pixels' angle p/(z_0·M), which a shorter gap only
        widens; the bound keeps the widest pixel blur of the box — what the sampling is
        planned for — within 4/3 of the narrowest at the same lenslets
    """

    min_eye_box_mm: float = 10.0
    min_fill: float = 0.5
    min_f_number: float = 1.0
    max_f_number: float = 8.0
    distance_range_mm: tuple | None = None
    min_gap_fraction: float = 0.75
    lens_form: str | None = None
    refractive_index: float = 1.5

    def __post_init__(self):
        finite_scalar("min_gap_fraction", self.min_gap_fraction, 0.0, 1.0, lo_open=True)
        if self.lens_form is not None and self.lens_form not in LENS_FORMS:
            raise ParameterError("lens_form", "{lens_form} must be one of {allowed} or None "
                                 "(aberration-free lenslets), got {got!r}",
                                 allowed=", ".join(LENS_FORMS), got=self.lens_form)
        finite_scalar("refractive_index", self.refractive_index, 1.0, 4.0, lo_open=True)
        finite_scalar("min_eye_box_mm", self.min_eye_box_mm, 0.0, lo_open=True)
        finite_scalar("min_fill", self.min_fill, 0.0, 1.0, lo_open=True)
        # the two ends of one range (one flag, --f-number LO HI): each says which end it is
        lo = finite_scalar("low end", self.min_f_number, 0.0, lo_open=True,
                           parameter="min_f_number")
        finite_scalar("high end (at least the low end)", self.max_f_number, lo,
                      parameter="max_f_number")
        if self.distance_range_mm is not None:
            a, b = (float(v) for v in self.distance_range_mm)
            finite_scalar("low end", a, 0.0, lo_open=True, parameter="distance_range_mm")
            finite_scalar("high end", b, a, parameter="distance_range_mm")
            object.__setattr__(self, "distance_range_mm", (a, b))

    def as_dict(self) -> dict:
        return dataclasses.asdict(self)


# ----------------------------------------------------------------------------- feasible map


def view_pitch_range_mm(n_per_side: int, pupil_diameter_mm: float) -> tuple[float, float]:
    """[D/(n + 1), D/n] (mm, the low end 0.1 % inside): n views fit across the pupil."""
    n = int(n_per_side)
    return pupil_diameter_mm / (n + 1) * 1.001, pupil_diameter_mm / n


def panel_from_box(x, template: Panel, n_per_side: int, cdp_D: float,
                   constraints: DesignConstraints) -> Panel:
    """The panel at box coordinates ``x`` ((3,) or (4,) in [0, 1]: view pitch, fill, gap,
    [distance]) for n views per side and the CDP at ``cdp_D`` (D); pixel pitch, count and
    fill, pupil, aperture and diffraction from ``template``. Differentiable in ``x``."""
    x = jnp.clip(jnp.asarray(x), 0.0, 1.0)
    if constraints.distance_range_mm is None:
        zm = template.distance_mm
    else:
        lo, hi = constraints.distance_range_mm
        zm = lo + x[3] * (hi - lo)
    inv_l = cdp_D / 1000.0
    vergence = inv_l / (1.0 - zm * inv_l)
    magnification = 1.0 + zm * vergence
    s_lo, s_hi = view_pitch_range_mm(n_per_side, template.pupil_diameter_mm)
    s_lo = jnp.maximum(s_lo, template.pixel_pitch_mm * magnification)  # a lenslet ≥ a pixel
    pitch = (s_lo + x[0] * (s_hi - s_lo)) / magnification
    fill = constraints.min_fill + x[1] * (1.0 - constraints.min_fill)
    aperture = fill * pitch
    gap_fast = 1.0 / (vergence + 1.0 / (constraints.min_f_number * aperture))
    gap_slow = 1.0 / (vergence + 1.0 / (constraints.max_f_number * aperture))
    gap_eye = zm * pitch / jnp.maximum(constraints.min_eye_box_mm - pitch, 1e-9)
    gap_hi = jnp.maximum(jnp.minimum(gap_slow, gap_eye), gap_fast)
    gap_lo = jnp.maximum(gap_fast, constraints.min_gap_fraction * gap_hi)
    gap = gap_lo + x[2] * (gap_hi - gap_lo)
    focal = 1.0 / (1.0 / gap - vergence)
    return Panel(template.pixel_pitch_mm, pitch, fill, focal, gap, zm, template.pixel_fill,
                 template.pixel_count, template.pupil_diameter_mm, template.aperture,
                 template.diffraction, f"{template.name} {n_per_side}x{n_per_side}")


def feasibility(template: Panel, n_per_side: int, cdp_D: float,
                constraints: DesignConstraints) -> str | None:
    """Why no panel of ``template``'s pixels makes n×n views (a sentence), or None."""
    zms = ([float(template.distance_mm)] if constraints.distance_range_mm is None
           else list(constraints.distance_range_mm))
    p = float(template.pixel_pitch_mm)
    reasons = []
    for zm in zms:
        if cdp_D * zm >= 1000.0:
            reasons.append(f"at {zm:g} mm the CDP {cdp_D:g} D would lie in front of the display "
                           f"(need distance < {1000.0 / cdp_D:.4g} mm)")
            continue
        m = 1.0 / (1.0 - zm * cdp_D / 1000.0)
        s_hi = view_pitch_range_mm(n_per_side, template.pupil_diameter_mm)[1]
        if s_hi / m < p:
            reasons.append(f"at {zm:g} mm, {n_per_side}x{n_per_side} views need lenslets of at most "
                           f"{s_hi / m:.4g} mm, smaller than a pixel ({p:g} mm)")
            continue
        return None
    return "; ".join(reasons)


def start_box(template: Panel, n_per_side: int, cdp_D: float, constraints: DesignConstraints,
              f_number: float = 3.0) -> np.ndarray:
    """Box coordinates of the starting design: the tangent array of
    :func:`lfjax.display.lenslets.lenslets_for_layout` (view pitch D/n, full fill, f-number
    ``f_number``) at the middle of the distance range (or the panel's distance), its gap
    moved into the box when the eye box or the f-number range excludes it."""
    x = [1.0, 1.0, 0.0] + ([0.5] if constraints.distance_range_mm is not None else [])
    x = np.asarray(x)
    lo = panel_from_box(x, template, n_per_side, cdp_D, constraints)
    hi = panel_from_box(np.where(np.arange(x.size) == 2, 1.0, x), template, n_per_side, cdp_D,
                        constraints)
    zm = float(lo.distance_mm)
    tangent = lenslets_for_layout(n_per_side, template.pupil_diameter_mm, cdp_D, zm, fill=1.0,
                                  f_number=f_number)
    g_lo, g_hi = float(lo.gap_mm), float(hi.gap_mm)
    x[2] = 1.0 if g_hi <= g_lo else float(np.clip((float(tangent.gap_mm) - g_lo) / (g_hi - g_lo), 0.0, 1.0))
    return x


# ----------------------------------------------------------------------------- problem


def _panel_optics(panel: Panel, constraints: DesignConstraints | None):
    """The panel's optics, with its lenslets' on-axis aberration when ``constraints`` names a
    lens form (:func:`lfjax.display.aberrations.panel_aberration`, differentiable in the panel)."""
    optics = panel.optics()
    if constraints is None or constraints.lens_form is None:
        return optics
    return optics.with_aberration(panel_aberration(panel, refractive_index=constraints.refractive_index,
                                                   lens_form=constraints.lens_form))


def _with_display(problem, panel: Panel, constraints: DesignConstraints | None = None):
    return eqx.tree_at(lambda p: p.display, problem, _panel_optics(panel, constraints))


def design_loss(x, problem, template: Panel, n_per_side: int, constraints: DesignConstraints):
    """The layout optimiser's loss (:func:`lfjax.layout_opt.layout_loss`) of the panel at
    box coordinates ``x``: its n×n views as the layout, its lenslet diffraction and pixel
    blur as the problem's display. Scalar, differentiable in ``x``."""
    panel = panel_from_box(x, template, n_per_side, problem.cdp_D, constraints)
    return layout_loss(panel.layout(n_per_side), _with_display(problem, panel, constraints))


_value_and_grad = eqx.filter_jit(jax.value_and_grad(design_loss))


def eye_chunk_size(n_eyes: int, eye_chunk: int | None) -> int:
    """Eyes per chunk of :func:`design_loss_chunked`: the largest divisor of ``n_eyes`` not
    above ``eye_chunk`` (None: all of them), so that every chunk has one shape and the
    chunks' means average to the population's exactly."""
    n = int(n_eyes)
    if eye_chunk is None:
        return n
    if isinstance(eye_chunk, bool) or int(eye_chunk) != eye_chunk or eye_chunk < 1:
        raise ParameterError("eye_chunk", "{eye_chunk} must be an integer >= 1 or None, got {got!r}",
                             got=eye_chunk)
    return max(c for c in range(1, min(int(eye_chunk), n) + 1) if n % c == 0)


def design_loss_chunked(x, problem, template: Panel, n_per_side: int,
                        constraints: DesignConstraints, eye_chunk: int | None = 1):
    """:func:`design_loss` with the training eyes taken ``eye_chunk`` at a time
    (:func:`eye_chunk_size`), each chunk under ``jax.checkpoint``: the same scalar (to the
    float summation order), whose reverse pass keeps one chunk's intermediates at a time
    instead of every eye's, at the price of one more forward evaluation.

    Every objective term is a mean over (eye, depth) with the same depths for every eye,
    so the population's mean is the mean of equal chunks' means; the loss then combines
    the population's terms (:func:`lfjax.layout_opt.combine`), so the accommodation
    penalty — a function of the population's RMSE, not a sum over eyes — is applied once,
    as in :func:`design_loss`, and its chain rule runs through the mean."""
    z = problem.eyes.zernike_um
    chunk = eye_chunk_size(z.shape[0], eye_chunk)

    @jax.checkpoint
    def chunk_terms(x_, zernike_um):
        # x enters explicitly (not closed over) so that the reverse pass recomputes the
        # chunk's panel and pipeline from it
        p = panel_from_box(x_, template, n_per_side, problem.cdp_D, constraints)
        sub = eqx.tree_at(lambda q: q.eyes.zernike_um, _with_display(problem, p, constraints), zernike_um)
        return objective_terms(p.layout(n_per_side), sub)

    per_chunk = jax.lax.map(lambda zc: chunk_terms(x, zc), z.reshape(-1, chunk, z.shape[-1]))
    terms = {k: jnp.mean(v) for k, v in per_chunk.items()}
    loss = combine(terms, problem.objective)
    return eqx.error_if(loss, ~jnp.isfinite(loss), "layout objective is not finite (NaN or inf)")


_chunked_value_and_grad = eqx.filter_jit(jax.value_and_grad(design_loss_chunked))


def _worst_optics(template: Panel, n_per_side: int, cdp_D: float,
                  constraints: DesignConstraints) -> DisplayOptics:
    """The display the sampling is planned for: the widest pixel blur over the box (the
    fastest gap at the smallest lenslets) and the shortest Fresnel distance."""
    candidates = []
    for corner in ([0.0, 0.0, 0.0], [0.0, 1.0, 0.0]):
        for d in ([] if constraints.distance_range_mm is None else [[0.0], [1.0]]) or [[]]:
            panel = panel_from_box(np.asarray(corner + d), template, n_per_side, cdp_D, constraints)
            candidates.append(panel.optics())
    width = max(float(c.pixel_width_arcmin) for c in candidates)
    distance = min(float(c.fresnel_distance_mm) for c in candidates)
    worst = DisplayOptics(template.diffraction, template.aperture, distance, width)
    if constraints.lens_form is None:
        return worst
    # the widest aberrated rays of the box (host, over all its corners): the field guard's
    # sampling must hold them
    n_box = 3 if constraints.distance_range_mm is None else 4
    slopes = []
    for corner in itertools.product((0.0, 1.0), repeat=n_box):
        panel = panel_from_box(np.asarray(corner), template, n_per_side, cdp_D, constraints)
        optics = _panel_optics(panel, constraints)
        slopes.append((optics.aberration_slope_rad(panel.layout(n_per_side).diameters_mm), optics.aberration))
    return worst.with_aberration(max(slopes, key=lambda t: t[0])[1])


def design_problem(template: Panel, n_per_side: int, eyes: Eyes, depths_D, cdp_D: float,
                   constraints: DesignConstraints, objective=None, wavelengths_nm=(550.0,),
                   accuracy: str = "fit", planning_eyes: Eyes | None = None, sampling=None):
    """The layout problem (:func:`lfjax.layout_opt.make_problem`) a design of n×n views is
    fitted on: the design pupil, view diameters within the box's range, the sampling
    planned for the widest pixel blur the box allows (or ``sampling``, a
    :class:`~lfjax.base.sampling.Sampling`, when given)."""
    pupil = template.pupil_diameter_mm
    s_lo, s_hi = view_pitch_range_mm(n_per_side, pupil)
    layout_constraints = Constraints(pupil_diameter_mm=pupil, max_diameter_mm=min(s_hi, pupil),
                                     min_diameter_mm=min(constraints.min_fill * s_lo, s_hi))
    return make_problem(eyes, depths_D, layout_constraints,
                        Objective() if objective is None else objective, cdp_D=cdp_D,
                        wavelengths_nm=wavelengths_nm, accuracy=accuracy,
                        options=ModelOptions(vsotf_reference="open_pupil"),
                        display=_worst_optics(template, n_per_side, cdp_D, constraints),
                        planning_eyes=planning_eyes, sampling=sampling)


REPORT_ACCURACIES = ("fast", "full", "fit")
"""Settings of the held-out report: ``"fast"`` (default) — :data:`FAST_REPORT_WAVELENGTHS_NM`,
the full setting's peak window, each peak at the grid parabola's vertex (no states beyond
the grid); ``"full"`` — :func:`lfjax.layout_opt.make_problem`'s full setting (31
wavelengths, peaks refined by ``local``); ``"fit"`` — the fit's own setting (its
wavelengths, 550 nm by default). RESULTS §21 compares "fast" with "full" on the presets."""

FAST_REPORT_WAVELENGTHS_NM = tuple(float(w) for w in np.arange(400.0, 701.0, 30.0))
"""The fast report's spectrum: 400–700 nm in 30 nm steps (11 wavelengths), V(λ)-weighted."""

REPORT_COUNTS = ("chosen", "all")
"""Which counts the held-out report scores: ``"chosen"`` (default) — the count with the lowest
training loss among those that pass the report, and any count whose training loss lies within
:data:`SCREEN_MARGIN` of it; ``"all"`` — every fitted count."""



def report_problem(problem, eyes: Eyes, report_accuracy: str = "fast", sampling=None):
    """The problem the held-out report evaluates: ``problem``'s scene (its display, the
    box's widest pixel blur) on ``eyes`` at the setting ``report_accuracy``
    (:data:`REPORT_ACCURACIES`), its sampling planned anew unless ``sampling`` is given."""
    if report_accuracy not in REPORT_ACCURACIES:
        raise ParameterError("report_accuracy", "{report_accuracy} must be one of {allowed}, got {got!r}",
                             allowed=", ".join(REPORT_ACCURACIES), got=report_accuracy)
    if report_accuracy != "fast":
        return problem.at_accuracy(report_accuracy, eyes=eyes, sampling=sampling)
    return make_problem(eyes, np.asarray(problem.depths_D, float), problem.constraints,
                        problem.objective, cdp_D=float(problem.cdp_D), options=problem.options,
                        window_D=problem.window_D,
                        spectrum=make_spectrum(np.asarray(FAST_REPORT_WAVELENGTHS_NM), problem.options),
                        display=problem.display, accuracy="full", peak_method="vertex",
                        sampling=sampling)


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
    problem = _with_display(problem, panel, constraints)
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


def _summary_numbers(evaluation: dict, resolution: np.ndarray) -> dict:
    keys = ("image_at_peak", "relative_accommodation_rmse_D", "accommodation_rmse_D",
            "accommodation_gain", "peak_success_fraction", "loss", "penalty", "n_eyes")
    out = {k: evaluation[k] for k in keys}
    out["perceivable_cpd_median"] = float(np.median(resolution))
    out["perceivable_cpd_p05"], out["perceivable_cpd_p95"] = (float(v) for v in np.percentile(resolution, [5, 95]))
    out["perceivable_cpd_by_depth"] = np.median(resolution, axis=0).tolist()
    return out


class CountVerdict:
    """The verdict of one count's design, from its ``refused``, ``failed`` and ``score``
    fields (shared by :class:`DesignFit` and the lenticular design's count)."""

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


FLAT_STEP = 1e-6
"""L-BFGS-B's ``ftol`` in the design fit: it stops after a step that lowers the loss by less
than this fraction of max(|loss|, 1), about eight float32 roundings of the loss — a change
the float32 loss cannot resolve. SciPy's default (2.2e-9) lies below that resolution: on
the phone preset's flat accommodation-penalty plateau (loss 97.66) a 1e-7 step was followed
by a second step whose line search spent 785 s on 10 eyes (RESULTS §36)."""


def _solve(x0, problem, template, n, constraints, steps: int, tol: float,
           eye_chunk: int | None = 1, say=None):
    """L-BFGS-B (SciPy's, on the host) in the box [0, 1]^k around the compiled loss and
    gradient (:func:`design_loss_chunked`, ``eye_chunk`` eyes at a time): at most ``steps``
    iterations, stopping when the projected gradient is below ``tol`` or a step lowers the
    loss by less than :data:`FLAT_STEP` of its magnitude. ``say`` (a
    callable, or None) receives a line per iteration. Returns (x, loss history: the
    start, then each iteration's)."""
    from scipy.optimize import minimize

    x = np.asarray(x0, float)
    if steps == 0:
        return jnp.asarray(x0), []
    dtype = jnp.asarray(x0).dtype

    seen = {}  # the callback asks again for the point the solver just evaluated

    def fun(x):
        key = np.asarray(x, float).tobytes()
        if key not in seen:
            if eye_chunk is None:  # all at once: no checkpoint, no recomputation
                value, grad = _value_and_grad(jnp.asarray(x, dtype), problem, template, n, constraints)
            else:
                value, grad = _chunked_value_and_grad(jnp.asarray(x, dtype), problem, template, n,
                                                      constraints, eye_chunk)
            value = float(value)
            if not math.isfinite(value):
                raise FloatingPointError("the design loss is not finite")
            seen.clear()
            seen[key] = (value, np.asarray(grad, float))
        return seen[key]

    t0 = time.perf_counter()
    history = [fun(x)[0]]

    def step(xk):
        history.append(fun(xk)[0])
        if say is not None:
            say(f"step {len(history) - 1}/{steps}: loss {history[-1]:.5f} "
                f"({time.perf_counter() - t0:.0f} s)")

    if say is not None:
        say(f"start: loss {history[0]:.5f} ({time.perf_counter() - t0:.0f} s, with compilation)")
    result = minimize(fun, x, jac=True, method="L-BFGS-B", bounds=[(0.0, 1.0)] * x.size,
                      callback=step, options=dict(maxiter=steps, gtol=tol, ftol=FLAT_STEP))
    return jnp.asarray(result.x, dtype), history


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
    return _cdp_within(finite_scalar("cdp_D", cdp_D, 0.0), lo, hi)


def _cdp_within(cdp: float, lo: float, hi: float) -> float:
    if not (lo - 1e-6 <= cdp <= hi + 1e-6):
        raise ParameterError(
            "cdp_D", "{cdp_D} = {cdp:.4g} D lies outside the depth range [{lo:g}, {hi:g}] D: depths on "
            "one side of the CDP only would be rendered far from it, where the views' defocus and "
            "the sampling limit are worst; choose {cdp_D} within the range (e.g. its dioptric "
            "middle, {middle:g} D) or widen the range", cdp=cdp, lo=lo, hi=hi, middle=0.5 * (lo + hi))
    return cdp


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


def check_design(panel: Panel, depth_range_D, n_depths: int = 3, cdp_D: float | None = None,
                 views_per_side=(1, 2, 3, 4), wavelengths_nm=(550.0,), steps: int = 10,
                 report_accuracy: str = "fast", report_counts: str = "chosen"):
    """:func:`fit_design`'s checks of its arguments (of the same names), on the host and
    before anything is traced; :func:`fit_design` makes them first. Returns (depths_D,
    cdp_D, counts). A refused value is a :class:`~lfjax.base.errors.ParameterError` naming
    the parameter."""
    if not isinstance(panel, Panel):
        raise ParameterError("panel", "{panel} must be lfjax.display.panel.Panel, got {got}",
                             got=type(panel).__name__)
    if report_accuracy not in REPORT_ACCURACIES:
        raise ParameterError("report_accuracy", "{report_accuracy} must be one of {allowed}, got {got!r}",
                             allowed=", ".join(REPORT_ACCURACIES), got=report_accuracy)
    if report_counts not in REPORT_COUNTS:
        raise ParameterError("report_counts", "{report_counts} must be one of {allowed}, got {got!r}",
                             allowed=", ".join(REPORT_COUNTS), got=report_counts)
    lo, hi = check_depth_range(depth_range_D, allow_empty=True)
    depths = depth_grid(lo, hi, n_depths)
    cdp = _cdp_within(float(panel.cdp_D) if cdp_D is None else finite_scalar("cdp_D", cdp_D, 0.0),
                      lo, hi)
    counts = [int(n) for n in views_per_side]
    if not counts or any(n != v or not 1 <= n <= 8 for n, v in zip(counts, views_per_side)):
        raise ParameterError("views_per_side", "{views_per_side} must be integers in [1, 8], got {got}",
                             got=list(views_per_side))
    if isinstance(steps, bool) or int(steps) != steps or steps < 0:
        raise ParameterError("steps", "{steps} must be an integer >= 0, got {got!r}", got=steps)
    make_spectrum(np.atleast_1d(np.asarray(wavelengths_nm, float)),
                  ModelOptions(vsotf_reference="open_pupil"))  # checks them
    return depths, cdp, counts


def fit_design(panel: Panel, *, depth_range_D, train_eyes: Eyes, test_eyes: Eyes | None = None,
               n_depths: int = 3, cdp_D: float | None = None, views_per_side=(1, 2, 3, 4),
               constraints: DesignConstraints = DesignConstraints(), objective=None,  # noqa: B008
               wavelengths_nm=(550.0,), steps: int = 10, tol: float = 1e-4,
               report_accuracy: str = "fast", report_counts: str = "chosen", sampling=None,
               progress=False, eye_chunk: int | None = 1, counts_dir=None) -> DesignResult:
    """Fit ``panel``'s lenslet array to ``train_eyes`` for each views-per-pupil count.

    Parameters
    ----------
    panel : the starting panel: its pixel pitch, count and fill, design pupil, viewing
        distance (unless ``constraints.distance_range_mm``), aperture shape and
        diffraction mode are kept
    depth_range_D : (low, high) rendered depths, D; ``n_depths`` evenly spaced
    train_eyes, test_eyes : the fit's population and the held-out one (None: report on
        the training eyes)
    cdp_D : the CDP, D (default the panel's); must lie in the depth range
    views_per_side : the counts n to try (n×n views)
    constraints : :class:`DesignConstraints`
    objective : the layout optimiser's objective (default the accommodation-aware one)
    wavelengths_nm : the fit's spectrum (V(λ)-weighted), nm
    steps, tol : L-BFGS-B steps per count and its tolerance on the projected gradient
    report_accuracy : the held-out report's setting, one of :data:`REPORT_ACCURACIES`:
        ``"fast"`` (default; 11 wavelengths, peaks at the grid vertex), ``"full"`` (31
        wavelengths, refined peaks) or ``"fit"`` (:func:`report_problem`)
    report_counts : which fitted counts the report scores, one of :data:`REPORT_COUNTS`:
        ``"chosen"`` (default) — in order of training loss until one passes (neither
        refused nor failing a requirement), and those within :data:`SCREEN_MARGIN` of that
        one; the rest are kept fitted, marked :attr:`DesignFit.unreported`. ``"all"`` —
        every count. The chosen count is the same either way unless two counts' training
        losses lie within the margin and their held-out losses in the other order — and
        then both are reported, so it is the same.
    sampling : a :class:`~lfjax.base.sampling.Sampling` for both settings (default: planned by
        the layout optimiser's aliasing guard for the widest pixel blur of each count's box)
    progress : False, True (print) or a callable taking one line: the plan
        (:class:`lfjax.design.plan.DesignPlan`: each count's sampling, estimated time and
        memory) before any fit, then a line per solver step and per report
    eye_chunk : training eyes per chunk of the gradient (:func:`design_loss_chunked`;
        default 1: the reverse pass holds one eye's intermediates; None: all at once,
        :func:`design_loss` without checkpoints, one forward evaluation less per step)
    counts_dir : a folder where each finished count is kept as it finishes
        (:mod:`lfjax.design.resume`); a count already kept there by a call with the same
        inputs is loaded instead of fitted again (None: nothing kept)

    Refuses (:func:`check_design`: a :class:`~lfjax.base.errors.ParameterError` naming the
    parameter, before anything is traced) a CDP outside the depth range, counts outside
    1 … 8 and wavelengths the model has no data for. Reported refused, with the reason, without fitting: a count no
    panel of these pixels can make, and 1×1 (one view: no light field); after fitting: a
    design whose accommodation does not follow the rendered depth (gain < 0.5) or whose eye
    box falls short.
    """
    depths, cdp, counts = check_design(panel, depth_range_D, n_depths, cdp_D, views_per_side,
                                       wavelengths_nm, steps, report_accuracy, report_counts)
    chunk = eye_chunk_size(train_eyes.n_eyes, eye_chunk)
    solver_chunk = None if eye_chunk is None else chunk
    say = progress if callable(progress) else (
        (lambda line: print(line, flush=True)) if progress else None)
    lo, hi = (float(v) for v in depth_range_D)
    objective = Objective.parse(objective) if objective is not None else Objective()
    steps = int(steps)
    planning = train_eyes if test_eyes is None else Eyes(
        np.concatenate([np.asarray(train_eyes.zernike_um), np.asarray(test_eyes.zernike_um)]),
        train_eyes.measured_pupil_mm)
    report_eyes = test_eyes if test_eyes is not None else train_eyes
    # The plan first: every count's problems (their sampling) and what they will cost,
    # before the first fit, so that a run too long or too large is seen at once.
    prepared, plan = {}, DesignPlan(train_eyes=train_eyes.n_eyes, report_eyes=report_eyes.n_eyes,
                                    eye_chunk=chunk, steps=steps, report_accuracy=report_accuracy,
                                    report_counts=report_counts)
    t_plan = time.perf_counter()

    def prepare_count(n: int):
        """A count's fit problem and its report's (their sampling planned)."""
        problem = design_problem(panel, n, train_eyes, depths, cdp, constraints, objective,
                                 wavelengths_nm, "fit", planning, sampling)
        return problem, (problem if report_accuracy == "fit" and test_eyes is None else
                         report_problem(problem, report_eyes, report_accuracy, sampling))

    keys, kept = {}, {}
    if counts_dir is not None:
        for n in counts:
            keys[n] = count_key(panel, n, depths_D=depths, cdp_D=cdp, constraints=constraints,
                                objective=objective, wavelengths_nm=wavelengths_nm, steps=steps,
                                tol=tol, report_accuracy=report_accuracy, sampling=sampling,
                                eye_chunk=eye_chunk, train_zernike_um=train_eyes.zernike_um,
                                test_zernike_um=None if test_eyes is None else test_eyes.zernike_um)
            found = load_count(counts_dir, n, keys[n])
            if found is not None:
                kept[n] = DesignFit(**found)
    for n in counts:
        if n in kept:  # finished by an earlier call with the same inputs
            prepared[n] = kept[n]
            plan.counts.append(CountPlan(n, resumed=f"fitted earlier, kept in {counts_dir}"))
            continue
        why = feasibility(panel, n, cdp, constraints)
        if why is not None:
            why = f"infeasible: {why}"
        elif n == 1:
            # one view is one aperture whatever the lenslets: no parallax, no light field
            why = ("the views have collapsed into one aperture: 1x1 puts a single view in the "
                   "pupil, so the rendered depth moves nothing on the retina and the eye focuses "
                   "on the CDP (choose views_per_side >= 2)")
        if why is not None:
            prepared[n] = why
            plan.counts.append(CountPlan(n, refused=why))
            continue
        problem, report = prepared[n] = prepare_count(n)
        plan.counts.append(count_plan(n, problem, report, train_eyes.n_eyes, report_eyes.n_eyes,
                                      steps, chunk, REFINEMENT_STATES.get(report.peak_method, 0)))
    if say is not None:
        say(plan.summary() + f"\n  (planned in {time.perf_counter() - t_plan:.0f} s)")
    # First every count's fit (its panel and training loss), then the held-out report of
    # the counts the question reads: the report's transforms are most of a design's cost.
    fits = {}
    for n in counts:
        if n in kept:
            fits[n] = kept[n]
            continue
        if isinstance(prepared[n], str):
            fits[n] = DesignFit(n, refused=prepared[n])
            continue
        problem, _ = prepared[n]
        t0 = time.perf_counter()
        tell = None if say is None else (lambda line, n=n: say(f"design {n}x{n}: {line}"))
        x0 = jnp.asarray(start_box(panel, n, cdp, constraints), jnp.result_type(float))
        x, history = _solve(x0, problem, panel, n, constraints, steps, tol, solver_chunk, tell)
        fitted = panel_from_box(np.asarray(x), panel, n, cdp, constraints)
        start = panel_from_box(np.asarray(x0), panel, n, cdp, constraints)
        fit = DesignFit(n, Panel(*_host_leaves(fitted), **_statics(fitted)),
                        Panel(*_host_leaves(start), **_statics(start)), history=history)
        fit.refused = parallax_warning(fit.panel.layout(n))  # the views' geometry alone
        if fit.refused is None and float(fit.panel.eye_box_mm()) < constraints.min_eye_box_mm * (1 - 1e-3):
            fit.refused = (f"the eye box {float(fit.panel.eye_box_mm()):.3g} mm is below min_eye_box_mm = "
                           f"{constraints.min_eye_box_mm:g} mm even at the fastest lenslets")
        fit.notes = design_notes(fit.panel, (lo, hi))
        fit.time_s = time.perf_counter() - t0
        if tell is not None:
            tell(f"fitted in {fit.time_s:.1f} s" + ("" if fit.training_loss is None else
                                                    f", training loss {fit.training_loss:.5f}"))
        if counts_dir is not None:  # kept at once: a later failure or Ctrl-C loses no count
            save_count(counts_dir, keys[n], fit)
        fits[n] = fit

    def report(fit: DesignFit) -> None:
        """The held-out report of a fitted count: its fitted and starting panels scored."""
        n = fit.n_per_side
        # a count kept by an earlier call before its report has no problems yet
        _, problem = prepared[n] if isinstance(prepared[n], tuple) else prepare_count(n)
        t0 = time.perf_counter()
        tell = None if say is None else (lambda line: say(f"design {n}x{n}: {line}"))
        scores = {}
        for key, candidate in (("fit", fit.panel), ("start", fit.start)):
            t1 = time.perf_counter()
            evaluation = evaluate_layout(candidate.layout(n), _with_display(problem, candidate, constraints))
            res = perceivable_resolution(candidate, n, problem, evaluation["values"]["peak_D"], constraints)
            scores[key] = (_summary_numbers(evaluation, res), evaluation)
            if tell is not None:
                tell(f"report of the {'fitted' if key == 'fit' else 'starting'} panel on "
                     f"{problem.eyes.n_eyes} eyes: {time.perf_counter() - t1:.0f} s")
        if test_eyes is not None:
            fit.test = scores["fit"][0]
        else:
            fit.train = scores["fit"][0]
        fit.start_test = scores["start"][0]
        fit.refused = parallax_warning(fit.panel.layout(n), scores["fit"][1])
        if fit.refused is None:
            fit.failed = design_failure(fit.score, objective,
                                        "held-out" if test_eyes is not None else "training")
        fit.unreported = None
        fit.time_s += time.perf_counter() - t0
        if tell is not None:
            tell(f"done in {fit.time_s:.1f} s")
        if counts_dir is not None:
            save_count(counts_dir, keys[n], fit)

    report_counts_in_order(list(fits.values()), report, report_counts)
    fits = [fits[n] for n in counts]
    provenance = {"train_eyes": train_eyes.n_eyes,
                  "test_eyes": None if test_eyes is None else test_eyes.n_eyes,
                  "wavelengths_nm": [float(w) for w in wavelengths_nm], "steps": steps,
                  "report_accuracy": report_accuracy, "report_counts": report_counts,
                  "eye_chunk": chunk,
                  "freq_step_cpd": None if sampling is None else float(sampling.freq_step_cpd)}
    return DesignResult(fits, cdp, depths.tolist(), constraints, objective, provenance)


def _host_leaves(panel: Panel):
    return [float(np.asarray(v)) for v in (panel.pixel_pitch_mm, panel.lenslet_pitch_mm, panel.fill,
                                           panel.focal_length_mm, panel.gap_mm, panel.distance_mm,
                                           panel.pixel_fill)]


def _statics(panel: Panel) -> dict:
    return dict(pixel_count=panel.pixel_count, pupil_diameter_mm=panel.pupil_diameter_mm,
                aperture=panel.aperture, diffraction=panel.diffraction, name=panel.name)


# ----------------------------------------------------------------------------- specification


def panel_specification(panel: Panel, wavelength_nm: float = 550.0) -> dict:
    """A buildable specification of ``panel``: every number under a key that names its
    unit, as ``{"value": x, "unit": "mm"}``."""
    units = {
        "pixel_pitch_mm": "mm", "pixel_fill": "emitting area fraction", "lenslet_pitch_mm": "mm",
        "lenslet_aperture_mm": "mm", "fill": "aperture/pitch", "focal_length_mm": "mm",
        "gap_mm": "mm", "viewing_distance_mm": "mm", "design_pupil_mm": "mm",
    }
    values = {
        "pixel_pitch_mm": panel.pixel_pitch_mm, "pixel_fill": panel.pixel_fill,
        "lenslet_pitch_mm": panel.lenslet_pitch_mm, "lenslet_aperture_mm": panel.aperture_mm,
        "fill": panel.fill, "focal_length_mm": panel.focal_length_mm, "gap_mm": panel.gap_mm,
        "viewing_distance_mm": panel.distance_mm, "design_pupil_mm": panel.pupil_diameter_mm,
    }
    build = {k: {"value": float(np.asarray(v)), "unit": units[k]} for k, v in values.items()}
    build["pixel_count"] = {"value": list(panel.pixel_count), "unit": "pixels (horizontal, vertical)"}
    build["aperture_shape"] = {"value": panel.aperture, "unit": None}
    derived_units = {
        "cdp_D": "D", "magnification": "unitless", "view_pitch_mm": "mm (in the pupil)",
        "view_diameter_mm": "mm (in the pupil)", "views_across_pupil": "views",
        "views_per_side": "views", "fresnel_number": f"unitless at {wavelength_nm:g} nm",
        "pixel_arcmin": "arcmin", "emitter_arcmin": "arcmin", "lenslet_arcmin": "arcmin",
        "nyquist_cpd": "cpd", "pixel_nyquist_cpd": "cpd", "pixels_per_lenslet": "pixels",
        "eye_box_mm": "mm", "emitter_sweep_mm": "mm (at the eye)", "depth_step_D": "D", "f_number": "unitless", "active_width_mm": "mm",
        "active_height_mm": "mm", "lenslets_horizontal": "lenslets",
        "lenslets_vertical": "lenslets", "field_of_view_h_deg": "degrees",
        "field_of_view_v_deg": "degrees",
    }
    derived = {k: {"value": v, "unit": derived_units[k]} for k, v in panel.summary(wavelength_nm).items()}
    return {"build": build, "derived": derived}


def _score_units(score: dict | None) -> dict | None:
    if score is None:
        return None
    units = {"image_at_peak": "VSOTF (open-pupil reference)", "relative_accommodation_rmse_D": "D",
             "accommodation_rmse_D": "D", "accommodation_gain": "unitless",
             "peak_success_fraction": "fraction", "loss": "objective units", "penalty": "objective units",
             "n_eyes": "eyes", "perceivable_cpd_median": "cpd", "perceivable_cpd_p05": "cpd",
             "perceivable_cpd_p95": "cpd", "perceivable_cpd_by_depth": "cpd (median per depth)"}
    return {k: {"value": v, "unit": units[k]} for k, v in score.items()}


def save_design(result: DesignResult, out_dir, command: str | None = None,
                force: bool = False) -> list[Path]:
    """Write ``design.json`` (every count's specification and scores, every number with its
    unit; the chosen count marked) and ``design.png`` (the chosen array's lenslets over a few
    pixels, and its views in the pupil) into ``out_dir``, both or neither (built in a staging
    folder beside it, then renamed into place: :func:`~lfjax.base.files.staged_output`;
    ``force``: into a folder with files in it). Returns the paths."""

    out = Path(out_dir)
    best = result.best
    held_out = result.provenance.get("test_eyes") is not None or any(f.test is not None for f in result.fits)
    designs = []
    for f in result.fits:
        designs.append({
            "views_per_side": f.n_per_side,
            "status": f.status, "refused": f.refused, "failed": f.failed,
            "specification": None if f.panel is None else panel_specification(f.panel),
            "start_specification": None if f.start is None else panel_specification(f.start),
            "held_out" if held_out else "training": _score_units(f.score),
            "start_held_out" if held_out else "start_training": _score_units(f.start_test),
            "notes": f.notes, "loss_history": f.history, "fit_time_s": round(f.time_s, 2),
            "unreported": f.unreported,
        })
    record = {
        "format": DESIGN_FORMAT,
        "chosen_views_per_side": None if best is None else best.n_per_side,
        "cdp_D": {"value": result.cdp_D, "unit": "D"},
        "depths_D": {"value": result.depths_D, "unit": "D"},
        "objective": dict(result.objective.as_dict(), name=result.objective.name),
        "constraints": {k: {"value": v, "unit": u} for (k, v), u in zip(
            result.constraints.as_dict().items(), ("mm", "aperture/pitch", "unitless", "unitless", "mm"))},
        "designs": designs,
        "provenance": dict(result.provenance, lfjax_version=__version__, command=command,
                           utc=datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds")),
    }
    if result.constraints.lens_form is not None:
        record["constraints"]["lens_form"] = {"value": result.constraints.lens_form, "unit": None}
        record["constraints"]["refractive_index"] = {"value": result.constraints.refractive_index,
                                                     "unit": "unitless"}
    names = ["design.json"]
    chosen = best or next((f for f in result.fits if f.panel is not None), None)
    with staged_output(out, force) as stage:  # both files, or neither
        atomic_write_text(stage / "design.json", json.dumps(jsonable(record), indent=2) + "\n")
        if chosen is not None:
            fig = fig_design(chosen.panel, chosen.n_per_side)
            try:
                fig.savefig(stage / "design.png", dpi=110)
            finally:
                import matplotlib.pyplot as plt

                plt.close(fig)
            names.append("design.png")
    return [out / name for name in names]


def fig_design(panel: Panel, n_per_side: int):
    """Two panels: the lenslet array in front of the pixels (a 3×3-lenslet patch, side
    view of the gap underneath), and the n×n views in the design pupil."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Circle, Rectangle

    du, a = float(panel.lenslet_pitch_mm), float(panel.aperture_mm)
    p = float(panel.pixel_pitch_mm)
    fig, (ax0, ax1) = plt.subplots(1, 2, figsize=(10, 4.6))
    extent = 1.5 * du
    n_pix = int(math.ceil(2 * extent / p))
    if n_pix <= 400:  # draw the pixel grid where it is visible
        for k in range(n_pix + 1):
            c = -extent + k * p
            ax0.axvline(c, color="0.85", lw=0.4)
            ax0.axhline(c, color="0.85", lw=0.4)
    for i in (-1, 0, 1):
        for j in (-1, 0, 1):
            ax0.add_patch(Rectangle((i * du - du / 2, j * du - du / 2), du, du, fill=False, ec="0.4"))
            shape = (Circle((i * du, j * du), a / 2) if panel.aperture == "circle"
                     else Rectangle((i * du - a / 2, j * du - a / 2), a, a))
            shape.set(fc="tab:blue", alpha=0.35, ec="tab:blue")
            ax0.add_patch(shape)
    ax0.set_xlim(-extent, extent)
    ax0.set_ylim(-extent, extent)
    ax0.set_aspect("equal")
    ax0.set_xlabel("mm on the lenslet plane")
    s = panel.summary()
    ax0.set_title(f"lenslets: pitch {du:.4g} mm, aperture {a:.4g} mm, f {float(panel.focal_length_mm):.4g} mm,\n"
                  f"gap {float(panel.gap_mm):.4g} mm, at {float(panel.distance_mm):.4g} mm; "
                  f"pixels {p * 1000:.3g} µm ({s['pixels_per_lenslet']:.1f} per lenslet)", fontsize=8)
    draw_layout(ax1, panel.layout(n_per_side), panel.pupil_diameter_mm,
                title=f"{n_per_side}x{n_per_side} views in the {panel.pupil_diameter_mm:g} mm pupil: "
                      f"pitch {s['view_pitch_mm']:.3g} mm, CDP {s['cdp_D']:.3g} D,\n"
                      f"Fresnel number {s['fresnel_number']:.3g}, pixel {s['pixel_arcmin']:.3g}', "
                      f"eye box {s['eye_box_mm']:.3g} mm")
    ax1.title.set_fontsize(8)
    fig.tight_layout()
    return fig


__all__ = [
    "FLAT_STEP",
    "DesignConstraints",
    "DesignFit",
    "DesignResult",
    "view_pitch_range_mm",
    "panel_from_box",
    "start_box",
    "feasibility",
    "design_problem",
    "design_loss",
    "design_loss_chunked",
    "eye_chunk_size",
    "report_problem",
    "report_counts_in_order",
    "REPORT_COUNTS",
    "SCREEN_MARGIN",
    "REPORT_ACCURACIES",
    "FAST_REPORT_WAVELENGTHS_NM",
    "perceivable_resolution",
    "design_notes",
    "design_cdp_D",
    "design_panel",
    "check_design",
    "fit_design",
    "panel_specification",
    "save_design",
    "fig_design",
    "DESIGN_FORMAT",
]
