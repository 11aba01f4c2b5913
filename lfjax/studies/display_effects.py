"""How a real display changes the paper's conclusions: lenslet diffraction, finite pixels and
an OLED-like spectrum switched on one by one (issue #13's study).

The paper's display is ideal (geometric subapertures, point emitters, V(λ)-weighted white).
:func:`run_display_study` evaluates the same eyes, layouts and rendered depths in four
cumulative steps —

1. ``ideal``: the paper's display;
2. ``+diffraction``: each view is the Fresnel pattern of its lenslet
   (:func:`lfjax.display.lenslets.lenslets_for_layout`: the lenslet array at ``display_distance_mm``
   that puts n×n tangent views in the pupil with its CDP at ``cdp_D``);
3. ``+pixels``: emitters of ``pixel_pitch_mm`` (× ``fill_factor`` area) on the panel;
4. ``+spectrum``: the display's white (``spectrum``, default an OLED-like RGB) instead of
   V(λ)-weighted equal-energy white —

and records the continuous VSOTF accommodation peak, its error against the rendered depth,
and the MTF cut-off frequency at the peak. :func:`lenslet_sweep` answers "from which lenslet
size on does diffraction change the 2×2 conclusion": the same 2×2 views made by lenslet
arrays at increasing distance (smaller Fresnel numbers).

The VSOTF reference is the ideal display's in every step (:mod:`lfjax.kernel.pipeline`), so values
compare across steps. Everything runs on :func:`lfjax.vision.focus.through_focus` with the
planner's field guard choosing the sampling of each scene.
"""

from __future__ import annotations

import math
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from lfjax.base.units import check_dioptres
from lfjax.base.grids import DepthGrid
from lfjax.display.lenslets import lenslets_for_layout
from lfjax.display.spectra import display_spectrum
from lfjax.model.eyes import Eyes
from lfjax.model.layouts import grid_layout
from lfjax.model.options import ModelOptions
from lfjax.vision.peak_options import PEAK_METHODS
from lfjax.planner.plan import plan_sampling
from lfjax.planner.scene import PlanScene
from lfjax.model.spectral import make_spectrum
from lfjax.vision.focus import through_focus
from lfjax.vision.prepare import States
from lfjax.vision.peak_options import PeakOptions
from lfjax.vision.viewing import Viewing

STEPS = ("ideal", "+diffraction", "+pixels", "+spectrum")
LAYOUT_SIZES = {"2x2": 2, "3x3": 3, "4x4": 4}


@dataclass(frozen=True)
class DisplayStudyConfig(DepthGrid):
    """Settings of the display-effects study (mm, D, nm).

    Attributes
    ----------
    layouts : names of n×n tangent grids ("2x2", "3x3", "4x4")
    pupil_diameter_mm, cdp_D : the paper's 3 mm pupil and 2 D CDP
    depth_offsets_D : rendered depths relative to the CDP, D
    accommodation_step_D : shared absolute accommodation grid step, D (0 D … max depth + window)
    window_D : states within ±window_D of each rendered depth are evaluated, D
    display_distance_mm : eye pupil–lenslet distance z_m of the display in steps 2–4, mm
    f_number : lenslet focal length / aperture (sets the gap and so the pixels' angle)
    pixel_pitch_mm, fill_factor : emitter pitch on the panel (mm) and emitting area fraction
    spectrum : built-in display name (:data:`lfjax.display.spectra.DISPLAY_NAMES`) for step 4
    wavelength_step_nm : wavelength step of the V(λ) white in steps 1–3 and the cell width
        of the display spectrum, nm (RESULTS §6: 20 nm moved no prediction on the paper's grid)
    sweep_distances_mm : display distances of :func:`lenslet_sweep` (2×2), mm
    sweep_window_D : the sweep's accommodation window, D (±2 D keeps the CDP — and the
        lenslet plane, near it — inside for every depth, so a metric can move there)
    options : ModelOptions
    cutoff_threshold : MTF value defining the cut-off frequency (paper: 0.05)
    peak_method : how the continuous VSOTF peak is refined from the grid
        (:func:`lfjax.vision.focus.through_focus`'s ``peak_method``: "auto" is Newton;
        "local" fits three states around the grid parabola's vertex, ~1e-4 D from Newton
        (:mod:`lfjax.vision.peaks`) and much cheaper to compile)
    """

    layouts: tuple[str, ...] = ("2x2", "3x3", "4x4")
    pupil_diameter_mm: float = 3.0
    cdp_D: float = 2.0
    depth_offsets_D: tuple[float, ...] = (-2.0, -1.0, 0.0, 1.0, 2.0)
    accommodation_step_D: float = 0.2
    window_D: float = 1.2
    display_distance_mm: float = 300.0
    f_number: float = 5.0
    pixel_pitch_mm: float = 0.01
    fill_factor: float = 0.5
    spectrum: str = "oled"
    wavelength_step_nm: float = 20.0
    sweep_distances_mm: tuple[float, ...] = (30.0, 100.0, 200.0, 300.0, 400.0, 450.0, 480.0, 495.0)
    sweep_window_D: float = 2.0
    options: ModelOptions = field(default_factory=ModelOptions)
    cutoff_threshold: float = 0.05
    peak_method: str = "auto"

    def __post_init__(self):
        unknown = [n for n in self.layouts if n not in LAYOUT_SIZES]
        if unknown or not self.layouts:
            raise ValueError(f"layouts must be a non-empty subset of {tuple(LAYOUT_SIZES)}, got {unknown}")
        limit = 1000.0 / self.cdp_D if self.cdp_D > 0 else math.inf
        if not (0 < self.display_distance_mm < limit):
            raise ValueError(f"display_distance_mm must be in (0, {limit:g}) mm (in front of the "
                             f"CDP), got {self.display_distance_mm}")
        if any(not (0 < d < limit) for d in self.sweep_distances_mm):
            raise ValueError(f"sweep_distances_mm must lie in (0, {limit:g}) mm, got {self.sweep_distances_mm}")
        if any(self.cdp_D + d < 0 for d in self.depth_offsets_D):
            raise ValueError("every rendered depth cdp_D + offset must be >= 0 D")
        check_dioptres("cdp_D", self.cdp_D, "CDP")
        check_dioptres("depth_offsets_D", [self.cdp_D + d for d in self.depth_offsets_D],
                       "rendered depth", note="cdp_D + each offset")
        if not (self.accommodation_step_D > 0 and self.window_D > 0 and self.wavelength_step_nm > 0):
            raise ValueError("accommodation_step_D, window_D and wavelength_step_nm must be > 0")
        if not (self.f_number > 0 and self.pixel_pitch_mm >= 0 and 0 < self.fill_factor <= 1):
            raise ValueError("f_number must be > 0, pixel_pitch_mm >= 0 mm and fill_factor in (0, 1]")

        if self.peak_method not in PEAK_METHODS:
            raise ValueError(f"peak_method must be one of {PEAK_METHODS}, got {self.peak_method!r}")

    @classmethod
    def quick(cls, **changes) -> DisplayStudyConfig:
        """A small version for tests and the notebook's test run: 2×2 only, three depths,
        0.5 D states, 50 nm wavelength steps, two sweep distances."""
        base = dict(layouts=("2x2",), depth_offsets_D=(-1.0, 0.0, 1.0), accommodation_step_D=0.5,
                    window_D=1.0, wavelength_step_nm=50.0, sweep_distances_mm=(100.0, 400.0))
        base.update(changes)
        return cls(**base)

    @property
    def accommodation_max_D(self) -> float:
        """Last accommodation state, D: the farthest rendered depth plus the wider window
        (``accommodation_D`` is 0 … this in ``accommodation_step_D``)."""
        return float(self.depths_D.max()) + max(self.window_D, self.sweep_window_D)

    def white_spectrum(self):
        """The paper's V(λ)-weighted white on 400–700 nm at ``wavelength_step_nm``."""
        return make_spectrum(np.arange(400.0, 700.0 + 1e-9, self.wavelength_step_nm), self.options)

    def display_white(self):
        return display_spectrum(self.spectrum, "white", self.options,
                                step_nm=max(self.wavelength_step_nm, 5.0))

    def lenslets(self, n_per_side: int, distance_mm: float | None = None):
        distance = self.display_distance_mm if distance_mm is None else distance_mm
        return lenslets_for_layout(n_per_side, self.pupil_diameter_mm, self.cdp_D, distance,
                                   f_number=self.f_number)

    def as_attrs(self) -> dict:
        out = {}
        for key, value in asdict(self).items():
            if key == "options":
                continue
            out[f"config_{key}"] = list(value) if isinstance(value, tuple) else value
        return out


def shared_sampling(eyes: Eyes, config: DisplayStudyConfig, layout, display, *spectra,
                    window_D: float | None = None):
    """One sampling for every step of a layout: the planner's field guard for the most
    demanding scene (``display``: diffraction and pixels on) and the finest over the spectra,
    so the steps differ by the display effects only, not by their sampling."""
    depths = config.depths_D
    window = config.window_D if window_D is None else window_D
    pairs = States.grid(config.accommodation_D, depths, window).pairs
    plans = [plan_sampling(PlanScene(
        layout, config.pupil_diameter_mm, config.cdp_D, depths_D=depths,
        accommodation_window_D=None, pairs=pairs,
        wavelengths_nm=np.asarray(spectrum.wavelengths_nm),
        spectral_weights=np.asarray(spectrum.weights), eyes=eyes, options=config.options,
        display=display,
    ), estimate_accuracy=False) for spectrum in spectra]
    return min((p.sampling for p in plans), key=lambda s: s.freq_step_cpd)


def _evaluate(eyes: Eyes, config: DisplayStudyConfig, layout, spectrum, display, sampling=None,
              window_D: float | None = None):
    tf = through_focus(
        eyes,
        layout,
        States.grid(
            config.accommodation_D,
            depths_D=config.depths_D,
            window_D=config.window_D if window_D is None else window_D,
        ),
        Viewing(pupil_diameter_mm=config.pupil_diameter_mm, cdp_D=config.cdp_D, display=display),
        spectrum=spectrum,
        sampling=sampling,
        options=config.options,
        peaks=PeakOptions(metrics=("vsotf",), method=config.peak_method),
    )
    peaks = tf.peaks["vsotf"]
    predicted = np.asarray(peaks.accommodation_D, float)
    return dict(
        predicted=predicted,
        success=np.asarray(peaks.success, bool),
        peak_vsotf=np.asarray(peaks.value, float),
        cutoff=np.asarray(tf.cutoff_cpd("vsotf", config.cutoff_threshold), float),
        df=float(tf.sampling.freq_step_cpd),
        strehl_grid=np.asarray(tf.predicted_accommodation_D("strehl"), float),
    )


def run_display_study(eyes: Eyes, eye_names, config: DisplayStudyConfig = DisplayStudyConfig(),  # noqa: B008
                      progress: bool = True, on_scene=None):
    """The four cumulative steps (:data:`STEPS`) for every layout: an xarray Dataset with
    dims (step, layout, eye, depth) holding ``predicted_accommodation`` (continuous VSOTF
    peak, D), ``accommodation_error`` (D), ``peak_vsotf``, ``cutoff_frequency`` (cpd, at
    the VSOTF peak), ``peak_success``, and per (step, layout) ``seconds`` and
    ``freq_step_cpd`` (one per layout, :func:`shared_sampling`); the lenslet arrays'
    geometry per layout as coordinates."""
    import xarray as xr
    from tqdm import tqdm  # text bar: tqdm.auto warns in notebooks without ipywidgets

    names = list(config.layouts)
    depths = config.depths_D
    shape = (len(STEPS), len(names), eyes.n_eyes, depths.size)
    pred, cut, val = (np.full(shape, np.nan) for _ in range(3))
    ok = np.zeros(shape, bool)
    seconds = np.zeros(shape[:2])
    df = np.zeros(shape[:2])
    geometry = {k: [] for k in ("lenslet_pitch_mm", "lenslet_aperture_mm", "focal_length_mm",
                                "fresnel_number_550nm", "pixel_arcmin")}
    white, display_white = config.white_spectrum(), config.display_white()
    bar = tqdm(total=len(STEPS) * len(names), disable=not progress, unit="scene")
    for li, name in enumerate(names):
        n = LAYOUT_SIZES[name]
        layout = grid_layout(n, config.pupil_diameter_mm)
        lenslets = config.lenslets(n)
        diffracted = lenslets.optics()
        with_pixels = lenslets.optics(config.pixel_pitch_mm, config.fill_factor)
        geometry["lenslet_pitch_mm"].append(float(lenslets.pitch_mm))
        geometry["lenslet_aperture_mm"].append(float(lenslets.aperture_mm))
        geometry["focal_length_mm"].append(float(lenslets.focal_length_mm))
        geometry["fresnel_number_550nm"].append(float(lenslets.fresnel_number(550.0)))
        geometry["pixel_arcmin"].append(float(with_pixels.pixel_width_arcmin))
        scenes = [(white, None), (white, diffracted), (white, with_pixels), (display_white, with_pixels)]
        sampling = shared_sampling(eyes, config, layout, with_pixels, white, display_white)
        for si, (spectrum, display) in enumerate(scenes):
            bar.set_description(f"{name} {STEPS[si]}")
            if on_scene is not None:
                on_scene(f"{name} {STEPS[si]} ({li * len(STEPS) + si + 1}/"
                         f"{len(STEPS) * len(names)})")
            t0 = time.perf_counter()
            r = _evaluate(eyes, config, layout, spectrum, display, sampling)
            seconds[si, li] = time.perf_counter() - t0
            pred[si, li], ok[si, li], val[si, li], cut[si, li] = (
                r["predicted"], r["success"], r["peak_vsotf"], r["cutoff"])
            df[si, li] = r["df"]
            bar.update(1)
    bar.close()
    dims = ("step", "layout", "eye", "depth")
    ds = xr.Dataset(
        dict(
            predicted_accommodation=(dims, pred, {"units": "D", "long_name": "continuous VSOTF peak"}),
            accommodation_error=(dims, pred - depths, {"units": "D"}),
            peak_vsotf=(dims, val),
            peak_success=(dims, ok),
            cutoff_frequency=(dims, cut, {"units": "cpd", "long_name":
                                          f"MTF cut-off (falls to {config.cutoff_threshold:g}) at the VSOTF peak"}),
            seconds=(("step", "layout"), seconds, {"units": "s"}),
            freq_step_cpd=(("step", "layout"), df, {"units": "cpd"}),
        ),
        coords=dict(step=list(STEPS), layout=names, eye=list(eye_names), depth=depths,
                    **{k: ("layout", v) for k, v in geometry.items()}),
        attrs=dict(cdp_D=config.cdp_D, spectrum_wavelengths=int(display_white.n_wavelengths),
                   white_wavelengths=int(white.n_wavelengths), **config.as_attrs()),
    )
    return ds


def lenslet_sweep(eyes: Eyes, eye_names, config: DisplayStudyConfig = DisplayStudyConfig(),  # noqa: B008
                  progress: bool = True, on_scene=None):
    """2×2 tangent views made by lenslet arrays at each of ``config.sweep_distances_mm``
    (diffraction on, point emitters, V(λ) white): Dataset with dims (distance, eye, depth)
    holding ``predicted_accommodation``, ``accommodation_error`` (D), ``cutoff_frequency``
    (cpd), ``peak_vsotf`` (the VSOTF at its peak: how good the best image is) and
    ``strehl_accommodation`` (the Strehl ratio's grid peak, D), and per distance the lenslet
    aperture (mm) and Fresnel number at 550 nm; the ideal display's values ride along as
    ``ideal_*`` (eye, depth). Accommodation within ±``sweep_window_D`` of each depth; one
    sampling serves all (:func:`shared_sampling`)."""
    import xarray as xr
    from tqdm import tqdm  # text bar: tqdm.auto warns in notebooks without ipywidgets

    depths = config.depths_D
    layout = grid_layout(2, config.pupil_diameter_mm)
    white = config.white_spectrum()
    distances = np.asarray(config.sweep_distances_mm, float)
    shape = (distances.size, eyes.n_eyes, depths.size)
    pred, cut, val, strehl = (np.full(shape, np.nan) for _ in range(4))
    aperture, fresnel = np.zeros(distances.size), np.zeros(distances.size)
    bar = tqdm(total=distances.size + 1, disable=not progress, unit="scene")
    bar.set_description("2x2 ideal")
    if on_scene is not None:
        on_scene(f"2x2 ideal (1/{distances.size + 1})")
    # diffraction's field guard does not depend on the distance: one sampling for all
    window = config.sweep_window_D
    sampling = shared_sampling(eyes, config, layout, config.lenslets(2, float(distances[0])).optics(),
                               white, window_D=window)
    ideal = _evaluate(eyes, config, layout, white, None, sampling, window)
    bar.update(1)
    for i, distance in enumerate(distances):
        bar.set_description(f"2x2 lenslets at {distance:g} mm")
        if on_scene is not None:
            on_scene(f"2x2 lenslets at {distance:g} mm ({i + 2}/{distances.size + 1})")
        lenslets = config.lenslets(2, float(distance))
        aperture[i] = float(lenslets.aperture_mm)
        fresnel[i] = float(lenslets.fresnel_number(550.0))
        r = _evaluate(eyes, config, layout, white, lenslets.optics(), sampling, window)
        pred[i], cut[i], val[i], strehl[i] = r["predicted"], r["cutoff"], r["peak_vsotf"], r["strehl_grid"]
        bar.update(1)
    bar.close()
    dims = ("distance", "eye", "depth")
    return xr.Dataset(
        dict(
            predicted_accommodation=(dims, pred, {"units": "D"}),
            accommodation_error=(dims, pred - depths, {"units": "D"}),
            cutoff_frequency=(dims, cut, {"units": "cpd"}),
            peak_vsotf=(dims, val),
            strehl_accommodation=(dims, strehl, {"units": "D", "long_name": "Strehl ratio grid peak"}),
            ideal_accommodation_error=(("eye", "depth"), ideal["predicted"] - depths, {"units": "D"}),
            ideal_cutoff_frequency=(("eye", "depth"), ideal["cutoff"], {"units": "cpd"}),
            ideal_peak_vsotf=(("eye", "depth"), ideal["peak_vsotf"]),
            ideal_strehl_accommodation=(("eye", "depth"), ideal["strehl_grid"], {"units": "D"}),
        ),
        coords=dict(distance=distances, eye=list(eye_names), depth=depths,
                    lenslet_aperture_mm=("distance", aperture),
                    fresnel_number_550nm=("distance", fresnel)),
        attrs=dict(cdp_D=config.cdp_D, **config.as_attrs()),
    )


def effects_table(ds):
    """Per (layout, step, depth): mean accommodation error (D) and mean cut-off (cpd) over
    the eyes, and their change from the ideal display — a pandas DataFrame."""
    import pandas as pd

    rows = []
    for layout in ds.layout.values:
        base = ds.sel(layout=layout, step="ideal")
        for step in ds.step.values:
            sub = ds.sel(layout=layout, step=step)
            for di, depth in enumerate(ds.depth.values):
                err = sub.accommodation_error.isel(depth=di).values
                cut = sub.cutoff_frequency.isel(depth=di).values
                rows.append(dict(
                    layout=str(layout), step=str(step), depth_D=float(depth),
                    depth_rel_cdp_D=float(depth - ds.attrs["cdp_D"]),
                    mean_error_D=float(np.mean(err)),
                    change_error_D=float(np.mean(err - base.accommodation_error.isel(depth=di).values)),
                    mean_cutoff_cpd=float(np.mean(cut)),
                    change_cutoff_cpd=float(np.mean(cut - base.cutoff_frequency.isel(depth=di).values)),
                    all_converged=bool(sub.peak_success.isel(depth=di).values.all()),
                ))
    return pd.DataFrame(rows)


def sweep_table(sweep):
    """Per (distance, depth): lenslet aperture (mm), Fresnel number, mean accommodation error
    (D), mean VSOTF at the peak, mean Strehl-ratio prediction (D) and mean cut-off (cpd), each
    with the ideal display's beside it."""
    import pandas as pd

    rows = []
    for i, distance in enumerate(sweep.distance.values):
        for di, depth in enumerate(sweep.depth.values):
            rows.append(dict(
                distance_mm=float(distance),
                lenslet_aperture_mm=float(sweep.lenslet_aperture_mm[i]),
                fresnel_number_550nm=float(sweep.fresnel_number_550nm[i]),
                depth_D=float(depth),
                mean_error_D=float(sweep.accommodation_error.isel(distance=i, depth=di).mean()),
                ideal_mean_error_D=float(sweep.ideal_accommodation_error.isel(depth=di).mean()),
                mean_peak_vsotf=float(sweep.peak_vsotf.isel(distance=i, depth=di).mean()),
                ideal_mean_peak_vsotf=float(sweep.ideal_peak_vsotf.isel(depth=di).mean()),
                mean_strehl_accommodation_D=float(sweep.strehl_accommodation.isel(distance=i, depth=di).mean()),
                ideal_mean_strehl_accommodation_D=float(sweep.ideal_strehl_accommodation.isel(depth=di).mean()),
                mean_cutoff_cpd=float(sweep.cutoff_frequency.isel(distance=i, depth=di).mean()),
                ideal_mean_cutoff_cpd=float(sweep.ideal_cutoff_frequency.isel(depth=di).mean()),
            ))
    return pd.DataFrame(rows)


def accommodative_gain(depths_D, predicted_D) -> float:
    """Slope of the predicted accommodation against the rendered depth (least squares, D/D):
    1 when accommodation follows the rendered depth, 0 when it stays at one plane (the CDP,
    or the lenslets for a pinhole display)."""
    return float(np.polyfit(np.asarray(depths_D, float), np.asarray(predicted_D, float), 1)[0])


def two_by_two_verdict(sweep, min_gain: float = 0.8, max_change_D: float = 0.25):
    """Does lenslet diffraction change the paper's 2×2 conclusion — that 2×2 views drive
    accommodation to the rendered depth? It holds while the accommodative gain
    (:func:`accommodative_gain` of the eyes' mean continuous VSOTF peaks over the rendered
    depths) stays ≥ ``min_gain`` and the mean error at every depth stays within
    ``max_change_D`` (the paper's "small error" scale) of the ideal display's. Returns (text, smallest lenslet aperture (mm) at which the
    conclusion still holds or NaN, largest aperture at which it fails or NaN). The text also
    gives, per lenslet size, the largest change of the mean error from the ideal display
    (D), the mean VSOTF at the peak (how good the best retinal image is) and the gain of
    the Strehl ratio's peaks (when present), which can disagree with the VSOTF's."""
    depths = sweep.depth.values
    ideal_gain = accommodative_gain(depths, depths + sweep.ideal_accommodation_error.mean("eye").values)
    apertures = sweep.lenslet_aperture_mm.values
    gains = np.array([accommodative_gain(depths, sweep.predicted_accommodation.isel(distance=i).mean("eye"))
                      for i in range(apertures.size)])
    ideal_mean = sweep.ideal_accommodation_error.mean("eye").values
    changes = np.array([np.max(np.abs(sweep.accommodation_error.isel(distance=i).mean("eye").values - ideal_mean))
                        for i in range(apertures.size)])
    keeps = (gains >= min_gain) & (changes <= max_change_D)
    kept, broken = apertures[keeps], apertures[~keeps]
    has_strehl = "strehl_accommodation" in sweep
    ideal_extra = ""
    if has_strehl:
        ideal_extra = (f", VSOTF at the peak {float(sweep.ideal_peak_vsotf.mean()):.3f}, Strehl gain "
                       f"{accommodative_gain(depths, sweep.ideal_strehl_accommodation.mean('eye')):.2f}")
    parts = [f"ideal display: VSOTF gain {ideal_gain:.2f}{ideal_extra}"]
    for i, distance in enumerate(sweep.distance.values):
        change = float(changes[i])
        extra = ""
        if has_strehl:
            strehl_gain = accommodative_gain(depths, sweep.strehl_accommodation.isel(distance=i).mean("eye"))
            extra = (f", VSOTF at the peak {float(sweep.peak_vsotf.isel(distance=i).mean()):.3f}, "
                     f"Strehl gain {strehl_gain:.2f}")
        parts.append(f"lenslets {apertures[i]:.3g} mm at {distance:g} mm (Fresnel number "
                     f"{float(sweep.fresnel_number_550nm[i]):.2g}): VSOTF gain {gains[i]:.2f} (mean error "
                     f"within {change:.2f} D of the ideal display's){extra}: "
                     f"{'holds' if keeps[i] else 'changed'}")
    return ("; ".join(parts), float(kept.min()) if kept.size else math.nan,
            float(broken.max()) if broken.size else math.nan)


def display_effects_markdown(ds, sweep) -> str:
    """The report section: what each display effect does to the predictions and the cut-off."""
    table = effects_table(ds)
    lines = []
    cfg = ds.attrs
    lines.append(
        f"Each step switches one more effect on (cumulative): lenslet diffraction of the lenslet "
        f"array at {cfg['config_display_distance_mm']:g} mm that makes each layout's views "
        f"(f-number {cfg['config_f_number']:g}), then emitters of {cfg['config_pixel_pitch_mm']:g} mm "
        f"pitch (fill {cfg['config_fill_factor']:g}), then the {cfg['config_spectrum']!r} display's "
        f"white ({cfg['spectrum_wavelengths']} wavelengths) instead of V(λ)-weighted white "
        f"({cfg['white_wavelengths']} wavelengths). Continuous VSOTF peaks; the VSOTF reference is the "
        "ideal display's in every step.")
    lines.append("")
    lines.append("| layout | lenslet aperture (mm) | Fresnel number (550 nm) | pixel (arcmin) |")
    lines.append("|---|---|---|---|")
    for li, name in enumerate(ds.layout.values):
        lines.append(f"| {name} | {float(ds.lenslet_aperture_mm[li]):.3f} | "
                     f"{float(ds.fresnel_number_550nm[li]):.2f} | {float(ds.pixel_arcmin[li]):.2f} |")
    lines.append("")
    lines.append("| layout | step | mean error over depths (D) | max change of mean error (D) | "
                 "mean cut-off (cpd) | change of mean cut-off (cpd) |")
    lines.append("|---|---|---|---|---|---|")
    for (layout, step), g in table.groupby(["layout", "step"], sort=False):
        lines.append(
            f"| {layout} | {step} | {g.mean_error_D.mean():+.3f} | "
            f"{g.change_error_D.abs().max():.3f} | {g.mean_cutoff_cpd.mean():.1f} | "
            f"{g.change_cutoff_cpd.mean():+.1f} |")
    lines.append("")
    text, smallest_kept, largest_broken = two_by_two_verdict(sweep)
    window = sweep.attrs.get("config_sweep_window_D", sweep.attrs.get("config_window_D"))
    lines.append(f"2x2 lenslet sweep (diffraction on, point emitters, V(λ) white; accommodation "
                 f"within ±{window:g} D of each depth, so the CDP is inside): {text}.")
    if np.isfinite(largest_broken):
        lines.append(f"Diffraction changes the 2x2 conclusion (VSOTF gain below 0.8, or a mean "
                     f"error more than 0.25 D from the ideal display's) for lenslets of "
                     f"{largest_broken:.3g} mm and smaller"
                     + (f"; it still holds at {smallest_kept:.3g} mm" if np.isfinite(smallest_kept) else "")
                     + ".")
    else:
        lines.append("Over the sweep, diffraction does not change the 2x2 conclusion: accommodation "
                     "follows the rendered depth (VSOTF gain >= 0.8, mean errors within 0.25 D of "
                     "the ideal display's) down to the smallest lenslet tried"
                     + (f", {smallest_kept:.3g} mm." if np.isfinite(smallest_kept) else "."))
    return "\n".join(lines)


def save_display_figures(ds, sweep, out) -> list[str]:
    """Figures: mean accommodation error and cut-off per step (one panel per layout), and the
    2×2 lenslet sweep. Returns the file names written into ``out``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out = Path(out)
    names = []
    fig, axes = plt.subplots(2, ds.layout.size, figsize=(4.2 * ds.layout.size, 6.4), squeeze=False,
                             sharex=True)
    for li, layout in enumerate(ds.layout.values):
        for step in ds.step.values:
            sub = ds.sel(layout=layout, step=step)
            axes[0, li].plot(ds.depth.values, sub.accommodation_error.mean("eye"), "o-", label=str(step))
            axes[1, li].plot(ds.depth.values, sub.cutoff_frequency.mean("eye"), "o-", label=str(step))
        axes[0, li].axhline(0.0, color="0.6", lw=0.8)
        axes[0, li].set_title(f"{layout}: lenslets {float(ds.lenslet_aperture_mm[li]):.2f} mm, "
                              f"N = {float(ds.fresnel_number_550nm[li]):.2g}")
        axes[1, li].set_xlabel("rendered depth (D)")
    axes[0, 0].set_ylabel("mean accommodation error (D)")
    axes[1, 0].set_ylabel("mean MTF cut-off at the peak (cpd)")
    axes[0, 0].legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out / "display_effects.png", dpi=110)
    plt.close(fig)
    names.append("display_effects.png")

    has_strehl = "strehl_accommodation" in sweep
    fig, axes = plt.subplots(1, 3 if has_strehl else 2, figsize=(15 if has_strehl else 10, 4))
    depths = sweep.depth.values
    for di, depth in enumerate(depths):
        line, = axes[0].plot(sweep.lenslet_aperture_mm, sweep.accommodation_error.isel(depth=di).mean("eye"),
                             "o-", label=f"{depth:g} D")
        axes[0].axhline(float(sweep.ideal_accommodation_error.isel(depth=di).mean()), color=line.get_color(),
                        ls=":", lw=0.8)
        axes[1].plot(sweep.lenslet_aperture_mm, sweep.cutoff_frequency.isel(depth=di).mean("eye"), "o-",
                     color=line.get_color())
        axes[1].axhline(float(sweep.ideal_cutoff_frequency.isel(depth=di).mean()), color=line.get_color(),
                        ls=":", lw=0.8)
        if has_strehl:
            axes[2].plot(sweep.lenslet_aperture_mm, sweep.strehl_accommodation.isel(depth=di).mean("eye"),
                         "s--", color=line.get_color())
            axes[2].axhline(depth, color=line.get_color(), ls=":", lw=0.8)
    for ax in axes:
        ax.set_xscale("log")
        ax.set_xlabel("lenslet aperture (mm)")
    axes[0].set_ylabel("2x2 mean accommodation error (D)")
    axes[1].set_ylabel("2x2 mean MTF cut-off (cpd)")
    if has_strehl:
        axes[2].set_ylabel("2x2 mean Strehl-ratio prediction (D)")
        axes[2].set_title("dotted: the rendered depth")
    axes[0].legend(title="rendered depth", fontsize=8)
    axes[0].set_title("dotted: ideal display")
    fig.tight_layout()
    fig.savefig(out / "display_lenslet_sweep.png", dpi=110)
    plt.close(fig)
    names.append("display_lenslet_sweep.png")
    return names


__all__ = [
    "STEPS",
    "DisplayStudyConfig",
    "run_display_study",
    "shared_sampling",
    "lenslet_sweep",
    "effects_table",
    "sweep_table",
    "two_by_two_verdict",
    "accommodative_gain",
    "display_effects_markdown",
    "save_display_figures",
]
