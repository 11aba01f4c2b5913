"""The reproduction's figures (Miyanishi et al. Figs. 3–11) from the study Datasets.

Host-only (numpy, matplotlib). Each ``fig*`` function takes the Datasets of
:func:`lfjax.reproduce.run_study` / :func:`lfjax.reproduce.compute_examples` and returns a
:class:`matplotlib.figure.Figure` built without pyplot (no global state, any backend);
:func:`all_figures` builds every figure the data allow and :func:`save_figures` writes them
as PNG under the names in ``FIGURES``.

Imports :mod:`~lfjax.reproduce.study` (its eye selectors) from the package.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import TYPE_CHECKING

import jax
import jax.numpy as jnp
import numpy as np

from lfjax.vision.claims import aberrated, average
from lfjax.model.eyes import sample_eyes, thibos_statistics
from lfjax.kernel.metrics import diffraction_limited_mtf, ncsf
from lfjax.base.zernike import nm_from_ansi

if TYPE_CHECKING:
    from matplotlib.figure import Figure


def _new_figure(**kwargs) -> Figure:
    """A matplotlib Figure (imported here: matplotlib's import costs 0.7 s that a command
    line run pays before any work; the reproduction draws in a thread while it computes)."""
    from matplotlib.figure import Figure

    return Figure(**kwargs)


def _hsv_to_rgb(hsv):
    from matplotlib.colors import hsv_to_rgb

    return hsv_to_rgb(hsv)


FIGURES = {
    "fig03": "fig03_zernike_coefficients.png",
    "fig04": "fig04_ncsf_csf.png",
    "fig05": "fig05_example_through_focus.png",
    "fig06": "fig06_vsotf_natural.png",
    "fig07": "fig07_vsotf_viewpoints.png",
    "fig08": "fig08_strehl_viewpoints.png",
    "fig09": "fig09_vsotf_vs_strehl.png",
    "fig10": "fig10_radial_mtf.png",
    "fig11": "fig11_cutoff_frequency.png",
}
"""PNG file name of each figure, keyed like :func:`all_figures`."""

GREY = "0.55"
MEAN_COLOUR = "tab:red"
AVERAGE_COLOUR = "tab:blue"
CDP_COLOUR = "tab:green"
METRIC_LABEL = {"vsotf": "VSOTF", "strehl": "Strehl ratio"}
# Panel grids place their axes by hand: a layout engine on ~30 axes costs seconds per figure.
_GRID_SPACING = dict(left=0.07, right=0.99, bottom=0.15, top=0.9, wspace=0.08, hspace=0.12)


def _attr_json(ds, key, default):
    value = ds.attrs.get(key)
    if value is None:
        return default
    try:
        return json.loads(value) if isinstance(value, str) else value
    except (TypeError, ValueError):
        return default


# ----------------------------------------------------------------------------- Fig. 3


def fig_zernike(ds) -> Figure:
    """Fig. 3: Zernike coefficients j = 1…13 of the virtual eyes against mean ± 2 SD."""
    pupil = float(ds.attrs.get("measured_pupil_mm", 3.0))
    mean, cov, n_subjects = thibos_statistics(pupil)
    sd = np.sqrt(np.diag(cov))
    seed = int(ds.attrs.get("config_seed", 0))
    n_eyes = int(ds.attrs.get("config_n_eyes", int((~ds.is_average).sum())))
    # the same draw with its tilts (the optics drops j = 0–2: they only shift the PSF)
    raw = np.asarray(sample_eyes(seed, n_eyes, pupil, zero_piston_tilt=False).zernike_um)
    j = np.arange(1, 14)
    fig = _new_figure(figsize=(8.0, 4.2), layout="constrained")
    ax = fig.add_subplot()
    colours = [f"C{i % 10}" for i in range(n_eyes)]
    for i in range(n_eyes):
        ax.plot(j, raw[i, j], "-", color=colours[i], lw=1.0, alpha=0.8,
                label=f"eye {i + 1}" if n_eyes <= 12 else None)
    ax.errorbar(j, mean[j], yerr=2 * sd[j], fmt="o", color="k", mfc="white", capsize=3,
                label=f"mean ± 2 SD (Thibos 2002, {n_subjects} eyes)", zorder=5)
    ax.axhline(0, color="0.8", lw=0.8, zorder=0)
    ax.set_xticks(j, [f"{k}\n{nm_from_ansi(int(k))}" for k in j], fontsize=8)
    ax.set_xlabel("OSA/ANSI index j  (n, m)")
    ax.set_ylabel(f"coefficient (µm, {pupil:g} mm pupil)")
    ax.set_title(f"Zernike coefficients of {n_eyes} virtual eyes (seed {seed})")
    ax.legend(fontsize=7, ncol=3, loc="lower left")
    return fig


# ----------------------------------------------------------------------------- Fig. 4


def fig_ncsf(ds, examples) -> Figure:
    """Fig. 4: (A) the NCSF in 2-D; (B) cross-section at f_y = 0 of NCSF, MTF and CSF for the
    aberration-free eye (3 mm pupil, polychromatic, focused on the CDP)."""
    from matplotlib.colors import LogNorm


    model = ds.attrs.get("option_ncsf", "watson_ahumada_2005")
    f = np.linspace(-60, 60, 481)
    fx, fy = np.meshgrid(f, f)
    # one jitted call: eager evaluation would compile every elementwise op separately
    s2d = np.asarray(jax.jit(ncsf, static_argnums=2)(jnp.asarray(fx), jnp.asarray(fy), model))
    top = float(s2d.max())
    fig = _new_figure(figsize=(10.0, 4.2), layout="constrained")
    ax1, ax2 = fig.subplots(1, 2, width_ratios=[1, 1.3])
    im = ax1.imshow(np.clip(s2d, top * 1e-3, None), origin="lower",
                    extent=[f[0], f[-1], f[0], f[-1]], cmap="viridis",
                    norm=LogNorm(top * 1e-3, top))
    fig.colorbar(im, ax=ax1, label="sensitivity (log scale)", shrink=0.85)
    ax1.set_xlabel("$f_x$ (cpd)")
    ax1.set_ylabel("$f_y$ (cpd)")
    ax1.set_title(f"A  NCSF ({model.replace('_', ' ')})", loc="left")
    fr = np.linspace(0.0, 60.0, 601)
    mtf = np.interp(fr, examples.dl_frequency.values, examples.fig4_dl_mtf.values)
    s1d = np.asarray(jax.jit(ncsf, static_argnums=2)(jnp.asarray(fr), jnp.zeros(fr.size), model))
    ax2.plot(fr, s1d, color="0.4", lw=1.5, label="NCSF")
    ax2.plot(fr, s1d * mtf, color="k", lw=2, label="CSF = MTF × NCSF")
    ax2.set_xlabel("$f_x$ (cpd), $f_y$ = 0")
    ax2.set_ylabel("contrast sensitivity")
    ax2.set_xlim(0, 60)
    ax2.set_ylim(bottom=0)
    ax3 = ax2.twinx()
    pupil = float(ds.attrs.get("pupil_diameter_mm", 3.0))
    ax3.plot(fr, mtf, color=AVERAGE_COLOUR, lw=1.5,
             label=f"MTF, aberration-free eye ({pupil:g} mm, polychromatic)")
    ax3.plot(fr, np.asarray(diffraction_limited_mtf(jnp.asarray(fr), pupil, 550.0)),
             color=AVERAGE_COLOUR, ls="--", lw=1, label="MTF, diffraction limit at 550 nm")
    ax3.set_ylim(0, 1.02)
    ax3.set_ylabel("MTF", color=AVERAGE_COLOUR)
    lines = ax2.get_legend_handles_labels()
    lines3 = ax3.get_legend_handles_labels()
    ax2.legend(lines[0] + lines3[0], lines[1] + lines3[1], fontsize=7, loc="upper right")
    ax2.set_title("B  cross-section", loc="left")
    return fig


# ----------------------------------------------------------------------------- Fig. 5


def _otf_rgb(modulus, phase):
    hue = np.mod(phase, 2 * np.pi) / (2 * np.pi)  # phase 0: red
    hsv = np.stack([hue, np.ones_like(hue), np.clip(modulus, 0, 1)], axis=-1)
    return _hsv_to_rgb(hsv)


def fig_example(ds, examples) -> Figure:
    """Fig. 5: through-focus VSOTF of one aberrated eye (natural view) with its PSFs and
    OTFs (hue: phase, brightness: modulus)."""
    eye = examples.attrs.get("fig5_eye", str(ds.eye.values[0]))
    cdp = float(ds.attrs["cdp_D"])
    sub = ds.sel(layout="natural", eye=eye).sel(depth=cdp, method="nearest")
    rel_all = ds.accommodation.values - cdp
    vs = sub.vsotf.values
    states_rel = examples.fig5_state_rel.values
    n = states_rel.size
    fig = _new_figure(figsize=(1.6 * n + 1.0, 6.8))
    grid = fig.add_gridspec(3, n, height_ratios=[1.3, 1, 1], left=0.1, right=0.99, bottom=0.07,
                            top=0.95, wspace=0.35, hspace=0.45)
    ax = fig.add_subplot(grid[0, :])
    ok = np.isfinite(vs)
    ax.plot(rel_all[ok], vs[ok], "k.-")
    pred = float(sub.predicted_accommodation.sel(metric="vsotf")) - cdp
    ax.axvline(pred, color=MEAN_COLOUR, lw=1.2, label=f"peak: {pred:+.1f} D")
    for r in states_rel:
        ax.axvline(r, color="0.85", lw=6, zorder=0)
    ax.set_xlim(states_rel[0] - 2 * abs(states_rel[1] - states_rel[0]),
                states_rel[-1] + 2 * abs(states_rel[1] - states_rel[0]))
    ax.set_xlabel("accommodation relative to the image (D)")
    ax.set_ylabel("VSOTF")
    ax.set_title(f"Through-focus, natural view, {eye}, point on the CDP ({cdp:g} D)")
    ax.legend(fontsize=8)
    psf = examples.fig5_psf.values
    ext_psf = [float(examples.psf_x[0]), float(examples.psf_x[-1]),
               float(examples.psf_y[0]), float(examples.psf_y[-1])]
    mod = examples.fig5_otf_modulus.values
    ph = examples.fig5_otf_phase.values
    fx = examples.otf_fx.values
    ext_otf = [fx[0], fx[-1], fx[0], fx[-1]]
    for k in range(n):
        a = fig.add_subplot(grid[1, k])
        a.imshow(psf[k], origin="lower", extent=ext_psf, cmap="gray", vmin=0,
                 vmax=float(psf[k].max()))
        a.set_title(f"{states_rel[k]:+.1f} D", fontsize=9)
        a.tick_params(labelsize=7)
        if k == 0:
            a.set_ylabel("PSF (own scale)\ny (arcmin)", fontsize=8)
        a.set_xlabel("x (arcmin)", fontsize=7)
        b = fig.add_subplot(grid[2, k])
        b.imshow(_otf_rgb(mod[k], ph[k]), origin="lower", extent=ext_otf)
        b.tick_params(labelsize=7)
        if k == 0:
            b.set_ylabel("OTF: hue phase (red 0),\nbrightness modulus\n$f_y$ (cpd)", fontsize=8)
        b.set_xlabel("$f_x$ (cpd)", fontsize=7)
    return fig


# ----------------------------------------------------------------------------- Figs. 6–8


def _vertical_lines(ax, x, **style):
    """Full-height vertical lines at data ``x`` as one collection: what ``ax.axvline`` draws
    for each, without an autoscale per line (351 of them took half of Figs. 7 and 8's time)."""
    from matplotlib.collections import LineCollection

    segments = [[(float(v), 0.0), (float(v), 1.0)] for v in np.atleast_1d(x)]
    ax.add_collection(LineCollection(segments, transform=ax.get_xaxis_transform(), zorder=2,
                                     colors=style.pop("color"), linewidths=style.pop("lw"),
                                     **style), autolim=False)


def _through_focus_panel(ax, ds, layout, depth_index, metric, show_cdp=True, legend=False,
                         values_in_labels=True):
    cdp = float(ds.attrs["cdp_D"])
    depth = float(ds.depth.values[depth_index])
    rel = ds.accommodation.values - depth
    sub = ds.sel(layout=layout).isel(depth=depth_index)
    ab, av = aberrated(sub), average(sub)
    values = ab[metric].values
    preds = ab.predicted_accommodation.sel(metric=metric).values - depth
    for i in range(values.shape[0]):
        ok = np.isfinite(values[i])
        ax.plot(rel[ok], values[i][ok], color=GREY, lw=0.8,
                label="aberrated eyes" if i == 0 else None)
    _vertical_lines(ax, preds, color=GREY, lw=0.6, alpha=0.8)
    ax.axvline(float(np.mean(preds)), color=MEAN_COLOUR, lw=1.4,
               label=f"mean peak {np.mean(preds):+.2f} D" if values_in_labels
               else "mean of the eyes' peaks")
    ok = np.isfinite(av[metric].values)
    ax.plot(rel[ok], av[metric].values[ok], color=AVERAGE_COLOUR, lw=1.4, label="average eye")
    a_pred = float(av.predicted_accommodation.sel(metric=metric)) - depth
    ax.axvline(a_pred, color=AVERAGE_COLOUR, lw=1.0, ls="--",
               label=f"average-eye peak {a_pred:+.1f} D" if values_in_labels
               else "average-eye peak")
    if show_cdp:
        ax.axvline(cdp - depth, color=CDP_COLOUR, lw=1.2, label="CDP")
    if legend:
        ax.legend(fontsize=7)


def fig_natural(ds, metric: str = "vsotf") -> Figure:
    """Fig. 6: through-focus VSOTF, natural view, point on the CDP."""
    cdp = float(ds.attrs["cdp_D"])
    di = int(np.argmin(np.abs(ds.depth.values - cdp)))
    fig = _new_figure(figsize=(7.0, 4.2), layout="constrained")
    ax = fig.add_subplot()
    _through_focus_panel(ax, ds, "natural", di, metric, show_cdp=False, legend=True)
    window = float(ds.attrs.get("config_window_D", 2.0))
    ax.set_xlim(-min(window, cdp), window)
    ax.set_xlabel("accommodation relative to the image depth (D)")
    ax.set_ylabel(METRIC_LABEL[metric])
    ax.set_title(f"Natural view, {int((~ds.is_average).sum())} eyes + average eye, "
                 f"image on the CDP ({cdp:g} D)")
    return fig


def _layout_by_depth(ds, panel, ylabel: str, xlabel: str, title: str, row_height: float,
                     sharey) -> Figure:
    """A panel per light-field layout (rows) × rendered depth (columns), drawn by
    ``panel(ax, layout, depth_index)``, with one legend and shared axis labels."""
    layouts = [n for n in ("2x2", "3x3", "4x4") if n in ds.layout.values]
    nd = ds.depth.size
    fig = _new_figure(figsize=(1.9 * nd + 1.0, row_height * len(layouts) + 1.2))
    axes = fig.subplots(len(layouts), nd, sharex=True, sharey=sharey, squeeze=False,
                        gridspec_kw=_GRID_SPACING)
    for r, name in enumerate(layouts):
        for c in range(nd):
            ax = axes[r, c]
            panel(ax, name, c)
            ax.tick_params(labelsize=7)
            if r == 0:
                ax.set_title(f"CDP {float(ds.depth_rel_cdp[c]):+.1f} D", fontsize=9)
            if c == 0:
                ax.set_ylabel(f"{name}\n{ylabel}", fontsize=9)
    handles, labels = axes[0, 0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="lower center", ncol=len(labels), fontsize=8, frameon=False)
    fig.supxlabel(xlabel, fontsize=9, y=0.07)
    fig.suptitle(title, fontsize=11)
    return fig


def fig_viewpoints(ds, metric: str = "vsotf") -> Figure:
    """Figs. 7 and 8: through-focus metric per viewpoint density (rows) × rendered depth
    (columns); grey: eyes, red: mean peak, blue: average eye, green: the CDP."""
    window = float(ds.attrs.get("config_window_D", 2.0))

    def panel(ax, name, c):
        _through_focus_panel(ax, ds, name, c, metric, values_in_labels=False)
        ax.set_xlim(-window - 0.1, window + 0.1)

    return _layout_by_depth(
        ds, panel, METRIC_LABEL[metric],
        "accommodation relative to the rendered depth (D); grey lines: each eye's peak",
        f"Through-focus {METRIC_LABEL[metric]} for viewpoint densities", 2.1, "row")


# ----------------------------------------------------------------------------- Fig. 9


def fig_vsotf_vs_strehl(ds, examples) -> Figure:
    """Fig. 9: VSOTF and Strehl through focus (2×2, deepest negative depth) with PSFs and
    simulated retinal letters at the VSOTF peak and at the CDP."""
    eye = examples.attrs["fig9_eye"]
    depth = float(examples.attrs["fig9_depth_D"])
    cdp = float(ds.attrs["cdp_D"])
    di = int(np.argmin(np.abs(ds.depth.values - depth)))
    sub = ds.sel(layout="2x2").isel(depth=di)
    acc = ds.accommodation.values
    fig = _new_figure(figsize=(11.0, 5.6), layout="constrained")
    grid = fig.add_gridspec(2, 4, width_ratios=[1.6, 1.6, 1, 1])
    states = examples.fig9_state.values
    names = [str(s) for s in examples.fig9_state_name.values]
    for k, metric in enumerate(("vsotf", "strehl")):
        ax = fig.add_subplot(grid[k, :2])
        vals = aberrated(sub)[metric].values
        for i in range(vals.shape[0]):
            ok = np.isfinite(vals[i])
            ax.plot(acc[ok], vals[i][ok], color=GREY, lw=0.7)
        one = sub.sel(eye=eye)[metric].values
        ok = np.isfinite(one)
        ax.plot(acc[ok], one[ok], color="k", lw=1.8, label=eye)
        av = average(sub)[metric].values
        ok = np.isfinite(av)
        ax.plot(acc[ok], av[ok], color=AVERAGE_COLOUR, lw=1.2, label="average eye")
        ax.axvline(depth, color="tab:orange", lw=1.2, label=f"image {depth:g} D")
        ax.axvline(cdp, color=CDP_COLOUR, lw=1.2, label=f"CDP {cdp:g} D")
        pred = float(sub.sel(eye=eye).predicted_accommodation.sel(metric=metric))
        ax.plot([pred], [np.nanmax(one)], "v", color=MEAN_COLOUR, ms=8,
                label=f"{eye} peak {pred:.1f} D")
        ax.set_ylabel(METRIC_LABEL[metric])
        ax.legend(fontsize=7, loc="best")
        if k == 1:
            ax.set_xlabel("accommodation (D, absolute)")
        else:
            ax.set_title(f"2x2 viewpoints, point at CDP {depth - cdp:+.1f} D ({depth:g} D)")
    psf = examples.fig9_psf.values
    ext_psf = [float(examples.psf9_x[0]), float(examples.psf9_x[-1]),
               float(examples.psf9_y[0]), float(examples.psf9_y[-1])]
    img = examples.fig9_retinal_image.values
    ext_img = [float(examples.img_x[0]), float(examples.img_x[-1]),
               float(examples.img_y[0]), float(examples.img_y[-1])]
    for k in range(2):
        a = fig.add_subplot(grid[0, 2 + k])
        a.imshow(psf[k], origin="lower", extent=ext_psf, cmap="gray", vmin=0)
        a.set_title(f"PSF at {states[k]:.1f} D\n({names[k]})", fontsize=9)
        a.set_xlabel("arcmin", fontsize=7)
        a.tick_params(labelsize=7)
        b = fig.add_subplot(grid[1, 2 + k])
        b.imshow(img[k], origin="lower", extent=ext_img, cmap="gray", vmin=0, vmax=1)
        b.set_title(f"retinal image, {float(examples.attrs['fig9_letter_arcmin']):g}' E",
                    fontsize=9)
        b.set_xlabel("arcmin", fontsize=7)
        b.tick_params(labelsize=7)
    return fig


# ----------------------------------------------------------------------------- Figs. 10–11


def _mtf_panel(ax, ds, layout, depth_index, fmax=60.0):
    f = ds.frequency.values
    keep = f <= fmax + 1e-9
    sub = ds.sel(layout=layout, metric="vsotf").isel(depth=depth_index)
    m = aberrated(sub).mtf_at_peak.values[:, keep]
    mean, sd = np.mean(m, axis=0), np.std(m, axis=0, ddof=1) if m.shape[0] > 1 else 0 * m[0]
    ax.fill_between(f[keep], mean - sd, mean + sd, color="0.8", lw=0)
    ax.plot(f[keep], mean, color="k", lw=1.2, label="aberrated eyes: mean ± SD")
    ax.plot(f[keep], average(sub).mtf_at_peak.values[keep], color=AVERAGE_COLOUR, lw=1.2,
            label="average eye")
    ax.set_xlim(0, fmax)
    ax.set_ylim(0, 1)


def fig_radial_mtf(ds) -> Figure:
    """Fig. 10: radial MTFs at the VSOTF-predicted accommodation per density × depth."""
    return _layout_by_depth(ds, lambda ax, name, c: _mtf_panel(ax, ds, name, c), "radial MTF",
                            "spatial frequency (cpd)",
                            "Radial MTF at the accommodation predicted by VSOTF", 2.0, True)


def fig_cutoff(ds) -> Figure:
    """Fig. 11: (A) radial MTF, natural view; (B) cut-off frequency vs rendered depth."""
    threshold = float(ds.attrs.get("config_cutoff_threshold", 0.05))
    cdp = float(ds.attrs["cdp_D"])
    fig = _new_figure(figsize=(10.0, 4.8), layout="constrained")
    ax1, ax2 = fig.subplots(1, 2)
    if "natural" in ds.layout.values:
        di = int(np.argmin(np.abs(ds.depth.values - cdp)))
        _mtf_panel(ax1, ds, "natural", di, fmax=80.0)
        ax1.axhline(threshold, color="tab:orange", lw=1, ls="--", label=f"MTF = {threshold:g}")
        ax1.axvline(60, color="0.6", lw=0.8, ls=":")
        ax1.legend(fontsize=8)
    ax1.set_xlabel("spatial frequency (cpd)")
    ax1.set_ylabel("radial MTF")
    ax1.set_title("A  natural view, 3 mm pupil, at the VSOTF peak", loc="left")
    rel = ds.depth_rel_cdp.values
    for k, name in enumerate(n for n in ("2x2", "3x3", "4x4") if n in ds.layout.values):
        sub = ds.sel(layout=name, metric="vsotf")
        c = aberrated(sub).cutoff_frequency.values
        mean = np.mean(c, axis=0)
        sd = np.std(c, axis=0, ddof=1) if c.shape[0] > 1 else np.zeros_like(mean)
        colour = f"C{k}"
        ax2.errorbar(rel, mean, yerr=sd, fmt="o-", color=colour, capsize=3,
                     label=f"{name}: mean ± SD")
        ax2.plot(rel, average(sub).cutoff_frequency.values, "--", color=colour, lw=1,
                 label=f"{name}: average eye")
    if "natural" in ds.layout.values:
        nat = ds.sel(layout="natural", metric="vsotf").sel(depth=cdp, method="nearest")
        ax2.axhline(float(np.mean(aberrated(nat).cutoff_frequency.values)), color="k", lw=0.8,
                    ls=":", label="natural view (mean)")
    ax2.set_xlabel("rendered depth relative to the CDP (D)")
    ax2.set_ylabel(f"cut-off frequency at MTF {threshold:g} (cpd)")
    ax2.set_title("B  cut-off frequency", loc="left")
    ax2.legend(fontsize=7, ncol=2, loc="upper center", bbox_to_anchor=(0.5, -0.16))
    return fig


# ----------------------------------------------------------------------------- all


def all_figures(ds, examples) -> dict[str, Figure]:
    """Every figure the data allow, keyed like :data:`FIGURES`."""
    figs = {"fig03": fig_zernike(ds)}
    if "fig4_dl_mtf" in examples:
        figs["fig04"] = fig_ncsf(ds, examples)
    if "natural" in ds.layout.values:
        figs["fig05"] = fig_example(ds, examples)
        figs["fig06"] = fig_natural(ds)
    if any(n in ds.layout.values for n in ("2x2", "3x3", "4x4")):
        figs["fig07"] = fig_viewpoints(ds, "vsotf")
        figs["fig08"] = fig_viewpoints(ds, "strehl")
        figs["fig10"] = fig_radial_mtf(ds)
    if "fig9_psf" in examples:
        figs["fig09"] = fig_vsotf_vs_strehl(ds, examples)
    figs["fig11"] = fig_cutoff(ds)
    return dict(sorted(figs.items()))


def save_figures(ds, examples, folder, config=None, dpi: int = 110) -> list[str]:
    """Write every figure as PNG into ``folder``; returns the file names."""
    folder = Path(folder)
    names = []
    for key, fig in all_figures(ds, examples).items():
        name = FIGURES[key]
        fig.savefig(folder / name, dpi=dpi)
        names.append(name)
    return names



__all__ = [
    "FIGURES",
    "all_figures",
    "fig_cutoff",
    "fig_example",
    "fig_natural",
    "fig_ncsf",
    "fig_radial_mtf",
    "fig_viewpoints",
    "fig_vsotf_vs_strehl",
    "fig_zernike",
    "save_figures",
]
