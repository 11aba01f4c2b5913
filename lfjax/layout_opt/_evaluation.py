"""Scoring a layout on (held-out) eyes, through-focus curves, diameter scans and the reference layouts.

Part of :mod:`lfjax.layout_opt` (its public names are re-exported there)."""

from __future__ import annotations

import dataclasses
import math

import equinox as eqx
import jax.numpy as jnp
import numpy as np

from lfjax.model.eyes import Eyes
from lfjax.model.layouts import make_layout
from lfjax.model.options import ModelOptions
from lfjax.vision.peaks import peaks_from_grid
from lfjax.kernel.pipeline import (
    Accommodation,
    PipelineConfig,
    Scene,
    retinal_metrics,
)
from lfjax.planner.plan import plan_sampling
from lfjax.planner.scene import PlanScene
from lfjax.base.sampling import Sampling
from lfjax.model.spectral import make_spectrum
from lfjax.layout_opt._feasible import Constraints, to_layout
from lfjax.layout_opt._objectives import (
    accommodation_penalty,
    combine,
    correct_focus_metrics,
    predicted_peaks,
    problem_peak_options,
    soft_cutoff_cpd,
)
from lfjax.layout_opt._params import as_free, free_params, lattice_sites, tangent_lattice
from lfjax.layout_opt._problem import (
    DEFAULT_WAVELENGTHS_NM,
    FULL_WAVELENGTHS_NM,
    LayoutProblem,
    check_depths,
    evaluated_pairs,
    guard_sampling,
    make_problem,
)


def _eye_chunks(eyes: Eyes, chunk: int):
    """(sub-batch of ``chunk`` eyes, valid mask) covering ``eyes``; the last chunk is padded
    with repeats of the last eye, so every chunk has one shape (one compilation)."""
    chunk = int(chunk)
    if chunk < 1:
        raise ValueError(f"chunk must be >= 1, got {chunk}")
    n = eyes.n_eyes
    for start in range(0, n, chunk):
        idx = np.arange(start, start + chunk)
        valid = idx < n
        yield Eyes(eyes.zernike_um[np.minimum(idx, n - 1)], eyes.measured_pupil_mm,
                   eyes.orientation), valid


@eqx.filter_jit
def _values_jit(layout, problem: LayoutProblem):
    """Per (eye, depth) values of every reported quantity, each (n_eyes, n_depth).

    One pipeline call covers the peak grid and the correct focus
    (:attr:`LayoutProblem.values_grid`): a rendered depth on the peak grid shares its
    elemental OTFs instead of computing them a second time."""
    if problem.values_grid is None:
        m = correct_focus_metrics(layout, problem)
        peaks = predicted_peaks(layout, problem)
        vsotf, radial_mtf = m.vsotf[..., 0], m.radial_mtf[..., 0, :]
    else:
        scene = problem.scene(layout, problem.peak_depths_D)
        both = retinal_metrics(problem.eyes, scene, problem.spectrum, problem.values_grid,
                               problem.config, problem.reference)
        peaks = peaks_from_grid(both.vsotf[..., :-1], problem.eyes, scene, problem.spectrum,
                                problem.peak_grid, problem.config, problem.reference, "vsotf",
                                problem_peak_options(problem), problem.peak_allowed)
        vsotf, radial_mtf = both.vsotf[:, :-1, -1], both.radial_mtf[:, :-1, -1, :]
    o = problem.objective
    depth = lambda x: x[:, :-1]  # noqa: E731 - the last column is the CDP's
    return {
        "vsotf": vsotf,
        "cutoff_cpd": soft_cutoff_cpd(radial_mtf, problem.config.freq_step_cpd,
                                      o.mtf_threshold, o.mtf_softness),
        "peak_D": depth(peaks.accommodation_D),
        "peak_vsotf": depth(peaks.value),
        "peak_success": depth(peaks.success),
        "peak_at_edge": depth(peaks.at_grid_edge),
        "peak_at_hyperopic_limit": depth(peaks.at_hyperopic_limit),
        "cdp_peak_D": peaks.accommodation_D[:, -1],
        "cdp_peak_success": peaks.success[:, -1],
    }


def accommodation_gain(depths_D, predicted_D) -> float:
    """Slope of the population-mean predicted accommodation against the rendered depth
    (least squares over the depths; 1 = the eye follows the display, 0 = it does not move).
    ``predicted_D`` (n_eyes, n_depth), D. NaN for fewer than two distinct depths."""
    d = np.asarray(depths_D, float)
    if np.unique(d).size < 2:
        return float("nan")
    mean = np.asarray(predicted_D, float).mean(axis=0)
    return float(np.polyfit(d, mean, 1)[0])


PARALLAX_MIN_GAIN = 0.5
"""Below this accommodation gain a fitted layout is reported as driving no accommodation."""


def parallax_warning(layout, evaluation: dict | None = None) -> str | None:
    """A warning when a layout's views no longer form a light field: their centres span
    less than half the mean view diameter (the views overlap into one aperture, so the
    rendered depth sets no parallax on the retina), or the evaluated accommodation gain is
    below :data:`PARALLAX_MIN_GAIN`. None when neither holds."""
    c = np.asarray(layout.centres_mm, float).reshape(-1, 2)
    d = np.asarray(layout.diameters_mm, float).reshape(-1)
    span = float(np.max(np.linalg.norm(c[:, None] - c[None], axis=-1))) if len(c) > 1 else 0.0
    problems = []
    if span < 0.5 * float(d.mean()):
        problems.append(f"the views' centres span {span:.3g} mm, less than half their mean diameter "
                        f"{d.mean():.3g} mm: the views have collapsed into one aperture")
    if evaluation is not None and math.isfinite(evaluation.get("accommodation_gain", math.nan)):
        gain = evaluation["accommodation_gain"]
        if gain < PARALLAX_MIN_GAIN:
            problems.append(f"the predicted accommodation follows the rendered depth with gain "
                            f"{gain:.2f} (< {PARALLAX_MIN_GAIN}): the display drives little accommodation")
    return ("; ".join(problems)) if problems else None


def evaluate_layout(layout, problem: LayoutProblem, eyes: Eyes | None = None, terms=None,
                    chunk: int | None = None, progress=None) -> dict:
    """Everything a report says of a layout on a population (host numbers).

    ``eyes`` (default the problem's) are evaluated ``chunk`` at a time (default the
    problem's eye count, so the fit's compiled functions are reused; the last chunk is
    padded with repeats). Each eye's predicted accommodation is the global maximum of its
    through-focus VSOTF over the problem's peak window (:func:`predicted_peaks`), never a
    search capped around the rendered depth; a maximum on a window edge is a failure.
    Returns a dict with each term's population mean (as the objective defines it:
    ``image_at_peak``, ``depth_of_field``, ``accommodation`` (D²), ``resolution`` (cpd)),
    ``loss`` (the problem's weighted objective with its penalty),
    ``accommodation_rmse_D`` (against the rendered depth), ``relative_accommodation_rmse_D``
    (less each eye's own error on the CDP: the display's share, which the default
    objective constrains), ``own_error_rmse_D`` (the eyes' own errors on the CDP),
    ``penalty``, ``accommodation_gain`` (:func:`accommodation_gain`),
    ``peak_success_fraction`` (peaks that converged inside their window, not on an edge),
    ``n_edge_peaks``, ``n_peaks``, per-depth means ``vsotf_by_depth``,
    ``image_at_peak_by_depth``, ``cutoff_by_depth`` (cpd), ``peak_by_depth`` (D),
    ``peak_error_by_depth`` (D), ``worst_depth_vsotf``, ``accuracy`` (the problem's
    setting) and the per-(eye, depth) arrays under ``values``. ``terms`` is accepted for
    compatibility and ignored: every quantity is reported. ``progress``: None, or a callable
    told the number of eyes each finished chunk scored (a progress bar's ``update``).
    """
    del terms
    eyes = problem.eyes if eyes is None else eyes
    layout = as_free(layout)
    parts = []
    for sub, valid in _eye_chunks(eyes, problem.eyes.n_eyes if chunk is None else chunk):
        vals = _values_jit(layout, problem.with_eyes(sub))
        parts.append({k: np.asarray(v)[valid] for k, v in vals.items()})
        if progress is not None:
            progress(int(np.sum(valid)))
    values = {k: np.concatenate([p[k] for p in parts]) for k in parts[0]}
    depths = np.asarray(problem.depths_D, float)
    out = {"n_eyes": eyes.n_eyes, "depths_D": depths.tolist(), "accuracy": problem.accuracy,
           "values": values}
    by_depth = values["vsotf"].mean(axis=0)
    out["image_at_peak"] = float(values["peak_vsotf"].mean())
    out["image_at_peak_by_depth"] = values["peak_vsotf"].mean(axis=0).tolist()
    out["depth_of_field"] = float(values["vsotf"].mean())
    out["vsotf_by_depth"] = by_depth.tolist()
    out["worst_depth_vsotf"] = float(by_depth.min())
    out["resolution"] = float(values["cutoff_cpd"].mean())
    out["cutoff_by_depth"] = values["cutoff_cpd"].mean(axis=0).tolist()
    err = values["peak_D"] - depths[None, :]
    out["accommodation"] = float(np.mean(err**2))
    out["accommodation_rmse_D"] = float(math.sqrt(out["accommodation"]))
    own = values["cdp_peak_D"] - float(problem.cdp_D)
    relative = err - own[:, None]
    out["relative_accommodation"] = float(np.mean(relative**2))
    out["relative_accommodation_rmse_D"] = float(math.sqrt(out["relative_accommodation"]))
    out["own_error_rmse_D"] = float(np.sqrt(np.mean(own**2)))
    out["accommodation_gain"] = accommodation_gain(depths, values["peak_D"])
    out["peak_by_depth"] = values["peak_D"].mean(axis=0).tolist()
    out["peak_error_by_depth"] = err.mean(axis=0).tolist()
    out["peak_success_fraction"] = float(values["peak_success"].mean())
    out["n_edge_peaks"] = int(values["peak_at_edge"].sum())
    out["n_peaks"] = int(values["peak_success"].size)
    out["penalty"] = float(accommodation_penalty(out["relative_accommodation"], problem.objective))
    out["loss"] = float(combine(out, problem.objective))
    for k, v in out.items():
        if isinstance(v, float) and not math.isfinite(v) and k != "accommodation_gain":
            raise FloatingPointError(f"evaluation gave a non-finite {k}")
    return out


@eqx.filter_jit
def _curves_jit(layout, problem: LayoutProblem, accommodation_D):
    acc = Accommodation.per_depth(accommodation_D, problem.options, problem.pupil_diameter_mm)
    m = retinal_metrics(problem.eyes, problem.scene(layout), problem.spectrum, acc, problem.config,
                        problem.reference)
    return m.vsotf


def through_focus_curves(layout, problem: LayoutProblem, offsets_D=None, eyes: Eyes | None = None,
                         chunk: int | None = None):
    """Through-focus VSOTF of a layout: (accommodation_D (n_depth, n_k), vsotf (n_eyes,
    n_depth, n_k)); accommodation = depth + offsets (default ±``window_D`` in 0.1 D steps),
    states below 0 D are NaN (the eye cannot relax beyond infinity)."""
    if offsets_D is None:
        w = problem.window_D
        offsets_D = np.round(np.arange(-w, w + 1e-9, 0.1), 9)
    offsets = np.asarray(offsets_D, float)
    depths = np.asarray(problem.depths_D)
    acc = depths[:, None] + offsets[None, :]
    eyes = problem.eyes if eyes is None else eyes
    rows = []
    for sub, valid in _eye_chunks(eyes, eyes.n_eyes if chunk is None else chunk):
        rows.append(np.asarray(_curves_jit(as_free(layout), problem.with_eyes(sub),
                                           jnp.asarray(np.maximum(acc, 0.0))))[valid])
    vs = np.concatenate(rows)
    vs[:, acc < 0] = np.nan
    return acc, vs


def diameter_scan(eyes: Eyes, n_per_side: int, pitch_mm: float, diameters_mm, depths_D,
                  reference: str = "open_pupil", *, pupil_diameter_mm: float = 3.0,
                  cdp_D: float = 2.0, wavelengths_nm=DEFAULT_WAVELENGTHS_NM,
                  sampling: Sampling | None = None, options: ModelOptions = ModelOptions()):
    """Mean VSOTF at the correct accommodation of an n×n grid at a fixed pitch for each
    subaperture diameter: (n_diameters, n_depth), the mean over ``eyes``.

    ``reference`` selects the VSOTF reference (``"paper"`` or ``"open_pupil"``); this is the
    check behind the module docstring's warning (with ``"paper"`` the mean rises as the
    subapertures shrink). ``sampling`` defaults to the planner's guard for the largest and
    smallest diameter on this grid.
    """
    d = np.atleast_1d(np.asarray(diameters_mm, float))
    depths = check_depths(depths_D)
    options = options.replace(vsotf_reference=reference)
    sites = lattice_sites("square", int(n_per_side) ** 2)
    centres = float(pitch_mm) * sites
    pupil = float(pupil_diameter_mm)
    window = float(min(d.max(), pupil))
    wl = np.atleast_1d(np.asarray(wavelengths_nm, float))
    if sampling is None:
        envelope = make_layout(np.concatenate([centres, centres[:1]]),
                               np.concatenate([np.full(len(centres), d.max()), [d.min()]]), pupil,
                               window_diameter_mm=window)
        sampling = plan_sampling(PlanScene(envelope, pupil_diameter_mm=pupil, cdp_D=cdp_D,
                                           depths_D=depths, accommodation_window_D=0.5,
                                           wavelengths_nm=wl, eyes=eyes, options=options),
                                 estimate_accuracy=False).sampling
    config = PipelineConfig.build(wl, window, pupil, sampling, options)
    spectrum = make_spectrum(wl, options)
    acc = Accommodation.per_depth(depths[:, None], options, pupil)
    rows = []
    for di in d:
        scene = Scene(centres, np.full(len(centres), di), cdp_D, depths, pupil)
        rows.append(np.asarray(retinal_metrics(eyes, scene, spectrum, acc, config).vsotf)[..., 0].mean(0))
    return np.stack(rows)


def natural_evaluation(problem: LayoutProblem, eyes: Eyes | None = None) -> dict:
    """:func:`evaluate_layout`'s numbers for natural viewing of real points at the
    rendered depths (open pupil, each depth its own focal plane; no display), at the
    problem's setting: the best a display can hope to match."""
    eyes = problem.eyes if eyes is None else eyes
    pupil = problem.pupil_diameter_mm
    open_constraints = Constraints(pupil, pupil, min(problem.constraints.min_diameter_mm, pupil))
    parts = []
    depths = np.asarray(problem.depths_D, float)
    kwargs = dict(options=problem.options,
                  spectrum=problem.spectrum if problem.spectrum_given else None,
                  setting=dataclasses.replace(problem.setting, eye_chunk=None))
    # One sampling for every depth (the finest of their guards): one compiled program.
    wl = (np.asarray(problem.spectrum.wavelengths_nm, float) if problem.spectrum_given
          else np.asarray(FULL_WAVELENGTHS_NM if problem.accuracy == "full" else
                          problem.spectrum.wavelengths_nm, float))
    sampling = min((guard_sampling(open_constraints, [d], float(d), wl, eyes, problem.window_D,
                                   problem.options, None, None,
                                   pairs=evaluated_pairs(np.array([d]), float(d),
                                                         problem.peak_step_D,
                                                         problem.peak_margin_D))
                    for d in depths), key=lambda smp: smp.freq_step_cpd)
    for d in depths:
        sub = make_problem(eyes, [d], open_constraints, problem.objective, cdp_D=float(d),
                           sampling=sampling, **kwargs)
        parts.append(evaluate_layout(free_params([[0.0, 0.0]], [pupil]), sub,
                                     chunk=min(eyes.n_eyes, max(problem.eyes.n_eyes, 8)))["values"])
    values = {k: np.concatenate([p[k] for p in parts], axis=1) for k in parts[0] if parts[0][k].ndim == 2}
    err = values["peak_D"] - depths[None, :]
    return {"n_eyes": eyes.n_eyes, "depths_D": depths.tolist(), "accuracy": problem.accuracy,
            "image_at_peak": float(values["peak_vsotf"].mean()),
            "accommodation_rmse_D": float(np.sqrt(np.mean(err**2))),
            "relative_accommodation_rmse_D": 0.0,  # each depth is its own focal plane
            "accommodation_gain": accommodation_gain(depths, values["peak_D"]),
            "peak_success_fraction": float(values["peak_success"].mean()), "values": values}


def tangent_grid_evaluations(problem: LayoutProblem, eyes: Eyes | None = None,
                             sizes=(2, 3, 4)) -> dict:
    """{"n×n": (Layout, evaluation)} of the paper's tangent n×n grids on ``eyes`` at the
    problem's setting (each grid's own window: a problem per grid)."""
    eyes = problem.eyes if eyes is None else eyes
    pupil = problem.pupil_diameter_mm
    out = {}
    for n in sizes:
        params = tangent_lattice("square", n * n, pupil)
        d = float(params.diameter_mm)
        sub = make_problem(eyes, np.asarray(problem.depths_D, float),
                           Constraints(pupil, d, min(problem.constraints.min_diameter_mm, d)),
                           problem.objective, cdp_D=float(problem.cdp_D), options=problem.options,
                           spectrum=problem.spectrum if problem.spectrum_given else None,
                           display=problem.display,
                           setting=dataclasses.replace(problem.setting, eye_chunk=None))
        layout = to_layout(params, sub.constraints, f"tangent {n}x{n}")
        out[f"{n}x{n}"] = (layout, evaluate_layout(params, sub,
                                                   chunk=min(eyes.n_eyes, max(problem.eyes.n_eyes, 8))))
    return out
