"""Both eyes' through-focus, one accommodation for the pair, and the conflict.

:func:`binocular_through_focus` runs the monocular :func:`lfjax.through_focus` for the left
and the right eyes of every viewer (one call, the eyes stacked: each eye's numbers are the
monocular model's), predicts one accommodation per viewer and depth from the two curves
(:class:`~lfjax.binocular.options.BinocularOptions`), and sets it against the vergence
demand: the conflict V − A (D) and whether the pair lies inside the zone of comfort.

:func:`pair_metrics_at` is the differentiable companion: the pair's combined VSOTF at given
states, a pure function of both eyes' coefficients (``jax.grad`` applies).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import jax.numpy as jnp
import numpy as np

from lfjax.base.errors import ParameterError
from lfjax.binocular.comfort import inside_zone, percival_zone, shibata_zone
from lfjax.binocular.displays import Display, check_display
from lfjax.binocular.geometry import (
    conflict_D,
    cross_linked_accommodation_D,
    vergence_demand_MA,
)
from lfjax.binocular.options import BinocularOptions
from lfjax.binocular.viewer import Viewer, check_viewer
from lfjax.model.eyes import Eyes
from lfjax.model.layouts import Layout
from lfjax.model.options import ModelOptions
from lfjax.vision.focus import metrics_at, through_focus
from lfjax.vision.prepare import States
from lfjax.vision.viewing import Viewing, check_viewing


@dataclass(frozen=True)
class BinocularFocus:
    """One display, viewers × rendered depths: each eye's through-focus and the pair's
    accommodation, conflict and comfort (host arrays).

    Attributes
    ----------
    display : the display's name
    depths_D : (n_depth,) rendered depths, D
    vergence_MA : (n_depth,) vergence demand, metre angles (≡ D)
    left_vsotf, right_vsotf : (n_viewers, n_depth, n_acc) each eye's VSOTF through focus
        (the monocular model's numbers; NaN where a state is not allowed)
    states_D : (n_depth, n_acc) the absolute accommodation states, D (around each eye's
        stimulus: the rendered depth, or the screen for a stereo display)
    allowed : (n_depth, n_acc) bool, False below 0 D (the hyperopic limit)
    blur_accommodation_D : (n_viewers, n_depth) the pair's accommodation from both eyes'
        VSOTF (grid states), D
    accommodation_D : (n_viewers, n_depth) after the vergence cross-link (equal to
        ``blur_accommodation_D`` when it is off), D
    driving_eye : (n_viewers, n_depth) int, 0 left, 1 right, −1 both (``"mean_vsotf"``)
    left_vsotf_at_pair, right_vsotf_at_pair : (n_viewers, n_depth) each eye's VSOTF at the
        pair's blur-driven accommodation (what each eye sees once the pair has focused)
    conflict_D : (n_viewers, n_depth) V − A, D
    zone_far_MA, zone_near_MA : (n_viewers, n_depth) the comfort zone's boundaries at A, MA
    inside : (n_viewers, n_depth) bool, the pair inside the zone of comfort
    options : the :class:`~lfjax.binocular.options.BinocularOptions` used
    """

    display: str
    depths_D: np.ndarray
    vergence_MA: np.ndarray
    left_vsotf: np.ndarray
    right_vsotf: np.ndarray
    states_D: np.ndarray
    allowed: np.ndarray
    blur_accommodation_D: np.ndarray
    accommodation_D: np.ndarray
    driving_eye: np.ndarray
    left_vsotf_at_pair: np.ndarray
    right_vsotf_at_pair: np.ndarray
    conflict_D: np.ndarray
    zone_far_MA: np.ndarray
    zone_near_MA: np.ndarray
    inside: np.ndarray
    options: BinocularOptions

    def fraction_inside(self) -> np.ndarray:
        """(n_depth,) fraction of viewers inside the zone of comfort."""
        return np.mean(self.inside, axis=0)

    def replace(self, **changes) -> BinocularFocus:
        return dataclasses.replace(self, **changes)


def _stacked(viewer: Viewer) -> Eyes:
    """The left eyes then the right eyes as one batch (orientation is not read by the
    pipeline: both are in the display frame)."""
    z = jnp.concatenate([viewer.left.zernike_um, viewer.right.zernike_um])
    return Eyes(z, viewer.left.measured_pupil_mm, "left")


def consensual_accommodation(left_vsotf, right_vsotf, states_D, allowed, options):
    """The pair's accommodation state from both eyes' VSOTF on one grid.

    ``left_vsotf``, ``right_vsotf`` (n_viewers, n_depth, n_acc) (NaN where not allowed),
    ``states_D`` (n_depth, n_acc) absolute states, D, ``allowed`` (n_depth, n_acc) bool.
    Returns (accommodation (n_viewers, n_depth) D, driving eye (n_viewers, n_depth): 0 left,
    1 right, −1 both, the index of that state along the last axis). Ties go to the first
    (lowest) state, as :meth:`lfjax.vision.focus.ThroughFocus.peak_index`.
    """
    mask = np.asarray(allowed, bool)[None]
    left = np.where(mask, np.asarray(left_vsotf), -np.inf)
    right = np.where(mask, np.asarray(right_vsotf), -np.inf)
    if options.combination == "mean_vsotf":
        index = np.argmax(np.where(mask, 0.5 * (left + right), -np.inf), axis=-1)
        driver = np.full(index.shape, -1)
    else:
        i_left, i_right = np.argmax(left, axis=-1), np.argmax(right, axis=-1)
        if options.combination == "better_eye":
            driver = (np.max(right, axis=-1) > np.max(left, axis=-1)).astype(int)
        else:
            driver = np.full(i_left.shape, int(options.dominant_eye == "right"))
        index = np.where(driver == 1, i_right, i_left)
    states = np.broadcast_to(np.asarray(states_D, float)[None], left.shape)
    return np.take_along_axis(states, index[..., None], axis=-1)[..., 0], driver, index


def binocular_through_focus(
    viewer: Viewer,
    display: Display,
    depths_D,
    viewing: Viewing = Viewing(),  # noqa: B008 - frozen, checked once
    *,
    offsets_D=None,
    binocular: BinocularOptions = BinocularOptions(),  # noqa: B008 - frozen, checked once
    zcsbv_MA=None,
    spectrum=None,
    options: ModelOptions = ModelOptions(),  # noqa: B008 - frozen, checked once
    sampling=None,
    eye_chunk: int | None = None,
) -> BinocularFocus:
    """Each eye's through-focus for ``display``, one accommodation per viewer and depth,
    the vergence–accommodation conflict and the zone of comfort.

    Parameters
    ----------
    viewer : :class:`~lfjax.binocular.viewer.Viewer` (n_viewers)
    display : :class:`~lfjax.binocular.displays.NaturalViewing`,
        :class:`~lfjax.binocular.displays.StereoDisplay`,
        :class:`~lfjax.binocular.displays.NearEyeDisplay` or
        :class:`~lfjax.binocular.displays.PanelDisplay` (which uses its panel's pupil, CDP
        and optics instead of ``viewing``'s)
    depths_D : (n_depth,) rendered depths on the midline, D (from the baseline's midpoint)
    viewing : :class:`~lfjax.Viewing` of each eye (pupil, mm; the light-field display's CDP,
        D; its optics)
    offsets_D : accommodation states around each stimulus depth, D (default −1 … +1 D in
        0.2 D steps, :meth:`lfjax.vision.prepare.States.around`); the predicted accommodation is one of
        them, so their step is its resolution
    binocular : :class:`~lfjax.binocular.options.BinocularOptions`
    zcsbv_MA : (far, near) limits of the zone of clear single binocular vision, MA,
        broadcastable to (n_viewers, n_depth); needed by ``comfort_zone="percival"`` only
    spectrum, options, sampling, eye_chunk : as :func:`lfjax.through_focus`

    Inputs are checked before any work: the viewer (two eyes, an IPD in 45–80 mm), the
    display (whether its eye boxes hold both eyes), the depths (the model's 0–10 D).
    """
    viewer = check_viewer(viewer)
    display = check_display(display)
    check_viewing(viewing)
    if not isinstance(binocular, BinocularOptions):
        raise ParameterError("binocular", "{binocular} must be lfjax.binocular.BinocularOptions, "
                             "got {got}", got=type(binocular).__name__)
    if binocular.comfort_zone == "percival" and zcsbv_MA is None:
        raise ParameterError("zcsbv_MA", "comfort_zone='percival' needs {zcsbv_MA}: the "
                             "viewers' (far, near) limits of clear single binocular vision, MA")
    display.check_fits(viewer, float(viewing.pupil_diameter_mm))
    depths = np.atleast_1d(np.asarray(depths_D, float))
    n = viewer.n_viewers
    runs = display.runs(depths, viewing, np.asarray(viewer.ipd_mm, float))
    vsotf, states, allowed = _eye_curves(_stacked(viewer), runs,
                                         offsets_D, dict(spectrum=spectrum, options=options,
                                                         sampling=sampling, eye_chunk=eye_chunk))
    if states.shape[0] != depths.size:  # one screen for every rendered depth
        vsotf = np.repeat(vsotf, depths.size, axis=1)
        states = np.repeat(states, depths.size, axis=0)
        allowed = np.repeat(allowed, depths.size, axis=0)
    blur, driver, index = consensual_accommodation(vsotf[:n], vsotf[n:], states, allowed,
                                                   binocular)
    at_pair = np.take_along_axis(vsotf, np.concatenate([index, index])[..., None], axis=-1)[..., 0]
    vergence = np.asarray(vergence_demand_MA(depths), float)
    ipd = np.asarray(viewer.ipd_mm, float)[:, None]
    acc = np.asarray(cross_linked_accommodation_D(
        blur, vergence[None], ipd, binocular.ca_c_D_per_prism_D, binocular.blur_loop_gain))
    if binocular.comfort_zone == "shibata2011":
        far, near = shibata_zone(acc)
    else:
        far, near = percival_zone(*zcsbv_MA)
    far = np.broadcast_to(np.asarray(far, float), acc.shape)
    near = np.broadcast_to(np.asarray(near, float), acc.shape)
    inside = np.asarray(inside_zone(vergence[None], (far, near)))
    return BinocularFocus(display.name, depths, vergence, vsotf[:n], vsotf[n:], states, allowed,
                          blur, acc, driver, at_pair[:n], at_pair[n:],
                          np.asarray(conflict_D(vergence[None], acc)), far, near, inside, binocular)


def _eye_curves(eyes: Eyes, runs, offsets_D, kw) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Both eyes' VSOTF over every run's depths: (2 n_viewers, n_rows, n_acc), the absolute
    states (n_rows, n_acc) D and ``allowed``. Runs of the same depths fill the rows of their
    eyes (``eye_rows``, None for all); runs of other depths add rows after them."""
    blocks: dict[tuple, list] = {}
    for i, (layout, depths, viewing, rows) in enumerate(runs):
        # a run of every eye is a block of its own; runs of some eyes share their depths' block
        key = (i,) if rows is None else tuple(np.asarray(depths, float).tolist())
        sub = eyes if rows is None else eyes[np.asarray(rows)]
        rows = np.arange(eyes.n_eyes) if rows is None else np.asarray(rows)
        tf = through_focus(sub, layout, States.around(depths, offsets_D), viewing, **kw)
        if key not in blocks:
            blocks[key] = [np.full((eyes.n_eyes,) + tf.vsotf.shape[1:], np.nan),
                           np.asarray(tf.accommodation_D, float), np.asarray(tf.allowed, bool)]
        blocks[key][0][rows] = np.asarray(tf.vsotf)
    vsotf, states, allowed = zip(*blocks.values())
    return (np.concatenate(vsotf, axis=1), np.concatenate(states, axis=0),
            np.concatenate(allowed, axis=0))


def pair_metrics_at(viewer: Viewer, layout: Layout, depths_D, accommodation_D,
                    viewing: Viewing = Viewing(),  # noqa: B008 - frozen, checked once
                    *, binocular: BinocularOptions = BinocularOptions(),  # noqa: B008
                    spectrum=None, sampling=None, options: ModelOptions = ModelOptions()):  # noqa: B008
    """The pair's combined VSOTF at given (depth, accommodation) pairs, differentiable in
    both eyes' coefficients (and everything :func:`lfjax.metrics_at` is).

    ``"mean_vsotf"``: (V_left + V_right)/2; ``"better_eye"``: the elementwise larger;
    ``"dominant_eye"``: the dominant eye's. Shapes as :func:`lfjax.metrics_at`: returns
    (n_viewers, n_depth, n_acc), unitless. The viewer is built by the caller (inside the
    differentiated function when its coefficients are traced).
    """
    viewer = check_viewer(viewer)
    kw = dict(viewing=viewing, spectrum=spectrum, sampling=sampling, options=options)
    both, _ = metrics_at(_stacked(viewer), layout, depths_D, accommodation_D, **kw)
    v_left, v_right = both[:viewer.n_viewers], both[viewer.n_viewers:]
    if binocular.combination == "mean_vsotf":
        return 0.5 * (v_left + v_right)
    if binocular.combination == "better_eye":
        return jnp.maximum(v_left, v_right)
    return v_right if binocular.dominant_eye == "right" else v_left


__all__ = ["BinocularFocus", "binocular_through_focus", "consensual_accommodation",
           "pair_metrics_at"]
