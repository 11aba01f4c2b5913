"""Horizontal-parallax-only (lenticular) views and cross-talk between views, for a population.

:func:`run_hpo_study` answers: does an HPO display (1×n vertical strips,
:func:`lfjax.model.strips.strip_layout`) drive accommodation, through which orientation,
and at what cost in resolution, against a full-parallax n×n display of the same view pitch?
For every layout it records, per eye and rendered depth, the predicted accommodation of the
whole VSOTF and of its two orientation bands (:mod:`lfjax.vision.orientation`: vertical
structure on the f_x axis, horizontal structure on the f_y axis), the VSOTF at the eye's own
peak and the MTF cut-off along each axis there. HPO strips are run twice: the idealised
1-D light field (no astigmatism, Δ = 0: the panel's pixels on the CDP) and the lenticular
phone (:func:`lfjax.display.lenticular.lenticular_phone`: along y the beam focuses on the
panel, Δ = −0.83 D).

:func:`run_crosstalk_study` scans, at a fixed view count, the views' width against their
pitch (gaps below 1, overlap above) and the leakage weight of the neighbours' content
(:class:`lfjax.display.lenticular.ViewOptics`), for an n×n grid and for 1×n strips, and
reads the accommodative gain — the slope of the predicted accommodation against the
rendered depth over the depths given (1 = follows, 0 = stays on the CDP) — and the threshold
where it falls below ``gain_threshold``.

Everything is an ideal display otherwise (geometric views, point emitters, the spectrum
given): the comparisons isolate the view geometry.
"""

from __future__ import annotations

import time
from dataclasses import asdict, dataclass, field

import jax
import numpy as np

from lfjax.base.apertures import CIRCLE, STRIP
from lfjax.base.errors import ParameterError
from lfjax.base.sampling import AliasingError, Sampling, finer_step
from lfjax.display.lenticular import lenticular_phone, strip_display
from lfjax.model.eyes import sample_eyes
from lfjax.model.layouts import grid_layout, make_layout
from lfjax.model.spectral import GAUSS_MAX_NODES, gauss_spectrum, make_spectrum
from lfjax.model.strips import strip_layout
from lfjax.vision.orientation import BANDS, orientation_through_focus
from lfjax.vision.prepare import States
from lfjax.vision.viewing import Viewing

@dataclass(frozen=True)
class HpoConfig:
    """Settings of the HPO and cross-talk studies (mm, D, nm).

    Attributes
    ----------
    n_eyes, seed : the population (Thibos et al. 2002 draws, 3 mm pupil)
    pupil_diameter_mm, cdp_D : the paper's 3 mm pupil and 2 D CDP
    depths_D : rendered depths, D (the paper's CDP − 2 … CDP + 2)
    accommodation_D : the shared accommodation grid, D (peaks refined by a parabola)
    views : n of the 1×n strips and n×n grids compared
    spectral_nodes : None (default): the uniform samples ``wavelengths_nm`` with V(λ)
        weights; an integer: the Gauss rule for V(λ) on 400–700 nm with that many nodes
        (:func:`lfjax.model.spectral.gauss_spectrum`). Against 31 wavelengths (4 eyes, 1×3
        strips) the default's 9 samples read peaks within 0.002 D and cut-offs within
        0.4 cpd; 5 Gauss nodes miss the y cut-off by 3 cpd
        (``benchmarks/validation/hpo_settings.py``)
    wavelengths_nm : the uniform samples, nm
    freq_step_cpd : first frequency step tried; refined while the field guard refuses it
    widths : view width / pitch of the overlap scan (< 1 gaps, > 1 overlap)
    leakage_weights : the leakage scan, unitless in [0, 1]
    crosstalk_views : n of the cross-talk scans' n×n grid and 1×n strips
    crosstalk_depths_D : rendered depths of the cross-talk scans (the gain is their slope)
    gain_threshold : accommodative gain below which accommodation no longer follows
    eye_chunk : eyes evaluated together
    """

    n_eyes: int = 20
    seed: int = 0
    pupil_diameter_mm: float = 3.0
    cdp_D: float = 2.0
    depths_D: tuple = (0.0, 1.0, 2.0, 3.0, 4.0)
    accommodation_D: tuple = tuple(np.round(np.arange(0.0, 4.51, 0.25), 6))
    views: tuple = (2, 3, 4)
    spectral_nodes: int | None = None
    wavelengths_nm: tuple = tuple(np.arange(450.0, 651.0, 25.0))
    freq_step_cpd: float = 0.75
    widths: tuple = (0.5, 0.75, 1.0, 1.25, 1.5)
    leakage_weights: tuple = (0.0, 0.1, 0.25, 0.5, 1.0)
    crosstalk_views: int = 3
    crosstalk_depths_D: tuple = (1.0, 2.0, 3.0)
    gain_threshold: float = 0.5
    eye_chunk: int | None = 4

    def __post_init__(self):
        if int(self.n_eyes) != self.n_eyes or self.n_eyes < 2:
            raise ParameterError("n_eyes", "{n_eyes} must be an integer >= 2, got {got!r}",
                                 owner="HpoConfig", got=self.n_eyes)
        for name in ("widths",):
            w = np.asarray(getattr(self, name), float)
            if w.size < 1 or not np.all((w > 0) & (w <= 2)):
                raise ParameterError(name, "{%s} must be view width / pitch ratios in (0, 2] "
                                     "(unitless), got {got}" % name, owner="HpoConfig", got=w.tolist())
        w = np.asarray(self.leakage_weights, float)
        if w.size < 1 or not np.all((w >= 0) & (w <= 1)):
            raise ParameterError("leakage_weights", "{leakage_weights} must lie in [0, 1] "
                                 "(unitless), got {got}", owner="HpoConfig", got=w.tolist())
        if len(self.crosstalk_depths_D) < 2:
            raise ParameterError("crosstalk_depths_D", "{crosstalk_depths_D} needs >= 2 depths "
                                 "(D) for a gain", owner="HpoConfig")
        if self.spectral_nodes is not None and (
                isinstance(self.spectral_nodes, bool) or int(self.spectral_nodes) != self.spectral_nodes
                or not 1 <= self.spectral_nodes <= GAUSS_MAX_NODES):
            raise ParameterError("spectral_nodes", "{spectral_nodes} must be None or an integer in "
                                 "1–%d (Gauss nodes in V(λ)), got {got!r}" % GAUSS_MAX_NODES,
                                 owner="HpoConfig", got=self.spectral_nodes)
        grid = np.asarray(self.accommodation_D, float)
        depths = tuple(self.depths_D) + tuple(self.crosstalk_depths_D) + (self.cdp_D,)
        if (grid.ndim != 1 or grid.size < 3 or np.any(np.diff(grid) <= 0)
                or grid[0] > min(depths) or grid[-1] < max(depths)):
            raise ParameterError("accommodation_D", "{accommodation_D} must be >= 3 increasing "
                                 "states (D) spanning the depths and the CDP (%g–%g D), got {got}"
                                 % (min(depths), max(depths)), owner="HpoConfig", got=grid.tolist())
        if not (0 < self.gain_threshold < 1):
            raise ParameterError("gain_threshold", "{gain_threshold} must be in (0, 1) "
                                 "(unitless), got {got}", owner="HpoConfig", got=self.gain_threshold)

    @classmethod
    def tiny(cls) -> HpoConfig:
        """A small version for tests and notebooks (2 eyes, 2 views, coarse grids)."""
        return cls(n_eyes=2, depths_D=(1.0, 2.0, 3.0), accommodation_D=tuple(np.arange(1.0, 3.01, 0.5)),
                   views=(2,), spectral_nodes=None, wavelengths_nm=(550.0,), freq_step_cpd=1.5, widths=(0.75, 1.0, 1.25),
                   leakage_weights=(0.0, 0.5), crosstalk_views=2, eye_chunk=None)

    def spectrum(self):
        """The studies' spectrum (:class:`lfjax.model.spectral.Spectrum`) and its record
        (rule, wavelengths nm, weights) for the output."""
        if self.spectral_nodes is None:
            spectrum = make_spectrum(list(self.wavelengths_nm))
            rule = "uniform"
        else:
            spectrum = gauss_spectrum(int(self.spectral_nodes))
            rule = f"Gauss rule for V(λ) on 400–700 nm, {int(self.spectral_nodes)} nodes"
        return spectrum, {"rule": rule,
                          "wavelengths_nm": np.asarray(spectrum.wavelengths_nm, float).tolist(),
                          "weights": np.asarray(spectrum.weights, float).tolist()}


def _run(eyes, layout, display, depths, config: HpoConfig, spectrum):
    """Orientation through-focus with the frequency step refined until the field holds."""
    step = float(config.freq_step_cpd)
    grid = config.accommodation_D
    for _ in range(8):
        try:
            return (
                orientation_through_focus(
                    eyes,
                    layout,
                    States.grid(list(grid), list(depths)),
                    Viewing(
                        pupil_diameter_mm=config.pupil_diameter_mm,
                        cdp_D=config.cdp_D,
                        display=display,
                    ),
                    spectrum=spectrum,
                    sampling=Sampling(step),
                    eye_chunk=config.eye_chunk,
                ),
                step,
            )
        except AliasingError as err:
            step = finer_step(err, step)
    raise RuntimeError("no frequency step held the field")


def _summary(result, depths) -> dict:
    """Per band: mean and sd of the peaks and errors (D), VSOTF at the eye's peak, cut-offs."""
    out = {"depths_D": [float(d) for d in depths]}
    for band in BANDS:
        peak = result.peak_D(band)
        out[f"peak_{band}_D"] = peak.mean(0).tolist()
        out[f"peak_{band}_sd_D"] = peak.std(0, ddof=1).tolist()
        out[f"vsotf_{band}_at_peak"] = result.value_at_peak(band).mean(0).tolist()
    out["peaks_whole_D"] = result.peak_D("whole").tolist()
    for axis in ("x", "y"):
        out[f"cutoff_{axis}_cpd"] = result.cutoff_cpd(axis).mean(0).tolist()
    return out


def gain(peaks_D, depths_D) -> np.ndarray:
    """Accommodative gain: least-squares slope of the peaks (…, n_depth) D against the
    rendered depths (n_depth,) D; 1 follows the depth, 0 stays put."""
    d = np.asarray(depths_D, float)
    p = np.asarray(peaks_D, float)
    dc = d - d.mean()
    return np.sum((p - p.mean(-1, keepdims=True)) * dc, -1) / np.sum(dc * dc)


def run_hpo_study(config: HpoConfig = HpoConfig(), progress=print) -> dict:
    """HPO strips (Δ = 0 and the lenticular phone's Δ) against n×n grids and the natural
    view, for ``config.n_eyes`` eyes (module docstring). Returns a JSON-ready dict."""
    eyes = sample_eyes(jax.random.PRNGKey(config.seed), config.n_eyes, config.pupil_diameter_mm)
    spectrum, spectrum_record = config.spectrum()
    phone = lenticular_phone(cdp_D=config.cdp_D)
    delta = float(phone.y_defocus_D)
    cases = [("natural", None, None, (config.cdp_D,))]
    for n in config.views:
        strips = strip_layout(n, config.pupil_diameter_mm)
        cases.append((f"1x{n} HPO", strips, strip_display(strips), config.depths_D))
        cases.append((f"{n}x{n}", grid_layout(n, config.pupil_diameter_mm), None, config.depths_D))
    mid = config.views[len(config.views) // 2]
    strips = strip_layout(mid, config.pupil_diameter_mm)
    cases.append((f"1x{mid} HPO lenticular phone", strips, strip_display(strips, y_defocus_D=delta),
                  config.depths_D))
    rows = {}
    start = time.perf_counter()
    for name, layout, display, depths in cases:
        t = time.perf_counter()
        result, step = _run(eyes, layout, display, depths, config, spectrum)
        rows[name] = _summary(result, depths) | {"freq_step_cpd": step,
                                                  "seconds": time.perf_counter() - t}
        if len(depths) > 1:
            rows[name]["gain_whole"] = gain(result.peak_D("whole"), depths).tolist()
            for band in ("x", "y"):
                rows[name][f"gain_{band}"] = gain(result.peak_D(band), depths).tolist()
        progress(f"{name}: {rows[name]['seconds']:.1f} s, step {step:g} cpd")
    return {"config": asdict(config), "spectrum": spectrum_record, "y_defocus_phone_D": delta, "rows": rows,
            "seconds": time.perf_counter() - start}


def run_crosstalk_study(config: HpoConfig = HpoConfig(), progress=print) -> dict:
    """Overlap/gap and leakage scans for an n×n grid and 1×n strips (module docstring)."""
    eyes = sample_eyes(jax.random.PRNGKey(config.seed), config.n_eyes, config.pupil_diameter_mm)
    spectrum, spectrum_record = config.spectrum()
    n, pupil = int(config.crosstalk_views), config.pupil_diameter_mm
    pitch = pupil / n
    depths = config.crosstalk_depths_D
    out = {"config": asdict(config), "spectrum": spectrum_record, "scans": {}}
    start = time.perf_counter()

    def layouts(ratio):
        grid = grid_layout(n, pupil)
        grid = make_layout(np.asarray(grid.centres_mm), np.full(n * n, ratio * pitch), pupil,
                           name=f"{n}x{n} w/p {ratio:g}")
        strips = strip_layout(n, pupil, width_mm=ratio * pitch)
        return {"grid": (grid, CIRCLE.name), "strips": (strips, STRIP.name)}

    for kind in ("grid", "strips"):
        for scan, values in (("width", config.widths), ("leakage", config.leakage_weights)):
            rows = []
            for v in values:
                layout, aperture = layouts(v if scan == "width" else 1.0)[kind]
                display = strip_display(layout, aperture=aperture,
                                        leakage_weight=v if scan == "leakage" else 0.0)
                t = time.perf_counter()
                result, step = _run(eyes, layout, display, depths, config, spectrum)
                row = _summary(result, depths) | {"value": float(v), "freq_step_cpd": step}
                row["gain_whole"] = gain(result.peak_D("whole"), depths).tolist()
                row["gain_x"] = gain(result.peak_D("x"), depths).tolist()
                rows.append(row)
                progress(f"{kind} {scan} {v:g}: gain {np.mean(row['gain_whole']):.3f} "
                         f"({time.perf_counter() - t:.1f} s)")
            values_arr = np.asarray(values, float)
            gains = np.asarray([np.mean(r["gain_whole"]) for r in rows])
            out["scans"][f"{kind} {scan}"] = {"rows": rows,
                                              "threshold": threshold_crossing(values_arr, gains,
                                                                              config.gain_threshold)}
    out["seconds"] = time.perf_counter() - start
    return out


def threshold_crossing(values, gains, level: float):
    """First value (linear interpolation) where ``gains`` crosses ``level`` along the scan,
    or None when it never does."""
    v, g = np.asarray(values, float), np.asarray(gains, float) - level
    for i in range(v.size - 1):
        if g[i] == 0:
            return float(v[i])
        if g[i] * g[i + 1] < 0:
            return float(v[i] + (v[i + 1] - v[i]) * g[i] / (g[i] - g[i + 1]))
    return None


__all__ = ["HpoConfig", "run_hpo_study", "run_crosstalk_study", "gain", "threshold_crossing"]
