"""A whole layout optimisation as one library call: checked settings, the fit, its report and its files.

:class:`OptimisationSettings` holds what ``lfjax optimise`` asks for as plain values (view
count, lattice, depths, pupil, eyes, solver, …) and checks them all when made, on the host
and before anything is traced: a refused value is a
:class:`~lfjax.base.errors.ParameterError` naming the field. :func:`optimise_and_save`
then draws the eyes, fits the layout, scores it on held-out eyes, draws the figures and
writes ``layout.json`` (with its provenance), and with ``front`` the trade-off front, into
a folder — as :func:`lfjax.design.fit_design` and :func:`lfjax.design.save_design` do for a
display design.

Part of :mod:`lfjax.layout_opt` (its public names are re-exported there)."""

from __future__ import annotations

import json
import math
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from lfjax.base.errors import ParameterError
from lfjax.base.files import (atomic_savefig, atomic_write_text, check_output_folder,
                              staged_output)
from lfjax.base.sampling import Sampling
from lfjax.base.types import finite_scalar
from lfjax.base.units import check_dioptres
from lfjax.display.lenslets import DisplayOptics, display_optics_at
from lfjax.display.spectra import display_primaries, display_spectrum
from lfjax.model import layout_plots
from lfjax.model.layout_files import jsonable
from lfjax.model.options import ModelOptions
from lfjax.model.spectral import make_spectrum
from lfjax.layout_opt._evaluation import through_focus_curves
from lfjax.layout_opt._eye_draw import MEASURED_PUPIL_MM, EyeDraw, planning_eyes, whole_number
from lfjax.layout_opt._feasible import Constraints, feasible_start, initial_lattice, to_box
from lfjax.layout_opt._files import save_layout_json
from lfjax.layout_opt._params import default_max_diameter_mm, free_params, lattice_sites
from lfjax.layout_opt._problem import (
    ACCURACIES,
    LayoutProblem,
    Objective,
    check_measured_pupil,
    depth_grid,
    make_problem,
)
from lfjax.layout_opt._solver import METHODS, Front, LayoutFit, optimise_layout, trade_off_front

PARAMETRISATIONS = ("lattice", "free")
"""``"lattice"``: pitch, diameter, rotation of the lattice; ``"free"``: every centre and
diameter (:class:`LatticeParams`, :class:`FreeParams`)."""

FIT_OPTIONS = ModelOptions(vsotf_reference="open_pupil")
"""The model options of every layout objective (:func:`make_problem`)."""


def _one_of(name: str, value, allowed) -> str:
    if value not in allowed:
        raise ParameterError(name, "{%s} must be one of {allowed}, got {got!r}" % name,
                             allowed=", ".join(allowed), got=value)
    return value


@dataclass(frozen=True)
class OptimisationSettings:
    """What a layout optimisation asks for, as plain values (``lfjax optimise``'s flags),
    checked when made: a refused value is a :class:`~lfjax.base.errors.ParameterError`
    naming the field (or the library parameter it reaches: ``n_views`` of
    :func:`lattice_sites`, ``distance_mm`` of
    :func:`~lfjax.display.lenslets.display_optics_at`, …). Nothing is traced.

    Attributes
    ----------
    n_views : number of views (square lattice: n·n; hex: any, 7 and 19 fill rings)
    lattice : ``"square"`` or ``"hex"``: the start's lattice (and the fit's, with
        ``parametrisation="lattice"``)
    parametrisation : ``"lattice"`` (pitch, diameter, rotation) or ``"free"`` (every
        centre and diameter)
    objective : ``"accommodation_aware"`` (None: the default), a name of
        :data:`OBJECTIVES`, a {name: weight} dict or an :class:`Objective`
    accommodation_tolerance_D : the accommodation RMSE constraint, D, replacing the
        objective's own (None: keep it — 0.25 D for the default, none for the others)
    depth_range_D : (low, high) rendered depths, D, 0 ≤ low < high
    n_depths : rendered depths evenly spanning the range, ≥ 2
    cdp_D : the display's central depth plane, D ≥ 0
    pupil_diameter_mm : the pupil, mm, in (0, :data:`MEASURED_PUPIL_MM`]
    max_diameter_mm : largest subaperture diameter, mm (None: 1.2 × the tangent
        lattice's, at most the pupil, :func:`default_max_diameter_mm`)
    min_diameter_mm : smallest subaperture diameter, mm
    containment, non_overlap : :class:`Constraints`
    train_eyes, test_eyes : virtual eyes fitted to (seed ``seed``) and held out (seed
        ``seed + 1``; 0: none, the report is then on the training eyes)
    seed : seed of the training eyes
    wavelengths_nm : the fit's wavelengths, nm, increasing (V(λ)-weighted)
    display_distance_mm : a lenslet-array display at this distance from the eye, mm (each
        view its lenslet's Fresnel pattern); None: the paper's ideal display
    pixel_width_arcmin : emitters of this angular width, arcmin (0: points)
    spectrum : a built-in display's white (``"crt"``, ``"lcd"``, ``"oled"``, ``"laser"``)
        instead of the V(λ)-weighted ``wavelengths_nm``
    freq_step_cpd : frequency step, cpd (None: the planner's aliasing guard for every
        feasible layout)
    method : ``"lbfgsb"`` or ``"bfgs"`` (:func:`optimise_layout`)
    steps : solver steps, ≥ 0
    report_accuracy : the held-out report's setting, ``"full"`` or ``"fit"``
    front : fit this many layouts along the trade-off front too (tolerances 0.1 … 1 D,
        ≥ 2; needs held-out eyes), or None
    """

    n_views: int = 4
    lattice: str = "square"
    parametrisation: str = "lattice"
    objective: Objective | str | dict | None = None
    accommodation_tolerance_D: float | None = None
    depth_range_D: tuple = (0.0, 4.0)
    n_depths: int = 5
    cdp_D: float = 2.0
    pupil_diameter_mm: float = 3.0
    max_diameter_mm: float | None = None
    min_diameter_mm: float = 0.5
    containment: str = "centre"
    non_overlap: bool = False
    train_eyes: int = 10
    test_eyes: int = 50
    seed: int = 0
    wavelengths_nm: tuple = (550.0,)
    display_distance_mm: float | None = None
    pixel_width_arcmin: float = 0.0
    spectrum: str | None = None
    freq_step_cpd: float | None = None
    method: str = "lbfgsb"
    steps: int = 30
    report_accuracy: str = "full"
    front: int | None = None

    def __post_init__(self):
        set_ = object.__setattr__
        lattice_sites(self.lattice, self.n_views)
        _one_of("parametrisation", self.parametrisation, PARAMETRISATIONS)
        try:
            pupil = float(self.pupil_diameter_mm)
        except (TypeError, ValueError):
            pupil = math.nan
        max_d = self.max_diameter_mm
        if max_d is None and math.isfinite(pupil) and pupil > 0:  # else Constraints refuses the pupil
            max_d = max(default_max_diameter_mm(self.lattice, self.n_views, pupil),
                        min(self.min_diameter_mm, pupil))
        constraints = Constraints(self.pupil_diameter_mm, max_d, self.min_diameter_mm,
                                  self.containment, self.non_overlap)
        check_measured_pupil(constraints.pupil_diameter_mm, MEASURED_PUPIL_MM)
        set_(self, "depth_range_D", tuple(float(v) for v in self.depth_range_D))
        depths = depth_grid(*self.depth_range_D, self.n_depths)
        check_dioptres("cdp_D", finite_scalar("cdp_D", self.cdp_D, 0.0), "CDP")
        sampling = None if self.freq_step_cpd is None else Sampling(self.freq_step_cpd)
        wavelengths = np.atleast_1d(np.asarray(self.wavelengths_nm, float))
        if wavelengths.ndim == 1:  # else make_spectrum refuses the shape
            set_(self, "wavelengths_nm", tuple(float(w) for w in wavelengths))
        objective = Objective.parse(self.objective)
        set_(self, "objective", objective)
        if self.accommodation_tolerance_D is not None:
            objective = Objective.parse(objective, self.accommodation_tolerance_D)
        eye_draw = EyeDraw(self.seed, self.train_eyes, self.test_eyes)
        if self.front is not None:
            if whole_number("front", self.front, 1) < 2:
                raise ParameterError("front", "{front} must be >= 2 points, got {got}", got=self.front)
            if self.test_eyes == 0:
                raise ParameterError("front", "{front} needs held-out eyes ({test_eyes} >= 1)")
        display = None
        if self.display_distance_mm is not None:
            display = display_optics_at(self.display_distance_mm, self.cdp_D, self.pixel_width_arcmin)
        elif self.pixel_width_arcmin != 0:
            display = DisplayOptics(pixel_width_arcmin=self.pixel_width_arcmin)
        if self.spectrum is not None:
            display_primaries(self.spectrum)
        make_spectrum(self.wavelengths_nm, FIT_OPTIONS)  # checks them
        _one_of("method", self.method, METHODS)
        whole_number("steps", self.steps, 0)
        _one_of("report_accuracy", self.report_accuracy, ACCURACIES)
        set_(self, "_built", dict(constraints=constraints, depths_D=depths, sampling=sampling,
                                  fit_objective=objective, display=display,
                                  eye_draw=eye_draw))
        self.start()  # a feasible start exists (the checks of to_box)

    @property
    def constraints(self) -> Constraints:
        """The feasible layouts, with ``max_diameter_mm`` resolved."""
        return self._built["constraints"]

    @property
    def depths_D(self) -> np.ndarray:
        """The rendered depths, D (n_depths,)."""
        return self._built["depths_D"].copy()

    @property
    def fit_objective(self) -> Objective:
        """The objective fitted: :attr:`objective` with ``accommodation_tolerance_D``."""
        return self._built["fit_objective"]

    @property
    def eye_draw(self) -> EyeDraw:
        """The training and held-out eyes (seeds ``seed`` and ``seed + 1``)."""
        return self._built["eye_draw"]

    @property
    def sampling(self) -> Sampling | None:
        return self._built["sampling"]

    @property
    def display(self) -> DisplayOptics | None:
        """The display's optics, or None for the paper's ideal display."""
        return self._built["display"]

    @property
    def name(self) -> str:
        """The fitted layout's name."""
        return f"optimised-{self.parametrisation}-{self.n_views}"

    def start(self):
        """The starting parameters: the tangent lattice moved into the constraints (2 %
        inside them for ``method="bfgs"``, whose sigmoid coordinates reach a bound only
        asymptotically); every view free with ``parametrisation="free"``."""
        constraints = self.constraints
        margin = 0.02 if self.method == "bfgs" else 0.0
        start = initial_lattice(self.lattice, self.n_views, constraints, margin)
        if self.parametrisation == "free":
            start = feasible_start(free_params(start.centres_mm, start.diameters_mm), constraints,
                                   margin)
        to_box(start, constraints)  # raises if no feasible start exists
        return start


@dataclass
class OptimisationResult:
    """What :func:`optimise_and_save` fitted and wrote.

    Attributes
    ----------
    fit : the :class:`LayoutFit` (layout, parameters, train/test scores, history)
    problem : the training :class:`LayoutProblem`
    files : the paths written
    summary : the fit's summary, and the front's table when fitted (text)
    front : the trade-off :class:`Front`, or None
    """

    fit: LayoutFit
    problem: LayoutProblem
    files: list
    summary: str
    front: Front | None = None


def _brief(evaluation):
    return None if evaluation is None else {
        k: {m: v for m, v in evaluation[k].items() if m != "values"} for k in ("before", "after")}


def optimise_and_save(settings: OptimisationSettings, out_dir, *, force: bool = False,
                      progress: bool = True, command: str | None = None) -> OptimisationResult:
    """Fit the layout ``settings`` describe and write it, with its report, into ``out_dir``.

    Draws the training eyes (seed ``settings.seed``) and the held-out eyes (seed + 1),
    fits on the cheap ``"fit"`` setting (:func:`make_problem`, :func:`optimise_layout`)
    and scores the start and the fit on the held-out eyes at ``settings.report_accuracy``.
    Writes into ``out_dir`` (new or empty unless ``force``, writable, with room for the
    outputs: checked before any work, :func:`~lfjax.base.files.check_output_folder`),
    whole or not at all (staged, then moved into place:
    :func:`~lfjax.base.files.staged_output`): ``layout.json`` (the layout, the
    objective with its before/after values, the parameters and the provenance —
    ``command`` among it), ``layouts.png``, ``through_focus.png`` and ``history.png``; with
    ``settings.front``, then ``front.png`` and ``front.json``. ``progress``: progress bars
    on stderr.
    """
    out = check_output_folder(out_dir, force, need_bytes=estimated_output_bytes(settings))
    start = settings.start()
    train, test = settings.eye_draw.train(), settings.eye_draw.test()
    planning = planning_eyes(train, test)
    constraints = settings.constraints
    spectrum = (None if settings.spectrum is None
                else display_spectrum(settings.spectrum, "white", FIT_OPTIONS))
    problem = make_problem(train, settings.depths_D, constraints, settings.fit_objective,
                           cdp_D=settings.cdp_D, wavelengths_nm=list(settings.wavelengths_nm),
                           sampling=settings.sampling, planning_eyes=planning, spectrum=spectrum,
                           display=settings.display)
    fit = optimise_layout(start, problem, method=settings.method, max_steps=settings.steps,
                          test_eyes=test, progress=progress, name=settings.name,
                          report_problem=settings.report_accuracy)
    shown = test if test is not None else train
    shown = shown[: min(shown.n_eyes, 20)]
    curves = {"before": through_focus_curves(fit.initial_params, problem, eyes=shown),
              "after": through_focus_curves(fit.params, problem, eyes=shown)}
    with staged_output(out, force) as stage:  # the folder appears whole, or not at all
        result = _write_outputs(settings, fit, problem, curves, constraints, command, test,
                                stage)
        if settings.front is not None:
            _front(settings, result, start, test, stage, progress)
    result.files = [out / path.name for path in result.files]
    return result


def estimated_output_bytes(settings: OptimisationSettings) -> int:
    """Room :func:`optimise_and_save` asks of its output folder's disk before any work,
    bytes: its figures (about 0.1-0.3 MB each at 110 dpi; 2 MB allowed per figure) and
    JSON files (layout.json carries the loss history: 1 MB allowed each)."""
    figures, tables = (4, 1) if settings.front is None else (5, 2)
    return figures * 2 * 2**20 + tables * 2**20


def _write_outputs(settings, fit, problem, curves, constraints, command, test, out: Path):
    """Write the figures and layout.json into ``out`` (the staging folder)."""
    files = layout_plots.save_fit_figures(fit, curves, out)
    record_objective = dict(fit.objective.as_dict(), name=fit.objective.name,
                            train=_brief(fit.train), test=_brief(fit.test), warning=fit.warning)
    provenance = {
        "command": command,
        **settings.eye_draw.provenance(),
        "depths_D": settings.depths_D.tolist(), "cdp_D": settings.cdp_D,
        "wavelengths_nm": [float(w) for w in problem.spectrum.wavelengths_nm],
        "report_accuracy": settings.report_accuracy,
        "spectrum": settings.spectrum or "V(lambda) white",
        "display_distance_mm": settings.display_distance_mm,
        "pixel_arcmin": settings.pixel_width_arcmin,
        "freq_step_cpd": problem.config.freq_step_cpd, "solver": fit.method,
        "steps": fit.n_steps, "converged": fit.converged, "time_s": round(fit.time_s, 2),
        "evaluation_s": round(fit.evaluation_s, 2),
        "constraints": constraints.as_dict(), "model_options": problem.options.as_dict(),
        "history": fit.history.tolist(),
    }
    files.append(save_layout_json(out / "layout.json", fit.layout, constraints.pupil_diameter_mm,
                                  objective=record_objective, provenance=provenance,
                                  parameters=fit.params))
    return OptimisationResult(fit, problem, files, fit.summary())


def _front(settings: OptimisationSettings, result: OptimisationResult, start, test, out: Path,
           progress: bool) -> None:
    """The trade-off front: fitted, drawn (front.png), tabled (front.json) and summarised."""
    t_front = time.perf_counter()
    tolerances = np.round(np.geomspace(0.1, 1.0, settings.front), 4)
    front = trade_off_front(start, result.problem, tolerances, test_eyes=test,
                            method=settings.method, max_steps=settings.steps, progress=progress,
                            report_problem=settings.report_accuracy)
    fig = layout_plots.fig_front(front, settings.constraints.pupil_diameter_mm)
    atomic_savefig(fig, out / "front.png", dpi=110)
    rows = front.table()
    atomic_write_text(out / "front.json", json.dumps(jsonable(
        {"tolerances_D": tolerances, "rows": rows, "time_s": time.perf_counter() - t_front}),
        indent=2) + "\n")
    result.files += [out / "front.png", out / "front.json"]
    lines = ["trade-off front (held-out): image at the predicted accommodation (VSOTF); "
             "accommodation RMSE, the display's share and in all (D)"]
    lines += [f"  {r['name']}: {r['image_at_peak']:.4f}; {r['relative_accommodation_rmse_D']:.3f} D, "
              f"{r['accommodation_rmse_D']:.3f} D" for r in rows]
    result.summary += "\n" + "\n".join(lines)
    result.front = front


__all__ = [
    "PARAMETRISATIONS",
    "OptimisationSettings",
    "OptimisationResult",
    "optimise_and_save",
    "estimated_output_bytes",
]
