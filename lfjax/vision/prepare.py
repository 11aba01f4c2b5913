"""The preparation seam: what a computation settles on the host before its compiled call.

Every entry point (:func:`~lfjax.vision.focus.through_focus`,
:func:`~lfjax.vision.focus.through_focus_variants`, :func:`~lfjax.vision.focus.metrics_at`,
:func:`~lfjax.vision.psf.polychromatic_otf`) and every application that calls the pipeline
on a layout (the sweep, the paper's study, the display studies) prepares it in the same five
steps, here and only here:

1. **checks** of the concrete inputs, each naming the parameter (eyes, calculation pupil,
   CDP, Zernike coefficients, every view of the layout reaching into the pupil; a
   :class:`States` checks its own depths and states, in the model's dioptric range, when it
   is built);
2. **states**: which (rendered depth, accommodation) pairs are computed — a :class:`States`,
   built by one of its constructors, the way diffrax's ``SaveAt`` says which times to save;
3. **sampling**: a given :class:`~lfjax.base.sampling.Sampling` is checked against the
   field guard (an :class:`~lfjax.base.sampling.AliasingError` when the PSF would wrap), and
   none given is planned (:func:`default_sampling`, the planner's field guard);
   :func:`with_aliasing_retry` makes a refused step finer and runs again;
4. the static configuration, :class:`~lfjax.kernel.pipeline.PipelineConfig`;
5. the :class:`~lfjax.kernel.scene.Scene` pytree.

:func:`prepare` runs the five and returns a :class:`Prepared`: what the compiled call takes
(``scene``, ``config``, ``accommodation(options)``) and what its result reports
(``states``, ``sampling``).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import jax.numpy as jnp
import numpy as np

from lfjax.base.errors import ParameterError
from lfjax.base.sampling import AliasingError, Sampling, finer_step
from lfjax.base.types import is_concrete
from lfjax.base.units import check_dioptres
from lfjax.display.lenticular import check_display_for_layout
from lfjax.kernel.optics import field_check, validate_coefficients, validate_pupil, validate_states
from lfjax.kernel.pipeline import PipelineConfig
from lfjax.kernel.scene import Accommodation, Scene
from lfjax.model.eyes import Eyes, check_eyes
from lfjax.model.layouts import Layout, check_views_in_pupil, open_pupil
from lfjax.model.options import ModelOptions
from lfjax.model.spectral import Spectrum, make_spectrum
from lfjax.planner.plan import plan_sampling
from lfjax.planner.scene import PlanScene
from lfjax.vision.viewing import Viewing, check_viewing

DEFAULT_OFFSETS_D = np.round(np.arange(-5, 6) * 0.2, 9)
"""The paper's through-focus: states −1 … +1 D around each rendered depth in 0.2 D steps."""

PLANNED_NEIGHBOURHOOD_D = DEFAULT_OFFSETS_D
"""Offsets (D) around each rendered depth that every default sampling covers: the default
through-focus grid (:data:`DEFAULT_OFFSETS_D`)."""

STATE_KINDS = ("grid", "around", "every", "per_depth")
"""How a :class:`States` was built (its constructor)."""


# ----------------------------------------------------------------------------- states


def _check_states(accommodation_D, depths_D) -> None:
    acc = np.asarray(accommodation_D, float)
    depth = np.asarray(depths_D, float)
    if acc.ndim != 1 or acc.size < 1:
        raise ValueError(
            f"accommodation_D must be a 1-D grid of >= 1 states, got shape {acc.shape}")
    if depth.ndim != 1 or depth.size < 1:
        raise ValueError(f"depths_D must be a 1-D array of >= 1 depths, got shape {depth.shape}")
    if not np.all(np.isfinite(acc)) or not np.all(np.isfinite(depth)):
        raise ValueError("accommodation_D and depths_D must be finite")
    if np.any(acc < 0):
        raise ValueError(
            "accommodation_D must be >= 0 D (hyperopic limit: an eye cannot focus beyond "
            f"infinity); got states down to {acc.min():g} D. Drop them, e.g. with "
            "relative_accommodation_grid(..., hyperopic_limit=True)"
        )
    if np.any(depth < 0):
        raise ValueError(
            f"depths_D must be >= 0 D (0 D is optical infinity); got {depth[depth < 0].tolist()}"
        )
    check_dioptres("accommodation_D", acc, "accommodation state")
    check_dioptres("depths_D", depth, "rendered depth")


def relative_accommodation_grid(depths_D, offsets_D, hyperopic_limit: bool = True):
    """Absolute accommodation grid covering ``depth + offset`` for every depth (host).

    Returns (accommodation_D (n_acc,), index (n_depth, n_offsets)) where
    ``accommodation_D[index[d, k]] == depths_D[d] + offsets_D[k]``; entries excluded by the
    hyperopic limit (negative accommodation) have index −1. Values are rounded to 1e-9 D
    so shared states are computed once.
    """
    depths = np.atleast_1d(np.asarray(depths_D, float))
    offsets = np.atleast_1d(np.asarray(offsets_D, float))
    states = np.round(depths[:, None] + offsets[None, :], 9)
    allowed = states >= 0 if hyperopic_limit else np.ones_like(states, bool)
    if not np.any(allowed):
        raise ValueError("the accommodation grid excludes every allowed state (all < 0 D)")
    grid = np.unique(states[allowed])
    index = np.where(allowed, np.searchsorted(grid, states), -1)
    return grid, index


def _used_states(grid, index, allowed):
    """Keep each absolute state once, and only those some allowed pair uses: (grid, index)."""
    used = np.zeros(grid.size, bool)
    used[index[allowed]] = True
    remap = np.cumsum(used) - 1
    return grid[used], np.where(allowed, remap[index], 0)


@dataclass(frozen=True, eq=False)
class States:
    """The (rendered depth, accommodation) pairs a computation evaluates, in D.

    Build one with a constructor; each checks its inputs (values and shapes, messages naming
    the parameter):

    * :meth:`grid` — one absolute grid shared by every depth, optionally only the states
      within ±``window_D`` of each (:func:`~lfjax.vision.focus.through_focus` with
      ``accommodation_D``, the sweep, the study);
    * :meth:`around` — states relative to each depth (the paper's through-focus; states
      below 0 D are not ``allowed``);
    * :meth:`every` — every state for every depth
      (:func:`~lfjax.vision.psf.polychromatic_otf`); the arrays may be traced;
    * :meth:`per_depth` — a row of states per depth (:func:`~lfjax.vision.focus.metrics_at`);
      the arrays may be traced.

    Attributes
    ----------
    kind : the constructor, one of :data:`STATE_KINDS`
    depths_D : (n_depth,) rendered depths, D (host float64 for ``grid``/``around``; as given
        otherwise)
    states_D : the states computed, D: each distinct state once, (n_states,), for
        ``grid``/``around``; (n_acc,) for ``every``; (n_depth, n_acc) for ``per_depth``
    index : (n_depth, n_acc) int, the entry of ``states_D`` of each pair (0 where not
        allowed); None for ``every``/``per_depth``
    allowed : (n_depth, n_acc) bool, False where a state is not computed (outside the
        window, or beyond the hyperopic limit); None for ``every``/``per_depth`` (all are)
    absolute_D : (n_depth, n_acc) the absolute state of every entry, D, also of those not
        allowed (``grid``/``around``); None otherwise
    """

    kind: str
    depths_D: Any
    states_D: Any
    index: np.ndarray | None = None
    allowed: np.ndarray | None = None
    absolute_D: np.ndarray | None = None

    @classmethod
    def grid(cls, accommodation_D, depths_D, window_D: float | None = None) -> States:
        """One absolute grid ``accommodation_D`` (n_acc,) D, strictly increasing, ≥ 0 D,
        seen by every rendered depth ``depths_D`` (n_depth,) D; with ``window_D`` (D) only
        the states within ±window_D of each depth are allowed."""
        validate_states(None, depths_D)
        depths = np.atleast_1d(np.asarray(depths_D, float))
        grid = np.atleast_1d(np.asarray(accommodation_D, float))
        _check_states(grid, depths)
        if grid.size > 1 and np.any(np.diff(grid) <= 0):
            raise ValueError("accommodation_D must be strictly increasing")
        index = np.broadcast_to(np.arange(grid.size), (depths.size, grid.size))
        allowed = np.ones(index.shape, bool)
        if window_D is not None:
            allowed = np.abs(grid[None, :] - depths[:, None]) <= float(window_D) + 1e-9
            if not np.all(allowed.any(axis=1)):
                raise ValueError(
                    f"window_D={window_D} leaves no accommodation state for some rendered depths"
                )
        absolute = grid[index]
        grid, index = _used_states(grid, index, allowed)
        return cls("grid", depths, grid, index, allowed, absolute)

    @classmethod
    def around(cls, depths_D, offsets_D=None) -> States:
        """States ``depth + offset`` for every rendered depth ``depths_D`` (n_depth,) D and
        offset ``offsets_D`` (n_acc,) D (default :data:`DEFAULT_OFFSETS_D`); those below
        0 D (the hyperopic limit) are not allowed, and their ``absolute_D`` still says where
        they were."""
        validate_states(None, depths_D)
        depths = np.atleast_1d(np.asarray(depths_D, float))
        offsets = (DEFAULT_OFFSETS_D if offsets_D is None
                   else np.atleast_1d(np.asarray(offsets_D, float)))
        _check_states(np.abs(offsets), depths)  # finiteness and depth range
        grid, index = relative_accommodation_grid(depths, offsets, hyperopic_limit=True)
        check_dioptres("accommodation_offsets_D", grid, "accommodation state",
                       note="each rendered depth plus each offset")
        allowed = index >= 0
        index = np.where(allowed, index, 0)
        # true state of every entry, also those beyond the hyperopic limit (not computed)
        absolute = np.where(allowed, grid[index], depths[:, None] + offsets[None, :])
        grid, index = _used_states(grid, index, allowed)
        return cls("around", depths, grid, index, allowed, absolute)

    @classmethod
    def every(cls, accommodation_D, depths_D) -> States:
        """Every absolute state ``accommodation_D`` (n_acc,) D for every rendered depth
        ``depths_D`` (n_depth,) D; either may be traced (checked on the host when concrete)."""
        validate_states(accommodation_D, depths_D)
        depths = jnp.atleast_1d(jnp.asarray(depths_D, float))
        states = jnp.atleast_1d(jnp.asarray(accommodation_D, float))
        return cls("every", depths, states)

    @classmethod
    def per_depth(cls, accommodation_D, depths_D) -> States:
        """A row of absolute states per rendered depth: ``accommodation_D`` (n_depth, n_acc)
        D for ``depths_D`` (n_depth,) D, each pair computed on its own; either may be traced
        (checked on the host when concrete)."""
        validate_states(accommodation_D, depths_D)
        if np.ndim(accommodation_D) != 2 or np.shape(accommodation_D)[0] != np.size(depths_D):
            raise ValueError(
                f"accommodation_D must have shape (n_depth, n_acc) = ({np.size(depths_D)}, n), "
                f"got {np.shape(accommodation_D)}"
            )
        return cls("per_depth", depths_D, accommodation_D)

    def __post_init__(self):
        if self.kind not in STATE_KINDS:
            raise ValueError(f"States.kind must be one of {STATE_KINDS}, got {self.kind!r}")

    @property
    def concrete(self) -> bool:
        """The depths and states are known on the host (not traced)."""
        return is_concrete(self.depths_D, self.states_D)

    @property
    def host_depths_D(self) -> np.ndarray:
        """(n_depth,) rendered depths, host float64, D (concrete states only)."""
        return np.atleast_1d(np.asarray(self.depths_D, float))

    @property
    def pairs(self) -> tuple[np.ndarray, np.ndarray]:
        """(accommodation D, depth D) of every computed pair, host float64 arrays
        (concrete states only)."""
        depths = self.host_depths_D
        if self.kind == "per_depth":
            acc = np.asarray(self.states_D, float)
            return acc.ravel(), np.broadcast_to(depths[:, None], acc.shape).ravel()
        if self.kind == "every":
            acc = np.asarray(self.states_D, float).reshape(-1)
            return np.repeat(acc, depths.size), np.tile(depths, acc.size)
        absolute = self.absolute_D
        return (absolute[self.allowed],
                np.broadcast_to(depths[:, None], absolute.shape)[self.allowed])

    @property
    def computed_D(self):
        """Every state computed, D (host when concrete): ``states_D``, flattened."""
        if self.kind == "per_depth":
            return np.asarray(self.states_D, float).ravel()
        return self.states_D

    def accommodation(self, options: ModelOptions, pupil_diameter_mm) -> Accommodation:
        """The kernel's :class:`~lfjax.kernel.scene.Accommodation` of these states, the
        accommodation SA from ``options`` (``ModelOptions`` or ``ModelParameters``) on the
        calculation pupil ``pupil_diameter_mm`` (mm)."""
        if self.kind == "per_depth":
            return Accommodation.per_depth(self.states_D, options, pupil_diameter_mm)
        if self.kind == "every":
            every_pair = jnp.broadcast_to(jnp.arange(self.states_D.shape[0], dtype=jnp.int32),
                                          self.depths_D.shape + self.states_D.shape)
            return Accommodation.shared(self.states_D, every_pair, options, pupil_diameter_mm)
        return Accommodation.shared(self.states_D, self.index, options, pupil_diameter_mm)


# ----------------------------------------------------------------------------- sampling


def default_sampling(eyes: Eyes, layout: Layout, states: States, viewing: Viewing, *,
                     spectrum: Spectrum, options: ModelOptions) -> Sampling:
    """The sampling a computation uses when none is given: the planner's field guard for
    this scene (milliseconds; no accuracy proxy). ``viewing``: a concrete
    :class:`~lfjax.vision.viewing.Viewing`.

    One rule for every entry point: the guard covers the pairs asked for *and* the default
    through-focus neighbourhood of every rendered depth (:data:`PLANNED_NEIGHBOURHOOD_D`,
    states ≥ 0 D). The guard picks the largest frequency step whose field holds the widest
    blur of the pairs it sees, so a single (depth, state) pair would otherwise get a coarser
    step than the curve through it, and :func:`~lfjax.vision.focus.through_focus` and
    :func:`~lfjax.vision.focus.metrics_at` would give different values at the same point
    (by 2e-3 in VSOTF, more than the planner's accuracy target)."""
    depths = states.host_depths_D
    pairs = states.pairs
    around = depths[:, None] + PLANNED_NEIGHBOURHOOD_D[None, :]
    keep = around >= 0
    pairs = (np.concatenate([np.asarray(pairs[0], float).ravel(), around[keep]]),
             np.concatenate([np.asarray(pairs[1], float).ravel(),
                             np.broadcast_to(depths[:, None], around.shape)[keep]]))
    scene = PlanScene(
        layout=layout, pupil_diameter_mm=float(viewing.pupil_diameter_mm),
        cdp_D=float(viewing.cdp_D),
        depths_D=np.asarray(depths, float), accommodation_D=np.unique(np.asarray(pairs[0], float)),
        accommodation_window_D=None,
        pairs=(np.asarray(pairs[0], float), np.asarray(pairs[1], float)),
        wavelengths_nm=np.asarray(spectrum.wavelengths_nm),
        spectral_weights=np.asarray(spectrum.weights), eyes=eyes, options=options,
        display=viewing.display,
    )
    return plan_sampling(scene, estimate_accuracy=False).sampling


def with_aliasing_retry(compute: Callable, sampling: Sampling | Sequence[Sampling], *,
                        attempts: int = 16, refine: bool = True, what: str = "the scene"):
    """``compute(sampling)``, made finer while the field guard refuses the sampling.

    Each :class:`~lfjax.base.sampling.AliasingError` that ``compute`` raises replaces the
    refused frequency step by :func:`~lfjax.base.sampling.finer_step` and runs it again,
    at most ``attempts`` times; then a ``RuntimeError`` says that no aliasing-free sampling
    was found for ``what``. ``refine=False`` lets the error through (a frequency step the
    user fixed). ``sampling`` may be a sequence, one per variant: ``compute`` gets the list,
    the error's ``variant`` attribute says which entry to refine (as
    :func:`~lfjax.vision.focus.through_focus_variants` sets it), and each variant has
    ``attempts`` tries.

    Returns ``(result, sampling)``: what ``compute`` returned and the sampling (or list)
    that it ran with.
    """
    several = not isinstance(sampling, Sampling)
    current = list(sampling) if several else sampling
    for _ in range(attempts * (len(current) if several else 1)):
        try:
            return compute(current), current
        except AliasingError as err:
            if not refine:
                raise
            if several:
                i = err.variant
                current[i] = dataclasses.replace(
                    current[i], freq_step_cpd=finer_step(err, current[i].freq_step_cpd))
            else:
                current = dataclasses.replace(
                    current, freq_step_cpd=finer_step(err, current.freq_step_cpd))
    raise RuntimeError(f"no aliasing-free sampling found for {what}")


# ----------------------------------------------------------------------------- prepare


def check_eye_chunk(eye_chunk) -> int | None:
    """``eye_chunk`` as an ``int``, or None: the number of eyes one step of a map over eyes
    evaluates together (memory grows with it), an integer ≥ 1; None keeps each entry
    point's own meaning (the pipeline: one eye at a time; the display design's gradient:
    every eye at once). A :class:`~lfjax.base.errors.ParameterError` naming ``eye_chunk``
    otherwise (0 or a negative count would reach ``jax.lax.map`` as no batching or a
    reshape error). The one check of every entry point that takes it."""
    if eye_chunk is None:
        return None
    try:
        whole = (not isinstance(eye_chunk, (bool, np.bool_)) and int(eye_chunk) == eye_chunk)
    except (TypeError, ValueError, OverflowError):
        whole = False
    if not whole or eye_chunk < 1:
        raise ParameterError("eye_chunk", "{eye_chunk} must be an integer >= 1 (eyes evaluated "
                             "together) or None, got {got!r}", got=eye_chunk)
    return int(eye_chunk)



def _check_layout(layout: Layout) -> None:
    """Host check of a concrete layout: finite centres, diameters > 0 mm."""
    c = np.asarray(layout.centres_mm, float)
    d = np.asarray(layout.diameters_mm, float)
    if not (np.all(np.isfinite(c)) and np.all(np.isfinite(d))):
        raise ValueError("layout centres_mm and diameters_mm must be finite")
    if np.any(d <= 0):
        raise ValueError(f"layout diameters_mm must be > 0 mm, got {d[d <= 0].tolist()}")


def _without_vanishing_aberration(display):
    """``display`` without its lenslet aberration when every coefficient is a concrete zero
    (:class:`~lfjax.display.aberrations.LensletAberration` promises the aberration-free
    numbers bit for bit then; computing a zero phase costs arithmetic and, with XLA's
    fusion choices, can move the last bit). A traced aberration (under ``jax.grad``) is
    kept, so its gradient at zero is still taken."""
    aberration = None if display is None else display.aberration
    if aberration is None or not is_concrete(aberration):
        return display
    terms = (aberration.spherical_um, aberration.coma_um, aberration.astigmatism_um,
             aberration.field_curvature_um)
    if any(np.any(np.asarray(term) != 0) for term in terms):
        return display
    return display.with_aberration(None)


def moved_layout(layout: Layout, pupil_offset_mm) -> Layout:
    """``layout`` as a pupil displaced by ``pupil_offset_mm`` = Δ = (x, y) mm sees it.

    The views are the display's: they cross the design pupil plane at fixed places, the
    layout's centres c_n (pupil coordinates of the design position, +x to the viewer's
    right, +y up). A pupil moved by Δ in that frame finds view n at c_n − Δ in its own
    coordinates, so every entry point moves by −Δ; the pipeline's pupil crops each view
    there (a view partly outside keeps only the light that enters). Each view's angular
    displacement, (D_depth − D_CDP)·(c_n − Δ), also moves: the views' common part,
    −(D_depth − D_CDP)·Δ, with the CDP parallax −Δ·D_CDP, is the rendered point's direction
    from the moved eye, −Δ·D_depth, so what stays is the image relative to that direction:
    the eye turns (by Δ·D_depth rad, a few mrad) to fixate the point, as the fovea does.

    Subtracting Δ is exact for Δ = 0 (c − 0.0 = c), so the design position reproduces the
    centred answer bit for bit; a traced Δ is differentiated through."""
    if is_concrete(pupil_offset_mm) and not np.any(np.asarray(pupil_offset_mm, float)):
        return layout  # the design position: no eager subtract program per layout shape
    centres = layout.centres_mm
    shift = jnp.asarray(pupil_offset_mm, centres.dtype).reshape(2)
    return Layout(centres - shift, layout.diameters_mm, layout.window_diameter_mm, layout.name)


def _check_moved_views(layout: Layout, pupil_diameter_mm, pupil_offset_mm) -> None:
    """A displaced pupil (concrete ``pupil_offset_mm``, mm) must still hold part of every
    view of the moved ``layout``: a :class:`~lfjax.base.errors.ParameterError` naming
    ``pupil_offset_mm`` otherwise (a view wholly outside brings no light; take the views
    that reach the moved pupil, :func:`lfjax.vision.eye_box.views_reaching`). At the
    design position :func:`~lfjax.model.layouts.check_views_in_pupil` says it, as before."""
    if not is_concrete(pupil_offset_mm):
        return
    offset = np.asarray(pupil_offset_mm, float).reshape(2)
    if not np.any(offset):
        return
    c = np.asarray(layout.centres_mm, float)
    gap = np.hypot(c[:, 0], c[:, 1]) - 0.5 * np.asarray(layout.diameters_mm, float) \
        - 0.5 * float(pupil_diameter_mm)
    outside = np.nonzero(gap >= 0)[0]
    if outside.size:
        raise ParameterError(
            "pupil_offset_mm", "viewing.{pupil_offset_mm} = ({x:g}, {y:g}) mm moves the "
            "{pupil:g} mm pupil off {n} of the {total} views of layout {name!r} (view {i} "
            "lies {gap:.4g} mm outside it): a view wholly outside the pupil brings no light. "
            "Give the views that reach the moved pupil "
            "(lfjax.vision.eye_box.views_reaching), or a smaller displacement",
            x=offset[0], y=offset[1], pupil=float(pupil_diameter_mm), n=int(outside.size),
            total=int(gap.size), name=layout.name, i=int(outside[0]),
            gap=float(gap[outside[0]]))


@dataclass(frozen=True, eq=False)
class Prepared:
    """A computation prepared on the host (:func:`prepare`).

    Attributes
    ----------
    scene : the :class:`~lfjax.kernel.scene.Scene` pytree (layout, depths, CDP, pupil, display)
    states : the :class:`States` computed
    sampling : the :class:`~lfjax.base.sampling.Sampling` used (checked, or planned)
    config : the static :class:`~lfjax.kernel.pipeline.PipelineConfig`
    layout : the :class:`~lfjax.model.layouts.Layout` as the pupil sees it (moved by
        ``viewing.pupil_offset_mm``: :func:`moved_layout`)
    spectrum : the :class:`~lfjax.model.spectral.Spectrum` (the default V(λ) one when none
        was given)
    pupil_diameter_mm : the calculation pupil as given (mm; may be traced)
    cdp_D : the CDP as given (D; may be traced)
    """

    scene: Scene
    states: States
    sampling: Sampling
    config: PipelineConfig
    layout: Layout
    spectrum: Spectrum
    pupil_diameter_mm: Any
    cdp_D: Any

    def accommodation(self, options: ModelOptions) -> Accommodation:
        """The states as the kernel takes them, the accommodation SA from ``options``."""
        return self.states.accommodation(options, self.pupil_diameter_mm)


def prepare(
    eyes: Eyes,
    layout: Layout | None,
    states: States,
    viewing: Viewing = Viewing(),  # noqa: B008 - frozen, checked once
    *,
    spectrum: Spectrum | None = None,
    options: ModelOptions = ModelOptions(),
    sampling: Sampling | None = None,
    check_aliasing: bool = True,
    eye_chunk: int | None = None,
    traced_checks: bool | None = None,
) -> Prepared:
    """Check, sample, configure and build the scene of one computation (module docstring).

    Parameters
    ----------
    eyes : :class:`~lfjax.model.eyes.Eyes`
    layout : the display's views, mm; None: the open pupil (natural viewing)
    states : the (depth, accommodation) pairs, a :class:`States`
    viewing : :class:`~lfjax.vision.viewing.Viewing`: the calculation pupil (mm, ≤
        ``eyes.measured_pupil_mm``; may be traced: the windows are then sized for the
        measured pupil), the display's central depth plane (D; may be traced), the
        display's optics (None: the paper's ideal display) and the pupil's displacement
        from the design position (mm; the layout is moved by :func:`moved_layout`, and a
        view wholly outside the moved pupil is refused; ignored when ``layout`` is None)
    spectrum : default V(λ) on 400–700 nm in 10 nm steps with ``options``' LCA and SCE
    options : :class:`~lfjax.model.options.ModelOptions`
    sampling : checked against the field guard when given (``check_aliasing``; concrete
        inputs only); planned by :func:`default_sampling` when None (concrete depths, states,
        pupil and CDP only — give it when they are traced)
    eye_chunk : eyes evaluated together inside the pipeline's map, an integer ≥ 1 (None: one
        at a time); :func:`check_eye_chunk`
    traced_checks : False when every input is checked here on the host (the layout too):
        the compiled program then carries no host callbacks, so JAX's persistent compilation
        cache can keep it across processes. True checks traced inputs inside the program
        (``eqx.error_if``). None (default): False when every input is concrete, else True.

    Raises ``ValueError`` for a bad input (naming it), ``TypeError`` for eyes that are not
    :class:`~lfjax.model.eyes.Eyes`, :class:`~lfjax.base.sampling.AliasingError` when the
    given sampling's field cannot hold the blur.
    """
    check_viewing(viewing)
    pupil_diameter_mm, cdp_D = viewing.pupil_diameter_mm, viewing.cdp_D
    display = _without_vanishing_aberration(viewing.display)
    eye_chunk = check_eye_chunk(eye_chunk)
    check_eyes(eyes)
    validate_pupil(pupil_diameter_mm, eyes.measured_pupil_mm)
    validate_states(None, None, cdp_D)
    validate_coefficients(eyes.zernike_um)
    spectrum = make_spectrum(options=options) if spectrum is None else spectrum
    # A traced pupil (under jax.grad) cannot size windows: the measured pupil bounds it.
    pupil_static = (float(pupil_diameter_mm) if is_concrete(pupil_diameter_mm)
                    else float(eyes.measured_pupil_mm))
    if layout is None:
        layout = (open_pupil(pupil_static) if is_concrete(pupil_diameter_mm) else Layout(
            jnp.zeros((1, 2)), jnp.reshape(jnp.asarray(pupil_diameter_mm, float), (1,)),
            pupil_static, "natural"))
    else:
        layout = moved_layout(layout, viewing.pupil_offset_mm)
    check_display_for_layout(display, layout, parameter="viewing", path=".display")
    if is_concrete(layout.centres_mm, layout.diameters_mm, pupil_diameter_mm):
        # a view outside the pupil brings no light: VSOTF would be 0/0 (NaN, or 1)
        _check_moved_views(layout, pupil_diameter_mm, viewing.pupil_offset_mm)
        check_views_in_pupil(layout.centres_mm, layout.diameters_mm, pupil_diameter_mm,
                             layout.name)
    concrete = states.concrete and is_concrete(pupil_diameter_mm, cdp_D)
    if sampling is None:
        if not concrete:
            raise ValueError(
                "sampling must be given when depths_D, accommodation_D, cdp_D or "
                "pupil_diameter_mm are traced (jax.jit / vmap / grad): plan it once on concrete "
                "values, e.g. lfjax.planner.plan.plan_sampling(...).sampling"
            )
        sampling = default_sampling(eyes, layout, states, viewing, spectrum=spectrum,
                                    options=options)
    elif check_aliasing and concrete:
        field_check(eyes.zernike_um, eyes.measured_pupil_mm, pupil_diameter_mm, cdp_D,
                    states.computed_D, states.host_depths_D, layout, spectrum, sampling,
                    pairs=states.pairs, display=display)
    if traced_checks is None:
        traced_checks = not (concrete and is_concrete(eyes, layout, display))
    if not traced_checks:
        _check_layout(layout)
    # views narrower along x than their window (strips) get a narrower FFT: PipelineConfig.build
    widest = (float(np.max(np.asarray(layout.diameters_mm)))
              if display is not None and is_concrete(layout.diameters_mm) else None)
    config = PipelineConfig.build(spectrum.wavelengths_nm, layout.window_diameter_mm,
                                  pupil_static, sampling, options, eye_chunk,
                                  traced_checks=traced_checks, display=display,
                                  widest_view_mm=widest)
    scene = Scene.from_layout(layout, states.depths_D, cdp_D, pupil_diameter_mm, display)
    return Prepared(scene, states, sampling, config, layout, spectrum, pupil_diameter_mm, cdp_D)


__all__ = [
    "States",
    "Prepared",
    "prepare",
    "moved_layout",
    "check_eye_chunk",
    "default_sampling",
    "with_aliasing_retry",
    "relative_accommodation_grid",
    "DEFAULT_OFFSETS_D",
    "PLANNED_NEIGHBOURHOOD_D",
    "STATE_KINDS",
]
