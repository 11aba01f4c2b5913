"""The spatio-angular trade-off of a real panel: perceivable resolution and accommodation
error against the number of views per pupil, over a population of eyes.

A maker who puts more views into the eye's pupil from the same panel shrinks the lenslets
(view pitch M·Δu = D/n in a pupil of diameter D). At a fixed viewing zone (eye box) the
gap shrinks with them, so each pixel subtends a wider angle at the eye (p/(z_0·M) grows
as n): the lenslet sampling gets finer and the pixel sampling coarser, and each view
diffracts more. :func:`panel_for_views` builds that family from a template panel — the
same pixels, viewing distance, CDP and eye box, tangent n×n views (fill 1), the focal
length that keeps the CDP — and :func:`run_tradeoff` sends every member through the
population sweep (:func:`lfjax.sweep.run_sweep`: the Thibos et al. (2002) eyes of
:func:`lfjax.model.eyes.sample_eyes`, chunked and resumable stores, the sampling planned on the
whole population), with each panel's lenslet diffraction and emitter width
(:meth:`lfjax.display.panel.Panel.optics`).

Read back (:func:`tradeoff_dataset`), each eye and rendered depth gives

* the perceivable resolution (cpd): the MTF cut-off at the eye's predicted accommodation
  (the grid state maximising its VSOTF) capped at the panel's sampling limit for that
  depth (:func:`lfjax.vision.resolution.perceivable_cutoff_cpd`'s model, :func:`lfjax.display.panel.sampling_limit_cpd`);
* the accommodation error (D): the continuous VSOTF peak minus the rendered depth (the
  grid peak where the refinement fails), and the display's share of it — less the eye's
  own error on the CDP, where every view reaches the eye unshifted as from a real point
  (the layout optimiser's ``relative_accommodation``).

:func:`tradeoff_table` gives medians and 5–95 % bands per count and depth, and
:func:`optimum` the count with the highest median perceivable resolution among those whose
display-share accommodation RMSE stays within a tolerance (default the layout optimiser's
0.25 D); one view (1×1) drives no accommodation and is never the optimum.
"""

from __future__ import annotations

import json
import math
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from lfjax.model.layout_files import LAYOUT_FORMAT
from lfjax.layout_opt import Objective
from lfjax.model.layouts import Layout, make_layout
from lfjax.model.options import ModelOptions
from lfjax.display.panel import Panel, sampling_limit_cpd
from lfjax.sweep import SweepConfig, open_store, plan_sweep, run_sweep
from lfjax.sweep.run import peak_rss_mb
from lfjax.sweep.store_checks import completed_chunks, is_store

TRADEOFF_FORMAT = "lfjax-tradeoff/1"

DEFAULT_TOLERANCE_D = float(Objective().accommodation_tolerance_D)
"""The layout optimiser's bound on the display's share of the accommodation RMSE, D."""


def panel_for_views(template: Panel, n_per_side: int, eye_box_mm: float | None = None) -> Panel:
    """The panel of ``template``'s pixels that puts tangent n×n views in its design pupil.

    Kept from ``template``: pixel pitch, count and fill, viewing distance z_m, CDP, design
    pupil D, aperture shape and diffraction mode. Chosen: lenslet pitch Δu = D/(n·M)
    (0.0001 % inside, so exactly n views fit), fill 1, the gap z_0 = z_m·Δu/(E − Δu) that
    keeps the eye box Δu·(1 + z_m/z_0) at ``eye_box_mm`` E (mm; default the template's,
    :meth:`~lfjax.display.panel.Panel.eye_box_mm`) and the focal length 1/f = 1/z_0 − V that keeps
    the CDP (V = the template's image vergence, 1/mm). Raises ``ValueError`` naming the
    limit when n < 1, when the lenslets would be smaller than a pixel, or when the eye box
    is not wider than a lenslet."""
    if isinstance(n_per_side, bool) or int(n_per_side) != n_per_side or n_per_side < 1:
        raise ValueError(f"n_per_side must be an integer >= 1, got {n_per_side!r}")
    n = int(n_per_side)
    box = float(template.eye_box_mm()) if eye_box_mm is None else float(eye_box_mm)
    m = float(template.magnification)
    pupil = float(template.pupil_diameter_mm)
    pitch = pupil / (n * m) * (1.0 - 1e-6)
    p = float(template.pixel_pitch_mm)
    if pitch < p:
        n_max = int(math.floor(pupil / (m * p)))
        raise ValueError(f"{n}x{n} views need lenslets of {pitch:.4g} mm, smaller than a pixel "
                         f"({p:.4g} mm): n_per_side must be in [1, {n_max}] for this panel")
    if not (math.isfinite(box) and box > pitch):
        raise ValueError(f"eye_box_mm must exceed the lenslet pitch {pitch:.4g} mm, got {box:g}")
    zm = float(template.distance_mm)
    gap = zm * pitch / (box - pitch)
    vergence = float(template.image_vergence_per_mm)
    focal = 1.0 / (1.0 / gap - vergence)
    return Panel(p, pitch, 1.0, focal, gap, zm, float(template.pixel_fill), template.pixel_count,
                 template.pupil_diameter_mm, template.aperture, template.diffraction,
                 f"{template.name} {n}x{n}")


def views_in_pupil(panel: Panel, n_per_side: int) -> Layout:
    """The panel's n×n views (:meth:`~lfjax.display.panel.Panel.layout`) without those whose disc
    lies wholly outside the design pupil (from 6×6 on the corners of a square grid of
    tangent views do): they send no light into the eye, so leaving them out changes
    nothing but the cost."""
    layout = panel.layout(n_per_side)
    c = np.asarray(layout.centres_mm, float)
    d = np.asarray(layout.diameters_mm, float)
    keep = np.linalg.norm(c, axis=1) - 0.5 * d < 0.5 * panel.pupil_diameter_mm - 1e-9
    return make_layout(c[keep], d[keep], panel.pupil_diameter_mm, name=layout.name,
                       window_diameter_mm=float(np.max(d)))


@dataclass(frozen=True)
class TradeoffConfig:
    """The sweep settings of a trade-off run (D, nm, mm).

    Attributes
    ----------
    counts : views per side n to sweep (n×n views)
    n_eyes, seed : the population, ``sample_eyes(seed, n_eyes)`` on the design pupil's
        Thibos fit (no average eye)
    depth_offsets_D : rendered depths relative to the panel's CDP, D (must include 0: the
        display's share of the accommodation error is read against the CDP)
    accommodation_step_D : accommodation grid step, D (continuous peaks refine off it)
    window_D : each depth is evaluated within ±window_D of it, D
    wavelengths_nm : (start, stop, step) of the V(λ)-weighted spectrum, nm
    chunk_size : eyes per compiled call (and per resumable chunk of a store)
    eye_box_mm : the eye box every count keeps (None: the template's)
    accommodation_tolerance_D : RMSE bound of the display's share of the accommodation
        error for :func:`optimum`, D
    options : the model's options (default: the layout optimiser's open-pupil VSOTF
        reference, as :mod:`lfjax.design.fit` uses)
    """

    counts: tuple = (1, 2, 3, 4, 5, 6)
    n_eyes: int = 100
    seed: int = 0
    depth_offsets_D: tuple = (-1.0, 0.0, 1.0)
    accommodation_step_D: float = 0.25
    window_D: float = 1.5
    wavelengths_nm: tuple = (500.0, 600.0, 50.0)
    chunk_size: int = 4
    eye_box_mm: float | None = None
    accommodation_tolerance_D: float = DEFAULT_TOLERANCE_D
    options: ModelOptions = field(default_factory=lambda: ModelOptions(vsotf_reference="open_pupil"))

    def __post_init__(self):
        counts = tuple(self.counts)
        if not counts or any(isinstance(n, bool) or int(n) != n or not 1 <= n <= 12 for n in counts):
            raise ValueError(f"counts must be integers in [1, 12], got {list(counts)}")
        object.__setattr__(self, "counts", tuple(int(n) for n in counts))
        offsets = tuple(float(d) for d in self.depth_offsets_D)
        if not any(abs(d) < 1e-9 for d in offsets):
            raise ValueError(f"depth_offsets_D must include 0 (the CDP), got {list(offsets)}")
        object.__setattr__(self, "depth_offsets_D", offsets)
        if int(self.n_eyes) < 1:
            raise ValueError(f"n_eyes must be >= 1, got {self.n_eyes}")
        if not (self.accommodation_tolerance_D > 0):
            raise ValueError(f"accommodation_tolerance_D must be > 0 D, got {self.accommodation_tolerance_D}")

    def as_dict(self) -> dict:
        out = asdict(self)
        out["options"] = self.options.as_dict()
        return out


def _slug(name: str) -> str:
    return "".join(ch if ch.isalnum() else "_" for ch in name.lower()).strip("_")


def sweep_config(panel: Panel, n_per_side: int, layout_path, config: TradeoffConfig) -> SweepConfig:
    """The :class:`~lfjax.sweep.SweepConfig` of one count: the layout file of its views,
    the panel's CDP (to 1e-4 D: the panel's leaves are single precision unless JAX runs
    in x64) and distance (its lenslet diffraction, :func:`lfjax.display.lenslets.display_optics_at`
    = :meth:`Panel.optics`'s) and emitter width."""
    return SweepConfig(
        n_eyes=int(config.n_eyes), seed=int(config.seed), average_eye=False,
        pupil_diameters_mm=(float(panel.pupil_diameter_mm),), layouts=(str(layout_path),),
        cdp_D=round(float(panel.cdp_D), 4), depth_offsets_D=config.depth_offsets_D,
        lenslet_distance_mm=float(panel.distance_mm),
        pixel_width_arcmin=float(panel.emitter_arcmin()),
        accommodation_step_D=float(config.accommodation_step_D),
        accommodation_max_D=float(math.ceil((round(float(panel.cdp_D), 4) + max(config.depth_offsets_D)
                                             + config.window_D) / config.accommodation_step_D - 1e-6)
                                  * config.accommodation_step_D),
        window_D=float(config.window_D), wavelengths_nm=tuple(config.wavelengths_nm),
        continuous_peaks=("vsotf",), chunk_size=int(config.chunk_size), options=config.options)


def _write_layout(path: Path, layout: Layout, panel: Panel) -> None:
    record = {"format": LAYOUT_FORMAT, "name": layout.name,
              "pupil_diameter_mm": float(panel.pupil_diameter_mm),
              "window_diameter_mm": float(layout.window_diameter_mm),
              "centres_mm": np.asarray(layout.centres_mm, float).tolist(),
              "diameters_mm": np.asarray(layout.diameters_mm, float).tolist(),
              "panel": {k: float(np.asarray(v)) for k, v in (
                  ("pixel_pitch_mm", panel.pixel_pitch_mm), ("lenslet_pitch_mm", panel.lenslet_pitch_mm),
                  ("fill", panel.fill), ("focal_length_mm", panel.focal_length_mm),
                  ("gap_mm", panel.gap_mm), ("distance_mm", panel.distance_mm))}}
    path.write_text(json.dumps(record, indent=1) + "\n")


@dataclass
class TradeoffPart:
    """One count of one panel: its panel, sweep configuration and store."""

    n_per_side: int
    panel: Panel
    sweep: SweepConfig
    store: Path
    seconds: float = 0.0
    peak_rss_mb: float = 0.0
    estimate: str = ""
    chunk_seconds: list = field(default_factory=list)


def plan_tradeoff(template: Panel, work_dir, config: TradeoffConfig = TradeoffConfig()) -> list[TradeoffPart]:  # noqa: B008
    """Every count's panel, layout file (written into ``work_dir``) and sweep configuration;
    computes nothing."""
    work = Path(work_dir)
    work.mkdir(parents=True, exist_ok=True)
    parts = []
    for n in config.counts:
        panel = panel_for_views(template, n, config.eye_box_mm)
        stem = f"{_slug(template.name)}_{n}x{n}"
        layout_path = work / f"{stem}.json"
        _write_layout(layout_path, views_in_pupil(panel, n), panel)
        parts.append(TradeoffPart(n, panel, sweep_config(panel, n, layout_path, config),
                                  work / f"{stem}.zarr"))
    return parts


def run_tradeoff(template: Panel, work_dir, config: TradeoffConfig = TradeoffConfig(),  # noqa: B008
                 progress: bool = False, dry_run: bool = False) -> list[TradeoffPart]:
    """Sweep every count of ``template`` (:func:`plan_tradeoff`) over the population into
    one store per count in ``work_dir``; a store already complete is kept, a partial one
    resumed. ``dry_run``: plan each sweep (sampling, cost estimate in ``estimate``) and
    compute nothing. Returns the parts (``seconds``: wall time of each sweep, s;
    ``peak_rss_mb``: the process's peak RSS after it, MiB; ``chunk_seconds``: each
    computed chunk's, s, the first with compilation)."""
    parts = plan_tradeoff(template, work_dir, config)
    for part in parts:
        t0 = time.perf_counter()
        if dry_run:
            part.estimate = plan_sweep(part.sweep)[-1].summary()
        elif not (is_store(part.store) and completed_chunks(part.store).all()):
            run = run_sweep(part.sweep, part.store, resume=part.store.exists(), progress=progress,
                            on_plan=lambda est, part=part: setattr(part, "estimate", est.summary()))
            part.chunk_seconds = list(run.chunk_seconds)
        part.seconds = time.perf_counter() - t0
        part.peak_rss_mb = peak_rss_mb()
        if progress:
            print(f"tradeoff {template.name} {part.n_per_side}x{part.n_per_side}: "
                  f"{part.seconds:.1f} s, peak RSS {part.peak_rss_mb:.0f} MiB", flush=True)
    return parts


def part_values(part: TradeoffPart) -> dict:
    """Per-eye values of one count's finished store (host arrays, (n_eyes, n_depth)):
    ``perceivable_cpd``, ``optical_cutoff_cpd``, ``sampling_limit_cpd`` (n_depth,),
    ``accommodation_D`` (continuous VSOTF peak, the grid peak where it failed),
    ``error_D`` (minus the rendered depth), ``display_error_D`` (less the eye's own error
    on the CDP), ``peak_success``, ``modulation`` (the through-focus VSOTF's (max − min)/max
    over the depth's window: near 0, a flat curve that predicts no accommodation) and
    ``depths_D`` (n_depth,)."""
    ds = open_store(part.store, complete_only=True).isel(pupil=0, layout=0).sel(metric="vsotf")
    depths = np.round(np.asarray(ds.depth.values, float), 6)
    cont = np.asarray(ds.predicted_accommodation_continuous.values, float)
    ok = np.asarray(ds.continuous_peak_success.values, bool) & np.isfinite(cont)
    grid = np.asarray(ds.predicted_accommodation.values, float)
    acc = np.where(ok, cont, grid)
    optical = np.asarray(ds.cutoff_frequency.values, float)
    limit = np.asarray(sampling_limit_cpd(part.panel, depths), float)
    err = acc - depths[None, :]
    cdp = int(np.argmin(np.abs(depths - float(part.panel.cdp_D))))
    curves = np.asarray(ds.vsotf.values, float)  # NaN outside each depth's window
    top = np.nanmax(curves, axis=-1)
    return {"depths_D": depths, "perceivable_cpd": np.minimum(optical, limit[None, :]),
            "modulation": (top - np.nanmin(curves, axis=-1)) / top,
            "optical_cutoff_cpd": optical, "sampling_limit_cpd": limit, "accommodation_D": acc,
            "error_D": err, "display_error_D": err - err[:, cdp:cdp + 1], "peak_success": ok}


def tradeoff_table(parts: list[TradeoffPart], panel_name: str | None = None) -> list[dict]:
    """Rows (one per count and rendered depth, then one per count over all depths,
    ``depth_D`` None): median and 5/95 percentiles of the perceivable resolution (cpd) and
    of the accommodation error (D), the display-share RMSE (D), the median through-focus
    modulation (:func:`part_values`), the sampling limit (cpd),
    the panel's lenslet pitch, gap, focal length (mm), pixel angle (arcmin), Fresnel number
    and eye count."""
    rows = []
    for part in parts:
        v = part_values(part)
        s = part.panel.summary()
        base = {"panel": panel_name or part.panel.name.rsplit(" ", 1)[0], "views": f"{part.n_per_side}x{part.n_per_side}",
                "n_per_side": part.n_per_side, "lenslet_pitch_mm": float(part.panel.lenslet_pitch_mm),
                "gap_mm": float(part.panel.gap_mm), "focal_length_mm": float(part.panel.focal_length_mm),
                "pixel_arcmin": s["pixel_arcmin"], "fresnel_number": s["fresnel_number"],
                "eye_box_mm": s["eye_box_mm"], "n_eyes": int(v["error_D"].shape[0])}
        for j in list(range(v["depths_D"].size)) + [None]:
            sl = slice(None) if j is None else slice(j, j + 1)
            res, err, rel = (v[k][:, sl].ravel() for k in ("perceivable_cpd", "error_D", "display_error_D"))
            q = lambda x: np.percentile(x, [50, 5, 95])  # noqa: E731
            rm, r5, r95 = q(res)
            em, e5, e95 = q(err)
            rows.append(dict(base, depth_D=None if j is None else float(v["depths_D"][j]),
                             perceivable_cpd_median=rm, perceivable_cpd_p05=r5, perceivable_cpd_p95=r95,
                             sampling_limit_cpd=(float(np.min(v["sampling_limit_cpd"])) if j is None
                                                 else float(v["sampling_limit_cpd"][j])),
                             error_D_median=em, error_D_p05=e5, error_D_p95=e95,
                             display_error_rmse_D=float(np.sqrt(np.mean(rel**2))),
                             modulation_median=float(np.median(v["modulation"][:, sl])),
                             peak_success_fraction=float(np.mean(v["peak_success"][:, sl]))))
    return rows


MIN_PEAK_SUCCESS = 0.5
"""Fewest (eye, depth) peaks that must converge inside their window for a count to be an
optimum: a maximum on the window's edge is no prediction of accommodation, so an error
read from it measures the window, not the display."""


def optimum(rows: list[dict], tolerance_D: float = DEFAULT_TOLERANCE_D,
            min_peak_success: float = MIN_PEAK_SUCCESS) -> dict | None:
    """The all-depth row (``depth_D`` None) of the count with the highest median perceivable
    resolution among counts above 1×1 whose display-share accommodation RMSE is at most
    ``tolerance_D`` (D) and whose peaks converged inside their window for at least
    ``min_peak_success`` of the eyes and depths. None when no count qualifies (1×1 drives
    no accommodation and never does)."""
    ok = [r for r in rows if r["depth_D"] is None and r["n_per_side"] > 1
          and r["display_error_rmse_D"] <= tolerance_D
          and r.get("peak_success_fraction", 1.0) >= min_peak_success]
    return max(ok, key=lambda r: r["perceivable_cpd_median"]) if ok else None


def markdown_table(rows: list[dict], best: dict | None) -> str:
    """The all-depth rows as a Markdown table, the optimum in bold, then the per-depth
    medians."""
    out = ["| views | lenslet mm | gap mm | pixel ′ | Fresnel N | perceivable cpd median [5–95 %] "
           "| acc. error D median [5–95 %] | display share RMSE D | peaks converged "
           "| through-focus modulation |",
           "|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        if r["depth_D"] is not None:
            continue
        mark = "**" if best is not None and r["n_per_side"] == best["n_per_side"] else ""
        out.append(f"| {mark}{r['views']}{mark} | {r['lenslet_pitch_mm']:.3g} | {r['gap_mm']:.3g} | "
                   f"{r['pixel_arcmin']:.3g} | {r['fresnel_number']:.3g} | "
                   f"{r['perceivable_cpd_median']:.2f} [{r['perceivable_cpd_p05']:.2f}, {r['perceivable_cpd_p95']:.2f}] | "
                   f"{r['error_D_median']:+.2f} [{r['error_D_p05']:+.2f}, {r['error_D_p95']:+.2f}] | "
                   f"{r['display_error_rmse_D']:.3f} | {r['peak_success_fraction']:.0%} | "
                   f"{r['modulation_median']:.2f} |")
    depths = sorted({r["depth_D"] for r in rows if r["depth_D"] is not None})
    out += ["", "| views | " + " | ".join(f"cpd @ {d:g} D (limit)" for d in depths) + " | "
            + " | ".join(f"error D @ {d:g} D" for d in depths) + " |",
            "|---|" + "---|" * (2 * len(depths))]
    for n in sorted({r["n_per_side"] for r in rows}):
        by = {r["depth_D"]: r for r in rows if r["n_per_side"] == n and r["depth_D"] is not None}
        out.append(f"| {n}x{n} | " + " | ".join(
            f"{by[d]['perceivable_cpd_median']:.2f} ({by[d]['sampling_limit_cpd']:.2f})" for d in depths)
            + " | " + " | ".join(f"{by[d]['error_D_median']:+.2f}" for d in depths) + " |")
    return "\n".join(out)


def fig_tradeoff(results: dict, tolerance_D: float = DEFAULT_TOLERANCE_D,
                 window_D: float | None = None):
    """The trade-off figure: one row per panel class (``results``: {name: rows of
    :func:`tradeoff_table`}), perceivable resolution (cpd) and accommodation error (D)
    against views per side, one line per rendered depth with its 5–95 % band, the
    optimum (:func:`optimum`) marked; ``window_D`` (D) draws the search window's edges,
    where an error means the curve had no peak inside it."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(len(results), 2, figsize=(10.5, 3.6 * len(results)), squeeze=False)
    for (name, rows), (ax_r, ax_e) in zip(results.items(), axes):
        depths = sorted({r["depth_D"] for r in rows if r["depth_D"] is not None})
        colours = plt.cm.viridis(np.linspace(0.1, 0.85, len(depths)))
        for d, colour in zip(depths, colours):
            rs = sorted((r for r in rows if r["depth_D"] == d), key=lambda r: r["n_per_side"])
            n = [r["n_per_side"] for r in rs]
            for ax, key in ((ax_r, "perceivable_cpd"), (ax_e, "error_D")):
                ax.plot(n, [r[f"{key}_median"] for r in rs], "o-", color=colour, label=f"{d:g} D")
                ax.fill_between(n, [r[f"{key}_p05"] for r in rs], [r[f"{key}_p95"] for r in rs],
                                color=colour, alpha=0.18, lw=0)
            ax_r.plot(n, [r["sampling_limit_cpd"] for r in rs], ":", color=colour, lw=1)
        best = optimum(rows, tolerance_D)
        for ax in (ax_r, ax_e):
            if best is not None:
                ax.axvline(best["n_per_side"], color="tab:red", lw=1.2, ls="--",
                           label=f"optimum {best['views']}")
            ax.set_xlabel("views per side n (n×n views in the pupil)")
            ax.set_xticks(sorted({r["n_per_side"] for r in rows}))
            ax.grid(alpha=0.3)
        ax_e.axhline(0, color="0.5", lw=0.8)
        if window_D is not None:
            for sign in (-1, 1):
                ax_e.axhline(sign * window_D, color="0.3", lw=0.8, ls=":",
                             label="window edge (no peak inside)" if sign > 0 else None)
        n_eyes = rows[0]["n_eyes"]
        ax_r.set_ylabel("perceivable resolution, cpd")
        ax_r.set_title(f"{name}: perceivable cut-off at the predicted accommodation\n"
                       f"(median, 5–95 % of {n_eyes} eyes; dotted: sampling limit)"
                       + ("" if best is not None else f"\nno optimum: no count above 1×1 drives "
                          f"accommodation within {tolerance_D:g} D"), fontsize=9)
        ax_e.set_ylabel("accommodation error, D")
        ax_e.set_title(f"{name}: predicted accommodation − rendered depth\n(median, 5–95 %)", fontsize=9)
        ax_e.legend(fontsize=7, title="rendered depth", title_fontsize=7)
    fig.tight_layout()
    return fig


__all__ = [
    "TRADEOFF_FORMAT",
    "TradeoffConfig",
    "TradeoffPart",
    "panel_for_views",
    "views_in_pupil",
    "sweep_config",
    "plan_tradeoff",
    "run_tradeoff",
    "part_values",
    "tradeoff_table",
    "optimum",
    "MIN_PEAK_SUCCESS",
    "markdown_table",
    "fig_tradeoff",
]
