"""Layout optimisation (lfjax.layout_opt): feasibility by construction, bad input, fits that
beat their start inside the pupil, objective gradients against finite differences, JSON,
the ``lfjax optimise`` command and the notebook.

One tiny problem (1 wavelength, Sampling(2 cpd), 2 depths, 4 views, 2 mm diameter cap) is
shared by the tests and by the command-line run, so they reuse one compiled objective.

Covers: lfjax.layout_opt._evaluation, lfjax.layout_opt._feasible, lfjax.layout_opt._files
Covers: lfjax.layout_opt._objectives, lfjax.layout_opt._params, lfjax.layout_opt._problem
Covers: lfjax.layout_opt._run, lfjax.layout_opt._solver, lfjax.cli.optimise
Covers: lfjax.model.layout_files, lfjax.model.layout_plots
"""

import json
import math
from pathlib import Path

import jax
import jax.numpy as jnp
import equinox as eqx
import numpy as np
import pytest

import lfjax
from lfjax import cli
from lfjax import layout_opt as lo
from lfjax.layout_opt import _feasible as feasible_maps

import helpers as H
from lfjax.vision.peak_options import PeakOptions
from lfjax.vision.prepare import States
from lfjax.vision.viewing import Viewing

ROOT = Path(__file__).resolve().parents[2]
NOTEBOOK = ROOT / "notebooks" / "optimise_layout.ipynb"

DEPTHS = [1.0, 3.0]
WAVELENGTHS = [550.0]
SAMPLING = lfjax.Sampling(2.0)
CONSTRAINTS = lo.Constraints(3.0, max_diameter_mm=2.0, min_diameter_mm=0.5)


def tiny_problem(eyes, objective="depth_of_field", constraints=CONSTRAINTS):
    return lo.make_problem(eyes, DEPTHS, constraints, objective, wavelengths_nm=WAVELENGTHS,
                           sampling=SAMPLING)


@pytest.fixture(scope="module")
def dl_problem():
    return tiny_problem(lfjax.model.eyes.aberration_free_eye())


def perturbed_tangent_2x2():
    """The paper's tangent 2×2 grid (pitch = d = 1.5 mm), each view nudged differently."""
    grid = lfjax.grid_layout(2, 3.0)
    shift = np.array([[0.05, -0.03], [-0.04, 0.02], [0.03, 0.04], [-0.02, -0.05]])
    return lo.free_params(np.asarray(grid.centres_mm) + shift,
                          np.asarray(grid.diameters_mm) + [0.05, -0.04, 0.02, -0.03])


def assert_inside(layout, constraints):
    c = np.asarray(layout.centres_mm)
    d = np.asarray(layout.diameters_mm)
    assert np.all(np.hypot(c[:, 0], c[:, 1]) <= constraints.radius_mm + 1e-12)
    assert np.all(d >= constraints.min_diameter_mm - 1e-12)
    assert np.all(d <= constraints.max_diameter_mm + 1e-12)
    assert constraints.violations(layout) == []


# ------------------------------------------------------------------ parametrisations


def test_square_lattice_is_the_papers_grid_and_hex_fills_rings():
    for n in (2, 3, 4):
        lat = lo.tangent_lattice("square", n * n)
        grid = lfjax.grid_layout(n, 3.0)
        np.testing.assert_allclose(lat.centres_mm, grid.centres_mm, atol=1e-12)
        np.testing.assert_allclose(lat.diameters_mm, grid.diameters_mm, atol=1e-12)
    hex7 = lo.lattice_sites("hex", 7)
    np.testing.assert_allclose(np.hypot(*hex7.T), [0] + [1] * 6, atol=1e-12)
    assert len(lo.hex_sites_in_pupil(1.0, 3.0)) == 7  # ring at 1 mm inside R = 1.5 mm
    lat = lo.lattice_params("hex", None, 1.0, 0.8, 0.1)
    assert lat.n_views == 7
    # rotation turns every centre about the pupil centre
    c0 = np.asarray(lo.lattice_params("square", 4, 1.5, 1.5, 0.0).centres_mm)
    c1 = np.asarray(lo.lattice_params("square", 4, 1.5, 1.5, 0.3).centres_mm)
    np.testing.assert_allclose(np.hypot(*c0.T), np.hypot(*c1.T), atol=1e-12)
    np.testing.assert_allclose(np.arctan2(c1[:, 1], c1[:, 0]) - np.arctan2(c0[:, 1], c0[:, 0]),
                               0.3, atol=1e-12)


def test_disc_maps_invert():
    q = np.random.default_rng(0).uniform(-1, 1, (200, 2))
    q = q[np.hypot(*q.T) < 0.999]
    np.testing.assert_allclose(feasible_maps._square_to_disc(feasible_maps._disc_to_square(q)), q, atol=1e-9)
    np.testing.assert_allclose(feasible_maps._plane_to_disc(feasible_maps._disc_to_plane(q)), q, atol=1e-9)
    # the square's boundary lands on the circle, its inside strictly inside
    s = np.stack([np.ones(5), np.linspace(-1, 1, 5)], axis=1)
    np.testing.assert_allclose(np.hypot(*np.asarray(feasible_maps._square_to_disc(s)).T), 1.0, atol=1e-12)


CONSTRAINT_CASES = [
    lo.Constraints(3.0),
    lo.Constraints(3.0, 2.0, 0.5, "contained"),
    lo.Constraints(3.0, 2.0, 0.4, "centre", non_overlap=True),
    lo.Constraints(3.0, 1.5, 0.3, "contained", non_overlap=True),
]


@pytest.mark.parametrize("constraints", CONSTRAINT_CASES, ids=lambda c: f"{c.containment}-{c.non_overlap}")
@pytest.mark.parametrize("kind", ["square4", "square9", "hex7", "free5"])
def test_every_coordinate_maps_to_a_feasible_layout(constraints, kind):
    """Random points of the box, its corners, and huge unconstrained values: never a
    violated constraint."""
    rng = np.random.default_rng(1)
    if kind == "free5":
        template = lo.free_params(np.zeros((5, 2)), np.ones(5))
    else:
        template = lo.tangent_lattice(kind[:-1], int(kind[-1]))
    x0, (lower, upper) = lo.to_box(_feasible(template, constraints), constraints)
    for trial in range(6):
        if trial < 2:  # corners: every coordinate at a bound
            x = lower if trial == 0 else upper
        else:
            x = jax.tree_util.tree_map(
                lambda lo_, hi_: lo_ + (hi_ - lo_) * rng.uniform(size=np.shape(lo_)), lower, upper)
        layout = lo.as_free(lo.from_box(x, template, constraints))
        if trial < 2 and kind == "free5" and constraints.non_overlap:
            # all views at one corner: coincident centres, the documented degenerate case
            assert "distinct centres" in " ".join(constraints.violations(layout))
            continue
        assert np.all(np.asarray(layout.diameters_mm) > 0)
        assert constraints.violations(layout) == [], (trial, constraints.violations(layout))
        u = jax.tree_util.tree_map(lambda a: 30.0 * rng.standard_normal(np.shape(a)), x0)
        layout = lo.as_free(lo.from_unconstrained(u, template, constraints))
        assert constraints.violations(layout) == []


def _feasible(template, constraints):
    if isinstance(template, lo.FreeParams):
        angles = np.linspace(0, 2 * np.pi, 5, endpoint=False)
        c = 0.9 * np.stack([np.cos(angles), np.sin(angles)], axis=1)
        return lo.free_params(c, np.full(5, constraints.min_diameter_mm))
    return lo.initial_lattice(template.kind, template.n_views, constraints)


def test_coordinates_round_trip():
    lat = lo.lattice_params("square", 4, 1.3, 1.1, 0.2)
    for to, back in ((lo.to_box, lo.from_box), (lo.to_unconstrained, lo.from_unconstrained)):
        x = to(lat, CONSTRAINTS)
        x = x[0] if isinstance(x, tuple) else x
        again = back(x, lat, CONSTRAINTS)
        for name in ("pitch_mm", "diameter_mm", "rotation_rad"):
            np.testing.assert_allclose(getattr(again, name), getattr(lat, name), atol=1e-9)
    free = perturbed_tangent_2x2()
    for to, back in ((lo.to_box, lo.from_box), (lo.to_unconstrained, lo.from_unconstrained)):
        x = to(free, CONSTRAINTS)
        x = x[0] if isinstance(x, tuple) else x
        again = back(x, free, CONSTRAINTS)
        np.testing.assert_allclose(again.centres_mm, free.centres_mm, atol=1e-9)
        np.testing.assert_allclose(again.diameters_mm, free.diameters_mm, atol=1e-9)


# ------------------------------------------------------------------ bad input


@pytest.mark.parametrize("make, match", [
    (lambda: lo.to_box(lo.lattice_params("square", 4, 2.5, 1.0), CONSTRAINTS), "pitch_mm"),
    (lambda: lo.to_box(lo.lattice_params("square", 4, 1.5, 0.2), CONSTRAINTS), "diameter_mm"),
    (lambda: lo.to_box(lo.lattice_params("square", 4, 1.5, 2.5), CONSTRAINTS), "diameter_mm"),
    (lambda: lo.to_box(lo.lattice_params("square", 4, 1.0, 1.0, 1.0), CONSTRAINTS), "rotation_rad"),
    (lambda: lo.to_box(lo.free_params([[1.6, 0.0]], [1.0]), CONSTRAINTS), r"centres_mm\[0\]"),
    (lambda: lo.to_box(lo.free_params([[1.3, 0.0]], [0.5]),
                       lo.Constraints(3.0, containment="contained")), r"centres_mm\[0\]"),
    (lambda: lo.to_unconstrained(lo.free_params([[0.5, 0.0], [-0.5, 0.0]], [1.2, 0.9]),
                                 lo.Constraints(3.0, non_overlap=True)), r"diameters_mm\[0\]"),
    (lambda: lo.to_box(lo.tangent_lattice("square", 16),
                       lo.Constraints(3.0, min_diameter_mm=1.0, non_overlap=True)), "no feasible"),
    (lambda: lo.lattice_params("square", 4, float("nan")), "pitch_mm"),
    (lambda: lo.lattice_params("square", 4, 1.0, float("inf")), "diameter_mm"),
    (lambda: lo.free_params([[0.0, float("nan")]], [1.0]), "centres_mm"),
    (lambda: lo.lattice_sites("square", 5), "n_views"),
    (lambda: lo.lattice_sites("hex", 0), "n_views"),
    (lambda: lo.free_params(np.zeros((0, 2)), []), "n_views"),
    (lambda: lo.Constraints(3.0, max_diameter_mm=1.0, min_diameter_mm=1.5), "min_diameter_mm"),
    (lambda: lo.Constraints(3.0, max_diameter_mm=4.0), "max_diameter_mm"),
    (lambda: lo.Constraints(float("nan")), "pupil_diameter_mm"),
    (lambda: lo.Constraints(3.0, containment="inside"), "containment"),
    (lambda: lo.depth_grid(3.0, 1.0, 5), "inverted"),
    (lambda: lo.depth_grid(2.0, 2.0, 5), "empty"),
    (lambda: lo.depth_grid(-1.0, 2.0, 5), r"\[0, inf\]"),
    (lambda: lo.depth_grid(0.0, float("nan"), 5), "high end"),
    (lambda: lo.depth_grid(0.0, 4.0, 0), "n_depths"),
    (lambda: lo.Objective.parse("sharpness"), "objective"),
    (lambda: lo.Objective.parse(None, -0.1), "accommodation_tolerance_D"),
    (lambda: lo.Objective(penalty_per_D2=0.0), "penalty_per_D2"),
    (lambda: lo.Objective.parse({"depth_of_field": 0.0}), "weight must be > 0"),
    (lambda: lo.Objective.parse({"resolution": float("nan")}), "weight of resolution"),
])
def test_bad_input_raises_naming_the_parameter(make, match):
    with pytest.raises(ValueError, match=match):
        make()


def test_problem_refuses_the_paper_reference_and_bad_depths():
    eye = lfjax.model.eyes.aberration_free_eye()
    with pytest.raises(ValueError, match="open_pupil"):
        lo.make_problem(eye, DEPTHS, CONSTRAINTS, options=lfjax.ModelOptions(), sampling=SAMPLING)
    for depths in ([], [-0.5, 1.0], [1.0, float("nan")]):
        with pytest.raises(ValueError, match="depths_D"):
            lo.make_problem(eye, depths, CONSTRAINTS, sampling=SAMPLING)
    with pytest.raises(ValueError, match="window_D"):
        lo.ProblemSetting(window_D=0.0)
    with pytest.raises(ValueError, match="accuracy"):
        lo.ProblemSetting(accuracy="precise")
    with pytest.raises(ValueError, match="peak_method"):
        lo.ProblemSetting(peak_method="auto")
    with pytest.raises(ValueError, match="peak_step_D"):
        lo.make_problem(eye, DEPTHS, CONSTRAINTS, sampling=SAMPLING,
                        setting=lo.ProblemSetting(peak_step_D=1.0, peak_margin_D=0.0))


def test_optimiser_arguments_are_checked(dl_problem):
    start = perturbed_tangent_2x2()
    with pytest.raises(ValueError, match="method"):
        lo.optimise_layout(start, dl_problem, method="adam")
    with pytest.raises(ValueError, match="max_steps"):
        lo.optimise_layout(start, dl_problem, max_steps=-1)
    outside = lo.free_params([[1.7, 0.0], [0, 0], [0, 0.5], [0.5, 0]], [1.0] * 4)
    with pytest.raises(ValueError, match=r"centres_mm\[0\]"):
        lo.optimise_layout(outside, dl_problem, max_steps=1)


# ------------------------------------------------------------------ fits


def test_lbfgsb_fit_beats_the_perturbed_tangent_grid_inside_the_pupil(dl_problem):
    start = perturbed_tangent_2x2()
    fit = lo.optimise_layout(start, dl_problem, method="lbfgsb", max_steps=6, progress=False)
    assert fit.history.shape == (fit.n_steps + 1,)
    assert np.all(np.isfinite(fit.history))
    assert np.all(np.diff(fit.history) <= 1e-9)  # line search: never worse
    before, after = fit.train["before"], fit.train["after"]
    assert after["depth_of_field"] > before["depth_of_field"] + 0.01
    assert fit.history[-1] == pytest.approx(-after["depth_of_field"], rel=1e-9)
    assert_inside(fit.layout, CONSTRAINTS)
    assert isinstance(fit.params, lo.FreeParams) and fit.layout.window_diameter_mm == 2.0


def test_layout_fits_a_real_lenslet_array_and_display_spectrum():
    """The optimiser accepts a real display (lenslet diffraction of an array at 300 mm,
    2-arcmin pixels) and a display's spectrum (laser lines): the objective sees them (it
    differs from the ideal display's), its gradient is finite, and a fit improves on the
    perturbed tangent grid inside the pupil."""
    from lfjax.display.lenslets import display_optics_at
    from lfjax.display.spectra import display_spectrum

    eye = lfjax.model.eyes.aberration_free_eye()
    options = lfjax.ModelOptions(vsotf_reference="open_pupil")
    real = lo.make_problem(eye, DEPTHS, CONSTRAINTS, "depth_of_field", sampling=lfjax.Sampling(1.5),
                           spectrum=display_spectrum("laser", "green", options),
                           display=display_optics_at(300.0, 2.0, pixel_width_arcmin=2.0))
    ideal = lo.make_problem(eye, DEPTHS, CONSTRAINTS, "depth_of_field", sampling=lfjax.Sampling(1.5),
                            wavelengths_nm=[532.0])
    start = perturbed_tangent_2x2()
    value, grad = lo.layout_value_and_grad(start, real)
    assert abs(float(value) - float(lo.layout_value_and_grad(start, ideal)[0])) > 1e-3
    assert all(np.all(np.isfinite(np.asarray(g))) for g in jax.tree_util.tree_leaves(grad))
    fit = lo.optimise_layout(start, real, method="lbfgsb", max_steps=4, progress=False)
    assert fit.train["after"]["depth_of_field"] > fit.train["before"]["depth_of_field"]
    assert_inside(fit.layout, CONSTRAINTS)
    with pytest.raises(ValueError, match="display must be"):
        lo.make_problem(eye, DEPTHS, CONSTRAINTS, display="lenslets")


def test_bfgs_free_fit_without_overlap_beats_its_start():
    """Free views that must not overlap, from the tangent lattice moved 2 % inside the
    bounds: BFGS in unconstrained coordinates improves (with the exact nearest-neighbour
    minimum it rejected every step: a kink where two neighbours tie) and nothing overlaps."""
    constraints = lo.Constraints(3.0, max_diameter_mm=2.0, min_diameter_mm=0.5, non_overlap=True)
    problem = tiny_problem(lfjax.model.eyes.aberration_free_eye(), constraints=constraints)
    lattice = lo.tangent_lattice("square", 4)
    start = lo.feasible_start(lo.free_params(lattice.centres_mm, lattice.diameters_mm),
                              constraints, margin=0.02)
    assert constraints.violations(start) == []
    fit = lo.optimise_layout(start, problem, method="bfgs", max_steps=5, progress=False)
    assert fit.train["after"]["depth_of_field"] > fit.train["before"]["depth_of_field"] + 0.01
    assert np.all(np.diff(fit.history) <= 1e-9)
    assert isinstance(fit.params, lo.FreeParams)
    assert_inside(fit.layout, constraints)


def test_feasible_start_moves_layouts_inside():
    constraints = lo.Constraints(3.0, 1.2, 0.5, "contained", non_overlap=True)
    for params in (lo.tangent_lattice("square", 9), lo.lattice_params("hex", 7, 2.0, 1.9, 1.0),
                   lo.free_params([[1.6, 0.0], [0.0, 0.1], [0.0, -0.1]], [3.0, 0.2, 2.0])):
        moved = lo.feasible_start(params, constraints, margin=0.05)
        assert constraints.violations(moved) == []
        lo.to_unconstrained(moved, constraints)  # accepted as a start


@pytest.mark.parametrize("objective", (*lo.OBJECTIVES, "penalised"))
def test_objective_gradients_match_finite_differences(objective):
    """Reverse-mode gradient of each objective (image at the predicted accommodation and
    accommodation MSE through the grid parabola's vertex of the uncapped peak; depth of
    field; soft cut-off; the default objective with its penalty active) against central
    differences of the same compiled loss along a random direction of all centres and
    diameters, float64."""
    if objective == "penalised":  # the default objective, with a tolerance it exceeds
        objective = lo.Objective.parse(None, 0.01)
    problem = tiny_problem(lfjax.sample_eyes(3, 1), objective)
    if isinstance(objective, lo.Objective):
        ev = lo.evaluate_layout(lo.free_params([[-0.7, -0.6], [0.75, -0.7], [-0.65, 0.8], [0.7, 0.72]],
                                               [1.2, 1.3, 1.25, 1.1]), problem)
        assert ev["penalty"] > 0, "the penalty must be active for this check"
    layout = lo.free_params([[-0.7, -0.6], [0.75, -0.7], [-0.65, 0.8], [0.7, 0.72]],
                            [1.2, 1.3, 1.25, 1.1])
    _, grad = lo.layout_value_and_grad(layout, problem)
    direction = H.random_direction(jax.random.key(0), layout)
    analytic = H.tree_vdot(grad, direction)
    fd = H.directional_fd(lambda f: lo.layout_value_and_grad(f, problem)[0], layout, direction, 1e-5)
    assert abs(fd) > 1e-4, f"{objective}: derivative too small to test"
    np.testing.assert_allclose(analytic, fd, rtol=1e-6)


def test_evaluation_on_held_out_eyes_pads_chunks(dl_problem):
    """Three eyes in chunks of the problem's one: same numbers as one at a time."""
    eyes = lfjax.sample_eyes(7, 3)
    layout = perturbed_tangent_2x2()
    whole = lo.evaluate_layout(layout, dl_problem, eyes)
    single = [lo.evaluate_layout(layout, dl_problem, eyes[i]) for i in range(3)]
    assert whole["n_eyes"] == 3
    assert whole["depth_of_field"] == pytest.approx(np.mean([s["depth_of_field"] for s in single]))
    assert whole["image_at_peak"] == pytest.approx(np.mean([s["image_at_peak"] for s in single]))
    assert whole["values"]["vsotf"].shape == (3, 2)
    assert whole["values"]["peak_D"].shape == (3, 2)


def test_one_pipeline_call_reports_what_two_did():
    """evaluate_layout's merged grid (peak grid + correct focus in one pipeline call) gives
    the numbers of the two separate calls, for depths on the peak grid (shared states) and
    off it (appended states)."""
    eyes = lfjax.sample_eyes(3, 2)
    layout = perturbed_tangent_2x2()
    for depths in ([0.0, 2.0, 4.0], [0.3, 2.6]):
        problem = lo.make_problem(eyes, depths, CONSTRAINTS, wavelengths_nm=WAVELENGTHS,
                                  sampling=SAMPLING)
        states = np.asarray(problem.values_grid.states_D)
        own = np.asarray(problem.values_grid.pair_index)[:-1, -1]
        np.testing.assert_allclose(states[own], depths, atol=1e-9)
        assert states.size == problem.peak_grid.states_D.size + sum(d % 0.25 != 0 for d in depths)
        separate = eqx.tree_at(lambda p: p.values_grid, problem, None, is_leaf=lambda x: x is None)
        merged = lo.evaluate_layout(layout, problem)["values"]
        apart = lo.evaluate_layout(layout, separate)["values"]
        for key in merged:
            np.testing.assert_allclose(merged[key], apart[key], rtol=1e-5, atol=1e-5, err_msg=key)


# ------------------------------------------------------------------ honest evaluation


def pinhole(diameter_mm=0.94):
    """Four views stacked on the pupil centre: one aperture, no light field (what the old
    depth-of-field default converged to)."""
    return lo.free_params(np.full((4, 2), 1e-8), np.full(4, diameter_mm))


@pytest.fixture(scope="module")
def seeded_problem():
    """Three seeded eyes, depths 0, 2 (the CDP) and 4 D, 550 nm, refined ("local") peaks."""
    return lo.make_problem(lfjax.sample_eyes(11, 3), [0.0, 2.0, 4.0], CONSTRAINTS,
                           wavelengths_nm=WAVELENGTHS, sampling=SAMPLING,
                           setting=lo.ProblemSetting(peak_method="local"))


def test_collapsed_pinhole_is_reported_as_through_focus_sees_it(seeded_problem):
    """The pinhole's peaks are the global maxima through_focus finds on a finer grid over a
    window holding the CDP (every depth's peak near the CDP), not a peak capped near the
    rendered depth: accommodation RMSE above 1 D, gain near 0, and a warning."""
    from lfjax.vision.focus import through_focus

    problem = seeded_problem
    ev = lo.evaluate_layout(pinhole(), problem)
    layout = lo.to_layout(pinhole(), problem.constraints)
    tf = through_focus(
        problem.eyes,
        layout,
        States.grid(
            np.round(np.arange(0.0, 6.01, 0.1), 9), depths_D=[0.0, 2.0, 4.0], window_D=3.0
        ),
        Viewing(pupil_diameter_mm=3.0, cdp_D=2.0),
        spectrum=problem.spectrum,
        sampling=SAMPLING,
        options=problem.options,
        peaks=PeakOptions(metrics=("vsotf",), method="newton"),
        check_aliasing=False,
    )
    reference = np.asarray(tf.continuous_peaks("vsotf").accommodation_D)
    np.testing.assert_allclose(ev["values"]["peak_D"], reference, atol=5e-3)
    assert np.all(np.abs(reference - 2.0) < 0.6)  # every eye focuses near the CDP
    assert ev["accommodation_rmse_D"] > 1.0
    assert ev["relative_accommodation_rmse_D"] > 1.0
    assert abs(ev["accommodation_gain"]) < 0.2
    assert lo.parallax_warning(lo.to_layout(pinhole(), problem.constraints), ev) is not None
    tangent = lo.evaluate_layout(lo.tangent_lattice("square", 4), problem)
    assert tangent["accommodation_gain"] > 0.8
    assert lo.parallax_warning(lo.to_layout(lo.tangent_lattice("square", 4), problem.constraints),
                               tangent) is None


def test_a_peak_on_the_window_edge_counts_as_a_failure():
    """A 1 D hyperopic eye (c(2,0) = -0.3248 µm on 3 mm) needs 1 D more than the rendered
    depth; with a 0.25 D margin its peaks for the CDP (2 D: window [1.75, 2.25]) and the
    4 D depth (window [1.75, 4.25]) lie beyond their windows' upper ends and are reported
    on the edge, as failures, while its peak for 0 D (window [0, 2.25]) is found at 1 D."""
    z = np.zeros((1, 15))
    z[0, 4] = -0.3248
    eye = lfjax.Eyes(z, 3.0)
    problem = lo.make_problem(eye, [0.0, 2.0, 4.0], CONSTRAINTS, wavelengths_nm=WAVELENGTHS,
                              sampling=SAMPLING,
                              setting=lo.ProblemSetting(peak_margin_D=0.25))
    ev = lo.evaluate_layout(lo.tangent_lattice("square", 4), problem)
    edge = ev["values"]["peak_at_edge"][0]
    assert edge.tolist() == [False, True, True]
    assert ev["values"]["peak_success"][0].tolist() == [True, False, False]
    assert ev["n_edge_peaks"] == 2 and ev["peak_success_fraction"] == pytest.approx(1 / 3)
    assert ev["values"]["peak_D"][0, 1] == pytest.approx(2.25, abs=0.05)
    assert ev["values"]["peak_D"][0, 2] == pytest.approx(4.25, abs=0.05)
    assert ev["values"]["peak_D"][0, 0] == pytest.approx(1.0, abs=0.25)


def test_default_objective_ranks_collapse_below_the_tangent_grid(seeded_problem):
    """By default (image at the predicted accommodation, display error <= 0.25 D) views that
    coincide — a pinhole, or one large aperture — score worse than the paper's tangent 2×2
    grid; unconstrained image quality alone would prefer the pinhole (why the constraint)."""
    problem = seeded_problem.with_objective(lo.DEFAULT_OBJECTIVE)
    loss = {name: float(lo.layout_value_and_grad(p, problem)[0]) for name, p in (
        ("tangent", lo.as_free(lo.tangent_lattice("square", 4))), ("pinhole", pinhole()),
        ("one aperture", pinhole(2.0)))}
    assert loss["pinhole"] > loss["tangent"] + 0.5
    assert loss["one aperture"] > loss["tangent"] + 0.5
    quality_only = problem.with_objective("image_at_peak")
    assert float(lo.layout_value_and_grad(pinhole(), quality_only)[0]) < \
        float(lo.layout_value_and_grad(lo.as_free(lo.tangent_lattice("square", 4)), quality_only)[0])


def test_front_and_references_on_a_tiny_case(seeded_problem, tmp_path):
    """Two tolerances, one step each, scored at the fit's setting: a front of fitted
    points, the tangent grid and natural viewing (whose display error is 0 by definition:
    each depth is its own focal plane), drawn into a PNG. (The first tolerance is the
    default objective's 0.25 D: its loss and evaluation are the programs the tests above
    compiled; each tolerance is a static part of the problem, a compile of its own.)"""
    from lfjax.model import layout_plots

    problem = seeded_problem.with_objective(lo.DEFAULT_OBJECTIVE)
    front = lo.trade_off_front(lo.tangent_lattice("square", 4), problem,
                               [problem.objective.accommodation_tolerance_D, 1.0], max_steps=1,
                               progress=False, report_problem=None, references=False)
    front.references.update(lo.tangent_grid_evaluations(problem, sizes=(2,)))
    front.references["natural"] = lo.natural_evaluation(problem)
    rows = front.table()
    assert [r["name"] for r in rows][-2:] == ["2x2", "natural"]
    assert rows[-1]["relative_accommodation_rmse_D"] == 0.0
    assert all(math.isfinite(r["image_at_peak"]) for r in rows)
    # the tangent reference is the fit's start: the fitted points' losses are no worse
    for fit in front.fits:
        assert fit.history[-1] <= fit.history[0] + 1e-9
    fig = layout_plots.fig_front(front, 3.0)
    fig.savefig(tmp_path / "front.png")
    assert (tmp_path / "front.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    with pytest.raises(ValueError, match="tolerances_D"):
        lo.trade_off_front(lo.tangent_lattice("square", 4), problem, [0.0])


# ------------------------------------------------------------------ files


def test_layout_json_round_trip(tmp_path):
    params = lo.lattice_params("hex", 7, 1.0, 0.8, 0.1)
    layout = lo.to_layout(params, lo.Constraints(3.0), "hex7")
    path = lo.save_layout_json(tmp_path / "layout.json", layout, 3.0,
                               objective={"name": "depth_of_field", "value": 0.5},
                               provenance={"seed": 0}, parameters=params)
    again, record = lo.load_layout_json(path)
    np.testing.assert_allclose(again.centres_mm, layout.centres_mm, atol=1e-15)
    np.testing.assert_allclose(again.diameters_mm, layout.diameters_mm, atol=1e-15)
    assert again.name == "hex7" and record["pupil_diameter_mm"] == 3.0
    assert record["objective"]["value"] == 0.5 and record["provenance"]["seed"] == 0
    assert "lfjax_version" in record["provenance"]
    back = lo.params_from_dict(record["parameters"])
    np.testing.assert_allclose(back.centres_mm, params.centres_mm, atol=1e-15)
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps({"format": "something else"}))
    with pytest.raises(ValueError, match="not an lfjax layout"):
        lo.load_layout_json(bad)
    record["diameters_mm"][0] = float("nan")
    bad.write_text(json.dumps(record))
    with pytest.raises(ValueError, match="finite"):
        lo.load_layout_json(bad)


# ------------------------------------------------------------------ command line

# one held-out eye, as many as training eyes: the held-out report reuses the fit's compiled
# evaluation (the chunk of eyes is part of its shape)
TINY_CLI = ["optimise", "--train-eyes", "1", "--test-eyes", "1", "--wavelengths", "550",
            "--freq-step", "2", "--depths", "1", "3", "--n-depths", "2", "--max-diameter", "2",
            "--steps", "2", "--parametrisation", "free", "--no-progress",
            "--report-accuracy", "fit"]


def test_cli_optimise_tiny_case(capsys, tmp_path, monkeypatch):
    monkeypatch.setattr(cli.cache, "enable_compilation_cache", lambda folder=None: None)
    out = tmp_path / "fit"
    code = cli.main([*TINY_CLI, "--out", str(out)])
    captured = capsys.readouterr()
    assert code == 0, captured.err[-2000:]
    assert str(out) in captured.out.strip().splitlines()[-1]
    names = {p.name for p in out.iterdir()}
    assert names == {"layout.json", "layouts.png", "through_focus.png", "history.png"}
    for name in names - {"layout.json"}:
        assert (out / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    layout, record = lo.load_layout_json(out / "layout.json")
    assert layout.n_subapertures == 4
    assert_inside(layout, CONSTRAINTS)
    test = record["objective"]["test"]
    assert test["before"]["n_eyes"] == 1
    assert math.isfinite(test["after"]["image_at_peak"])
    assert test["after"]["accuracy"] == "fit" and 0 <= test["after"]["peak_success_fraction"] <= 1
    assert record["objective"]["train"]["after"]["loss"] <= \
        record["objective"]["train"]["before"]["loss"] + 1e-9
    assert record["objective"]["accommodation_tolerance_D"] == 0.25
    assert record["provenance"]["seed_test"] == 1 and record["parameters"]["kind"] == "free"
    # a second run into the same folder needs --force
    code = cli.main([*TINY_CLI, "--out", str(out)])
    assert code == 2 and "--force" in capsys.readouterr().err


@pytest.mark.parametrize("args, message", [
    (["--depths", "3", "1"], "inverted"),
    (["--depths", "2", "2"], "empty"),
    (["--depths", "-1", "2"], ">= 0 D"),
    (["--depths", "0", "nan"], "--depths"),
    (["--views", "0"], "--views"),
    (["--views", "5"], "--views"),
    (["--pupil", "nan"], "--pupil"),
    (["--pupil", "4"], "--pupil"),
    (["--n-depths", "1"], "--n-depths"),
    (["--min-diameter", "2.5", "--max-diameter", "2"], "--min-diameter"),
    (["--objective", "sharpness"], "--objective"),
    (["--objective", "resolution=nan"], "--objective"),
    (["--wavelengths", "600", "500"], "--wavelengths"),
    (["--train-eyes", "0"], "--train-eyes"),
    (["--display-distance", "600"], "--display-distance"),
    (["--pixel-arcmin", "-1"], "--pixel-arcmin"),
    (["--spectrum", "plasma"], "--spectrum"),
    (["--accommodation-tolerance", "0"], "--accommodation-tolerance"),
    (["--front", "1"], "--front"),
    (["--front", "3", "--test-eyes", "0"], "--front"),
])
def test_cli_bad_input_one_line_exit_2(capsys, tmp_path, args, message):
    out = tmp_path / "never"
    code = cli.main(["optimise", *args, "--out", str(out)])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2
    assert len(err) == 1 and message in err[0] and "error" in err[0]
    assert not out.exists()


# ------------------------------------------------------------------ notebook


def test_notebook_matches_its_script_twin():
    H.committed_notebook_outputs(NOTEBOOK)


def test_notebook_executes(tmp_path):
    """notebooks/optimise_layout.ipynb runs top to bottom at its tiny size
    (LFJAX_NOTEBOOK_SIZE=tiny; the committed outputs are from the 'small' size)."""
    _, images, text = H.execute_notebook_tiny(NOTEBOOK, tmp_path)
    assert len(images) >= 3
    assert "held-out" in text
