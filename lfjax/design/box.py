"""The design's feasible box and its problem: every point of [0, 1]^k is a buildable panel
(:func:`panel_from_box`), the layout optimiser's loss of that panel (:func:`design_loss`,
:func:`design_loss_chunked`) and the problems a count is fitted and reported on
(:func:`design_problem`, :func:`report_problem`). The box is described in
:mod:`lfjax.design.fit`'s docstring."""

from __future__ import annotations

import itertools

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from lfjax.base.errors import ParameterError
from lfjax.design.settings import FAST_REPORT_WAVELENGTHS_NM, REPORT_ACCURACIES, DesignConstraints
from lfjax.display.aberrations import panel_aberration
from lfjax.display.lenslets import DisplayOptics, lenslets_for_layout
from lfjax.display.panel import Panel
from lfjax.layout_opt import (
    Constraints,
    Objective,
    ProblemSetting,
    combine,
    layout_loss,
    make_problem,
    objective_terms,
)
from lfjax.model.eyes import Eyes
from lfjax.model.options import ModelOptions
from lfjax.model.spectral import make_spectrum
from lfjax.vision.prepare import check_eye_chunk


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


def panel_optics(panel: Panel, constraints: DesignConstraints | None):
    """The panel's optics, with its lenslets' on-axis aberration when ``constraints`` names a
    lens form (:func:`lfjax.display.aberrations.panel_aberration`, differentiable in the panel)."""
    optics = panel.optics()
    if constraints is None or constraints.lens_form is None:
        return optics
    return optics.with_aberration(panel_aberration(panel, refractive_index=constraints.refractive_index,
                                                   lens_form=constraints.lens_form))


def with_display(problem, panel: Panel, constraints: DesignConstraints | None = None):
    return eqx.tree_at(lambda p: p.display, problem, panel_optics(panel, constraints))


def design_loss(x, problem, template: Panel, n_per_side: int, constraints: DesignConstraints):
    """The layout optimiser's loss (:func:`lfjax.layout_opt.layout_loss`) of the panel at
    box coordinates ``x``: its n×n views as the layout, its lenslet diffraction and pixel
    blur as the problem's display. Scalar, differentiable in ``x``."""
    panel = panel_from_box(x, template, n_per_side, problem.cdp_D, constraints)
    return layout_loss(panel.layout(n_per_side), with_display(problem, panel, constraints))


design_value_and_grad = eqx.filter_jit(jax.value_and_grad(design_loss))


def eye_chunk_size(n_eyes: int, eye_chunk: int | None) -> int:
    """Eyes per chunk of :func:`design_loss_chunked`: the largest divisor of ``n_eyes`` not
    above ``eye_chunk`` (None: all of them), so that every chunk has one shape and the
    chunks' means average to the population's exactly."""
    n = int(n_eyes)
    if eye_chunk is None:
        return n
    chunk = check_eye_chunk(eye_chunk)
    return max(c for c in range(1, min(chunk, n) + 1) if n % c == 0)


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
        sub = eqx.tree_at(lambda q: q.eyes.zernike_um, with_display(problem, p, constraints), zernike_um)
        return objective_terms(p.layout(n_per_side), sub)

    per_chunk = jax.lax.map(lambda zc: chunk_terms(x, zc), z.reshape(-1, chunk, z.shape[-1]))
    terms = {k: jnp.mean(v) for k, v in per_chunk.items()}
    loss = combine(terms, problem.objective)
    return eqx.error_if(loss, ~jnp.isfinite(loss), "layout objective is not finite (NaN or inf)")


design_value_and_grad_chunked = eqx.filter_jit(jax.value_and_grad(design_loss_chunked))


def worst_optics(template: Panel, n_per_side: int, cdp_D: float,
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
        optics = panel_optics(panel, constraints)
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
                        wavelengths_nm=wavelengths_nm, setting=ProblemSetting(accuracy),
                        options=ModelOptions(vsotf_reference="open_pupil"),
                        display=worst_optics(template, n_per_side, cdp_D, constraints),
                        planning_eyes=planning_eyes, sampling=sampling)



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
                        spectrum=make_spectrum(np.asarray(FAST_REPORT_WAVELENGTHS_NM), problem.options),
                        display=problem.display, sampling=sampling,
                        setting=ProblemSetting("full", peak_method="vertex", window_D=problem.window_D))


