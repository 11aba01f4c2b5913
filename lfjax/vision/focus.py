"""Through-focus image quality and predicted accommodation (Miyanishi et al. §3).

One jitted call evaluates VSOTF, Strehl ratio and radial MTF for eyes × rendered depths ×
accommodation states of one layout. Elemental OTFs are computed once per eye and reused
for every rendered depth; only OTFs' metrics leave the jitted region, so memory stays at
one eye's OTF stack (eyes are mapped in chunks).
"""

from __future__ import annotations

import functools
import warnings
from collections.abc import Sequence

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, ArrayLike, Bool, Float, Real

from lfjax.base.errors import FLAT_CURVE_RANGE, FlatCurveWarning, ParameterError
from lfjax.base.types import shape_checked
from lfjax.model.eyes import Eyes
from lfjax.model.layouts import Layout
from lfjax.kernel.metrics import cutoff_frequency
from lfjax.model.options import STATIC_CHOICES, ModelOptions, stack_parameters
from lfjax.vision.peak_options import PeakOptions
from lfjax.vision.peaks import Peaks, peaks_from_grid
from lfjax.kernel.pipeline import (
    Accommodation,
    PipelineConfig,
    reference_normalisers,
    retinal_metrics,
    vsotf_and_strehl,
)
from lfjax.base.programs import call_cached
from lfjax.base.sampling import AliasingError, Sampling
from lfjax.vision.prepare import Prepared, States, prepare
from lfjax.vision.viewing import Viewing, check_viewing
from lfjax.model.spectral import Spectrum, make_spectrum, model_spectrum, sce_rho_table


class ThroughFocus(eqx.Module):
    """Through-focus metrics with their axes.

    Attributes
    ----------
    vsotf, strehl : (n_eyes, n_depth, n_acc) unitless; NaN where ``allowed`` is False
    radial_mtf : (n_eyes, n_depth, n_acc, n_freq) meridian-averaged MTF
    radial_freq_cpd : (n_freq,) cpd
    accommodation_D : (n_depth, n_acc) absolute accommodation states 1/z_acc, D
    allowed : (n_depth, n_acc) bool, False where the state is beyond the hyperopic limit
        (accommodation < 0 D); such states are not computed
    depths_D : (n_depth,) rendered depths, D
    cdp_D : float, D
    layout_name : str
    sampling : the Sampling used (planned by the field guard when none was given)
    peaks : {metric: :class:`lfjax.vision.peaks.Peaks`} continuous peaks refined from the grid
        (``through_focus(peaks=PeakOptions(metrics=...))``)
    """

    vsotf: Float[Array, "n_eyes n_depth n_acc"]
    strehl: Float[Array, "n_eyes n_depth n_acc"]
    radial_mtf: Float[Array, "n_eyes n_depth n_acc n_freq"]
    radial_freq_cpd: Float[Array, " n_freq"]
    accommodation_D: Float[np.ndarray, "n_depth n_acc"]
    allowed: Bool[np.ndarray, "n_depth n_acc"]
    depths_D: Float[np.ndarray, " n_depth"]
    cdp_D: float = eqx.field(static=True)
    layout_name: str = eqx.field(static=True, default="custom")
    sampling: Sampling | None = eqx.field(static=True, default=None)
    peaks: dict = eqx.field(default_factory=dict)

    def metric(self, name: str):
        if name not in ("vsotf", "strehl"):
            raise ValueError(f"metric must be 'vsotf' or 'strehl', got {name!r}")
        return getattr(self, name)

    def peak_index(self, metric: str = "vsotf"):
        """Index of the grid peak along accommodation among allowed states, (n_eyes, n_depth).
        A :class:`~lfjax.base.errors.FlatCurveWarning` says how many curves are too flat for
        their peak to be determined (:func:`flat_curves`)."""
        values = np.where(np.asarray(self.allowed)[None], np.asarray(self.metric(metric)), -np.inf)
        warn_flat_curves(values, metric)
        return np.argmax(values, axis=-1)

    def predicted_accommodation_D(self, metric: str = "vsotf"):
        """Grid peak: the allowed accommodation state (D, absolute, exact grid value)."""
        idx = self.peak_index(metric)
        acc = np.broadcast_to(
            np.asarray(self.accommodation_D, float)[None], idx.shape + self.accommodation_D.shape[-1:]
        )
        return np.take_along_axis(acc, idx[..., None], axis=-1)[..., 0]

    @property
    def relative_accommodation_D(self):
        """Accommodation relative to each rendered depth, (n_depth, n_acc), D."""
        return self.accommodation_D - self.depths_D[:, None]

    def accommodation_error_D(self, metric: str = "vsotf"):
        """Predicted accommodation minus rendered depth, D (negative: focused farther)."""
        return self.predicted_accommodation_D(metric) - np.asarray(self.depths_D, float)[None, :]

    def continuous_peaks(self, metric: str = "vsotf") -> Peaks:
        """The continuous peaks of ``metric`` (:class:`lfjax.vision.peaks.Peaks`, (n_eyes, n_depth))."""
        if metric not in self.peaks:
            raise ValueError(
                f"no continuous peaks of {metric!r} were computed (have {sorted(self.peaks)}); "
                f"pass peaks=PeakOptions(metrics=({metric!r},)) to through_focus"
            )
        return self.peaks[metric]

    def continuous_accommodation_D(self, metric: str = "vsotf"):
        """Continuous predicted accommodation (global maximum), D, (n_eyes, n_depth); a
        :class:`~lfjax.base.errors.FlatCurveWarning` as :meth:`peak_index`'s."""
        peaks = self.continuous_peaks(metric)
        warn_flat_curves(np.where(np.asarray(self.allowed)[None], np.asarray(self.metric(metric)),
                                  -np.inf), metric)
        return np.asarray(peaks.accommodation_D, float)

    def continuous_error_D(self, metric: str = "vsotf"):
        """Continuous predicted accommodation minus rendered depth, D."""
        return self.continuous_accommodation_D(metric) - np.asarray(self.depths_D, float)[None, :]

    def mtf_at_peak(self, metric: str = "vsotf"):
        """Radial MTF at the predicted accommodation, (n_eyes, n_depth, n_freq)."""
        return _mtf_at_index(self.radial_mtf, jnp.asarray(self.peak_index(metric)))

    def cutoff_cpd(self, metric: str = "vsotf", threshold: float = 0.05):
        """Cut-off frequency (cpd) of the MTF at the predicted accommodation."""
        return _cutoff_at_index(self.radial_mtf, jnp.asarray(self.peak_index(metric)),
                                self.radial_freq_cpd, float(threshold))


def flat_curves(values) -> np.ndarray:
    """Where a through-focus curve is too flat for its peak to be determined: bool
    (…) over the last axis of ``values`` (…, n_acc; states not computed −inf or NaN), True
    where at least two finite states differ by less than
    :data:`~lfjax.base.errors.FLAT_CURVE_RANGE` of the curve's largest magnitude."""
    v = np.asarray(values, float)
    finite = np.isfinite(v)
    top = np.max(np.where(finite, v, -np.inf), axis=-1)
    low = np.min(np.where(finite, v, np.inf), axis=-1)
    scale = np.max(np.where(finite, np.abs(v), 0.0), axis=-1)
    with np.errstate(invalid="ignore"):
        return (finite.sum(axis=-1) >= 2) & (top - low <= FLAT_CURVE_RANGE * scale)


def warn_flat_curves(values, metric: str = "vsotf") -> None:
    """A :class:`~lfjax.base.errors.FlatCurveWarning` when any curve of ``values`` (…,
    n_acc) is flat (:func:`flat_curves`), saying how many and that their peaks are not
    results."""
    flat = flat_curves(values)
    if np.any(flat):
        warnings.warn(
            f"{int(flat.sum())} of {flat.size} {metric} through-focus curves vary by less than "
            f"{FLAT_CURVE_RANGE:g} of their value over the accommodation states: their peak is "
            f"undetermined (the grid peak is just the first state), and so are the predicted "
            f"accommodation, its error and the cut-off there. A pupil or views this small "
            f"barely change the image with focus; use a larger pupil (a human pupil is at "
            f"least about 1.5 mm) or wider views", FlatCurveWarning, stacklevel=3)


# One compiled program per shape: run eagerly, these few lines were about ten small
# compilations for every new layout shape (a cold `lfjax reproduce` makes eight such shapes).
@jax.jit
def _mtf_at_index(radial_mtf, index):
    return jnp.take_along_axis(radial_mtf, index[..., None, None], axis=2)[:, :, 0]


@functools.partial(jax.jit, static_argnames="threshold")
def _cutoff_at_index(radial_mtf, index, frequencies_cpd, threshold: float):
    return cutoff_frequency(_mtf_at_index(radial_mtf, index), frequencies_cpd, threshold)


# No shape check: its shaped inputs arrive checked inside States and Viewing.
def through_focus(
    eyes: Eyes,
    layout: Layout | None = None,
    states: States | None = None,
    viewing: Viewing = Viewing(),  # noqa: B008 - frozen, checked once
    *,
    spectrum: Spectrum | None = None,
    sampling: Sampling | None = None,
    options: ModelOptions = ModelOptions(),
    peaks: PeakOptions = PeakOptions(),  # noqa: B008 - frozen, checked once
    eye_chunk: int | None = None,
    check_aliasing: bool = True,
) -> ThroughFocus:
    """VSOTF, Strehl and radial MTF through focus for eyes × depths × accommodation states.

    Parameters
    ----------
    eyes : Eyes (n_eyes batch)
    layout : Layout, default open pupil (natural view); every view must reach into the
        calculation pupil (:func:`lfjax.model.layouts.check_views_in_pupil`)
    states : :class:`~lfjax.vision.prepare.States`, the (rendered depth, accommodation)
        pairs, D, built by :meth:`~lfjax.vision.prepare.States.grid` (one absolute grid for
        every depth, optionally within ±``window_D`` of each) or
        :meth:`~lfjax.vision.prepare.States.around` (states relative to each depth: the
        paper's through-focus; states below 0 D are not ``allowed``). Default
        ``States.around([viewing.cdp_D])``: offsets −1 … +1 D in 0.2 D steps around the CDP.
    viewing : :class:`~lfjax.vision.viewing.Viewing`: calculation pupil (mm, ≤
        ``eyes.measured_pupil_mm``), the display's central depth plane (D) and its optics
        (lenslet diffraction and finite pixels of a real display; default the paper's ideal
        display — the VSOTF and Strehl reference stays the ideal display's, so values
        compare across displays)
    spectrum, options : see :func:`lfjax.vision.psf.polychromatic_otf`
    sampling : Sampling, optional
        Default: the planner's field guard for this scene (the largest frequency step whose
        PSF field holds every blur and display shift; milliseconds,
        :func:`lfjax.vision.prepare.default_sampling`). The result's ``sampling`` says what
        was used.
    peaks : :class:`~lfjax.vision.peak_options.PeakOptions`: the metrics whose continuous peak is
        refined from the grid in the same compiled call (default none: grid peaks only), the
        method, its tolerance and whether second peaks are refined
    eye_chunk : eyes evaluated together inside the pipeline's map, an integer ≥ 1 (None: one
        at a time)

    Elemental OTFs are computed once per distinct absolute state and reused by every depth.
    The VSOTF/Strehl reference follows ``options.vsotf_reference`` (default: the same layout,
    aberration-free, focused and rendered at the CDP, accommodation SA and LCA kept).

    Examples
    --------
    The average eye and a point rendered at 1 D by 2×2 views (one wavelength, to stay
    small): the grid peak and its continuous refinement, D.

    >>> import lfjax
    >>> from lfjax.model.spectral import monochromatic_spectrum
    >>> tf = lfjax.through_focus(
    ...     lfjax.average_eye(3.0), lfjax.grid_layout(2),
    ...     lfjax.States.grid([0.6, 0.8, 1.0, 1.2, 1.4], depths_D=[1.0]),
    ...     spectrum=monochromatic_spectrum(550.0),
    ...     peaks=lfjax.PeakOptions(metrics=("vsotf",), method="vertex"))
    >>> tf.vsotf.shape  # (n_eyes, n_depth, n_acc)
    (1, 1, 5)
    >>> float(tf.predicted_accommodation_D()[0, 0])
    1.0
    >>> round(float(tf.continuous_accommodation_D()[0, 0]), 2)
    0.95
    """
    spectrum = make_spectrum(options=options) if spectrum is None else spectrum
    states = _through_focus_states(states, viewing)
    _check_peak_options(peaks)
    prepared = prepare(eyes, layout, states, viewing, spectrum=spectrum, options=options,
                       sampling=sampling, check_aliasing=check_aliasing, eye_chunk=eye_chunk,
                       traced_checks=False)
    # exported once and reloaded by later processes when the program cache is on (the
    # command line's): tracing this program costs seconds per layout in every new process
    metrics, found = call_cached(
        _metrics_and_peaks, eyes, prepared.scene, spectrum, prepared.accommodation(options),
        prepared.states.allowed, config=prepared.config, peaks=peaks,
    )
    return _result(prepared, metrics, found)


def _check_peak_options(peaks) -> None:
    if not isinstance(peaks, PeakOptions):
        raise ParameterError("peaks", "{peaks} must be lfjax.PeakOptions (metrics, method, "
                             "tolerance, second peaks), got {got}", got=type(peaks).__name__)


def _through_focus_states(states, viewing) -> States:
    """The :class:`~lfjax.vision.prepare.States` :func:`through_focus` evaluates: ``states``,
    or by default the paper's offsets around the CDP."""
    check_viewing(viewing)
    if states is None:
        return States.around([float(viewing.cdp_D)])
    if not isinstance(states, States) or states.kind not in ("grid", "around"):
        raise ParameterError(
            "states", "{states} must be lfjax.States built by States.grid or States.around (a "
            "grid per depth with its allowed entries), got {got}",
            got=getattr(states, "kind", type(states).__name__))
    return states


def _result(prepared: Prepared, metrics, peaks) -> ThroughFocus:
    states = prepared.states
    mask = jnp.asarray(states.allowed)
    # NaN marks states beyond the hyperopic limit (never computed); `allowed` says which.
    return ThroughFocus(
        jnp.where(mask[None], metrics.vsotf, jnp.nan), jnp.where(mask[None], metrics.strehl, jnp.nan),
        metrics.radial_mtf,
        jnp.arange(prepared.config.n_fft // 2 + 1) * prepared.sampling.freq_step_cpd,
        np.asarray(states.absolute_D, float), np.asarray(states.allowed), states.depths_D,
        float(prepared.cdp_D), prepared.layout.name, prepared.sampling, peaks,
    )


def _each_variant(variants, fn) -> list:
    """``fn(*variant)`` for each variant in order; an :class:`~lfjax.base.sampling.AliasingError` is
    re-raised carrying ``variant``, the index of the variant that raised it."""
    results = []
    for i, variant in enumerate(variants):
        try:
            results.append(fn(*variant))
        except AliasingError as err:
            err.variant = i
            raise
    return results


def through_focus_variants(
    eyes: Eyes,
    layout: Layout | None,
    states: States | None,
    options: Sequence[ModelOptions],
    viewing: Viewing = Viewing(),  # noqa: B008 - frozen, checked once
    *,
    wavelengths_nm=None,
    samplings: Sequence[Sampling | None] | None = None,
    spectral_weights=None,
    peaks: PeakOptions = PeakOptions(),  # noqa: B008 - frozen, checked once
    eye_chunk: int | None = None,
    check_aliasing: bool = True,
    batch: str = "auto",
) -> list[ThroughFocus]:
    """:func:`through_focus` under several :class:`~lfjax.ModelOptions` at once: one compiled
    program over their stacked :class:`~lfjax.model.options.ModelParameters` per sampling.

    The variants may differ in every number and in every choice that has a numeric form
    (SCE form, accommodation SA reading, wavelength normalisation, LCA and SA constants,
    ρ table and scale); the choices that select code or set shapes
    (:data:`lfjax.model.options.STATIC_CHOICES`) must agree. Each variant's sampling is planned
    (or, given in ``samplings``, checked) on its own, exactly as :func:`through_focus`
    would; variants whose samplings agree share one compiled, vmapped call. The spectrum is
    :func:`lfjax.model.spectral.make_spectrum`'s for ``wavelengths_nm`` (default 400–700 nm in
    10 nm steps), its chromatic leaves computed inside the program from each variant's
    parameters (float32 rounding apart, the numbers :func:`through_focus` gives);
    ``spectral_weights`` (n_wavelengths,) replaces V(λ)·Δλ as the wavelengths' weights (a
    Gauss rule's, :func:`lfjax.model.spectral.gauss_rule`).

    ``batch``: how the variants run — ``"vmap"`` (one program, side by side: what an
    accelerator wants), ``"map"`` (one program, one variant after another inside it,
    ``jax.lax.map``: one variant's memory), ``"loop"`` (a :func:`through_focus` call per
    variant: the programs are those of the baseline, compiled once for every variant of the
    same shapes, since the parameters are data) or ``"auto"`` (default: ``"loop"`` on the
    CPU, where both batched forms were slower — more programs to compile and no parallel
    hardware to fill, benchmarks/RESULTS.md §17 — and ``"vmap"`` elsewhere, not yet timed
    on an accelerator).

    An :class:`~lfjax.base.sampling.AliasingError` from a variant's sampling check carries ``variant``,
    its index in ``options``. Other arguments as :func:`through_focus`. Returns one
    :class:`ThroughFocus` per variant, in order.
    """
    if batch not in VARIANT_BATCHES:
        raise ValueError(f"batch must be one of {VARIANT_BATCHES}, got {batch!r}")
    if batch == "auto":
        batch = "loop" if jax.default_backend() == "cpu" else "vmap"
    options = list(options)
    if not options or not all(isinstance(o, ModelOptions) for o in options):
        raise ValueError("options must be a non-empty sequence of ModelOptions")
    for name in STATIC_CHOICES:
        values = {getattr(o, name) for o in options}
        if len(values) > 1:
            raise ValueError(
                f"the variants' ModelOptions.{name} must agree (it selects code or sets "
                f"shapes; run them apart), got {sorted(map(repr, values))}"
            )
    samplings = [None] * len(options) if samplings is None else list(samplings)
    if len(samplings) != len(options):
        raise ValueError(f"samplings must hold one entry per variant ({len(options)}), "
                         f"got {len(samplings)}")
    _check_peak_options(peaks)
    states = _through_focus_states(states, viewing)
    spectra = [make_spectrum(wavelengths_nm, o, weights=spectral_weights) for o in options]
    variants = list(zip(options, spectra, samplings))
    if batch == "loop":
        return _each_variant(variants, lambda o, spectrum, sampling: through_focus(
            eyes, layout, states, viewing, spectrum=spectrum, sampling=sampling, options=o,
            peaks=peaks, eye_chunk=eye_chunk, check_aliasing=check_aliasing))
    prepared = _each_variant(variants, lambda o, spectrum, sampling: prepare(
        eyes, layout, states, viewing, spectrum=spectrum, options=o, sampling=sampling,
        check_aliasing=check_aliasing, eye_chunk=eye_chunk, traced_checks=False))
    groups: dict[PipelineConfig, list[int]] = {}
    for i, p in enumerate(prepared):
        groups.setdefault(p.config, []).append(i)
    wl = np.asarray(spectra[0].wavelengths_nm)
    weights = np.asarray(spectra[0].weights)
    results: list[ThroughFocus | None] = [None] * len(options)
    for config, members in groups.items():
        first = prepared[members[0]]
        parameters = stack_parameters([options[i].parameters() for i in members])
        rho_tables = np.stack([sce_rho_table(wl, options[i]) for i in members])
        # exported once and reloaded by later processes, like through_focus's program: on
        # an accelerator (batch "vmap") tracing it cost seconds per layout in every process
        metrics, found = call_cached(
            _metrics_and_peaks_variants, eyes, first.scene, wl, weights,
            (parameters, rho_tables), first.states.states_D, first.states.index,
            jnp.asarray(viewing.pupil_diameter_mm, float), first.states.allowed, config=config,
            peaks=peaks, batch=batch,
        )
        # sliced on the host: an eager x[k] per leaf and variant compiles a program each
        metrics, found = jax.device_get((metrics, found))
        for k, i in enumerate(members):
            one = jax.tree_util.tree_map(lambda x, k=k: jnp.asarray(x[k]), (metrics, found))
            results[i] = _result(prepared[i], *one)
    return results


VARIANT_BATCHES = ("auto", "vmap", "map", "loop")


# Arrays first, static choices by keyword: the form lfjax.base.programs.call_cached exports
# and reloads, so each program has one definition.
@eqx.filter_jit
def _metrics_and_peaks_variants(eyes, scene, wavelengths_nm, weights, variants, states_D,
                                pair_index, pupil_diameter_mm, allowed, *, config,
                                peaks: PeakOptions, batch: str = "vmap"):
    """:func:`_metrics_and_peaks` over the ``variants``: (stacked ModelParameters (leading
    axis), their ρ(λ) tables (n_variants, n_wavelengths)), vmapped or mapped (``batch``): one
    compiled program for them all."""

    def one(p, rho_table):
        spectrum = model_spectrum(wavelengths_nm, weights, rho_table, p)
        accommodation = Accommodation.shared(states_D, pair_index, p, pupil_diameter_mm)
        return _metrics_and_peaks(eyes, scene, spectrum, accommodation, allowed, config=config,
                                  peaks=peaks)

    if batch == "map":
        return jax.lax.map(lambda xs: one(*xs), variants)
    return jax.vmap(one)(*variants)


@eqx.filter_jit
def _metrics_and_peaks(eyes, scene, spectrum, accommodation, allowed, *, config,
                       peaks: PeakOptions):
    """Grid metrics and the continuous peaks of ``peaks.metrics`` refined from them, in one
    compiled call."""
    reference = reference_normalisers(scene, spectrum, accommodation, config)
    metrics = retinal_metrics(eyes, scene, spectrum, accommodation, config, reference)
    found = {
        name: peaks_from_grid(getattr(metrics, name), eyes, scene, spectrum, accommodation,
                              config, reference, name, peaks, allowed)
        for name in peaks.metrics
    }
    return metrics, found


@shape_checked
def metrics_at(
    eyes: Eyes,
    layout: Layout,
    depths_D: Real[ArrayLike, " n_depth"] | Sequence[float],
    accommodation_D: Real[ArrayLike, "n_depth n_acc"] | Sequence[Sequence[float]],
    viewing: Viewing = Viewing(),  # noqa: B008 - frozen, checked once
    spectrum: Spectrum | None = None,
    sampling: Sampling | None = None,
    options: ModelOptions = ModelOptions(),
) -> tuple[Float[Array, "n_eyes n_depth n_acc"], Float[Array, "n_eyes n_depth n_acc"]]:
    """VSOTF and Strehl at given (depth, accommodation) pairs — differentiable in everything.

    Unlike :func:`through_focus` (a host-side grid with the hyperopic limit), this is a pure
    function of arrays: ``jax.jit``, ``jax.vmap`` and ``jax.grad`` apply from outside, and
    gradients flow to the eyes' Zernike coefficients, ``depths_D``, ``accommodation_D``, the
    ``viewing``'s pupil, CDP and display optics (Fresnel distance, pixel width; see
    :mod:`lfjax.display.lenslets`; build the :class:`~lfjax.vision.viewing.Viewing` inside the
    differentiated function) and the layout's centres and diameters — the building block of
    peak finders and layout optimisers. Window sizes are static: they come from
    ``layout.window_diameter_mm`` and, when the pupil is traced, the eyes' measured pupil. Concrete inputs are checked on the host (values, aliasing); traced ones
    inside the pipeline (``eqx.error_if``).

    Parameters
    ----------
    depths_D : (n_depth,) rendered depths, D
    accommodation_D : (n_depth, n_acc) absolute accommodation states for each depth, D
    sampling : Sampling; default the planner's field guard for these pairs (needs concrete
        depths and states — give it explicitly when they are traced)

    Returns
    -------
    (vsotf, strehl), each (n_eyes, n_depth, n_acc).

    Examples
    --------
    >>> import lfjax
    >>> from lfjax.model.spectral import monochromatic_spectrum
    >>> vsotf, strehl = lfjax.metrics_at(
    ...     lfjax.average_eye(3.0), lfjax.grid_layout(2), depths_D=[1.0],
    ...     accommodation_D=[[1.0]], spectrum=monochromatic_spectrum(550.0))
    >>> vsotf.shape  # (n_eyes, n_depth, n_acc)
    (1, 1, 1)
    >>> round(float(vsotf[0, 0, 0]), 2)
    0.61
    """
    spectrum = make_spectrum(options=options) if spectrum is None else spectrum
    prepared = prepare(eyes, layout, States.per_depth(accommodation_D, depths_D), viewing,
                       spectrum=spectrum, options=options, sampling=sampling)
    return vsotf_and_strehl(eyes, prepared.scene, spectrum, prepared.accommodation(options),
                            prepared.config)


__all__ = ["ThroughFocus", "through_focus", "through_focus_variants", "metrics_at",
           "flat_curves", "warn_flat_curves"]
