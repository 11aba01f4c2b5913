"""The fit: value and gradient in feasible coordinates, L-BFGS-B or BFGS, and the trade-off front.

Part of :mod:`lfjax.layout_opt` (its public names are re-exported there)."""

from __future__ import annotations

import sys
import time
import warnings
from dataclasses import dataclass

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optimistix as optx

from lfjax.base.types import FULL, finite_scalar
from lfjax.model.eyes import Eyes
from lfjax.model.layouts import Layout
from lfjax.layout_opt._evaluation import (
    evaluate_layout,
    natural_evaluation,
    parallax_warning,
    tangent_grid_evaluations,
)
from lfjax.layout_opt._feasible import (
    Constraints,
    check_finite_params,
    from_box,
    from_unconstrained,
    to_box,
    to_layout,
    to_unconstrained,
)
from lfjax.layout_opt._objectives import layout_loss
from lfjax.layout_opt._params import as_free, describe_params, free_params
from lfjax.layout_opt._problem import LayoutProblem, Objective

METHODS = ("lbfgsb", "bfgs")


#
# The expensive part of every solver step is the objective and its gradient with respect to
# the subapertures' centres and diameters. It is compiled once (layout_value_and_grad, per
# view count and problem) and shared by both routes and both parametrisations; the
# coordinate maps (box or unconstrained → layout) and their pullbacks are small compiled
# functions, and the solvers' own steps run eagerly on these compiled pieces. Compiling the
# solvers' steps whole would trace the pipeline once per call site (jaxopt's zoom line
# search: 8 times, ~40 s to compile on 2 cores; optimistix BFGS: ~16 s) for no speed-up.

layout_value_and_grad = eqx.filter_jit(eqx.filter_value_and_grad(layout_loss))
"""(loss, gradient) of :func:`layout_loss` with respect to a FreeParams' centres and
diameters, compiled (``layout_value_and_grad(FreeParams, problem)``)."""


def _coords_to_params(coords, template, constraints: Constraints, route: str):
    if route == "box":
        return from_box(coords, template, constraints)
    return from_unconstrained(coords, template, constraints)


@eqx.filter_jit
def _coords_to_free(coords, template, constraints: Constraints, route: str):
    return as_free(_coords_to_params(coords, template, constraints, route))


@eqx.filter_jit
def _coords_pullback(coords, template, constraints: Constraints, route: str, grad_free):
    _, pull = jax.vjp(lambda x: as_free(_coords_to_params(x, template, constraints, route)), coords)
    return pull(grad_free)[0]


class _CoordinateObjective:
    """Loss and gradient in solver coordinates: compiled pieces composed on the host."""

    def __init__(self, template, problem: LayoutProblem, route: str):
        self.template, self.problem, self.route = template, problem, route
        self.constraints = problem.constraints
        self._last = None  # (coordinates, result): jaxopt asks twice for an accepted step

    def value_and_grad(self, coords):
        key = [np.asarray(x) for x in jax.tree_util.tree_leaves(coords)]
        if self._last is not None and len(key) == len(self._last[0]) and all(
                a.shape == b.shape and np.array_equal(a, b) for a, b in zip(key, self._last[0])):
            return self._last[1]
        free = _coords_to_free(coords, self.template, self.constraints, self.route)
        value, grad_free = layout_value_and_grad(free, self.problem)
        result = (value, _coords_pullback(coords, self.template, self.constraints, self.route,
                                          grad_free))
        self._last = (key, result)
        return result

    def optimistix_fn(self):
        """fn(y, args) → (loss, None) for optimistix, differentiable through a custom JVP
        whose tangent is ⟨∇loss, t⟩ from the compiled gradient."""

        @jax.custom_jvp
        def loss(y):
            return self.value_and_grad(y)[0]

        @loss.defjvp
        def loss_jvp(primals, tangents):
            value, grad = self.value_and_grad(primals[0])
            dot = sum(jnp.vdot(g, t, precision=FULL)
                      for g, t in zip(jax.tree_util.tree_leaves(grad),
                                      jax.tree_util.tree_leaves(tangents[0])))
            return value, dot

        return lambda y, args: (loss(y), None)


def _lbfgsb(fun, tol: float):
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message="JAXopt is no longer maintained")
        import jaxopt
    # jit=False: jaxopt's loop and line search run on the host around the compiled
    # objective; backtracking needs one objective + gradient per trial step (zoom ~2x more).
    solver = jaxopt.LBFGSB(fun=fun, value_and_grad=True, tol=tol, maxls=12, jit=False,
                           linesearch="backtracking")
    # Sufficient decrease alone (Armijo), halving the step. jaxopt's backtracking checks the
    # strong Wolfe curvature condition by default, which a search that can only shrink the
    # step rarely meets on a loss that is smooth only piecewise (the predicted peak's grid
    # index switches): measured on the default objective, 4 eyes, 8 steps: 107 objective
    # evaluations, most of them shrinking steps that already improved the loss.
    line_search = solver.run_ls.__self__
    line_search.condition = "armijo"
    line_search.decrease_factor = 0.5
    return solver


class LayoutWarning(UserWarning):
    """A fitted layout that no longer forms a light field (:func:`parallax_warning`)."""


@dataclass
class LayoutFit:
    """Result of :func:`optimise_layout`.

    Attributes
    ----------
    layout, initial_layout : fitted and starting :class:`lfjax.model.layouts.Layout`
    params, initial_params : fitted and starting parameters (LatticeParams or FreeParams)
    history : loss (the problem's weighted objective) at the accepted iterate after each
        solver step, starting with the initial layout's
    method, n_steps, converged : solver, steps taken, tolerance met
    time_s : wall time of the fit, s
    evaluation_s : wall time of all before/after evaluations, s; test_evaluation_s of the
        held-out ones alone
    train : {"before": …, "after": …} :func:`evaluate_layout` on the training eyes (the
        fit's setting)
    test : the same on the held-out eyes (None without them), at the report's setting
    objective, constraints : what was optimised, within which bounds
    """

    layout: Layout
    params: object
    initial_layout: Layout
    initial_params: object
    history: np.ndarray
    method: str
    n_steps: int
    converged: bool
    time_s: float
    train: dict
    test: dict | None
    objective: Objective
    constraints: Constraints
    evaluation_s: float = float("nan")
    test_evaluation_s: float = float("nan")

    @property
    def warning(self) -> str | None:
        """:func:`parallax_warning` of the fitted layout (held-out evaluation when present)."""
        return parallax_warning(self.layout, (self.test or self.train)["after"])

    def summary(self) -> str:
        lines = [f"objective: {self.objective.name}; method {self.method}, {self.n_steps} steps "
                 f"({'converged' if self.converged else 'step limit'}) in {self.time_s:.1f} s, "
                 f"evaluation {self.evaluation_s:.1f} s"
                 + (f" (held-out {self.test_evaluation_s:.1f} s)" if self.test is not None else ""),
                 f"loss: {self.history[0]:.6g} -> {self.history[-1]:.6g}"]
        rows = (("image at the predicted accommodation (mean VSOTF)", "image_at_peak", "{:.4f}"),
                ("accommodation RMSE against the rendered depth (D)", "accommodation_rmse_D", "{:.3f}"),
                ("  of which the display's (relative to each eye's own error on the CDP)",
                 "relative_accommodation_rmse_D", "{:.3f}"),
                ("accommodation gain (slope)", "accommodation_gain", "{:.3f}"),
                ("VSOTF at the rendered depth", "depth_of_field", "{:.4f}"),
                ("worst-depth VSOTF at the rendered depth", "worst_depth_vsotf", "{:.4f}"),
                ("smooth cut-off (cpd)", "resolution", "{:.2f}"))
        for label, ev in (("train", self.train), ("test", self.test)):
            if ev is None:
                continue
            b, a = ev["before"], ev["after"]
            lines.append(f"{label}: {b['n_eyes']} eyes, {b['accuracy']} accuracy; before -> after")
            for text, key, fmt in rows:
                lines.append(f"  {text}: {fmt.format(b[key])} -> {fmt.format(a[key])}")
            lines.append(f"  peaks found (not on a window edge): {b['peak_success_fraction']:.1%} "
                         f"-> {a['peak_success_fraction']:.1%} of {a['n_peaks']}")
        lines.append("fitted: " + describe_params(self.params))
        if self.warning is not None:
            lines.append("WARNING: " + self.warning)
        return "\n".join(lines)


def optimise_layout(
    initial, problem: LayoutProblem, *, method: str = "lbfgsb", max_steps: int = 50,
    tol: float = 1e-5, test_eyes: Eyes | None = None, progress: bool = True,
    name: str = "optimised", report_problem: LayoutProblem | str | None = "full",
    ftol: float = 2e-3, patience: int = 3,
) -> LayoutFit:
    """Fit a layout to the problem's (training) eyes and report it on held-out eyes.

    Parameters
    ----------
    initial : LatticeParams or FreeParams, feasible under ``problem.constraints`` (else a
        ``ValueError`` names the parameter and its allowed range)
    problem : :func:`make_problem`
    method : ``"lbfgsb"`` (jaxopt L-BFGS-B in box coordinates) or ``"bfgs"`` (optimistix BFGS
        in unconstrained coordinates); see the module docstring
    max_steps : solver steps (each one or a few objective + gradient evaluations)
    tol : stopping tolerance (L-BFGS-B: projected-gradient norm; BFGS: rtol = atol = tol)
    ftol, patience : also stop (converged) when the loss has improved by less than
        ``ftol``·|loss| over the last ``patience`` steps. The default objective is smooth
        only piecewise (the predicted peak's grid index switches), so its projected
        gradient rarely falls below ``tol``; measured on 4 eyes, 96 % of 8 steps' gain came
        in the first 2, and each later step improved the loss by 0.01–0.5 %. 0 disables
        the rule.
    test_eyes : held-out population (evaluated before and after, never fitted)
    progress : tqdm progress bar on stderr
    report_problem : how the held-out eyes are scored: ``"full"`` (default; the report's
        accuracy, :meth:`LayoutProblem.at_accuracy`), ``"fit"`` or None (the training
        setting), or a :class:`LayoutProblem` of the same scene. The training eyes are
        scored at the fit's own setting (what the solver saw).

    A layout whose views collapse or whose predicted accommodation stops following the
    rendered depth (:func:`parallax_warning`, judged on the held-out eyes when given) is
    returned with ``LayoutFit.warning`` set and a :class:`LayoutWarning` issued.

    Returns a :class:`LayoutFit`. Raises ``FloatingPointError`` rather than return a
    non-finite layout.
    """
    _check_solver_options(method, max_steps, tol, ftol, patience)
    constraints = problem.constraints
    if isinstance(initial, Layout):
        initial = free_params(initial.centres_mm, initial.diameters_mm)
    t0 = time.perf_counter()
    history = []
    bar = None
    if progress:
        from tqdm.auto import tqdm

        bar = tqdm(total=int(max_steps), desc=f"optimise {problem.objective.name}", unit="step",
                   leave=True)
    try:
        def tick():
            if bar is not None:
                bar.update(1)
                bar.set_postfix(loss=f"{history[-1]:.5g}")

        fit_with = _fit_lbfgsb if method == "lbfgsb" else _fit_bfgs
        fitted, converged = fit_with(initial, problem, max_steps, tol, (ftol, patience),
                                     history, tick)
    finally:
        if bar is not None:
            bar.close()
    t_fit = time.perf_counter() - t0
    history = np.asarray(history, float)
    if not np.all(np.isfinite(history)):
        raise FloatingPointError(f"the objective became non-finite during the fit: {history.tolist()}")
    check_finite_params(fitted)
    layout = to_layout(fitted, constraints, name)
    constraints.check(layout)  # by construction; kept as a guard against regressions
    initial_layout = to_layout(initial, constraints, "initial")
    train = {"before": evaluate_layout(initial, problem), "after": evaluate_layout(fitted, problem)}
    t_eval = time.perf_counter()
    test = _held_out_scores(initial, fitted, problem, test_eyes, report_problem, progress)
    t_end = time.perf_counter()
    fit = LayoutFit(layout, fitted, initial_layout, initial, history, method, len(history) - 1,
                    bool(converged), t_fit, train, test, problem.objective, constraints,
                    t_end - t0 - t_fit, t_end - t_eval)
    if fit.warning is not None:
        warnings.warn(f"fitted layout: {fit.warning}", LayoutWarning, stacklevel=2)
    return fit


def _check_solver_options(method, max_steps, tol, ftol, patience) -> None:
    """:func:`optimise_layout`'s solver options, checked before any work (a ``ValueError``
    names the parameter and its allowed range)."""
    if method not in METHODS:
        raise ValueError(f"method must be one of {METHODS}, got {method!r}")
    if isinstance(max_steps, bool) or int(max_steps) != max_steps or max_steps < 0:
        raise ValueError(f"max_steps must be an integer >= 0, got {max_steps!r}")
    finite_scalar("tol", tol, 0.0, None, lo_open=True)
    finite_scalar("ftol", ftol, 0.0, 1.0)
    if isinstance(patience, bool) or int(patience) != patience or patience < 1:
        raise ValueError(f"patience must be an integer >= 1, got {patience!r}")


def _stalled(history: list, stall: tuple) -> bool:
    """Whether the loss improved by less than ``ftol``·|loss| over the last ``patience``
    steps (``stall`` = (ftol, patience); ftol <= 0 disables the rule)."""
    ftol, patience = stall
    if ftol <= 0 or len(history) <= patience:
        return False
    return history[-1 - patience] - history[-1] < ftol * abs(history[-1])


def _fit_lbfgsb(initial, problem: LayoutProblem, max_steps, tol, stall: tuple, history: list,
                tick):
    """jaxopt L-BFGS-B in box coordinates from ``initial``, at most ``max_steps`` steps,
    appending each step's loss to ``history`` (and calling ``tick``); returns (fitted
    parameters, converged)."""
    constraints = problem.constraints
    x, bounds = to_box(initial, constraints)
    target = _CoordinateObjective(initial, problem, "box")
    solver = _lbfgsb(target.value_and_grad, float(tol))
    state = solver.init_state(x, bounds)
    history.append(float(state.value))
    for _ in range(int(max_steps)):
        if float(state.error) <= tol or _stalled(history, stall):
            break
        x, state = solver.update(x, state, bounds)
        history.append(float(state.value))
        tick()
    converged = float(state.error) <= tol or _stalled(history, stall)
    return from_box(x, initial, constraints), converged


def _fit_bfgs(initial, problem: LayoutProblem, max_steps, tol, stall: tuple, history: list,
              tick):
    """optimistix BFGS in unconstrained coordinates from ``initial``, as
    :func:`_fit_lbfgsb`; a rejected step records the initial loss. Returns (fitted
    parameters, converged)."""
    constraints = problem.constraints
    converged = False
    y = to_unconstrained(initial, constraints)
    target = _CoordinateObjective(initial, problem, "raw")
    fn = target.optimistix_fn()
    solver = optx.BFGS(rtol=float(tol), atol=float(tol))
    f_struct = jax.ShapeDtypeStruct((), jnp.result_type(float))
    state = solver.init(fn, y, None, {}, f_struct, None, frozenset())
    history.append(float(target.value_and_grad(y)[0]))
    for _ in range(int(max_steps)):
        y, state, _ = solver.step(fn, y, None, {}, state, frozenset())
        accepted = int(state.num_accepted_steps) > 0
        history.append(float(state.f_info.f) if accepted else history[0])
        tick()
        done, result = solver.terminate(fn, y, None, {}, state, frozenset())
        if bool(done):
            converged = result == optx.RESULTS.successful
            break
        if accepted and _stalled(history, stall):
            converged = True
            break
    return from_unconstrained(y, initial, constraints), converged


def _held_out_scores(initial, fitted, problem: LayoutProblem, test_eyes: Eyes | None,
                     report_problem, progress: bool = False) -> dict | None:
    """The initial and fitted layouts scored on ``test_eyes`` at ``report_problem``'s setting
    (:func:`optimise_layout`), {"before": …, "after": …}; None without held-out eyes.
    ``progress``: a line on stderr saying what is scored, then a bar over the eyes (the
    full setting's first chunk compiles for a minute or more)."""
    if test_eyes is None:
        return None
    if isinstance(report_problem, LayoutProblem):
        held_out = report_problem.with_eyes(test_eyes)
    else:
        held_out = problem.at_accuracy(report_problem or problem.accuracy, eyes=test_eyes)
    chunk = min(test_eyes.n_eyes, max(problem.eyes.n_eyes, 8))
    if not progress:
        return {"before": evaluate_layout(initial, held_out, chunk=chunk),
                "after": evaluate_layout(fitted, held_out, chunk=chunk)}
    from tqdm.auto import tqdm

    tqdm.write(f"held-out report: the initial and fitted layouts on {test_eyes.n_eyes} held-out "
               f"eyes, {chunk} at a time, at the {held_out.accuracy!r} setting "
               f"({held_out.spectrum.n_wavelengths} wavelengths; the first chunk compiles)",
               file=sys.stderr)
    with tqdm(total=2 * test_eyes.n_eyes, desc="held-out report", unit="eye",
              leave=True) as bar:
        return {"before": evaluate_layout(initial, held_out, chunk=chunk, progress=bar.update),
                "after": evaluate_layout(fitted, held_out, chunk=chunk, progress=bar.update)}


@dataclass
class Front:
    """A trade-off front (:func:`trade_off_front`).

    Attributes
    ----------
    tolerances_D : (n,) accommodation-RMSE tolerances the points were fitted under, D
    fits : the n :class:`LayoutFit` (each with its held-out evaluation in ``test``)
    references : {"n×n": (Layout, evaluation)} tangent grids and {"natural": evaluation}
        on the same held-out eyes and setting
    """

    tolerances_D: np.ndarray
    fits: list
    references: dict

    def table(self) -> list[dict]:
        """One row per point and reference: held-out image quality at the predicted
        accommodation (mean VSOTF) and accommodation RMSE (D)."""
        rows = []
        for t, fit in zip(self.tolerances_D, self.fits):
            ev = (fit.test or fit.train)["after"]
            rows.append(dict(name=f"fit, tolerance {t:.3g} D", tolerance_D=float(t),
                             image_at_peak=ev["image_at_peak"],
                             accommodation_rmse_D=ev["accommodation_rmse_D"],
                             relative_accommodation_rmse_D=ev["relative_accommodation_rmse_D"],
                             accommodation_gain=ev["accommodation_gain"],
                             parameters=describe_params(fit.params)))
        for name, ref in self.references.items():
            ev = ref[1] if isinstance(ref, tuple) else ref
            rows.append(dict(name=name, tolerance_D=None, image_at_peak=ev["image_at_peak"],
                             accommodation_rmse_D=ev["accommodation_rmse_D"],
                             relative_accommodation_rmse_D=ev["relative_accommodation_rmse_D"],
                             accommodation_gain=ev["accommodation_gain"], parameters=None))
        return rows


def trade_off_front(initial, problem: LayoutProblem, tolerances_D, *, test_eyes: Eyes | None = None,
                    method: str = "lbfgsb", max_steps: int = 30, tol: float = 1e-5,
                    progress: bool = True, report_problem="full", references: bool = True) -> Front:
    """Fit one layout per accommodation tolerance (D) — image quality at each eye's own
    predicted accommodation against how far that accommodation may stray — each started
    from ``initial`` and scored on ``test_eyes`` (default the training eyes) at the
    report's setting, with the tangent 2×2…4×4 grids and natural viewing as references.
    Tight tolerances keep the light field's accommodation; loose ones let the views
    shrink towards one pinhole (sharp everywhere, accommodation on the CDP)."""
    tolerances = np.atleast_1d(np.asarray(tolerances_D, float))
    if tolerances.ndim != 1 or tolerances.size < 1 or not np.all(np.isfinite(tolerances)) or np.any(
            tolerances <= 0):
        raise ValueError(f"tolerances_D must be a non-empty list of finite values > 0 D, got {tolerances_D!r}")
    fits = []
    for t in tolerances:
        sub = problem.with_objective(Objective.parse(problem.objective, float(t)))
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", LayoutWarning)  # the front shows collapse on purpose
            fits.append(optimise_layout(initial, sub, method=method, max_steps=max_steps, tol=tol,
                                        test_eyes=test_eyes, progress=progress,
                                        report_problem=report_problem, name=f"front-{t:.3g}D"))
    refs = {}
    if references:
        if isinstance(report_problem, LayoutProblem):
            scored = report_problem.with_eyes(problem.eyes if test_eyes is None else test_eyes)
        else:
            scored = problem.at_accuracy(report_problem or problem.accuracy,
                                         eyes=problem.eyes if test_eyes is None else test_eyes)
        refs.update(tangent_grid_evaluations(scored))
        refs["natural"] = natural_evaluation(scored)
    return Front(tolerances, fits, refs)
