"""Design a lenticular (horizontal-parallax-only) display from a panel: 1×n strips, scored
on eyes by orientation.

A lenticular sheet (:class:`lfjax.display.lenticular.LenticularPanel`) has cylindrical
lenslets with power along x only, so its n views are vertical strips of the pupil, each an
astigmatic beam: along x it focuses on the CDP (and carries the x parallax), along y on the
panel's own plane, Δ = CDP − 1000/(z_m + z_0) D away (:mod:`lfjax.display.lenticular`).

**The design rule (closed form, no gradient fit).** For each count n of 1×n views the
panel's pixels and distance are kept and the CDP is the one asked (as for the n×n designs
of :mod:`lfjax.design.fit`):

* view pitch in the pupil D/n (n tangent strips filling the design pupil, the paper's n×n
  grid's pitch), fill 1 (every lower ``min_fill`` is met), so the lenticule pitch is
  Δu = D/(n·M) with M = 1/(1 − z_m·CDP/1000);
* the gap z_0 as long as the constraints allow: the smaller of the slowest lenticule
  (``max_f_number``) and the gap at which the eye box Δu(1 + z_m/z_0) shrinks to
  ``min_eye_box_mm`` (never below the fastest lenticule); the focal length follows,
  1/f = 1/z_0 − V. At a fixed CDP, distance and pitch the gap changes only three things:
  the pixel's angle along x, p/(z_0·M), and the views' y defocus |Δ| both shrink as the gap
  grows, and the eye box shrinks too. The first two only improve the image, so the best gap
  is the longest the eye box and the f-number range allow — the corner
  :func:`lfjax.design.fit.panel_from_box` reaches at (1, 1, 1).

Each count is then scored on eyes by :func:`lfjax.vision.orientation.orientation_through_focus`
(whole VSOTF and its two orientation bands: vertical structure on the f_x axis, horizontal
structure on the f_y axis) over an absolute accommodation grid: each band's predicted
accommodation per depth and its gain (slope against the rendered depth: 1 follows, 0 stays),
the whole VSOTF at each eye's own peak, the display's accommodation RMSE (each eye's error
less its own error on the CDP in natural viewing, the n×n design's requirement), and the MTF
0.05 cut-off along each axis at the eye's peak, capped at what the display samples (along x
the lenticules' depth-dependent limit, :func:`lfjax.display.panel.sampling_limit_cpd` of the
same x geometry; along y the panel's pixel rows seen directly, Nyquist 1/(2·p/(z_m + z_0))).
A count is ok when its RMSE is within ``accommodation_tolerance_D`` (0.25 D); the chosen one
has the highest whole VSOTF at the peak among those ok.

The design runs through the one runner of both kinds (:func:`lfjax.design.runner.run_counts`,
with a :class:`LenticularKind`): the same refusals, kept counts and files
(:func:`lfjax.design.write.save_design`) as the n×n design; what differs is how a count is
made (in closed form) and scored (by orientation).

Not for a lenticular design: a fitted viewing distance (``distance_range_mm``) and the
lenslets' aberration (``lens_form``: :mod:`lfjax.display.aberrations` models spherical
lenslets), both refused by :func:`check_lenticular_design`.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import math
import time
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from lfjax._version import __version__, stamp
from lfjax.base.errors import ParameterError
from lfjax.base.sampling import AliasingError, Sampling, finer_step
from lfjax.design.box import panel_from_box
from lfjax.design.fit import check_design
from lfjax.design.report import CountVerdict
from lfjax.design.runner import DesignKind, run_counts
from lfjax.design.settings import (FAST_REPORT_WAVELENGTHS_NM, REPORT_ACCURACIES, DesignConstraints,
                                   DesignTarget, ReportSettings)
from lfjax.display.lenticular import LenticularPanel
from lfjax.display.panel import Panel, sampling_limit_cpd
from lfjax.model.eyes import Eyes
from lfjax.model.layout_files import jsonable
from lfjax.model.layout_plots import draw_layout
from lfjax.model.options import ModelOptions
from lfjax.model.spectral import make_spectrum
from lfjax.vision.orientation import BANDS, orientation_through_focus
from lfjax.vision.prepare import States
from lfjax.vision.viewing import Viewing

LENTICULAR_FORMAT = "lfjax-design-lenticular/1"

ACCOMMODATION_STEP_D = 0.25
"""Step of the absolute accommodation grid the peaks are read on, D (refined by a parabola)."""

WINDOW_MARGIN_D = 1.0
"""The grid spans the depth range widened by this much on each side, D (from 0 D at least)."""

FIRST_FREQ_STEP_CPD = 0.75
EYE_CHUNK = 2
"""Eyes evaluated together: each holds the kernel's workspace
(:data:`lfjax.kernel.optics.KERNEL_WORKSPACE_BYTES`), so the peak memory grows with the
chunk; at 4 the command's defaults peaked at 4.15 GB."""
"""First frequency step tried without ``--freq-step``, cpd; refined while the field guard
refuses it (as :mod:`lfjax.studies.hpo` does)."""

FULL_REPORT_WAVELENGTHS_NM = tuple(float(w) for w in np.arange(400.0, 701.0, 10.0))
"""The ``"full"`` setting's spectrum: 400–700 nm in 10 nm steps (31 wavelengths)."""


def lenticular_panel(template: Panel, n_views: int, cdp_D: float,
                     constraints: DesignConstraints) -> LenticularPanel:
    """The lenticular panel of ``n_views`` strips by the design rule (module docstring):
    ``template``'s pixel pitch, distance and design pupil, the CDP at ``cdp_D`` D."""
    box = panel_from_box(np.ones(3), template, n_views, cdp_D, constraints)
    return LenticularPanel(*(float(np.asarray(v)) for v in (
        box.pixel_pitch_mm, box.lenslet_pitch_mm, box.fill, box.focal_length_mm, box.gap_mm,
        box.distance_mm)))


def accommodation_grid_D(depths_D) -> np.ndarray:
    """The absolute accommodation grid (D) the peaks are read on: the depth range widened
    by :data:`WINDOW_MARGIN_D` each side (from 0 D), in :data:`ACCOMMODATION_STEP_D` steps."""
    lo = max(0.0, float(np.min(depths_D)) - WINDOW_MARGIN_D)
    hi = float(np.max(depths_D)) + WINDOW_MARGIN_D
    n = int(round((hi - lo) / ACCOMMODATION_STEP_D)) + 1
    return np.round(lo + ACCOMMODATION_STEP_D * np.arange(n), 9)


def lenticular_target(depth_range_D, n_depths: int = 3, cdp_D: float | None = None,
                      views=(2, 3, 4), wavelengths_nm=(550.0,)) -> DesignTarget:
    """The :class:`~lfjax.design.settings.DesignTarget` of a lenticular design: ``views``
    are the n of 1×n strips, integers in [1, 8] (a refusal says so); the rest as there."""
    try:
        return DesignTarget(depth_range_D, n_depths, cdp_D, views, wavelengths_nm)
    except ParameterError as err:
        if err.parameter != "views_per_side":
            raise
        raise ParameterError("views_per_side", "{views_per_side} must be integers in [1, 8] "
                             "(the n of 1xn lenticular views), got {got}", got=list(views)) from None


def check_lenticular_design(panel: Panel, target: DesignTarget,
                            constraints: DesignConstraints = DesignConstraints()):  # noqa: B008
    """:func:`fit_lenticular_design`'s checks, on the host before any work: those of
    :func:`lfjax.design.fit.check_design` and the constraints a lenticular design cannot
    honour (a :class:`~lfjax.base.errors.ParameterError` naming them). Returns (depths_D,
    cdp_D, counts)."""
    if constraints.distance_range_mm is not None:
        raise ParameterError("distance_range_mm", "{distance_range_mm} is not for a lenticular "
                             "design: its geometry is set in closed form at the panel's viewing "
                             "distance (use --distance instead)")
    if constraints.lens_form is not None:
        raise ParameterError("lens_form", "{lens_form} is not for a lenticular design: the "
                             "lenslet aberration model (lfjax.display.aberrations) is of spherical "
                             "lenslets, not cylindrical lenticules")
    return check_design(panel, target)


def report_wavelengths_nm(report_accuracy: str, wavelengths_nm) -> tuple:
    """The spectrum the score is computed on: ``"fast"`` 400–700 nm in 30 nm, ``"full"`` in
    10 nm, ``"fit"`` the wavelengths given (nm)."""
    if report_accuracy not in REPORT_ACCURACIES:
        raise ParameterError("report_accuracy", "{report_accuracy} must be one of {allowed}, got {got!r}",
                             allowed=", ".join(REPORT_ACCURACIES), got=report_accuracy)
    return {"fast": FAST_REPORT_WAVELENGTHS_NM, "full": FULL_REPORT_WAVELENGTHS_NM,
            "fit": tuple(float(w) for w in wavelengths_nm)}[report_accuracy]


def _through_focus(eyes, layout, display, depths, grid, pupil, cdp, spectrum, sampling):
    """Orientation through-focus; without ``sampling`` the step is refined until the field
    holds. Returns (result, frequency step cpd)."""
    if sampling is not None:
        return orientation_through_focus(
            eyes,
            layout,
            States.grid(list(grid), list(depths)),
            Viewing(pupil_diameter_mm=pupil, cdp_D=cdp, display=display),
            spectrum=spectrum,
            sampling=sampling,
            options=ModelOptions(vsotf_reference="open_pupil"),
            eye_chunk=EYE_CHUNK,
        ), float(sampling.freq_step_cpd)
    step = FIRST_FREQ_STEP_CPD
    for _ in range(8):
        try:
            return _through_focus(eyes, layout, display, depths, grid, pupil, cdp, spectrum,
                                  Sampling(step))
        except AliasingError as err:
            step = finer_step(err, step)
    raise RuntimeError("no frequency step held the PSF field")


def gain(peaks_D, depths_D) -> np.ndarray:
    """Accommodative gain per eye: the least-squares slope of the peaks (…, n_depth) D
    against the rendered depths (n_depth,) D; 1 follows the depth, 0 stays put."""
    d = np.asarray(depths_D, float)
    p = np.asarray(peaks_D, float)
    dc = d - d.mean()
    return np.sum((p - p.mean(-1, keepdims=True)) * dc, -1) / np.sum(dc * dc)


def y_sampling_limit_cpd(panel: LenticularPanel) -> float:
    """Nyquist of the panel's pixel rows seen directly (no power along y), cpd:
    1/(2·p/(z_m + z_0)) cycles/rad."""
    rad = float(panel.pixel_pitch_mm) / (float(panel.distance_mm) + float(panel.gap_mm))
    return 1.0 / (2.0 * math.degrees(rad))


def x_sampling_limit_cpd(panel: LenticularPanel, depths_D) -> np.ndarray:
    """The lenticules' sampling limit along x at ``depths_D`` (cpd): that of a spherical
    lenslet panel of the same x geometry (:func:`lfjax.display.panel.sampling_limit_cpd`)."""
    same_x = Panel(*(float(np.asarray(v)) for v in (
        panel.pixel_pitch_mm, panel.lens_pitch_mm, panel.fill, panel.focal_length_mm,
        panel.gap_mm, panel.distance_mm)))
    return np.asarray(sampling_limit_cpd(same_x, np.asarray(depths_D, float)), float)


def score_lenticular(panel: LenticularPanel, eyes: Eyes, depths_D, cdp_D: float, *,
                     pupil_diameter_mm: float = 3.0, spectrum=None, diffraction: str = "fresnel",
                     sampling: Sampling | None = None, natural_peak_D=None) -> dict:
    """Scores of ``panel``'s 1×n strips on ``eyes`` (module docstring): JSON-ready numbers
    (D, cpd, VSOTF). ``natural_peak_D`` (n_eyes,) D: each eye's whole-band peak viewing a
    real point on the CDP (computed when None)."""
    depths = np.asarray(depths_D, float)
    grid = accommodation_grid_D(depths)
    layout = panel.layout(pupil_diameter_mm)
    display = panel.optics(layout, diffraction=diffraction)
    result, step = _through_focus(eyes, layout, display, depths, grid, pupil_diameter_mm, cdp_D,
                                  spectrum, sampling)
    if natural_peak_D is None:
        natural_peak_D = natural_peaks_D(eyes, cdp_D, pupil_diameter_mm, spectrum, sampling)
    own = np.asarray(natural_peak_D, float) - cdp_D
    out = {"freq_step_cpd": step, "accommodation_grid_D": [float(grid[0]), float(grid[-1])],
           "n_eyes": int(eyes.n_eyes)}
    for band in BANDS:
        peak = result.peak_D(band)
        out[f"peak_{band}_D_by_depth"] = peak.mean(0).tolist()
        out[f"gain_{band}_median"] = float(np.median(gain(peak, depths)))
        i = result.peak_index(band)
        out[f"edge_fraction_{band}"] = float(np.mean((i == 0) | (i == grid.size - 1)))
        out[f"vsotf_{band}_at_peak"] = float(result.value_at_peak(band, at="whole").mean())
    relative = result.peak_D("whole") - depths[None, :] - own[:, None]
    out["relative_accommodation_rmse_D"] = float(np.sqrt(np.mean(relative ** 2)))
    out["image_at_peak"] = out["vsotf_whole_at_peak"]
    limit_x = x_sampling_limit_cpd(panel, depths)
    limit_y = y_sampling_limit_cpd(panel)
    for axis, limit in (("x", limit_x[None, :]), ("y", limit_y)):
        raw = result.cutoff_cpd(axis, at="whole")
        capped = np.minimum(raw, limit)
        out[f"cutoff_{axis}_cpd_median"] = float(np.median(raw))
        out[f"perceivable_{axis}_cpd_median"] = float(np.median(capped))
        out[f"perceivable_{axis}_cpd_p05"], out[f"perceivable_{axis}_cpd_p95"] = (
            float(v) for v in np.percentile(capped, [5, 95]))
    out["sampling_limit_x_cpd_by_depth"] = limit_x.tolist()
    out["sampling_limit_y_cpd"] = float(limit_y)
    return out


def natural_peaks_D(eyes: Eyes, cdp_D: float, pupil_diameter_mm: float = 3.0, spectrum=None,
                    sampling: Sampling | None = None) -> np.ndarray:
    """Each eye's whole-band predicted accommodation viewing a real point at ``cdp_D``
    (open pupil), (n_eyes,) D: its own error, which the display's RMSE leaves out."""
    grid = accommodation_grid_D([cdp_D])
    result, _ = _through_focus(eyes, None, None, [cdp_D], grid, pupil_diameter_mm, cdp_D,
                               spectrum, sampling)
    return result.peak_D("whole")[:, 0]


def panel_record(panel: LenticularPanel, wavelength_nm: float = 550.0) -> dict:
    """The buildable specification and what follows from it, ``{"value", "unit"}`` each."""
    f = float(panel.focal_length_mm)
    aperture = float(panel.fill) * float(panel.lens_pitch_mm)
    numbers = {
        "pixel_pitch_mm": (panel.pixel_pitch_mm, "mm"),
        "lens_pitch_mm": (panel.lens_pitch_mm, "mm (cylindrical lenticules, power along x)"),
        "fill": (panel.fill, "aperture/pitch"), "focal_length_mm": (f, "mm"),
        "gap_mm": (panel.gap_mm, "mm (air-equivalent: a substrate t thick of index n counts t/n)"),
        "viewing_distance_mm": (panel.distance_mm, "mm"),
        "f_number": (f / aperture, "unitless"),
        "cdp_D": (panel.cdp_D, "D (along x)"),
        "panel_D": (panel.panel_D, "D (the y focus: the pixel plane's vergence)"),
        "y_defocus_D": (panel.y_defocus_D, "D (CDP - panel: the views' extra defocus along y)"),
        "strip_pitch_mm": (panel.view_pitch_mm, "mm (in the pupil)"),
        "strip_width_mm": (panel.view_width_mm, "mm (in the pupil; full pupil height)"),
        "eye_box_mm": (panel.eye_box_mm(), "mm"),
        "pixel_arcmin": (panel.pixel_arcmin(), "arcmin (along x, on the CDP)"),
        "fresnel_distance_mm": (panel.fresnel_distance_mm, "mm"),
        "fresnel_number_x": (float(panel.view_width_mm) ** 2 / (
            4e-6 * wavelength_nm * float(panel.fresnel_distance_mm)),
            f"unitless at {wavelength_nm:g} nm (along x only)"),
    }
    return {k: {"value": float(np.asarray(v)), "unit": u} for k, (v, u) in numbers.items()}


@dataclass
class LenticularFit(CountVerdict):
    """One count's lenticular design: ``panel`` (None when refused), ``score`` (the report
    eyes' numbers, :func:`score_lenticular`), ``refused`` / ``failed`` (why not, or None)."""

    n_views: int
    panel: LenticularPanel | None = None
    refused: str | None = None
    failed: str | None = None
    score: dict | None = None
    time_s: float = 0.0


@dataclass
class LenticularDesign:
    """Every count's :class:`LenticularFit`; the chosen one (:attr:`best`)."""

    fits: list
    cdp_D: float
    depths_D: list
    constraints: DesignConstraints
    tolerance_D: float
    provenance: dict = field(default_factory=dict)

    @property
    def best(self) -> LenticularFit | None:
        ok = [f for f in self.fits if f.ok]
        return max(ok, key=lambda f: f.score["image_at_peak"]) if ok else None

    def summary(self) -> str:
        eyes = self.provenance.get("scored_on", "report")
        lines = [f"design (lenticular, horizontal parallax only): CDP {self.cdp_D:g} D, depths "
                 f"{self.depths_D} D; 1xn vertical strips, cylindrical lenticules; scores on the "
                 f"{eyes} eyes (peaks: mean per depth; gain: median slope against the depth)"]
        for f in self.fits:
            if f.panel is None:
                lines.append(f"  1x{f.n_views}  refused: {f.refused}")
                continue
            p = panel_record(f.panel)
            s = f.score
            lines.append(
                f"  1x{f.n_views}  strips {p['strip_width_mm']['value']:.3g} mm wide (pitch "
                f"{p['strip_pitch_mm']['value']:.3g} mm) in the pupil; lenticules pitch "
                f"{p['lens_pitch_mm']['value']:.4g} mm, f {p['focal_length_mm']['value']:.4g} mm "
                f"(f/{p['f_number']['value']:.2g}), gap {p['gap_mm']['value']:.4g} mm; y focus "
                f"{p['panel_D']['value']:.3g} D, y defocus {p['y_defocus_D']['value']:+.3g} D")
            if s is None:
                lines.append(f"        {f.status}")
                continue
            peaks = {b: ", ".join(f"{v:.2f}" for v in s[f"peak_{b}_D_by_depth"]) for b in BANDS}
            lines.append(f"        accommodation D: whole [{peaks['whole']}] (gain {s['gain_whole_median']:.2f}), "
                         f"x / vertical structure [{peaks['x']}] (gain {s['gain_x_median']:.2f}), "
                         f"y / horizontal structure [{peaks['y']}] (gain {s['gain_y_median']:.2f}"
                         + (f", {100 * s['edge_fraction_y']:.0f} % on the grid's edge" if s['edge_fraction_y'] > 0 else "")
                         + ")")
            lines.append(f"        VSOTF at peak {s['image_at_peak']:.4f} (x band {s['vsotf_x_at_peak']:.4f}, "
                         f"y band {s['vsotf_y_at_peak']:.4f}); display's acc. RMSE "
                         f"{s['relative_accommodation_rmse_D']:.3f} D; perceivable cpd median "
                         f"x {s['perceivable_x_cpd_median']:.2f} [{s['perceivable_x_cpd_p05']:.2f}, "
                         f"{s['perceivable_x_cpd_p95']:.2f}], y {s['perceivable_y_cpd_median']:.2f} "
                         f"[{s['perceivable_y_cpd_p05']:.2f}, {s['perceivable_y_cpd_p95']:.2f}]; {f.status}")
        best = self.best
        lines.append(f"  chosen: 1x{best.n_views}" if best else "  chosen: none (no count is ok)")
        return "\n".join(lines)

    def record(self, command: str | None = None) -> dict:
        """``design.json``'s record (format :data:`LENTICULAR_FORMAT`): every count's
        specification and scores with units, the design marked HPO, the provenance stamp
        (:func:`lfjax._version.stamp`, with ``command``)."""
        best = self.best
        designs = [{"views": f"1x{f.n_views}", "n_views": f.n_views, "status": f.status,
                    "refused": f.refused, "failed": f.failed,
                    "specification": None if f.panel is None else panel_record(f.panel),
                    "scores": None if f.score is None else {k: {"value": v, "unit": score_unit(k)}
                                                            for k, v in f.score.items()},
                    "time_s": round(f.time_s, 2)} for f in self.fits]
        return {
            "format": LENTICULAR_FORMAT, "parallax": "horizontal only (lenticular, 1xn strips)",
            "chosen_views": None if best is None else f"1x{best.n_views}",
            "cdp_D": {"value": self.cdp_D, "unit": "D"},
            "depths_D": {"value": self.depths_D, "unit": "D"},
            "accommodation_tolerance_D": {"value": self.tolerance_D, "unit": "D"},
            "constraints": {"min_eye_box_mm": {"value": self.constraints.min_eye_box_mm, "unit": "mm"},
                            "f_number": {"value": [self.constraints.min_f_number,
                                                   self.constraints.max_f_number], "unit": "unitless"}},
            "designs": designs,
            "provenance": stamp(**self.provenance, command=command),
        }

    def figure(self):
        """``design.png``: the chosen count's strips in the pupil (the first count with a panel
        when none is chosen), or None when no count has one."""
        chosen = self.best or next((f for f in self.fits if f.panel is not None), None)
        if chosen is None:
            return None
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        p = panel_record(chosen.panel)
        pupil = float(self.provenance.get("pupil_diameter_mm", 3.0))
        fig, ax = plt.subplots(figsize=(5, 5))
        try:
            draw_layout(ax, chosen.panel.layout(pupil), pupil, aperture="strip",
                        title=f"1x{chosen.n_views} lenticular strips: width {p['strip_width_mm']['value']:.3g} mm,\n"
                              f"lenticules {p['lens_pitch_mm']['value']:.4g} mm, f {p['focal_length_mm']['value']:.3g} mm, "
                              f"gap {p['gap_mm']['value']:.3g} mm;\ny defocus {p['y_defocus_D']['value']:+.3g} D")
            ax.title.set_fontsize(8)
            fig.tight_layout()
        except BaseException:
            plt.close(fig)
            raise
        return fig


SCORE_UNITS = {"freq_step_cpd": "cpd", "accommodation_grid_D": "D (first, last)", "n_eyes": "eyes",
               "relative_accommodation_rmse_D": "D", "image_at_peak": "VSOTF (open-pupil reference)",
               "sampling_limit_y_cpd": "cpd", "sampling_limit_x_cpd_by_depth": "cpd per depth"}
"""Units of the scores :func:`score_lenticular` names outright; :func:`score_unit` the rest."""


def score_unit(key: str) -> str:
    """The unit of the score ``key`` of :func:`score_lenticular`."""
    if key in SCORE_UNITS:
        return SCORE_UNITS[key]
    for prefix, unit in (("peak_", "D (mean per depth)"), ("gain_", "unitless (median over eyes)"),
                         ("edge_", "fraction of peaks on the accommodation grid's edge"),
                         ("vsotf_", "VSOTF at the whole band's peak (mean)")):
        if key.startswith(prefix):
            return unit
    return "cpd"


def _key(template: Panel, n: int, **inputs) -> str:
    record = {"format": LENTICULAR_FORMAT, "lfjax_version": __version__, "n_views": int(n),
              "template": [float(np.asarray(v)) for v in (template.pixel_pitch_mm, template.distance_mm)]
              + [template.pupil_diameter_mm, template.diffraction], **inputs}
    return hashlib.blake2b(json.dumps(jsonable(record), sort_keys=True).encode(),
                           digest_size=16).hexdigest()


ONE_STRIP = "one strip fills the pupil: no parallax, the eye focuses on the CDP (choose views >= 2)"
"""Why a lenticular design refuses 1×1 (:func:`lfjax.design.runner.count_refusal`)."""


@dataclass
class LenticularKind(DesignKind):
    """The lenticular design as a kind of :func:`lfjax.design.runner.run_counts`: each count's
    panel set in closed form (:func:`lenticular_panel`; refused when its eye box falls short),
    every such count scored on ``eyes`` by orientation (:func:`score_lenticular`) and failed
    when its accommodation RMSE exceeds ``tolerance_D`` (D). The fields are
    :func:`fit_lenticular_design`'s (``cdp_D``: the design's CDP, D; ``report``: its
    spectrum's setting)."""

    panel: Panel
    target: DesignTarget
    cdp_D: float
    constraints: DesignConstraints
    tolerance_D: float
    report_accuracy: str
    sampling: Sampling | None
    eyes: Eyes
    held_out: bool = True
    natural_peak_D: np.ndarray | None = None
    """Each eye's whole-band peak on a real point at the CDP, (n_eyes,) D, once scored."""

    counts_format = LENTICULAR_FORMAT
    counts_stem = "lenticular"
    one_view = ONE_STRIP
    report_counts = "all"  # no training loss to rank the counts by: every count is scored

    @property
    def wavelengths_nm(self) -> tuple:
        return report_wavelengths_nm(self.report_accuracy, self.target.wavelengths_nm)

    def key(self, n: int) -> str:
        eyes = np.ascontiguousarray(np.asarray(self.eyes.zernike_um, np.float64)).tobytes()
        return _key(self.panel, n, depths_D=np.asarray(self.target.depths_D).tolist(), cdp_D=self.cdp_D,
                    constraints=self.constraints.as_dict(), tolerance_D=self.tolerance_D,
                    wavelengths_nm=list(self.wavelengths_nm),
                    sampling=None if self.sampling is None else dataclasses.asdict(self.sampling),
                    eyes=hashlib.blake2b(eyes, digest_size=16).hexdigest())

    def record(self, fit: LenticularFit) -> dict:
        panel = None if fit.panel is None else [float(np.asarray(v)) for v in (
            fit.panel.pixel_pitch_mm, fit.panel.lens_pitch_mm, fit.panel.fill,
            fit.panel.focal_length_mm, fit.panel.gap_mm, fit.panel.distance_mm)]
        return jsonable({"n_views": fit.n_views, "panel": panel, "refused": fit.refused,
                         "failed": fit.failed, "score": fit.score, "time_s": fit.time_s})

    def from_record(self, record: dict) -> LenticularFit:
        panel = None if record["panel"] is None else LenticularPanel(*record["panel"])
        return LenticularFit(int(record["n_views"]), panel, record["refused"], record["failed"],
                             record["score"], float(record["time_s"]))

    def refused(self, n: int, why: str) -> LenticularFit:
        return LenticularFit(n, refused=why)

    def plan(self, counts: list, kept: set, refusals: dict, counts_dir, say) -> None:
        if say is None:
            return
        depths = self.target.depths_D
        grid = accommodation_grid_D(depths)
        say(f"plan: lenticular (horizontal parallax only) 1xN, N in {list(counts)}, on the "
            f"{self.panel.name}'s pixels at {float(self.panel.distance_mm):g} mm; no fit (closed "
            f"form); scored on {self.eyes.n_eyes} {'held-out' if self.held_out else 'training'} "
            f"eyes at {len(self.wavelengths_nm)} wavelength(s), {len(depths)} depths, accommodation "
            f"{grid[0]:g}-{grid[-1]:g} D ({grid.size} states); each count about a minute per 10 "
            f"eyes on 2 CPU cores")
        for n in counts:
            if n in kept:
                say(f"design 1x{n}: resumed, kept in {counts_dir}")
            elif n in refusals:
                say(f"design 1x{n}: refused: {refusals[n]}")

    def make(self, n: int, say) -> LenticularFit:
        t0 = time.perf_counter()
        lens = lenticular_panel(self.panel, n, self.cdp_D, self.constraints)
        fit = LenticularFit(n, lens)
        if float(lens.eye_box_mm()) < self.constraints.min_eye_box_mm * (1 - 1e-3):
            fit.refused = (f"the eye box {float(lens.eye_box_mm()):.3g} mm is below "
                           f"min_eye_box_mm = {self.constraints.min_eye_box_mm:g} mm even at the "
                           f"fastest lenticules")
        fit.time_s = time.perf_counter() - t0
        if say is not None and fit.refused is not None:
            say(f"design 1x{n}: {fit.status} ({fit.time_s:.1f} s)")
        return fit

    @cached_property
    def spectrum(self):
        return make_spectrum(np.asarray(self.wavelengths_nm), ModelOptions(vsotf_reference="open_pupil"))

    def report(self, fit: LenticularFit, n: int, say) -> None:
        t0 = time.perf_counter()
        pupil = float(self.panel.pupil_diameter_mm)
        spectrum = self.spectrum
        if self.natural_peak_D is None:
            self.natural_peak_D = natural_peaks_D(self.eyes, self.cdp_D, pupil, spectrum, self.sampling)
        fit.score = score_lenticular(fit.panel, self.eyes, self.target.depths_D, self.cdp_D,
                                     pupil_diameter_mm=pupil, spectrum=spectrum,
                                     diffraction=self.panel.diffraction, sampling=self.sampling,
                                     natural_peak_D=self.natural_peak_D)
        rmse = fit.score["relative_accommodation_rmse_D"]
        if not math.isfinite(rmse) or not math.isfinite(fit.score["image_at_peak"]):
            fit.failed = "its scores are not finite"
        elif rmse > self.tolerance_D:
            fit.failed = (f"the display's accommodation RMSE {rmse:.3f} D exceeds the "
                          f"tolerance accommodation_tolerance_D = {self.tolerance_D:g} D")
        fit.time_s += time.perf_counter() - t0
        if say is not None:
            say(f"design 1x{n}: {fit.status} ({fit.time_s:.1f} s)")


def fit_lenticular_design(panel: Panel, target: DesignTarget, eyes: Eyes, *, held_out: bool = True,
                          constraints: DesignConstraints = DesignConstraints(),  # noqa: B008
                          tolerance_D: float = 0.25,
                          report: ReportSettings = ReportSettings(),  # noqa: B008 (frozen)
                          sampling: Sampling | None = None, progress=None,
                          counts_dir=None) -> LenticularDesign:
    """Design a lenticular panel of ``panel``'s pixels for each count n of 1×n views and score
    it on ``eyes`` (module docstring), by the one runner of the designs
    (:func:`lfjax.design.runner.run_counts` with a :class:`LenticularKind`).

    ``panel``: its pixel pitch, viewing distance, design pupil and diffraction mode are kept
    (its lenslets are replaced). ``target``: the depths, the CDP, the counts n
    (``views_per_side``; :func:`lenticular_target`) and the wavelengths of the ``"fit"``
    report. ``held_out``: whether ``eyes`` are held-out eyes (the report says which).
    ``tolerance_D``: the display's accommodation RMSE a count must keep, D. ``report``: its
    ``accuracy`` sets the spectrum (:func:`report_wavelengths_nm`); every count is scored
    (``report.counts`` is not read: there is no training loss to rank counts by).
    ``progress``: a callable receiving a line per stage, or None. ``counts_dir``: finished
    counts are kept there and a later call with the same inputs loads them."""
    depths, cdp, counts = check_lenticular_design(panel, target, constraints)
    kind = LenticularKind(panel, target, cdp, constraints, tolerance_D, report.accuracy, sampling,
                          eyes, held_out)
    fits = run_counts(kind, counts, counts_dir, progress if callable(progress) else None)
    provenance = {"n_eyes": int(eyes.n_eyes), "pupil_diameter_mm": float(panel.pupil_diameter_mm),
                  "wavelengths_nm": list(kind.wavelengths_nm), "report_accuracy": report.accuracy,
                  "freq_step_cpd": None if sampling is None else float(sampling.freq_step_cpd),
                  "scored_on": "held-out" if held_out else "training"}
    return LenticularDesign(fits, cdp, np.asarray(depths).tolist(), constraints, tolerance_D, provenance)


__all__ = ["LENTICULAR_FORMAT", "ONE_STRIP", "LenticularFit", "LenticularDesign", "LenticularKind",
           "lenticular_panel", "lenticular_target", "accommodation_grid_D", "check_lenticular_design",
           "score_lenticular", "natural_peaks_D", "fit_lenticular_design", "panel_record", "gain",
           "score_unit", "x_sampling_limit_cpd", "y_sampling_limit_cpd", "report_wavelengths_nm"]
