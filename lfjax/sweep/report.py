"""A sweep's report: population distributions as pictures, a CSV of percentiles, a summary.

:func:`sweep_report` (``lfjax sweep-report STORE``) reads a sweep store
(:mod:`lfjax.sweep.store`) — only the eyes of complete chunks, so a sweep still running or
interrupted is reported on what it has, and only a store that ``lfjax sweep --verify``
passes — and writes into a folder:

* ``percentiles.csv`` (:func:`percentile_table`): per pupil × layout × rendered depth and
  quantity, the 5th, 25th, 50th, 75th and 95th percentiles, mean and count over the virtual
  eyes (the Thibos average eye is never part of a population statistic; cells without a
  value — natural view off the CDP — have no row);
* ``accommodation_error.png``: VSOTF accommodation error (continuous peak where stored, else
  the grid peak) against rendered depth relative to the CDP, as percentile bands per layout,
  one panel per pupil; ``cutoff_frequency.png``: the cut-off frequency at the
  VSOTF-predicted accommodation, the same way; ``layouts.png``: each layout's subapertures
  in each pupil (:func:`lfjax.model.layout_plots.draw_layout`);
* ``ten_eyes.md`` / ``ten_eyes.csv``: "what ten eyes cannot tell"
  (:mod:`lfjax.sweep.ten_eyes`) when the store holds enough eyes and the layouts the claims
  need;
* ``summary.md``: population, sampling, headline numbers per layout, the figures linked.

Host-only (numpy, pandas, matplotlib with the Agg canvas; no pyplot state).
"""

from __future__ import annotations

import json
import tempfile
import tomllib
import warnings
from pathlib import Path

import numpy as np

from lfjax.base.apertures import CIRCLE, STRIP
from lfjax.base.errors import FlatCurveWarning, ParameterError
from lfjax.base.tables import printable
from lfjax.model.layout_plots import draw_layout
from lfjax.model.layouts import LF_LAYOUTS
from lfjax.sweep.compute import resolve_layout
from lfjax.sweep.config import config_from_dict
from lfjax.sweep.config_keys import strip_views
from lfjax.sweep.guard import display_effects
from lfjax.base.files import check_writable, staged_output
from lfjax.sweep.store import open_verified_store
from lfjax.sweep.store_checks import StoreCorruptError, is_store, store_damage
from lfjax.sweep.ten_eyes import ten_eye_claims, ten_eye_markdown, ten_eye_table

PERCENTILES = (5, 25, 50, 75, 95)
"""Percentiles (%) reported over the eyes of each cell."""

QUANTITIES = (
    ("accommodation_error", "vsotf", "D"),
    ("continuous_error", "vsotf", "D"),
    ("accommodation_error", "strehl", "D"),
    ("continuous_error", "strehl", "D"),
    ("cutoff_frequency", "vsotf", "cpd"),
    ("peak_value", "vsotf", "1"),
)
"""(store variable, metric, units) of ``percentiles.csv``: grid and continuous accommodation
error (predicted minus rendered depth) for each metric, the cut-off frequency at the
VSOTF-predicted accommodation and the VSOTF peak value. Continuous errors exist only for the
metrics the sweep refined (``metrics.continuous_peaks``); cells without values get no row."""

FILES = {
    "summary": "summary.md",
    "percentiles": "percentiles.csv",
    "accommodation_error": "accommodation_error.png",
    "cutoff_frequency": "cutoff_frequency.png",
    "layouts": "layouts.png",
    "ten_eyes_md": "ten_eyes.md",
    "ten_eyes_csv": "ten_eyes.csv",
}
"""Keys of :func:`sweep_report`'s result and the file names it writes."""

COLOURS = {"natural": "tab:grey", "2x2": "tab:red", "3x3": "tab:blue", "4x4": "tab:green"}
_MORE_COLOURS = ("tab:purple", "tab:orange", "tab:brown", "tab:pink", "tab:olive", "tab:cyan")


# --------------------------------------------------------------------------- numbers


def _virtual(ds):
    """The store's virtual eyes (the average eye left out of every population statistic)."""
    return ds.isel(eye=np.flatnonzero(~ds.is_average.values))


PEAK_VARIABLES = ("predicted_accommodation", "accommodation_error",
                  "predicted_accommodation_continuous", "continuous_error", "peak_value",
                  "cutoff_frequency", "mtf_at_peak")
"""Store variables read from a metric's peak (dims ``eye, pupil, layout, depth, metric``)."""


def flat_curves(ds):
    """Where a metric's through-focus curve has no maximum: bool DataArray (``eye, pupil,
    layout, depth, metric``), True where every finite value of the curve over the
    accommodation states is the same number (at least two of them). A store written before
    lfjax refused layouts outside the calculation pupil holds such curves (VSOTF exactly 1
    at every state): their "peak", error and cut-off are not results."""
    import xarray as xr

    flags = []
    for metric in ds.metric.values:
        curve = ds[str(metric)].astype(np.float64)
        finite = curve.notnull().sum("accommodation")
        span = curve.max("accommodation") - curve.min("accommodation")
        flags.append((finite >= 2) & (span <= 1e-12 * np.maximum(1.0, abs(curve).max("accommodation"))))
    return xr.concat(flags, dim="metric").assign_coords(metric=ds.metric.values)


def without_flat_curves(ds):
    """``ds`` with every peak quantity (:data:`PEAK_VARIABLES`) NaN where
    :func:`flat_curves` is True, and ``continuous_peak_success`` False there."""
    flat = flat_curves(ds)
    if not bool(flat.any()):
        return ds
    out = ds.copy()
    for name in PEAK_VARIABLES:
        if name in out.data_vars:
            out[name] = out[name].where(~flat)
    if "continuous_peak_success" in out.data_vars:
        out["continuous_peak_success"] = out["continuous_peak_success"] & ~flat
    return out


def flat_curve_cells(ds) -> list[tuple[float, str, str, int, int]]:
    """(pupil mm, layout, metric, eyes with a flat curve, cells) per (pupil, layout,
    metric) holding any: what :func:`without_flat_curves` leaves out, for the summary."""
    flat = flat_curves(_virtual(ds))
    rows = []
    for pupil in flat.pupil.values:
        for layout in flat.layout.values:
            for metric in flat.metric.values:
                cell = flat.sel(pupil=pupil, layout=layout, metric=metric).values
                if cell.any():
                    rows.append((float(pupil), str(layout), str(metric),
                                 int(cell.any(axis=-1).sum()), int(cell.sum())))
    return rows


def percentile_table(ds):
    """Population percentiles per pupil × layout × depth × quantity (pandas DataFrame).

    ``ds``: a sweep store's Dataset (:func:`lfjax.sweep.open_store`, dims ``eye, pupil,
    layout, depth, metric``). Over the virtual eyes of each cell (average eye excluded) and
    only their finite values (float64): ``n``, ``mean`` and ``p5`` … ``p95``
    (``numpy.percentile``, linear interpolation). Columns: ``pupil_mm``, ``layout``,
    ``depth_D`` (absolute), ``depth_rel_cdp_D``, ``variable`` (the store's name),
    ``metric``, ``units``, ``n``, ``mean``, ``p5``, ``p25``, ``p50``, ``p75``, ``p95``.
    A cell with no finite value (natural view off the CDP; a metric without continuous
    peaks) has no row. Curves without a maximum (:func:`flat_curves`) are left out.
    """
    import pandas as pd

    pop = without_flat_curves(_virtual(ds))
    rows = []
    for variable, metric, units in QUANTITIES:
        if variable not in pop.data_vars:
            continue
        values = (pop[variable].sel(metric=metric)
                  .transpose("eye", "pupil", "layout", "depth").values.astype(np.float64))
        for pi, pupil in enumerate(pop.pupil.values):
            for li, layout in enumerate(pop.layout.values):
                for di, depth in enumerate(pop.depth.values):
                    cell = values[:, pi, li, di]
                    cell = cell[np.isfinite(cell)]
                    if cell.size == 0:
                        continue
                    p = np.percentile(cell, PERCENTILES)
                    rows.append(dict(
                        pupil_mm=float(pupil), layout=str(layout), depth_D=float(depth),
                        depth_rel_cdp_D=float(pop.depth_rel_cdp.values[di]),
                        variable=variable, metric=metric, units=units, n=int(cell.size),
                        mean=float(cell.mean()),
                        **{f"p{q}": float(v) for q, v in zip(PERCENTILES, p)}))
    columns = ["pupil_mm", "layout", "depth_D", "depth_rel_cdp_D", "variable", "metric",
               "units", "n", "mean"] + [f"p{q}" for q in PERCENTILES]
    return pd.DataFrame(rows, columns=columns)


def error_rows(table):
    """The rows of the accommodation-error figure: the continuous VSOTF error where the
    table has it for a (pupil, layout, depth), else the grid VSOTF error. Adds a column
    ``peak``: "continuous" or "grid"."""
    import pandas as pd

    keys = ["pupil_mm", "layout", "depth_D"]
    vs = table[table.metric == "vsotf"]
    cont = vs[vs.variable == "continuous_error"].assign(peak="continuous")
    grid = vs[vs.variable == "accommodation_error"].assign(peak="grid")
    have = set(map(tuple, cont[keys].itertuples(index=False, name=None)))
    grid = grid[[k not in have for k in grid[keys].itertuples(index=False, name=None)]]
    return pd.concat([cont, grid]).sort_values(keys).reset_index(drop=True)


# --------------------------------------------------------------------------- the config


def stored_config(ds, folder):
    """The sweep's :class:`~lfjax.sweep.config.SweepConfig`, rebuilt from the store's
    ``config_toml``. Layout JSON files are written into ``folder`` from the copies the
    store recorded (``config_json``'s ``layout_files``): a relative path in the TOML was
    relative to a config file the store does not know, and the recorded copy is what the
    sweep used. Returns (config, {store layout entry: entry to pass to resolve_layout})."""
    data = tomllib.loads(ds.attrs["config_toml"])
    recorded = json.loads(ds.attrs["config_json"]).get("layout_files", {})
    entries = list(data.get("display", {}).get("layouts", []))
    mapping = {}
    for i, entry in enumerate(entries):
        if entry in recorded:
            path = Path(folder) / f"layout{i}-{Path(entry).name}"
            path.write_text(json.dumps(recorded[entry]))
            mapping[entry] = str(path)
    if mapping:
        data["display"]["layouts"] = [mapping.get(e, e) for e in entries]
    config = config_from_dict(data, base_dir=folder, source="the store's config_toml")
    return config, {e: mapping.get(e, e) for e in entries}


# --------------------------------------------------------------------------- figures


def _colour(layout: str, i: int) -> str:
    return COLOURS.get(layout, _MORE_COLOURS[i % len(_MORE_COLOURS)])


def _band_panel(ax, rows, colour: str, label: str) -> None:
    """Percentile bands of one layout against depth relative to the CDP (rows: one per
    depth of :func:`percentile_table`): 5–95 % light, 25–75 % darker, the median a line.
    A single depth (natural view) is drawn as a point with whiskers."""
    rows = rows.sort_values("depth_rel_cdp_D")
    x = rows.depth_rel_cdp_D.values
    if x.size == 1:
        med = rows.p50.values
        ax.vlines(x, rows.p5.values, rows.p95.values, color=colour, lw=1.0)
        ax.vlines(x, rows.p25.values, rows.p75.values, color=colour, lw=4.0, alpha=0.6)
        ax.plot(x, med, "o", color=colour, ms=5, label=label)
        return
    ax.fill_between(x, rows.p5.values, rows.p95.values, color=colour, alpha=0.15, lw=0)
    ax.fill_between(x, rows.p25.values, rows.p75.values, color=colour, alpha=0.35, lw=0)
    ax.plot(x, rows.p50.values, "-o", color=colour, lw=1.6, ms=3, label=label)


def _band_figure(rows, ylabel: str, title: str, zero_line: bool, label_of=None,
                 panel_per_layout: bool = False, layouts=None):
    """Percentile bands against depth: one panel per pupil with the layouts coloured, or
    (``panel_per_layout``) a row of panels per pupil, one per layout, sharing the y axis
    (overlapping bands of similar size are unreadable in one panel). ``layouts``: their
    order (default: as they come in ``rows``)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    pupils = sorted(rows.pupil_mm.unique())
    layouts = [x for x in (layouts or ()) if x in set(rows.layout)] or list(
        dict.fromkeys(rows.layout))
    n_rows = max(len(pupils), 1)
    n_cols = len(layouts) if panel_per_layout else 1
    width = 3.0 * n_cols + 0.6 if panel_per_layout else 5.0
    fig = Figure(figsize=(width, 3.4 * n_rows + 0.4), layout="constrained")
    FigureCanvasAgg(fig)
    axes = fig.subplots(n_rows, n_cols, sharex=True, sharey=True, squeeze=False)
    for r, pupil in enumerate(pupils):
        sub = rows[rows.pupil_mm == pupil]
        eyes = int(sub.n.max()) if len(sub) else 0
        for j, layout in enumerate(layouts):
            ax = axes[r, j if panel_per_layout else 0]
            part = sub[sub.layout == layout]
            if len(part):
                label = label_of(layout, part) if label_of else layout
                _band_panel(ax, part, _colour(layout, j), label)
        for c in range(n_cols):
            ax = axes[r, c]
            if zero_line:
                ax.axhline(0.0, color="black", lw=0.7, ls=":")
            ax.axvline(0.0, color="black", lw=0.5, ls="--", alpha=0.5)
            ax.set_title(f"{pupil:g} mm pupil, {eyes:,} eyes"
                         + (f": {layouts[c]}" if panel_per_layout else ""), fontsize=9)
            if r == n_rows - 1:
                ax.set_xlabel("rendered depth − CDP (D)")
            ax.legend(fontsize=7, loc="best")
    fig.supylabel(ylabel, fontsize=10)
    fig.suptitle(f"{title}\nmedian (line); bands: 25–75 % (dark), 5–95 % (light) of the eyes",
                 fontsize=10)
    return fig


def fig_accommodation_error(table):
    """Accommodation error (D) of the VSOTF peak per layout and depth, population bands
    (a panel per pupil and layout)."""
    rows = error_rows(table)

    def label(layout, part):
        kinds = set(part.peak)
        return layout + (" (continuous peak)" if kinds == {"continuous"} else " (grid peak)"
                         if kinds == {"grid"} else " (grid peak at some depths)")

    return _band_figure(rows, "accommodation error (D): predicted − rendered",
                        "VSOTF-predicted accommodation error", True, label,
                        panel_per_layout=True, layouts=list(dict.fromkeys(table.layout)))


def fig_cutoff_frequency(table, threshold: float):
    """Cut-off frequency (cpd) at the VSOTF-predicted accommodation, population bands (a
    panel per pupil, layouts coloured)."""
    rows = table[(table.variable == "cutoff_frequency") & (table.metric == "vsotf")]
    return _band_figure(rows, f"cut-off frequency (cpd), MTF = {threshold:g}",
                        "Cut-off frequency at the VSOTF-predicted accommodation", False)


def fig_layouts(layouts: dict, pupils_mm, strip_labels=()) -> object:
    """Subapertures of each layout in each pupil (rows: pupils, columns: layouts).
    ``layouts``: {(pupil_mm, label): Layout}; ``strip_labels``: the labels of 1xN strip
    layouts (drawn as strips spanning the pupil's height)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure


    labels = list(dict.fromkeys(label for _, label in layouts))
    pupils = list(pupils_mm)
    fig = Figure(figsize=(2.9 * len(labels), 3.0 * len(pupils)), layout="compressed")
    FigureCanvasAgg(fig)
    for r, pupil in enumerate(pupils):
        for c, label in enumerate(labels):
            layout = layouts[(pupil, label)]
            ax = fig.add_subplot(len(pupils), len(labels), r * len(labels) + c + 1)
            d = np.asarray(layout.diameters_mm, float).reshape(-1)
            strips = label in strip_labels
            title = (f"{label}, {pupil:g} mm pupil\n{d.size} {'strip' if strips else 'view'}"
                     f"{'s' if d.size > 1 else ''}, {'w' if strips else 'd'} = {d.max():.3g} mm")
            draw_layout(ax, layout, pupil, _colour(label, c), title,
                        aperture=STRIP.name if strips else CIRCLE.name)
    return fig


# --------------------------------------------------------------------------- summary


def _cell(table, pupil, layout, variable, metric, rel):
    sel = table[(table.pupil_mm == pupil) & (table.layout == layout) & (table.variable == variable)
                & (table.metric == metric) & np.isclose(table.depth_rel_cdp_D, rel)]
    return None if sel.empty else sel.iloc[0]


def _fmt_band(row, digits: int, signed: bool = False) -> str:
    if row is None:
        return "–"
    f = (lambda v: f"{v:+.{digits}f}") if signed else (lambda v: f"{v:.{digits}f}")
    return f"{f(row.p50)} [{f(row.p5)}, {f(row.p95)}]"


def _headline(table, pupil: float, layout: str) -> list[str]:
    """Cells of one summary row: error and cut-off at the CDP, their spread over depths."""
    err = error_rows(table)
    err = err[(err.pupil_mm == pupil) & (err.layout == layout)]
    at_cdp = err[np.isclose(err.depth_rel_cdp_D, 0.0)]
    e0 = None if at_cdp.empty else at_cdp.iloc[0]
    peak = "" if e0 is None or e0.peak == "continuous" else " (grid)"
    cut = table[(table.pupil_mm == pupil) & (table.layout == layout)
                & (table.variable == "cutoff_frequency") & (table.metric == "vsotf")]
    c0 = _cell(table, pupil, layout, "cutoff_frequency", "vsotf", 0.0)
    v0 = _cell(table, pupil, layout, "peak_value", "vsotf", 0.0)
    if len(err) > 1:
        spread = f"{err.p50.min():+.2f} … {err.p50.max():+.2f}"
    else:
        spread = "(CDP only)"
    best = "–"
    if len(cut):
        b = cut.loc[cut.p50.idxmax()]
        best = f"{b.p50:.1f} at {b.depth_rel_cdp_D:+g} D"
    return [_fmt_band(e0, 2, signed=True) + peak, spread, _fmt_band(c0, 1), best,
            "–" if v0 is None else f"{v0.p50:.3f}"]


def _rule_label(record) -> str:
    """``"Gauss rule in V(λ), 8 nodes"`` / ``"uniform 25 nm (13)"`` for a ``spectra_json``
    entry (``"?"`` for a store made before rules were recorded)."""
    if record is None:
        return "?"
    n = record["n_wavelengths"]
    if record["rule"] == "gauss":
        return f"Gauss rule in V(λ), {n} nodes"
    if record.get("step_nm") is not None:
        return f"uniform {record['step_nm']:g} nm ({n})"
    return f"{record['rule']} ({n})"


def _summary(path: Path, store: Path, ds, config, table, samplings: dict, files: dict,
             counts: dict, ten: dict) -> None:
    lines = []
    add = lines.append
    a = ds.attrs
    spectra_all = json.loads(a.get("spectra_json", "{}"))  # each (pupil, layout)'s rule
    spectra = spectra_all if config.wavelength_step_planned and config.display_spectrum is None else {}
    add(f"# Sweep report: `{store.name}`")
    add("")
    add(f"Store `{store}` (lfjax {a.get('lfjax_version', '?')}, JAX {a.get('jax_version', '?')}).")
    add("")
    add("## Population")
    add("")
    avg = ("plus the Thibos average eye, which is left out of every population statistic "
           "(claims 4 and 5 compare against it)" if config.average_eye else "no average eye")
    add(f"- {config.n_eyes:,} virtual eyes drawn from the Thibos et al. (2002) statistics of the "
        f"{config.fit_pupil_mm:g} mm pupil (`lfjax.sample_eyes`, seed {config.seed}), {avg}.")
    if counts["virtual_done"] < config.n_eyes or counts["chunks_done"] < counts["chunks"]:
        add(f"- **Incomplete sweep**: {counts['chunks_done']} of {counts['chunks']} chunks are "
            f"complete, holding {counts['virtual_done']:,} of {config.n_eyes:,} virtual eyes"
            + ("" if counts["average_done"] or not config.average_eye
               else " (the average eye's chunk is not complete)")
            + f". Everything below is computed on those {counts['virtual_done']:,} eyes.")
    else:
        add(f"- All {counts['chunks']} chunks complete ({config.chunk_size} eyes per chunk).")
    for pupil, layout, metric, eyes, cells in flat_curve_cells(ds):
        add(f"- **Left out, no peak**: {pupil:g} mm {layout}: the {metric} curve is flat over "
            f"every accommodation state (no maximum) for {eyes:,} eyes ({cells:,} eye×depth "
            f"cells); their peaks, errors and cut-offs are not results and no statistic "
            f"counts them. A store written before lfjax refused layouts whose views lie "
            f"outside the calculation pupil holds such curves: run the sweep again.")
    add(f"- Pupils: {', '.join(f'{p:g}' for p in config.pupil_diameters_mm)} mm. CDP "
        f"{config.cdp_D:g} D; rendered depths "
        f"{', '.join(f'{d:+g}' for d in ds.depth_rel_cdp.values)} D from the CDP (natural "
        f"view: the CDP only); accommodation grid 0–{config.accommodation_max_D:g} D in "
        f"{config.accommodation_step_D:g} D steps, ±{config.window_D:g} D around each depth; "
        f"{config.wavelengths_nm[0]:g}–{config.wavelengths_nm[1]:g} nm "
        + (f"in {_wavelength_step(ds, config):g} nm steps" if not spectra else
           "sampled per layout (below: a uniform step or the Gauss rule in V(λ), whichever "
           "met the targets with fewer wavelengths)")
        + (f" (planned for peaks to {config.peak_tolerance_D:g} D and cut-offs to "
           f"{config.cutoff_tolerance_cpd:g} cpd)." if config.wavelength_step_planned else "."))
    effects = display_effects(config)
    add("- Display: " + ("; ".join(effects) + " (lenticular strips, cross-talk, lenslets, "
                         "emitters: `[display]` keys set away from their defaults)." if effects
                         else "the paper's ideal display (every `[display]` key beyond the "
                              "layouts, CDP and depths at its default)."))
    add(f"- Peaks: grid peak of each metric; continuous peaks ({config.peak_method!r}) for "
        f"{', '.join(config.continuous_peaks) or 'no metric'}. Cut-off frequency: where the "
        f"radial MTF at the predicted accommodation falls to {config.cutoff_threshold:g}.")
    add("")
    add("## Sampling per layout")
    add("")
    add("| pupil (mm) | layout | views | subaperture (mm) | frequency step (cpd) | PSF field "
        "(arcmin) | FFT size | transform | wavelengths |")
    add("|---|---|---|---|---|---|---|---|---|")
    for pi, pupil in enumerate(ds.pupil.values):
        for li, layout in enumerate(ds.layout.values):
            step = float(ds.freq_step_cpd.values[pi, li])
            s = samplings.get(f"{pi},{li}", {})
            add(f"| {pupil:g} | {layout} | {int(ds.n_subapertures.values[pi, li])} | "
                f"{float(ds.subaperture_diameter_mm.values[pi, li]):.3g} | {step:.4g} | "
                f"{60.0 / step:.1f} | {int(ds.n_fft.values[pi, li])} | "
                f"{s.get('transform', '?')} | {_rule_label(spectra_all.get(f'{pi},{li}'))} |")
    add("")
    if spectra:
        add("Wavelengths (nm) each layout sums, and why the planner chose them:")
        add("")
        for pi, pupil in enumerate(ds.pupil.values):
            for li, layout in enumerate(ds.layout.values):
                r = spectra.get(f"{pi},{li}")
                if r is None:
                    continue
                nodes = ", ".join(f"{w:.1f}" for w in r["wavelengths_nm"])
                add(f"- {pupil:g} mm {layout}: {_rule_label(r)}: {nodes}. {r['reason']}")
        add("")
    add("## Headline numbers")
    add("")
    add("Median [5th, 95th percentile] over the virtual eyes. Error: VSOTF-predicted "
        "accommodation minus rendered depth (continuous peak unless marked grid; negative: "
        "focused farther than the image). Cut-off: at the VSOTF-predicted accommodation.")
    add("")
    add("| pupil (mm) | layout | error at the CDP (D) | median error over depths (D) | "
        "cut-off at the CDP (cpd) | best median cut-off (cpd, at depth − CDP) | "
        "VSOTF peak at the CDP (median) |")
    add("|---|---|---|---|---|---|---|")
    for pupil in ds.pupil.values:
        for layout in ds.layout.values:
            add(f"| {pupil:g} | {layout} | " + " | ".join(_headline(table, float(pupil),
                                                                    str(layout))) + " |")
    add("")
    add("## Figures")
    add("")
    for key, caption in (("accommodation_error", "Accommodation error per layout and depth"),
                         ("cutoff_frequency", "Cut-off frequency against depth"),
                         ("layouts", "The layouts")):
        add(f"![{caption}]({files[key].name})")
        add("")
    add(f"Percentiles of every quantity per pupil, layout and depth: "
        f"[`{files['percentiles'].name}`]({files['percentiles'].name}) (columns `variable`, "
        f"`metric`, `units`, `n`, `mean`, `p5` … `p95`; average eye excluded; cells without "
        f"values omitted).")
    add("")
    add("## What ten eyes cannot tell")
    add("")
    if ten.get("markdown"):
        add(ten["markdown"].rstrip())
        add("")
        add(f"Per claim and pupil: [`{FILES['ten_eyes_csv']}`]({FILES['ten_eyes_csv']}); "
            f"the table alone: [`{FILES['ten_eyes_md']}`]({FILES['ten_eyes_md']}).")
    else:
        add(f"Not computed: {ten['reason']}.")
    path.write_text("\n".join(lines) + "\n")


# --------------------------------------------------------------------------- ten eyes


def _ten_eye_reason(ds, sample_size: int) -> str | None:
    """Why the ten-eye table cannot be made from ``ds`` (None: it can)."""
    n_virtual = int((~ds.is_average.values).sum())
    if n_virtual < sample_size + 1:
        return (f"the store has {n_virtual} complete virtual eye(s); drawing samples of "
                f"{sample_size} needs at least {sample_size + 1}")
    if int(ds.is_average.values.sum()) != 1:
        return "the average eye is not in a complete chunk (claims 4 and 5 need it)"
    layouts = [str(x) for x in ds.layout.values]
    lf = [x for x in LF_LAYOUTS if x in layouts]
    if "natural" not in layouts or len(lf) < 2:
        return (f"the claims need natural view and at least two of {', '.join(LF_LAYOUTS)}; "
                f"the store has {', '.join(layouts)}")
    flat = sorted({f"{pupil:g} mm {layout}" for pupil, layout, *_ in flat_curve_cells(ds)})
    if flat:
        return (f"the claims read every eye's peak, and some curves have none "
                f"({', '.join(flat)}: see above)")
    return None


def _positive_int(name: str, value) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
        raise ParameterError(name, "{%s} must be a whole number >= 1, got {got!r}" % name, got=value)
    return int(value)


def sweep_report(store_path, out_dir, *, draws: int = 1000, sample_size: int = 10,
                 seed: int = 0, dpi: int = 110, progress: bool = False) -> dict[str, Path]:
    """Write the report of the sweep store ``store_path`` into the folder ``out_dir``.

    Only the eyes of complete chunks count (the summary says how many of the total that
    is), and only from a store that ``lfjax sweep --verify`` passes
    (:func:`~lfjax.sweep.store.open_verified_store`): a damaged store — a chunk file
    deleted, replaced or altered, a chunk mark or the configuration damaged — is refused
    with a :class:`~lfjax.base.errors.ParameterError` naming ``store_path``, each damaged
    chunk and the command that repairs it, and nothing is written. ``draws``, ``sample_size``, ``seed``: the ten-eye table's samples
    (:func:`lfjax.sweep.ten_eyes.ten_eye_claims`), made for every pupil when the store has
    more than ``sample_size`` complete virtual eyes, its average eye and the layouts the
    claims need (natural and two of 2x2, 3x3, 4x4). ``dpi``: resolution of the PNGs.

    Returns {key: path written} with the keys of :data:`FILES` (the ten-eye files only
    when made). Existing files of those names in ``out_dir`` are replaced.
    """
    store = Path(store_path)
    if not is_store(store):
        damage = store_damage(store)
        if damage is not None:
            raise ParameterError("store_path", "{store_path} {store} looks like an lfjax sweep "
                                 "store but {damage}; it cannot be read", store=store,
                                 damage=damage)
        raise ParameterError("store_path", "{store_path} {store} is not an lfjax sweep store (a folder "
                             "written by `lfjax sweep`)", store=store)
    draws = _positive_int("draws", draws)
    sample_size = _positive_int("sample_size", sample_size)
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ParameterError("seed", "{seed} must be a whole number >= 0, got {got!r}", got=seed)
    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise ParameterError("out_dir", "{out_dir} {out} exists and is not a folder", out=out)

    check_writable(out, REPORT_BYTES, "out_dir")  # read-only or full: said before any work
    try:  # only what lfjax sweep --verify passes: damaged numbers are never reported
        ds = open_verified_store(store, complete_only=True)
    except StoreCorruptError as err:
        raise ParameterError("store_path", "{store_path} {why}; no report is written",
                             why=str(err)) from None
    for pupil, layout, metric, eyes, _ in flat_curve_cells(ds):
        warnings.warn(f"{store}: {pupil:g} mm {layout}: the {metric} curve of {eyes} eye(s) is "
                      f"flat over every accommodation state (no peak); the report leaves "
                      f"them out (a store written before lfjax refused views outside the "
                      f"calculation pupil: run the sweep again)", FlatCurveWarning, stacklevel=2)
    if ds.sizes["eye"] == 0 or not np.any(~ds.is_average.values):
        raise ParameterError("store_path", "{store_path} {store} has no complete chunk of virtual eyes yet",
                             store=store)
    # every file staged, then moved in (each whole; files of the same names replaced): an
    # interrupted or failed report leaves out as it was
    with staged_output(out, force=True) as stage:
        files = _write_report(store, ds, stage, draws, sample_size, seed, dpi, progress)
    return {key: out / path.name for key, path in files.items()}


def _write_report(store: Path, ds, out: Path, draws, sample_size, seed, dpi, progress) -> dict:
    """Every file of :func:`sweep_report` into the folder ``out``; {key: path}."""
    files = {key: out / name for key, name in FILES.items()}

    with tempfile.TemporaryDirectory(prefix="lfjax-sweep-report-") as tmp:
        config, entries = stored_config(ds, tmp)

        layouts = {(float(p), str(label)): resolve_layout(config, entries[str(entry)], float(p))
                   for p in ds.pupil.values
                   for label, entry in zip(ds.layout.values, ds.layout_entry.values)}

    table = percentile_table(ds)
    printable(table).to_csv(files["percentiles"], index=False, float_format="%.6g")
    figures = {
        "accommodation_error": fig_accommodation_error(table),
        "cutoff_frequency": fig_cutoff_frequency(table, float(config.cutoff_threshold)),
        "layouts": fig_layouts(layouts, [float(p) for p in ds.pupil.values],
                               [str(label) for label, entry in zip(ds.layout.values,
                                                                   ds.layout_entry.values)
                                if strip_views(entries[str(entry)]) is not None]),
    }
    for key, fig in figures.items():
        fig.savefig(files[key], dpi=dpi)

    ten: dict = {"reason": _ten_eye_reason(ds, sample_size)}
    if ten["reason"] is None:
        import pandas as pd


        parts, tables = [], []
        for pupil in ds.pupil.values:
            result = ten_eye_claims(ds, n_draws=draws, sample_size=sample_size, seed=seed,
                                    pupil_mm=float(pupil), progress=progress)
            heading = f"### {float(pupil):g} mm pupil" if ds.sizes["pupil"] > 1 else None
            parts.append(ten_eye_markdown(result, heading=heading))
            tables.append(ten_eye_table(result))
        ten["markdown"] = "\n".join(parts)
        files["ten_eyes_md"].write_text("# What ten eyes cannot tell\n\n" + ten["markdown"])
        printable(pd.concat(tables)).to_csv(files["ten_eyes_csv"], index=False,
                                            float_format="%.6g")
    else:
        files.pop("ten_eyes_md")
        files.pop("ten_eyes_csv")

    size = int(ds.attrs["chunk_size"])
    done = np.asarray(ds.chunk_complete.values, bool)
    counts = dict(chunks=int(done.size), chunks_done=int(done.sum()),
                  virtual_done=int((~ds.is_average.values).sum()),
                  average_done=bool(ds.is_average.values.any()), chunk_size=size)
    samplings = json.loads(ds.attrs.get("sampling_json", "{}"))
    _summary(files["summary"], store, ds, config, table, samplings, files, counts, ten)
    return files


REPORT_BYTES = 16 * 2**20
"""Room :func:`sweep_report` asks of its output folder's disk before reading the store, bytes
(three figures, a few tables and the summary: about 0.5 MB; a wide margin)."""


def default_out_dir(store_path) -> Path:
    """``STORE-report`` beside the store (``results.zarr`` → ``results-report``)."""
    store = Path(store_path)
    return store.with_name(f"{store.name.removesuffix('.zarr')}-report")


def _wavelength_step(ds, config) -> float:
    """The sweep's wavelength step (nm): the store's recorded wavelengths, else the config's."""
    recorded = ds.attrs.get("wavelengths_nm")
    if recorded is not None:
        wl = json.loads(recorded)
        if len(wl) > 1:
            return float(wl[1] - wl[0])
    return float(config.wavelengths_nm[2]) if len(config.wavelengths_nm) == 3 else float("nan")


__all__ = [
    "flat_curves",
    "without_flat_curves",
    "FILES",
    "PERCENTILES",
    "QUANTITIES",
    "default_out_dir",
    "error_rows",
    "fig_accommodation_error",
    "fig_cutoff_frequency",
    "fig_layouts",
    "percentile_table",
    "stored_config",
    "sweep_report",
]

