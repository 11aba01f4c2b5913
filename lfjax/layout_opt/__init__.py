"""Subaperture layout optimisation: fit where the views enter the pupil and how large they are.

A light-field display samples the eye's pupil with subapertures (views). Their layout sets
the depth of field, the accommodation the display drives and the resolution the eye sees.
This module fits a layout to a population of virtual eyes with the pure, differentiable
pipeline (:func:`lfjax.kernel.pipeline.retinal_metrics`) and reports it on a held-out population.

Parametrisations
----------------
:class:`LatticeParams`
    a square (n×n) or hexagonal lattice: pitch (mm), one subaperture diameter (mm) and a
    rotation (rad). The lattice sites are chosen once (``lattice_sites``), so the view count
    and every array shape stay fixed during a fit.
:class:`FreeParams`
    free centres (n_views, 2) and diameters (n_views,), mm.

Both expose ``centres_mm`` and ``diameters_mm``, differentiable in their leaves, and so does
:class:`lfjax.model.layouts.Layout`; every objective accepts any of the three.

Constraints (:class:`Constraints`)
----------------------------------
* inside the pupil, one of two readings (``containment``):
  ``"centre"`` (default) — each subaperture's centre lies in the pupil, |c| ≤ R. The pupil
  crops the rest, as it crops the paper's tangent n×n grids (whose corner views reach
  beyond the pupil: |c| + d/2 > R), and every view transmits light (at least the part of
  its disc on the pupil side of its centre). ``"contained"`` — each disc lies wholly in
  the pupil, |c| + d/2 ≤ R (the paper's grids violate it);
* diameters in [``min_diameter_mm``, ``max_diameter_mm``] (positive by construction;
  ``max_diameter_mm`` also sizes the static FFT windows);
* optionally no overlap, |c_i − c_j| ≥ (d_i + d_j)/2 (``non_overlap``).

Violations are impossible by construction: a fit moves in *feasible coordinates* whose
every value maps to a feasible layout, and a starting layout that is not feasible raises a
``ValueError`` naming the parameter and its allowed range. (One degenerate exception: free
views that must not overlap and whose centres coincide exactly would need a zero diameter;
the pipeline refuses it, "diameters_mm must be > 0 mm".) Two coordinate systems, two
solvers:

* ``method="lbfgsb"`` — box coordinates, solved with ``jaxopt.LBFGSB``. Lattice: diameter
  and pitch as fractions in [0, 1] of their feasible interval (the pitch interval depends
  on the diameter when discs must be contained or must not overlap), rotation in
  ±π/4 (square) or ±π/6 (hex). Free: each centre a point of the square [−1, 1]² mapped onto
  the pupil disc by the elliptical grid map (smooth, one-to-one; Fong 2015), each diameter
  a fraction in [0, 1] between the lower bound and its cap (the largest diameter the
  constraints allow at that centre: ``max_diameter_mm``, 2(R − |c|) when contained, a
  smooth lower bound of the nearest other centre's distance when views must not overlap).
* ``method="bfgs"`` — unconstrained coordinates, solved with ``optimistix.BFGS``:
  fractions = sigmoid(u), centre = R·tanh(|u|)·u/|u| (the tanh-radial map of the plane
  onto the open disc), rotation free.

Objectives (each a mean over the eyes and the rendered depths of the problem)
-------------------------------------------------------------------------------
Every eye's *predicted accommodation* is found as the project's peak finder finds it
(:func:`predicted_peaks`): the global maximum of its through-focus VSOTF on a grid over a
window that holds both the rendered depth and the display's CDP (:func:`peak_window`) —
the two places a light-field display can draw the eye — refined from the grid. Nothing
caps the search around the rendered depth, so a layout that lets the eye focus on the CDP
is seen doing so; a maximum on the window's edge is reported as a failure.

``"accommodation_aware"`` (the default, :data:`DEFAULT_OBJECTIVE`)
    maximise ``image_at_peak`` subject to the display's accommodation error within
    ``accommodation_tolerance_D`` (0.25 D), by a quadratic penalty
    (:func:`accommodation_penalty`). The display's error is each eye's error at the
    rendered depth less its own error on the CDP, where every view reaches the eye
    unshifted as from a real point (:class:`Objective`).
``"image_at_peak"`` (maximised)
    population-mean VSOTF at each eye's own predicted accommodation. Alone it is won by
    removing the light field: views stacked on the pupil centre make one pinhole, sharp at
    every depth, whose every eye focuses on the CDP (tests pin the ordering).
``"depth_of_field"`` (maximised)
    population-mean VSOTF at the correct accommodation (accommodation = rendered depth),
    :func:`depth_of_field`. It also rewards the pinhole.
``"accommodation"`` (minimised)
    mean squared error (D²) of the predicted accommodation against the rendered depth,
    :func:`accommodation_mse`.
``"resolution"`` (maximised)
    a smooth MTF cut-off (cpd) at the correct accommodation: the frequency extent over
    which the radial MTF exceeds ``mtf_threshold`` (0.05, the paper's cut-off criterion),
    counted with a logistic step of width ``mtf_softness`` instead of a hard threshold,
    :func:`soft_cutoff_cpd`. For a monotone MTF it equals the cut-off frequency to within
    the frequency step; where the MTF of an off-CDP rendering dips below the threshold and
    rises again, the bands above it count too.

Two settings (:class:`ProblemSetting`'s ``accuracy``, given to :func:`make_problem`): a fit runs on the cheap ``"fit"``
setting (550 nm, a 0.25 D peak grid, the grid parabola's vertex), and the report scores
held-out eyes on the ``"full"`` one (31 wavelengths, a 0.25 D grid refined by the
``"local"`` three-state fit) — model no more than the fit needs, verify on what the study
uses. :func:`trade_off_front` fits one layout per tolerance and scores them beside the
tangent grids and natural viewing.

A dict of weights gives a weighted sum: loss = −w_dof·DoF + w_acc·MSE − w_res·resolution
(units: VSOTF, D², cpd — scale the weights accordingly, e.g. resolution 0.01 per cpd).

Why the open-pupil VSOTF reference is enforced
-----------------------------------------------
The paper normalises VSOTF by the same layout without aberrations. That reference moves
with the layout: shrink the subapertures and reference and eye both lose contrast, but
the eye's defocus and aberrations matter less, so the ratio rises. Every objective then
rewards shrinking the subapertures without bound (measured by :func:`diameter_scan`: 2×2
at 1.5 mm pitch, 4 seeded eyes, correct accommodation at 0–4 D, 450/550/650 nm: mean
VSOTF 0.82 at d = 0.5 mm against 0.43 at the tangent 1.5 mm). Scored against the natural
open pupil (``ModelOptions(vsotf_reference="open_pupil")``, a reference that does not
depend on the layout) the same scan has an interior optimum at d ≈ 1 mm (0.367 against
0.316 for the tangent grid; worst depth 0.291 against 0.148). :func:`make_problem`
refuses any other reference.

What the old default favoured (benchmarks/studies/layout_optimisation.py, 2×2 lattice, 10 training
eyes, 200 held-out eyes, 0–4 D): depth of field alone, with overlapping views allowed,
collapsed the lattice onto the pupil centre (one 0.93 mm aperture, no light field left),
and an evaluation that searched for peaks only ±0.3 D around each depth reported 0.28 D
of accommodation RMSE for it where every eye focuses within 0.3 D of the CDP (1.4 D RMSE).
Hence the accommodation-aware default and the uncapped evaluation.

The package's parts, each a private module importing only those before it, behind this one
public face: ``_params`` (parametrisations), ``_feasible`` (constraints and the feasible
coordinates a solver moves in), ``_problem`` (the objective and the problem set-up),
``_objectives`` (what a layout is scored on, and the loss), ``_evaluation`` (scoring on
held-out eyes, curves, scans), ``_solver`` (the fit and the trade-off front), ``_files``
(JSON) and ``_run`` (a whole optimisation as one call: :class:`OptimisationSettings`, checked
plain values, and :func:`optimise_and_save`, the fit, its report and its files — what
``lfjax optimise`` runs). Reading a layout file lives below every application, in :mod:`lfjax.model.layout_files`.
"""

from __future__ import annotations

from lfjax.model.layout_files import load_layout_json as load_layout_json
from lfjax.layout_opt._evaluation import accommodation_gain as accommodation_gain
from lfjax.layout_opt._evaluation import diameter_scan as diameter_scan
from lfjax.layout_opt._evaluation import evaluate_layout as evaluate_layout
from lfjax.layout_opt._evaluation import natural_evaluation as natural_evaluation
from lfjax.layout_opt._evaluation import parallax_warning as parallax_warning
from lfjax.layout_opt._evaluation import tangent_grid_evaluations as tangent_grid_evaluations
from lfjax.layout_opt._evaluation import through_focus_curves as through_focus_curves
from lfjax.layout_opt._feasible import Constraints as Constraints
from lfjax.layout_opt._feasible import feasible_start as feasible_start
from lfjax.layout_opt._feasible import from_box as from_box
from lfjax.layout_opt._feasible import from_unconstrained as from_unconstrained
from lfjax.layout_opt._feasible import initial_lattice as initial_lattice
from lfjax.layout_opt._feasible import to_box as to_box
from lfjax.layout_opt._feasible import to_layout as to_layout
from lfjax.layout_opt._feasible import to_unconstrained as to_unconstrained
from lfjax.layout_opt._files import params_from_dict as params_from_dict
from lfjax.layout_opt._files import params_to_dict as params_to_dict
from lfjax.layout_opt._files import save_layout_json as save_layout_json
from lfjax.layout_opt._objectives import accommodation_mse as accommodation_mse
from lfjax.layout_opt._objectives import accommodation_penalty as accommodation_penalty
from lfjax.layout_opt._objectives import combine as combine
from lfjax.layout_opt._objectives import correct_focus_metrics as correct_focus_metrics
from lfjax.layout_opt._objectives import depth_of_field as depth_of_field
from lfjax.layout_opt._objectives import layout_loss as layout_loss
from lfjax.layout_opt._objectives import objective_terms as objective_terms
from lfjax.layout_opt._objectives import predicted_accommodation_D as predicted_accommodation_D
from lfjax.layout_opt._objectives import predicted_peaks as predicted_peaks
from lfjax.layout_opt._objectives import resolution as resolution
from lfjax.layout_opt._objectives import soft_cutoff_cpd as soft_cutoff_cpd
from lfjax.layout_opt._params import CONTAINMENTS as CONTAINMENTS
from lfjax.layout_opt._params import LATTICES as LATTICES
from lfjax.layout_opt._params import FreeParams as FreeParams
from lfjax.layout_opt._params import LatticeParams as LatticeParams
from lfjax.layout_opt._params import as_free as as_free
from lfjax.layout_opt._params import default_max_diameter_mm as default_max_diameter_mm
from lfjax.layout_opt._params import describe_params as describe_params
from lfjax.layout_opt._params import free_params as free_params
from lfjax.layout_opt._params import hex_sites_in_pupil as hex_sites_in_pupil
from lfjax.layout_opt._params import lattice_params as lattice_params
from lfjax.layout_opt._params import lattice_sites as lattice_sites
from lfjax.layout_opt._params import tangent_lattice as tangent_lattice
from lfjax.layout_opt._problem import ACCURACIES as ACCURACIES
from lfjax.layout_opt._problem import DEFAULT_OBJECTIVE as DEFAULT_OBJECTIVE
from lfjax.layout_opt._problem import FULL_WAVELENGTHS_NM as FULL_WAVELENGTHS_NM
from lfjax.layout_opt._problem import OBJECTIVES as OBJECTIVES
from lfjax.layout_opt._problem import LayoutProblem as LayoutProblem
from lfjax.layout_opt._problem import Objective as Objective
from lfjax.layout_opt._problem import ProblemSetting as ProblemSetting
from lfjax.layout_opt._problem import check_depth_range as check_depth_range
from lfjax.layout_opt._problem import check_measured_pupil as check_measured_pupil
from lfjax.layout_opt._problem import depth_grid as depth_grid
from lfjax.layout_opt._problem import envelope_layout as envelope_layout
from lfjax.layout_opt._problem import guard_sampling as guard_sampling
from lfjax.layout_opt._problem import make_problem as make_problem
from lfjax.layout_opt._problem import peak_window as peak_window
from lfjax.layout_opt._solver import METHODS as METHODS
from lfjax.layout_opt._solver import Front as Front
from lfjax.layout_opt._solver import LayoutFit as LayoutFit
from lfjax.layout_opt._solver import LayoutWarning as LayoutWarning
from lfjax.layout_opt._solver import layout_value_and_grad as layout_value_and_grad
from lfjax.layout_opt._solver import optimise_layout as optimise_layout
from lfjax.layout_opt._solver import trade_off_front as trade_off_front
from lfjax.layout_opt._eye_draw import EYE_DRAW_KEYS as EYE_DRAW_KEYS
from lfjax.layout_opt._eye_draw import MEASURED_PUPIL_MM as MEASURED_PUPIL_MM
from lfjax.layout_opt._eye_draw import EyeDraw as EyeDraw
from lfjax.layout_opt._eye_draw import planning_eyes as planning_eyes
from lfjax.layout_opt._run import PARAMETRISATIONS as PARAMETRISATIONS
from lfjax.layout_opt._run import OptimisationResult as OptimisationResult
from lfjax.layout_opt._run import OptimisationSettings as OptimisationSettings
from lfjax.layout_opt._run import optimise_and_save as optimise_and_save
from lfjax.layout_opt._run import estimated_output_bytes as estimated_output_bytes

__all__ = [
    "OBJECTIVES",
    "LATTICES",
    "CONTAINMENTS",
    "METHODS",
    "lattice_sites",
    "hex_sites_in_pupil",
    "LatticeParams",
    "lattice_params",
    "tangent_lattice",
    "initial_lattice",
    "feasible_start",
    "FreeParams",
    "free_params",
    "as_free",
    "Constraints",
    "to_box",
    "from_box",
    "to_unconstrained",
    "from_unconstrained",
    "Objective",
    "LayoutProblem",
    "DEFAULT_OBJECTIVE",
    "ACCURACIES",
    "FULL_WAVELENGTHS_NM",
    "depth_grid",
    "check_depth_range",
    "check_measured_pupil",
    "peak_window",
    "predicted_peaks",
    "accommodation_penalty",
    "accommodation_gain",
    "parallax_warning",
    "LayoutWarning",
    "default_max_diameter_mm",
    "natural_evaluation",
    "tangent_grid_evaluations",
    "Front",
    "trade_off_front",
    "envelope_layout",
    "guard_sampling",
    "make_problem",
    "ProblemSetting",
    "EyeDraw",
    "EYE_DRAW_KEYS",
    "planning_eyes",
    "correct_focus_metrics",
    "depth_of_field",
    "soft_cutoff_cpd",
    "resolution",
    "predicted_accommodation_D",
    "accommodation_mse",
    "objective_terms",
    "combine",
    "layout_loss",
    "layout_value_and_grad",
    "evaluate_layout",
    "through_focus_curves",
    "diameter_scan",
    "LayoutFit",
    "describe_params",
    "to_layout",
    "optimise_layout",
    "params_to_dict",
    "params_from_dict",
    "save_layout_json",
    "load_layout_json",
    "MEASURED_PUPIL_MM",
    "PARAMETRISATIONS",
    "OptimisationSettings",
    "OptimisationResult",
    "optimise_and_save",
    "estimated_output_bytes",
]
