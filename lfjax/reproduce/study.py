"""The study's computation: through-focus of every eye per layout, and the example data.

:func:`layout_through_focus` evaluates all eyes for one layout in one
:func:`lfjax.vision.focus.through_focus` call (at the planned sampling, made finer only if
the PSF field would alias); :func:`run_study` runs it for every layout and gathers the
numbers into one labelled :class:`xarray.Dataset`; :func:`study_sampling` reads back the
sampling a layout used (the examples behind Figs. 4, 5 and 9 are
:mod:`lfjax.reproduce.examples`'). ``lfjax.vision.claims.aberrated`` / ``average`` select the virtual eyes / the
average eye of a study Dataset (for the claims, the tables and the figures).

Host-side orchestration (numpy, xarray); the numerics are :mod:`lfjax.vision.focus` and
:mod:`lfjax.kernel.optics`. Imports only :mod:`lfjax.reproduce.config` from the package.
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
import time
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor

import jax
import numpy as np

from lfjax._version import stamp
from lfjax.base.errors import ParameterError
from lfjax.base.parabola import parabola_vertex
from lfjax.base.programs import in_callers_jax_context
from lfjax.model.eyes import Eyes
from lfjax.model.layouts import Layout, paper_layouts
from lfjax.model.options import ModelOptions
from lfjax.base.sampling import Sampling
from lfjax.model.spectral import make_spectrum
from lfjax.vision.focus import ThroughFocus, through_focus, through_focus_variants
from lfjax.vision.peak_options import PeakOptions
from lfjax.vision.prepare import States, with_aliasing_retry
from lfjax.reproduce.config import METRICS, StudyConfig, planned_sampling, study_eyes
from lfjax.vision.viewing import Viewing

# ----------------------------------------------------------------------------- one layout


def layout_through_focus(
    eyes: Eyes, layout: Layout, depths_D, config: StudyConfig, spectrum=None,
    options: ModelOptions | None = None,
) -> tuple[ThroughFocus, Sampling]:
    """Through-focus of all eyes for one layout in one call, on the shared accommodation grid.

    The frequency step is :func:`lfjax.planner.plan.plan_sampling`'s choice for the scene (the
    largest step whose PSF field holds the blur), made finer only if
    :func:`lfjax.vision.focus.through_focus` still reports that the field would alias.
    The transform is the FFT, or the MFT for the layouts in ``config.mft_pupil_samples``.
    """
    tf, sampling, _ = _layout_run(eyes, layout, depths_D, config, spectrum, options)
    return tf, sampling


def _layout_run(eyes, layout, depths_D, config, spectrum=None, options=None):
    """:func:`layout_through_focus`, returning also the wavelengths (nm) it used."""
    options = config.options if options is None else options
    sampling, wavelengths, weights = planned_sampling(eyes, layout, depths_D, config, options)
    if spectrum is None:
        spectrum = make_spectrum(wavelengths, options, weights=weights)
    wavelengths = np.asarray(spectrum.wavelengths_nm, float)
    rule = _rule_of(config, wavelengths, weights)

    def run(sampling):
        return jax.block_until_ready(through_focus(
            eyes, layout, study_states(config, depths_D), study_viewing(config),
            spectrum=spectrum, sampling=sampling, options=options, peaks=peak_settings(config),
        ))

    tf, sampling = with_aliasing_retry(run, sampling, what=f"layout {layout.name}")
    return tf, sampling, (wavelengths, rule)


def _rule_of(config, wavelengths, weights) -> tuple[str, float]:
    """(rule, value) of a planned spectrum, as :attr:`StudyConfig.wavelength_rules` holds it:
    ("gauss", nodes) for a Gauss rule's weights, ("uniform", step nm) for V(λ)·Δλ on a grid."""
    if weights is not None:
        return "gauss", float(len(wavelengths))
    if len(wavelengths) > 1:
        return "uniform", float(wavelengths[1] - wavelengths[0])
    return "uniform", float(config.wavelengths_nm[1] - config.wavelengths_nm[0])


def peak_settings(config: StudyConfig) -> PeakOptions:
    """How the study refines its continuous VSOTF peaks (claim 2 reads the global peak;
    second peaks stay grid-located).

    ``accuracy="claims"``: ``"adaptive"``, refining only the peaks whose grid estimate may
    lie further than half of ``peak_tolerance_D`` from the maximum (the other half is the
    planned spectrum's). ``"vsotf"`` (the reference): ``"local"`` on every peak (a
    three-point stencil, no solver loop: within ~1e-4 D of Newton, and it compiles like
    the grid, where Newton's loop added ~25 s per layout).
    """
    if config.accuracy == "claims":
        return PeakOptions(("vsotf",), "adaptive", 0.5 * config.peak_tolerance_D,
                           second_peaks=False)
    return PeakOptions(("vsotf",), "local", second_peaks=False)


def study_states(config: StudyConfig, depths_D) -> States:
    """The study's states for ``depths_D`` (D): its absolute accommodation grid, within
    ±``config.window_D`` of each depth."""
    return States.grid(config.accommodation_D, np.asarray(depths_D, float), config.window_D)


def study_viewing(config: StudyConfig) -> Viewing:
    """The study's viewing conditions: its calculation pupil and CDP, the ideal display."""
    return Viewing(pupil_diameter_mm=config.pupil_diameter_mm, cdp_D=config.cdp_D)


# ----------------------------------------------------------------------------- study


def _interp_last(x_new, x, y):
    """Linear interpolation along the last axis of y (x increasing); 0 beyond x[-1]."""
    x = np.asarray(x, float)
    idx = np.clip(np.searchsorted(x, x_new, side="right") - 1, 0, x.size - 2)
    w = np.clip((x_new - x[idx]) / (x[idx + 1] - x[idx]), 0.0, 1.0)
    out = y[..., idx] * (1.0 - w) + y[..., idx + 1] * w
    return np.where(x_new <= x[-1] + 1e-9, out, 0.0)


def _parabolic_peak(acc_grid, values, index):
    """Sub-grid peak position from a parabola through the grid peak and its neighbours, on
    the study's uniform grid (:func:`lfjax.base.parabola.parabola_vertex`)."""
    values = np.asarray(values, float)
    acc = np.asarray(acc_grid, float)
    step = float(acc[1] - acc[0]) if len(acc) > 1 else 0.0
    return parabola_vertex(np.broadcast_to(acc, values.shape), values, np.asarray(index), step)


def run_study(
    config: StudyConfig = StudyConfig(),  # noqa: B008 (frozen dataclass)
    options: ModelOptions | None = None,
    stage: Callable[[str], None] | None = None,
    workers: int | None = None,
):
    """Run the through-focus study; returns an :class:`xarray.Dataset`.

    One :func:`~lfjax.vision.focus.through_focus` call per layout evaluates every eye
    (the virtual eyes and the average eye in one batch). ``stage(name)`` is called, in
    the calling thread, before the study waits for each layout (progress reporting; with
    several workers, in the order they are started: the most views × depths first).
    ``workers``: layouts computed at once in threads (:func:`layout_workers`; default:
    one per CPU core on the CPU, one elsewhere); the numbers do not depend on it.

    Dataset (dims ``layout, eye, depth, accommodation, frequency, metric``):
    ``vsotf``, ``strehl`` (NaN outside the evaluated window and, for natural view, at
    depths other than the CDP), ``radial_mtf`` (meridian-averaged MTF interpolated onto a
    common 1 cpd axis; 0 beyond a layout's frequency grid, which lies beyond its optical
    cut-off), ``predicted_accommodation``, ``accommodation_error``, ``peak_value``,
    ``predicted_accommodation_parabolic``, ``predicted_accommodation_continuous`` and
    ``continuous_peak_success`` (VSOTF; :mod:`lfjax.vision.peaks`), ``cutoff_frequency`` (at each metric's peak,
    from the layout's native frequency grid), ``mtf_at_peak``, ``zernike_um``,
    ``freq_step_cpd``, ``n_fft``.
    """
    options = config.options if options is None else options
    return _run_studies(config, {"": options}, stage, batched=False, workers=workers)[""]


def run_study_variants(
    config: StudyConfig, variants: dict[str, ModelOptions],
    stage: Callable[[str], None] | None = None, workers: int | None = None,
) -> dict:
    """:func:`run_study` under several model options, {name: ModelOptions} → {name: Dataset}.

    Each layout's variants run as one batch (:func:`layout_through_focus_variants`: one
    compiled program over their stacked :class:`~lfjax.model.options.ModelParameters`); ``stage``
    is called once per layout and ``workers`` is :func:`run_study`'s. Each Dataset's
    ``compute_seconds`` is the whole batch's."""
    return _run_studies(config, dict(variants), stage, batched=True, workers=workers)


def layout_workers(workers: int | None, n_layouts: int) -> int:
    """How many layouts :func:`run_study` computes at once, in threads.

    ``None``: on the CPU, one per core the process may use (at most one per layout): one
    layout's compiled program keeps about one core busy (XLA's CPU runtime runs its FFTs
    and fusions on one thread), so a second layout in another thread fills the second
    core of a two-core machine (the compiled programs release the GIL while they run;
    benchmarks/RESULTS.md §32). On an accelerator, one: its programs already fill it.
    Otherwise ``workers`` itself, an integer ≥ 1.
    """
    if workers is None:
        if jax.default_backend() != "cpu":
            return 1
        try:
            cores = len(os.sched_getaffinity(0))
        except AttributeError:  # not Linux
            cores = os.cpu_count() or 1
        return max(1, min(cores, n_layouts))
    if isinstance(workers, bool) or not isinstance(workers, (int, np.integer)) or workers < 1:
        raise ParameterError("workers", "{workers} must be an integer ≥ 1 (layouts computed at "
                             "once) or None (one per CPU core), got {got!r}", got=workers)
    return int(workers)


def layout_through_focus_variants(
    eyes: Eyes, layout: Layout, depths_D, config: StudyConfig, options: list[ModelOptions],
) -> list[tuple[ThroughFocus, Sampling]]:
    """:func:`layout_through_focus` for several model options in one batch: each variant's
    sampling planned (and, if the field would alias, made finer) on its own, as
    :func:`layout_through_focus` does, then the variants computed together by
    :func:`lfjax.vision.focus.through_focus_variants` (one compiled call per sampling)."""
    return [(tf, sampling) for tf, sampling, _ in
            _layout_run_variants(eyes, layout, depths_D, config, options)]


def _layout_run_variants(eyes, layout, depths_D, config, options):
    """:func:`layout_through_focus_variants`, each with the wavelengths (nm) it used: the
    first variant's (the planned spectrum is the baseline's, so every variant is measured
    on the same wavelengths)."""
    first, wavelengths, weights = planned_sampling(eyes, layout, depths_D, config, options[0])
    rule = _rule_of(config, wavelengths, weights)
    if (config.accuracy == "claims"
            and layout.name not in {entry[0] for entry in config.wavelength_rules}):
        config = config.replace(wavelength_rules=tuple(config.wavelength_rules)
                                + ((layout.name, *rule),))
    samplings = [first] + [planned_sampling(eyes, layout, depths_D, config, o)[0]
                           for o in options[1:]]

    def run(samplings):
        return jax.block_until_ready(through_focus_variants(
            eyes, layout, study_states(config, depths_D), options, study_viewing(config),
            wavelengths_nm=wavelengths, samplings=samplings, spectral_weights=weights,
            peaks=peak_settings(config),
        ))

    tfs, samplings = with_aliasing_retry(run, samplings, what=f"layout {layout.name}")
    return [(tf, sampling, (wavelengths, rule)) for tf, sampling in zip(tfs, samplings)]


def _run_studies(config: StudyConfig, variants: dict, stage, batched: bool,
                 workers: int | None = None) -> dict:
    names = list(config.layouts)
    n_workers = layout_workers(workers, len(names))
    eyes, labels = study_eyes(config)
    layouts = paper_layouts(config.pupil_diameter_mm)
    depths = config.depths_D

    def one_layout(name):
        t0 = time.perf_counter()
        layout_depths = np.array([config.cdp_D]) if name == "natural" else depths
        if batched:
            results = _layout_run_variants(eyes, layouts[name], layout_depths, config,
                                           list(variants.values()))
        else:
            results = [_layout_run(eyes, layouts[name], layout_depths, config, None, o)
                       for o in variants.values()]
        return results, time.perf_counter() - t0

    per_layout = {name: [] for name in variants}  # variant → [(tf, sampling, λ, seconds)]

    def gather(results, seconds):
        for variant, (tf, sampling, wavelengths) in zip(variants, results):
            per_layout[variant].append((tf, sampling, wavelengths, seconds))

    if n_workers == 1:
        for name in names:
            if stage is not None:
                stage(name)
            gather(*one_layout(name))
    else:
        pool = ThreadPoolExecutor(n_workers, thread_name_prefix="lfjax-layout")
        try:
            task = in_callers_jax_context(one_layout)
            # the most views × depths first, so that the short layouts (the natural view:
            # one view, one depth) fill the end rather than one long layout running alone
            order = sorted(names, key=lambda n: -layouts[n].n_subapertures
                           * (1 if n == "natural" else len(depths)))
            futures = {name: pool.submit(task, name) for name in order}
            done = {}
            for name in order:
                if stage is not None:
                    stage(name)
                done[name] = futures[name].result()
            for name in names:  # the Dataset keeps the configuration's order
                gather(*done[name])
        except BaseException:
            # an error or an interrupt: drop the layouts not started, wait for none
            pool.shutdown(wait=False, cancel_futures=True)
            raise
        pool.shutdown(wait=True)
    return {variant: _study_dataset(config, o, eyes, labels, layouts, per_layout[variant])
            for variant, o in variants.items()}


def _layout_results(config: StudyConfig, names: list[str], n_eye: int, per_layout) -> dict:
    """Each layout's through-focus results in the study's arrays (layout, eye, depth, …),
    NaN where a layout is not evaluated (natural view: the CDP only): ``vs``, ``sr``
    (layout, eye, depth, accommodation); ``pred`` (grid peak, D), ``pred_par`` (parabolic),
    ``pred_cont`` (continuous, VSOTF only), ``cont_ok``, ``peak``, ``cutoff`` (cpd)
    (layout, eye, depth, metric); ``native`` ({layout: (frequencies cpd, radial MTF,
    depth slots)}); ``steps``, ``nffts``, ``times``, ``samplings``, ``spectra``, ``rules``."""
    depths = config.depths_D
    acc = config.accommodation_D
    n_depth, n_acc = depths.size, acc.size
    shape = (len(names), n_eye, n_depth, n_acc)
    vs = np.full(shape, np.nan)
    sr = np.full(shape, np.nan)
    pred = np.full((len(names), n_eye, n_depth, 2), np.nan)
    pred_par = np.full_like(pred, np.nan)
    pred_cont = np.full_like(pred, np.nan)
    cont_ok = np.zeros(pred.shape, bool)
    peak = np.full_like(pred, np.nan)
    cutoff = np.full_like(pred, np.nan)
    native = {}
    steps, nffts, times, samplings, spectra, rules = [], [], [], {}, {}, {}
    cdp_index = int(np.argmin(np.abs(depths - config.cdp_D)))
    for li, (name, (tf, sampling, (wavelengths, rule), seconds)) in enumerate(
            zip(names, per_layout)):
        times.append(seconds)
        spectra[name] = [float(w) for w in wavelengths]
        rules[name] = rule
        slots = [cdp_index] if name == "natural" else list(range(n_depth))
        vs[li][:, slots] = np.asarray(tf.vsotf, float)
        sr[li][:, slots] = np.asarray(tf.strehl, float)
        for mi, metric in enumerate(METRICS):
            idx = np.asarray(tf.peak_index(metric))
            pred[li][:, slots, mi] = acc[idx]  # exact grid values (float64)
            values = np.where(np.asarray(tf.allowed)[None], np.asarray(tf.metric(metric)), np.nan)
            peak[li][:, slots, mi] = np.take_along_axis(values, idx[..., None], -1)[..., 0]
            pred_par[li][:, slots, mi] = _parabolic_peak(acc, values, idx)
            cutoff[li][:, slots, mi] = np.asarray(
                tf.cutoff_cpd(metric, threshold=config.cutoff_threshold), float
            )
        continuous = tf.continuous_peaks("vsotf")
        pred_cont[li][:, slots, 0] = np.asarray(continuous.accommodation_D, float)
        cont_ok[li][:, slots, 0] = np.asarray(continuous.success)
        native[name] = (np.asarray(tf.radial_freq_cpd, float), np.asarray(tf.radial_mtf), slots)
        steps.append(sampling.freq_step_cpd)
        samplings[name] = dataclasses.asdict(sampling)
        nffts.append(2 * (int(tf.radial_mtf.shape[-1]) - 1))
    return dict(vs=vs, sr=sr, pred=pred, pred_par=pred_par, pred_cont=pred_cont,
                cont_ok=cont_ok, peak=peak, cutoff=cutoff, native=native, steps=steps,
                nffts=nffts, times=times, samplings=samplings, spectra=spectra, rules=rules)


def _on_common_frequencies(native: dict, names: list[str], shape: tuple):
    """Every layout's radial MTF on one 1 cpd frequency axis from 0 to the highest any
    layout reaches: (frequencies cpd, MTF (layout, eye, depth, accommodation, frequency)
    float32, NaN where a layout is not evaluated)."""
    f_max = max(float(f[-1]) for f, _, _ in native.values())
    freq = np.arange(0.0, math.floor(f_max) + 1.0, 1.0)
    mtf = np.full(shape + (freq.size,), np.nan, np.float32)
    for li, name in enumerate(names):
        f, m, slots = native[name]
        mtf[li][:, slots] = _interp_last(freq, f, np.asarray(m, float)).astype(np.float32)
    return freq, mtf


def _mtf_at_prediction(mtf, pred, step_D: float):
    """The MTF at each metric's predicted accommodation (``pred`` (layout, eye, depth,
    metric) D on the grid of step ``step_D``): (layout, eye, depth, metric, frequency), NaN
    where no accommodation is predicted."""
    n_acc = mtf.shape[3]
    safe = np.where(np.isfinite(pred), pred, 0.0)
    acc_index = np.clip(np.rint(safe / step_D).astype(int), 0, n_acc - 1)
    mtf_peak = _mtf_at(mtf, acc_index)
    return np.where(np.isfinite(pred)[..., None], mtf_peak, np.nan)


def _study_dataset(config: StudyConfig, options: ModelOptions, eyes: Eyes, labels, layouts,
                   per_layout):
    """The study's Dataset from each layout's (ThroughFocus, Sampling, (wavelengths, rule),
    seconds)."""
    import xarray as xr

    depths = config.depths_D
    acc = config.accommodation_D
    names = list(config.layouts)
    r = _layout_results(config, names, len(labels), per_layout)
    vs, sr, pred, pred_par, pred_cont, cont_ok, peak, cutoff = (
        r[k] for k in ("vs", "sr", "pred", "pred_par", "pred_cont", "cont_ok", "peak", "cutoff"))
    steps, nffts, times, samplings, spectra, rules = (
        r[k] for k in ("steps", "nffts", "times", "samplings", "spectra", "rules"))
    freq, mtf = _on_common_frequencies(r["native"], names, vs.shape)
    mtf_peak = _mtf_at_prediction(mtf, pred, config.accommodation_step_D)

    is_avg = np.array([label == "average" for label in labels])
    zern = np.asarray(eyes.zernike_um, float)
    layout_objs = [layouts[n] for n in names]
    ds = xr.Dataset(
        data_vars=dict(
            vsotf=(("layout", "eye", "depth", "accommodation"), vs, {
                "long_name": "visual Strehl ratio computed from the OTF (VSOTF)", "units": "1"}),
            strehl=(("layout", "eye", "depth", "accommodation"), sr, {
                "long_name": "Strehl ratio (PSF peak / reference PSF peak)", "units": "1"}),
            radial_mtf=(("layout", "eye", "depth", "accommodation", "frequency"), mtf, {
                "long_name": "radial (meridian-averaged) MTF", "units": "1"}),
            predicted_accommodation=(("layout", "eye", "depth", "metric"), pred, {
                "long_name": "accommodation state maximising the metric on the grid",
                "units": "D"}),
            predicted_accommodation_parabolic=(("layout", "eye", "depth", "metric"), pred_par, {
                "long_name": "sub-grid peak: parabola through the grid peak and neighbours",
                "units": "D"}),
            predicted_accommodation_continuous=(("layout", "eye", "depth", "metric"), pred_cont, {
                "long_name": "continuous peak: three-point local refinement of the grid peak "
                             "(lfjax.vision.peaks 'local'; VSOTF only, NaN for Strehl)", "units": "D"}),
            continuous_peak_success=(("layout", "eye", "depth", "metric"), cont_ok, {
                "long_name": "the continuous peak converged inside its bracket"}),
            accommodation_error=(("layout", "eye", "depth", "metric"),
                                 pred - depths[None, None, :, None], {
                "long_name": "predicted accommodation minus rendered depth (negative: "
                             "focused farther than the image)", "units": "D"}),
            peak_value=(("layout", "eye", "depth", "metric"), peak, {
                "long_name": "metric value at its peak", "units": "1"}),
            cutoff_frequency=(("layout", "eye", "depth", "metric"), cutoff, {
                "long_name": f"frequency where the radial MTF at the predicted accommodation "
                             f"falls to {config.cutoff_threshold:g}", "units": "cpd"}),
            mtf_at_peak=(("layout", "eye", "depth", "metric", "frequency"),
                         mtf_peak.astype(np.float32), {
                "long_name": "radial MTF at the predicted accommodation", "units": "1"}),
            zernike_um=(("eye", "zernike_j"), zern, {
                "long_name": "OSA/ANSI Zernike coefficients on the measured pupil "
                             "(piston and tilt zeroed)", "units": "um"}),
            freq_step_cpd=(("layout",), np.asarray(steps, float), {
                "long_name": "frequency step of the layout's OTF grid (PSF field 60/df)",
                "units": "cpd"}),
            n_fft=(("layout",), np.asarray(nffts, int), {
                "long_name": "FFT size of the layout's subaperture window", "units": "1"}),
            compute_seconds=(("layout",), np.asarray(times, float), {
                "long_name": "wall time of the layout's through-focus call, incl. compilation",
                "units": "s"}),
        ),
        coords=dict(
            layout=("layout", names),
            eye=("eye", labels),
            is_average=("eye", is_avg, {"long_name": "the Thibos et al. (2002) average eye"}),
            depth=("depth", depths, {"long_name": "rendered depth (absolute)", "units": "D"}),
            depth_rel_cdp=("depth", np.round(depths - config.cdp_D, 9), {
                "long_name": "rendered depth relative to the CDP", "units": "D"}),
            accommodation=("accommodation", acc, {
                "long_name": "absolute accommodation state 1/z_acc", "units": "D"}),
            frequency=("frequency", freq, {"long_name": "spatial frequency", "units": "cpd"}),
            metric=("metric", list(METRICS)),
            zernike_j=("zernike_j", np.arange(zern.shape[1])),
            n_subapertures=("layout", [lay.n_subapertures for lay in layout_objs]),
            subaperture_diameter_mm=("layout", [float(np.max(np.asarray(lay.diameters_mm)))
                                                for lay in layout_objs], {"units": "mm"}),
        ),
        attrs=_dataset_attrs(config, options, eyes),
    )
    ds.attrs["sampling_json"] = json.dumps(samplings)
    ds.attrs["wavelengths_json"] = json.dumps(spectra)
    ds["n_wavelengths"] = (("layout",), np.asarray([len(spectra[n]) for n in names], int), {
        "long_name": "wavelengths summed in the layout's polychromatic OTF", "units": "1"})
    ds["spectral_rule"] = (("layout",), np.asarray([rules[n][0] for n in names]), {
        "long_name": "how the layout's wavelengths were chosen: 'uniform' (a step, weights "
                     "V(λ)·Δλ) or 'gauss' (the Gauss rule for V(λ): nodes and weights)"})
    ds["wavelength_step_nm"] = (("layout",), np.asarray(
        [rules[n][1] if rules[n][0] == "uniform" else np.nan for n in names]), {
        "long_name": "wavelength step of the layout's uniform spectrum (400-700 nm; NaN for "
                     "a Gauss rule)", "units": "nm"})
    return ds


def study_wavelength_rules(ds) -> dict[str, tuple[str, float]]:
    """{layout: (rule, value)} a study Dataset used (its plan, to reuse as
    :attr:`~lfjax.reproduce.config.StudyConfig.wavelength_rules`): ("uniform", step nm) or
    ("gauss", nodes)."""
    rules = {}
    for name in ds.layout.values:
        layout_ds = ds.sel(layout=name)
        rule = str(layout_ds.spectral_rule.values) if "spectral_rule" in ds else "uniform"
        if rule == "gauss":
            rules[str(name)] = ("gauss", float(layout_ds.n_wavelengths))
        elif np.isfinite(float(layout_ds.wavelength_step_nm)):
            rules[str(name)] = ("uniform", float(layout_ds.wavelength_step_nm))
    return rules


def replace_layouts(ds, other):
    """``ds`` with the layouts of ``other`` (a study Dataset of the same eyes, depths and
    states, computed on another spectrum or sampling) put in place of its own: every
    per-layout variable, the samplings and spectra in the attributes, and
    ``reference_layouts_json`` (the layouts so replaced). The frequency axis becomes the
    longer of the two (a layout's MTF is 0 beyond its own frequency grid)."""
    names = [str(n) for n in other.layout.values]
    missing = [n for n in names if n not in [str(x) for x in ds.layout.values]]
    if missing:
        raise ValueError(f"replace_layouts: {missing} are not layouts of the Dataset")
    freq = ds.frequency.values if ds.frequency.size >= other.frequency.size else other.frequency.values
    ds, other = _on_frequency_axis(ds, freq), _on_frequency_axis(other, freq)
    out = ds.copy()
    for var in out.data_vars:
        if "layout" not in out[var].dims:
            continue
        values = other[var].sel(layout=names).transpose(*out[var].dims).values
        if out[var].dtype.kind == "U":  # e.g. spectral_rule: "gauss" cannot hold "uniform"
            out[var] = out[var].astype(object)
        data = out[var].values.copy()
        index = [list(out.layout.values).index(n) for n in names]
        axis = out[var].dims.index("layout")
        np.moveaxis(data, axis, 0)[index] = np.moveaxis(values, axis, 0)
        out[var] = (out[var].dims, data.astype(str) if data.dtype == object else data,
                    out[var].attrs)
    for key in ("sampling_json", "wavelengths_json"):
        merged = json.loads(out.attrs[key])
        merged.update({n: json.loads(other.attrs[key])[n] for n in names})
        out.attrs[key] = json.dumps(merged)
    done = set(json.loads(ds.attrs.get("reference_layouts_json", "[]"))) | set(names)
    out.attrs["reference_layouts_json"] = json.dumps(
        [str(n) for n in out.layout.values if str(n) in done])
    return out


def _on_frequency_axis(ds, freq):
    """``ds`` with its MTFs on the frequency axis ``freq`` (a longer 1 cpd axis from 0):
    0 beyond each layout's own grid where the layout was computed, NaN where it was not."""
    if ds.frequency.size == len(freq):
        return ds
    computed = np.isfinite(ds.radial_mtf.isel(frequency=0))
    at_peak = np.isfinite(ds.mtf_at_peak.isel(frequency=0))
    out = ds.reindex(frequency=freq)
    out["radial_mtf"] = out.radial_mtf.fillna(0.0).where(computed).astype(np.float32)
    out["mtf_at_peak"] = out.mtf_at_peak.fillna(0.0).where(at_peak).astype(np.float32)
    return out


def study_sampling(ds, layout: str) -> Sampling:
    """The :class:`~lfjax.base.sampling.Sampling` the study used for ``layout``."""
    return Sampling(**json.loads(ds.attrs["sampling_json"])[layout])


def _mtf_at(mtf, acc_index):
    """mtf (layout, eye, depth, acc, f) at acc_index (layout, eye, depth, metric) →
    (layout, eye, depth, metric, f)."""
    idx = acc_index[..., None]  # (l, e, d, m, 1)
    idx = np.broadcast_to(idx, acc_index.shape + (mtf.shape[-1],))
    return np.take_along_axis(mtf, idx, axis=3)


def _dataset_attrs(config: StudyConfig, options: ModelOptions, eyes: Eyes) -> dict:
    attrs = {
        "title": "lfjax reproduction of Miyanishi, Sahin & Gotchev: eyes viewing a "
                 "light-field display",
        "units": "depths and accommodation in dioptres (D, absolute 1/m; 0 D = infinity); "
                 "frequency in cycles per degree (cpd); Zernike coefficients in um",
        "pupil_diameter_mm": float(config.pupil_diameter_mm),
        "cdp_D": float(config.cdp_D),
        "measured_pupil_mm": float(eyes.measured_pupil_mm),
        "eye_orientation": eyes.orientation,
        "eyes_source": "Thibos, Bradley & Hong (2002) statistics, lfjax.sample_eyes(seed, n)",
        "wavelengths_nm": (json.dumps([float(w) for w in config.wavelength_grid_nm])
                           if config.accuracy == "vsotf" else
                           "planned per layout: wavelengths_json, spectral_rule, wavelength_step_nm"),
        "accuracy_plan": config.accuracy,
        "model_options_json": json.dumps(options.as_dict()),
    }
    # the one provenance stamp (lfjax._version.stamp); netCDF attributes cannot hold None,
    # so a source tree that is no git checkout records its commit as ""
    attrs.update({key: "" if value is None else value for key, value in stamp().items()})
    for key, value in options.as_dict().items():
        attrs[f"option_{key}"] = str(value) if isinstance(value, bool) else value
    attrs.update(config.as_attrs())
    return attrs


# ----------------------------------------------------------------------------- the Dataset's eyes



__all__ = [
    "layout_through_focus",
    "layout_through_focus_variants",
    "layout_workers",
    "run_study",
    "run_study_variants",
    "study_sampling",
    "study_wavelength_rules",
    "replace_layouts",
]
