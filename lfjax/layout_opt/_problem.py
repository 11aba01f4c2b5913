"""The objective and the problem set-up: eyes, spectrum, depths, sampling and reference, built once per fit.

Part of :mod:`lfjax.layout_opt` (its public names are re-exported there)."""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from lfjax.base.errors import ParameterError
from lfjax.base.types import finite_scalar
from lfjax.base.units import check_dioptres
from lfjax.display.lenslets import DisplayOptics
from lfjax.display.lenticular import check_display_for_layout
from lfjax.model.eyes import Eyes
from lfjax.model.layouts import Layout, make_layout
from lfjax.model.options import ModelOptions
from lfjax.vision.peak_options import PEAK_METHODS
from lfjax.vision.prepare import check_eye_chunk
from lfjax.kernel.pipeline import (
    Accommodation,
    PipelineConfig,
    Scene,
    reference_normalisers,
)
from lfjax.planner.plan import plan_sampling
from lfjax.planner.scene import PlanScene
from lfjax.base.sampling import Sampling
from lfjax.model.spectral import Spectrum, make_spectrum
from lfjax.layout_opt._feasible import Constraints

OBJECTIVES = ("image_at_peak", "depth_of_field", "accommodation", "resolution")


MAXIMISED = ("image_at_peak", "depth_of_field", "resolution")


DEFAULT_OBJECTIVE = "accommodation_aware"


DEFAULT_TOLERANCE_D = 0.25


ACCURACIES = ("fit", "full")


DEFAULT_WAVELENGTHS_NM = (550.0,)
"""The fit setting's spectrum: one wavelength at the LCA reference (550 nm, no chromatic
defocus). A fit needs the ordering of layouts, not their absolute VSOTF; the report
re-scores the fitted layout on 31 wavelengths (:data:`FULL_WAVELENGTHS_NM`)."""


@dataclass(frozen=True)
class Objective:
    """What a fit optimises (static, hashable).

    Attributes
    ----------
    weights : ((name, weight), …) over :data:`OBJECTIVES`; loss = Σ ± weight·term with −
        for the maximised terms (image_at_peak and depth_of_field: VSOTF; resolution: cpd)
        and + for accommodation (D²)
    accommodation_tolerance_D : a constraint on the display's accommodation error (D), or
        None: the RMSE over eyes and depths of each eye's predicted accommodation error at
        the rendered depth less its own error on the CDP (where every view reaches the eye
        unshifted, as from a real point: what remains is the eye's refraction and lag,
        which no display causes or corrects — natural viewing alone misses the rendered
        depth by 0.3–0.4 D RMS on the Thibos population, so a bound on the raw error
        would be unattainable for reasons that are not the layout's). When the RMSE
        exceeds the tolerance the loss gains ``penalty_per_D2``·(RMSE − tolerance)² (a
        quadratic penalty: zero, with zero gradient, inside the tolerance)
    penalty_per_D2 : weight of that penalty, loss units per D²
    mtf_threshold : MTF level of the cut-off (the paper's 0.05)
    mtf_softness : width of the logistic step that counts frequencies above the threshold

    The default, ``Objective()`` (:data:`DEFAULT_OBJECTIVE`, "accommodation_aware"), is
    image quality at each eye's own predicted accommodation (population-mean VSOTF at the
    global peak of its through-focus curve) subject to an accommodation RMSE within
    0.25 D (the display's share, above), about the eye's depth of focus: a display that drives no accommodation (views
    stacked on the pupil centre: a pinhole whose every eye focuses on the CDP) violates it
    by a dioptre or more and scores far below the paper's tangent grids.
    """

    weights: tuple = (("image_at_peak", 1.0),)
    accommodation_tolerance_D: float | None = DEFAULT_TOLERANCE_D
    penalty_per_D2: float = 100.0
    mtf_threshold: float = 0.05
    mtf_softness: float = 0.02

    def __post_init__(self):
        w = tuple((str(k), float(v)) for k, v in dict(self.weights).items())
        for name, value in w:
            if name not in OBJECTIVES:
                raise ParameterError("objective", "{objective}: {name!r} unknown; choose from {allowed}",
                                     name=name, allowed=OBJECTIVES)
            finite_scalar(f"weight of {name}", value, 0.0, parameter="objective")
        if not any(v > 0 for _, v in w):
            raise ParameterError("objective", "{objective}: at least one weight must be > 0, got {got}",
                                 got=dict(w))
        object.__setattr__(self, "weights", w)
        if self.accommodation_tolerance_D is not None:
            object.__setattr__(self, "accommodation_tolerance_D", finite_scalar(
                "accommodation_tolerance_D", self.accommodation_tolerance_D, 0.0, 2.0, lo_open=True))
        finite_scalar("penalty_per_D2", self.penalty_per_D2, 0.0, None, lo_open=True)
        finite_scalar("mtf_threshold", self.mtf_threshold, 0.0, 1.0, lo_open=True)
        finite_scalar("mtf_softness", self.mtf_softness, 0.0, 1.0, lo_open=True)

    @classmethod
    def parse(cls, objective, accommodation_tolerance_D="default") -> Objective:
        """An Objective from itself, ``"accommodation_aware"`` (the default), a name of
        :data:`OBJECTIVES` (alone, unconstrained) or a {name: weight} dict (unconstrained).
        ``accommodation_tolerance_D`` (D or None) replaces the constraint when given."""
        if isinstance(objective, Objective):
            out = objective
        elif objective is None or objective == DEFAULT_OBJECTIVE:
            out = cls()
        elif isinstance(objective, str):
            if objective not in OBJECTIVES:
                raise ParameterError("objective", "{objective} must be {default!r}, one of {allowed} or a "
                                     "dict of weights, got {got!r}", default=DEFAULT_OBJECTIVE,
                                     allowed=OBJECTIVES, got=objective)
            out = cls(((objective, 1.0),), accommodation_tolerance_D=None)
        elif isinstance(objective, dict):
            out = cls(tuple(objective.items()), accommodation_tolerance_D=None)
        else:
            raise ParameterError("objective", "{objective} must be a name, a dict of weights or an "
                                 "Objective, got {got!r}", got=objective)
        if accommodation_tolerance_D != "default":
            out = dataclasses.replace(out, accommodation_tolerance_D=accommodation_tolerance_D)
        return out

    def weight(self, name: str) -> float:
        return dict(self.weights).get(name, 0.0)

    @property
    def active(self) -> tuple[str, ...]:
        return tuple(k for k, v in self.weights if v > 0)

    @property
    def needs_peaks(self) -> bool:
        """Whether the loss needs each eye's predicted accommodation."""
        return (self.accommodation_tolerance_D is not None
                or "image_at_peak" in self.active or "accommodation" in self.active)

    @property
    def name(self) -> str:
        terms = (self.active[0] if len(self.active) == 1
                 else " + ".join(f"{v:g}·{k}" for k, v in self.weights if v > 0))
        if self.accommodation_tolerance_D is None:
            return terms
        return f"{terms} s.t. accommodation RMSE <= {self.accommodation_tolerance_D:g} D"

    def as_dict(self) -> dict:
        return dict(weights=dict(self.weights), accommodation_tolerance_D=self.accommodation_tolerance_D,
                    penalty_per_D2=self.penalty_per_D2, mtf_threshold=self.mtf_threshold,
                    mtf_softness=self.mtf_softness)


class LayoutProblem(eqx.Module):
    """Everything a layout objective needs besides the layout (see :func:`make_problem`).

    Attributes
    ----------
    eyes : the population the objective averages over
    spectrum : wavelengths, weights, LCA, SCE
    depths_D : (n_depth,) rendered depths, D
    cdp_D : () central depth plane, D
    accommodation : the correct-focus states (accommodation = rendered depth)
    peak_grid : the accommodation grid on which each eye's through-focus VSOTF is
        evaluated to find its predicted accommodation: absolute states shared by every
        depth, each depth seeing (``peak_allowed``) the states between its own depth and
        the CDP, widened by ``peak_margin_D`` on both sides (lower end ≥ 0 D). The two
        attractors of a light-field display — the rendered depth and the display's CDP —
        are both inside every depth's window, so a layout that lets the eye focus on the
        CDP is seen doing so.
    peak_depths_D : (n_depth + 1,) the rendered depths and, last, the CDP: a point rendered
        on the CDP reaches the eye from every view unshifted, as a real point would, so the
        eye's peak there is its own accommodation error (refraction, lag, aberrations),
        which the display neither causes nor can correct; errors are also reported
        relative to it
    peak_allowed : (n_depth + 1, n_k) bool, the states each of those depths sees
    reference : open-pupil VSOTF/Strehl normalisers (independent of the layout)
    config, objective, constraints, options : static
    accuracy : static, ``"fit"`` (the cheap training setting) or ``"full"`` (the report's)
    peak_method : static, refinement of the grid peak (:mod:`lfjax.vision.peaks`)
    peak_step_D, peak_margin_D : static, the peak grid's step and margin, D
    window_D : static, accommodation offsets (± D) drawn by :func:`through_focus_curves`
    spectrum_given : static, whether the spectrum was the caller's (a display's) rather
        than V(λ)-weighted wavelengths (the full setting then keeps it)
    display : the display's optics (lenslet diffraction, pixels) or None (ideal display)
    values_grid : the peak grid's states and the correct-focus states in one grid, for
        reports: pairs (n_depth + 1, n_k + 1), the first n_k columns the peak grid's
        (``peak_allowed``), the last each rendered depth's correct focus (unused in the
        CDP's row). A report then computes each shared state's elemental OTFs once
        (:func:`evaluate_layout`); None for a problem built without it
    """

    eyes: Eyes
    spectrum: Spectrum
    depths_D: Float[Array, " n_depth"]
    cdp_D: Float[Array, ""]
    accommodation: Accommodation
    peak_grid: Accommodation
    peak_depths_D: Float[Array, " n_peak_depth"]
    peak_allowed: Array
    reference: tuple
    config: PipelineConfig = eqx.field(static=True)
    objective: Objective = eqx.field(static=True)
    constraints: Constraints = eqx.field(static=True)
    options: ModelOptions = eqx.field(static=True)
    accuracy: str = eqx.field(static=True)
    peak_method: str = eqx.field(static=True)
    peak_step_D: float = eqx.field(static=True)
    peak_margin_D: float = eqx.field(static=True)
    window_D: float = eqx.field(static=True)
    spectrum_given: bool = eqx.field(static=True)
    display: DisplayOptics | None = None
    values_grid: Accommodation | None = None

    @property
    def pupil_diameter_mm(self) -> float:
        return self.constraints.pupil_diameter_mm

    def with_eyes(self, eyes: Eyes) -> LayoutProblem:
        """The same problem on another population (the held-out eyes)."""
        if eyes.measured_pupil_mm < self.pupil_diameter_mm:
            raise ValueError(f"eyes measured on {eyes.measured_pupil_mm:g} mm cannot be evaluated "
                             f"on a {self.pupil_diameter_mm:g} mm pupil")
        return eqx.tree_at(lambda p: p.eyes, self, eyes)

    def with_objective(self, objective) -> LayoutProblem:
        """The same problem with another objective."""
        return dataclasses.replace(self, objective=Objective.parse(objective))

    def at_accuracy(self, accuracy: str = "full", eyes: Eyes | None = None,
                    sampling: Sampling | None = None) -> LayoutProblem:
        """The same scene at another accuracy setting (:func:`make_problem`'s
        ``accuracy``), on ``eyes`` (default this problem's); the sampling is planned anew
        for that setting unless given."""
        eyes = self.eyes if eyes is None else eyes
        return make_problem(
            eyes, np.asarray(self.depths_D, float), self.constraints, self.objective,
            cdp_D=float(self.cdp_D), options=self.options,
            spectrum=self.spectrum if self.spectrum_given else None, display=self.display,
            setting=ProblemSetting(accuracy, window_D=self.window_D), sampling=sampling)

    @property
    def setting(self) -> ProblemSetting:
        """This problem's :class:`ProblemSetting` (its peak grid resolved; the eye chunk is
        the pipeline's, :attr:`config`)."""
        return ProblemSetting(self.accuracy, self.peak_step_D, self.peak_margin_D,
                              self.peak_method, self.window_D, self.config.eye_chunk)

    def scene(self, layout, depths_D=None) -> Scene:
        """The pipeline's scene of ``layout`` (a :class:`~lfjax.model.layouts.Layout`, mm) in
        this problem, rendering ``depths_D`` (D; default the problem's); the problem's strip
        display must be built for the layout's views."""
        check_display_for_layout(self.display, layout)
        return Scene(layout.centres_mm, layout.diameters_mm, self.cdp_D,
                     self.depths_D if depths_D is None else depths_D,
                     self.pupil_diameter_mm, self.display)


def depth_grid(low_D: float, high_D: float, n_depths: int) -> np.ndarray:
    """``n_depths`` rendered depths evenly spanning [low_D, high_D] (D), validated:
    0 ≤ low < high, finite; n_depths ≥ 2 (or 1 with low == high). A refused range is a
    :class:`~lfjax.base.errors.ParameterError` naming ``depth_range_D`` (the pair
    (low_D, high_D), as :func:`lfjax.design.fit_design` and :class:`OptimisationSettings`
    take it); a refused count names ``n_depths``."""
    lo, hi = check_depth_range((low_D, high_D), allow_empty=True)
    if isinstance(n_depths, bool) or int(n_depths) != n_depths or n_depths < 1:
        raise ParameterError("n_depths", "{n_depths} must be an integer >= 1, got {got!r}", got=n_depths)
    if n_depths == 1 and hi == lo:
        return np.array([lo])
    check_depth_range((lo, hi))
    if n_depths < 2:
        raise ParameterError("n_depths", "{n_depths} must be >= 2 for a depth range, got {got}",
                             got=n_depths)
    return np.linspace(lo, hi, int(n_depths))


def check_depth_range(depth_range_D, allow_empty: bool = False) -> tuple[float, float]:
    """(low, high) of a rendered depth range in D, finite with 0 ≤ low < high ≤ the model's
    :data:`~lfjax.base.units.MAX_DIOPTRES_D` (low == high
    too with ``allow_empty``); a :class:`~lfjax.base.errors.ParameterError` naming
    ``depth_range_D`` otherwise."""
    try:
        lo, hi = (float(v) for v in depth_range_D)
    except (TypeError, ValueError):
        raise ParameterError("depth_range_D", "{depth_range_D} must be two numbers (low, high) in D, "
                             "got {got!r}", got=depth_range_D) from None
    for end, value in (("low", lo), ("high", hi)):
        if not (math.isfinite(value) and value >= 0):
            raise ParameterError("depth_range_D", "{depth_range_D}: the {end} end must be finite and "
                                 ">= 0 D (0 D is optical infinity; allowed [0, inf]), got {got!r}",
                                 end=end, got=value)
    check_dioptres("depth_range_D", (lo, hi), "rendered depth")
    if hi < lo or (hi == lo and not allow_empty):
        raise ParameterError("depth_range_D", "{depth_range_D} must satisfy 0 <= low < high (D); got "
                             "low = {lo:g}, high = {hi:g} ({how})", lo=lo, hi=hi,
                             how="empty" if hi == lo else "inverted")
    return lo, hi


def check_measured_pupil(pupil_diameter_mm: float, measured_pupil_mm: float) -> None:
    """The calculation pupil must not exceed the pupil the eyes were measured on (their
    Zernike coefficients are defined over it); a :class:`~lfjax.base.errors.ParameterError`
    naming ``pupil_diameter_mm`` otherwise."""
    if measured_pupil_mm < pupil_diameter_mm - 1e-12:
        raise ParameterError("pupil_diameter_mm", "{pupil_diameter_mm} = {pupil:g} exceeds the eyes' "
                             "measured pupil {measured:g} mm", pupil=pupil_diameter_mm,
                             measured=measured_pupil_mm)


def check_depths(depths_D) -> np.ndarray:
    """Rendered depths (D) as a 1-D float array; non-empty, finite and ≥ 0 D, or a ValueError."""
    d = np.atleast_1d(np.asarray(depths_D, float))
    if d.ndim != 1 or d.size < 1:
        raise ValueError(f"depths_D must be a non-empty 1-D array, got shape {d.shape}")
    if not np.all(np.isfinite(d)) or np.any(d < 0):
        raise ValueError(f"depths_D must be finite and >= 0 D (0 D is optical infinity), got {d.tolist()}")
    return d


def peak_window(depths_D, cdp_D: float, step_D: float, margin_D: float):
    """The accommodation grid on which predicted accommodation is searched (host numbers).

    Each rendered depth d sees the states in [max(min(d, CDP) − margin, 0),
    max(d, CDP) + margin]: both places a light-field display can draw the eye to. States
    are multiples of ``step_D`` from 0 D. Returns (states_D (n_k,), index (n_depth, n_k),
    allowed (n_depth, n_k) bool); every state is seen by at least one depth.
    """
    depths = check_depths(depths_D)
    step = finite_scalar("peak_step_D", step_D, 0.0, 1.0, lo_open=True)
    margin = finite_scalar("peak_margin_D", margin_D, 0.0, 5.0)
    lo = np.maximum(np.minimum(depths, cdp_D) - margin, 0.0)
    hi = np.maximum(depths, cdp_D) + margin
    states = np.round(np.arange(0.0, hi.max() + 0.5 * step, step), 9)
    allowed = (states[None, :] >= lo[:, None] - 1e-9) & (states[None, :] <= hi[:, None] + 1e-9)
    if np.any(allowed.sum(axis=1) < 3):
        raise ValueError(f"peak_step_D = {step:g} D leaves fewer than 3 states in some depth's "
                         f"window; use a smaller step or a larger margin")
    used = allowed.any(axis=0)
    states, allowed = states[used], allowed[:, used]
    index = np.broadcast_to(np.arange(states.size), allowed.shape)
    return states, index, allowed


def _values_grid_pairs(states_D, depths_D, cdp_D: float):
    """(states (n,), pair_index (n_depth + 1, n_k + 1)) of :attr:`LayoutProblem.values_grid`:
    the peak grid's states, then every rendered depth not already among them; the first
    n_k columns index the peak grid's states, the last each depth's own state (index 0 in
    the CDP's row, which has no correct-focus pair)."""
    states = np.asarray(states_D, float)
    depths = np.asarray(depths_D, float)
    missing = [d for d in depths if not np.any(np.abs(states - d) <= 1e-9)]
    union = np.concatenate([states, np.asarray(missing, float)])
    own = np.array([int(np.argmin(np.abs(union - d))) for d in depths] + [0])
    index = np.empty((depths.size + 1, states.size + 1), np.int32)
    index[:, :-1] = np.arange(states.size)
    index[:, -1] = own
    return union, index


def envelope_layout(constraints: Constraints) -> Layout:
    """The worst case of the feasible set for the sampling guard: the largest disc at the
    pupil edge (widest defocus blur and display shift) and the smallest one (widest
    diffraction blur)."""
    radius = constraints.centre_radius_mm
    if constraints.containment == "contained":
        radius = constraints.radius_mm - 0.5 * constraints.max_diameter_mm
    edge = max(radius * (1 - 1e-6), 0.0)
    return make_layout([[edge, 0.0], [0.0, 0.0]],
                       [constraints.max_diameter_mm, constraints.min_diameter_mm],
                       constraints.pupil_diameter_mm, name="envelope",
                       window_diameter_mm=constraints.max_diameter_mm)


def guard_sampling(constraints: Constraints, depths_D, cdp_D: float, wavelengths_nm,
                   eyes: Eyes | None = None, window_D: float = 0.5,
                   options: ModelOptions = ModelOptions(vsotf_reference="open_pupil"),
                   display: DisplayOptics | None = None, spectral_weights=None,
                   pairs: tuple | None = None) -> Sampling:
    """Frequency sampling whose aliasing guard holds for every feasible layout: the
    planner's guard (``estimate_accuracy=False``) on :func:`envelope_layout`, for ``eyes``
    (None: aberration-free), accommodation within ±``window_D`` of each depth, or for the
    (accommodation D, depth D) ``pairs`` when given."""
    depths = check_depths(depths_D)
    extra = {}
    if pairs is not None:
        extra = dict(pairs=(np.asarray(pairs[0], float), np.asarray(pairs[1], float)),
                     accommodation_D=np.unique(np.asarray(pairs[0], float)))
    scene = PlanScene(
        envelope_layout(constraints), pupil_diameter_mm=constraints.pupil_diameter_mm,
        cdp_D=float(cdp_D), depths_D=depths,
        accommodation_window_D=None if pairs is not None else window_D,
        wavelengths_nm=np.asarray(wavelengths_nm, float), spectral_weights=spectral_weights,
        eyes=eyes, options=options, display=display, **extra,
    )
    return plan_sampling(scene, estimate_accuracy=False).sampling


def evaluated_pairs(depths, cdp: float, step_D: float, margin_D: float):
    """Every (accommodation D, depth D) pair a problem evaluates: the peak grid (rendered
    depths and the CDP) and the correct focus."""
    peak_depths = np.append(depths, cdp)
    states, index, allowed = peak_window(peak_depths, cdp, step_D, margin_D)
    depth_of = np.broadcast_to(peak_depths[:, None], allowed.shape)
    return (np.concatenate([states[index][allowed], depths]),
            np.concatenate([depth_of[allowed], depths]))


_SETTINGS = {
    # peak grid step (D), margin (D), refinement
    "fit": dict(peak_step_D=0.25, peak_margin_D=0.5, peak_method="vertex"),
    "full": dict(peak_step_D=0.25, peak_margin_D=0.75, peak_method="local"),
}


@dataclass(frozen=True)
class ProblemSetting:
    """How a :class:`LayoutProblem` evaluates a layout (static, hashable), checked when made.

    Attributes
    ----------
    accuracy : ``"fit"`` (default) — what a fit needs: :func:`make_problem`'s wavelengths
        (550 nm by default), predicted accommodation on a 0.25 D grid within 0.5 D around each
        depth's window, located by the grid parabola's vertex (``"vertex"``: no evaluation
        beyond the grid); ``"full"`` — what a report needs: 31 wavelengths (400–700 nm,
        10 nm), a 0.25 D grid within 0.75 D around each window, refined by ``"local"`` (the
        sweep's and the study's peak finder). Both find the *global* maximum of each eye's
        through-focus VSOTF over a window holding the rendered depth and the CDP
        (:func:`peak_window`); a maximum on a window edge is reported as such.
    peak_step_D : the peak grid's step, D > 0 (None: the accuracy's, 0.25 D)
    peak_margin_D : the peak grid's margin around each depth's window, D ≥ 0 (None: the
        accuracy's)
    peak_method : refinement of the grid peak, a method of :mod:`lfjax.vision.peaks` other
        than ``"auto"`` (None: the accuracy's)
    window_D : accommodation offsets (± D) drawn by :func:`through_focus_curves`, > 0
    eye_chunk : eyes evaluated together inside the pipeline's map, ≥ 1 (None: one at a time)
    """

    accuracy: str = "fit"
    peak_step_D: float | None = None
    peak_margin_D: float | None = None
    peak_method: str | None = None
    window_D: float = 0.5
    eye_chunk: int | None = None

    def __post_init__(self):
        if self.accuracy not in ACCURACIES:
            raise ParameterError("accuracy", "{accuracy} must be one of {allowed}, got {got!r}",
                                 allowed=", ".join(ACCURACIES), got=self.accuracy)
        methods = tuple(m for m in PEAK_METHODS if m != "auto")
        if self.peak_method is not None and self.peak_method not in methods:
            raise ParameterError("peak_method", "{peak_method} must be one of {allowed} or None, "
                                 "got {got!r}", allowed=", ".join(methods), got=self.peak_method)
        if self.peak_step_D is not None:
            object.__setattr__(self, "peak_step_D",
                               finite_scalar("peak_step_D", self.peak_step_D, 0.0, lo_open=True))
        if self.peak_margin_D is not None:
            object.__setattr__(self, "peak_margin_D",
                               finite_scalar("peak_margin_D", self.peak_margin_D, 0.0))
        object.__setattr__(self, "window_D",
                           finite_scalar("window_D", self.window_D, 0.0, None, lo_open=True))
        object.__setattr__(self, "eye_chunk", check_eye_chunk(self.eye_chunk))

    def resolved(self) -> dict:
        """The peak grid's step and margin (D) and the refinement method, the accuracy's
        values where this setting leaves them None."""
        setting = dict(_SETTINGS[self.accuracy])
        for key in setting:
            if getattr(self, key) is not None:
                setting[key] = getattr(self, key)
        return setting


FULL_WAVELENGTHS_NM = tuple(float(w) for w in np.arange(400.0, 701.0, 10.0))
"""The full setting's spectrum: 400–700 nm in 10 nm steps (31 wavelengths, the study's)."""


def make_problem(
    eyes: Eyes, depths_D, constraints: Constraints = Constraints(), objective=DEFAULT_OBJECTIVE,
    *, cdp_D: float = 2.0, wavelengths_nm=DEFAULT_WAVELENGTHS_NM,
    options: ModelOptions = ModelOptions(vsotf_reference="open_pupil"),
    sampling: Sampling | None = None, planning_eyes: Eyes | None = None,
    spectrum: Spectrum | None = None, display: DisplayOptics | None = None,
    setting: ProblemSetting = ProblemSetting(),  # noqa: B008 (frozen, checked once)
) -> LayoutProblem:
    """A layout-optimisation problem, validated on the host.

    Parameters
    ----------
    eyes : population the objective averages over (the training eyes)
    depths_D : rendered depths, D (finite, ≥ 0)
    constraints : feasible layouts (pupil, diameter range, containment, overlap)
    objective : ``"accommodation_aware"`` (default), a name of :data:`OBJECTIVES`, a
        {name: weight} dict or an :class:`Objective`
    cdp_D : the display's central depth plane, D
    wavelengths_nm : spectrum (V(λ)-weighted), nm; the ``"full"`` setting replaces it by
        :data:`FULL_WAVELENGTHS_NM`
    options : model options; ``vsotf_reference`` must be ``"open_pupil"`` (module docstring)
    sampling : frequency sampling; default :func:`guard_sampling` for the constraints'
        envelope and every (accommodation, depth) pair the problem evaluates (the peak
        grid and the correct focus), for ``planning_eyes`` (default ``eyes``)
    spectrum : a :class:`~lfjax.model.spectral.Spectrum` instead of ``wavelengths_nm`` (e.g. a
        display's, :func:`lfjax.display.spectra.display_spectrum`); kept by both settings
    display : :class:`~lfjax.display.lenslets.DisplayOptics` of a real display (lenslet diffraction,
        pixels; e.g. ``LensletArray.optics()``) the layout is optimised for; default the
        paper's ideal display. The reference stays the ideal open pupil.
    setting : :class:`ProblemSetting`: the accuracy (``"fit"``, the default, or ``"full"``,
        which replaces the wavelengths by :data:`FULL_WAVELENGTHS_NM`), the peak grid and its
        refinement, the through-focus window and the eye chunk
    """
    if not isinstance(setting, ProblemSetting):
        raise ParameterError("setting", "{setting} must be lfjax.layout_opt.ProblemSetting, got {got}",
                             got=type(setting).__name__)
    accuracy, window_D, eye_chunk = setting.accuracy, setting.window_D, setting.eye_chunk
    setting = setting.resolved()
    if display is not None and not isinstance(display, DisplayOptics):
        raise ValueError(f"display must be lfjax.display.lenslets.DisplayOptics or None, got {type(display).__name__}")
    if options.vsotf_reference != "open_pupil":
        raise ValueError(
            "layout objectives need ModelOptions(vsotf_reference='open_pupil'): the paper's "
            "reference (the same layout without aberrations) shrinks with the subapertures, so "
            f"every objective would reward shrinking them without bound; got {options.vsotf_reference!r}"
        )
    if not isinstance(eyes, Eyes):
        raise ValueError(f"eyes must be lfjax.Eyes, got {type(eyes).__name__}")
    if not np.all(np.isfinite(np.asarray(eyes.zernike_um))):
        raise ValueError("eyes.zernike_um contains non-finite values (NaN or inf)")
    check_measured_pupil(constraints.pupil_diameter_mm, eyes.measured_pupil_mm)
    depths = check_depths(depths_D)
    cdp = finite_scalar("cdp_D", cdp_D, 0.0)
    objective = Objective.parse(objective)
    spectrum_given = spectrum is not None
    if spectrum is None:
        wl = FULL_WAVELENGTHS_NM if accuracy == "full" else wavelengths_nm
        spectrum = make_spectrum(np.atleast_1d(np.asarray(wl, float)), options)
    elif not isinstance(spectrum, Spectrum):
        raise ValueError(f"spectrum must be lfjax.Spectrum or None, got {type(spectrum).__name__}")
    wl = np.asarray(spectrum.wavelengths_nm, float)
    peak_depths = np.append(depths, cdp)
    states, index, allowed = peak_window(peak_depths, cdp, setting["peak_step_D"],
                                         setting["peak_margin_D"])
    if sampling is None:
        plan_eyes = eyes if planning_eyes is None else planning_eyes
        pairs = evaluated_pairs(depths, cdp, setting["peak_step_D"], setting["peak_margin_D"])
        sampling = guard_sampling(constraints, depths, cdp, wl, plan_eyes, window_D, options,
                                  display, np.asarray(spectrum.weights), pairs=pairs)
    config = PipelineConfig.build(wl, constraints.max_diameter_mm, constraints.pupil_diameter_mm,
                                  sampling, options, eye_chunk, display=display)
    accommodation = Accommodation.per_depth(depths[:, None], options, constraints.pupil_diameter_mm)
    peak_grid = Accommodation.shared(states, index, options, constraints.pupil_diameter_mm)
    values_grid = Accommodation.shared(*_values_grid_pairs(states, depths, cdp), options,
                                       constraints.pupil_diameter_mm)
    dtype = jnp.result_type(float)
    cdp_arr, depths_arr = jnp.asarray(cdp, dtype), jnp.asarray(depths, dtype)
    # Open-pupil reference: independent of the layout, so computed once (any layout will do).
    any_layout = Scene(jnp.zeros((1, 2), dtype), jnp.full((1,), constraints.max_diameter_mm, dtype),
                       cdp_arr, depths_arr, constraints.pupil_diameter_mm)
    reference = reference_normalisers(any_layout, spectrum, accommodation, config)
    return LayoutProblem(eyes, spectrum, depths_arr, cdp_arr, accommodation, peak_grid,
                         jnp.asarray(peak_depths, dtype), jnp.asarray(allowed), tuple(jax.lax.stop_gradient(r) for r in reference),
                         config, objective, constraints, options, accuracy,
                         setting["peak_method"], float(setting["peak_step_D"]),
                         float(setting["peak_margin_D"]), window_D, spectrum_given, display,
                         values_grid)
