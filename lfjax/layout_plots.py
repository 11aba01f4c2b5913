"""Figures of a layout fit (:mod:`lfjax.layout_opt`): layouts, through-focus VSOTF, history.

Host-only (numpy, matplotlib). Each ``fig_*`` function returns a
:class:`matplotlib.figure.Figure` built without pyplot (no global state, any backend);
:func:`save_fit_figures` writes them as PNG.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.figure import Figure
from matplotlib.patches import Circle

COLOURS = ("tab:grey", "tab:red", "tab:blue", "tab:green")
FIGURES = {"layouts": "layouts.png", "through_focus": "through_focus.png", "history": "history.png"}


def draw_layout(ax, layout, pupil_diameter_mm: float, colour: str = "tab:red", title: str | None = None):
    """Subaperture discs (filled, cropped by the pupil) and the pupil outline on ``ax`` (mm)."""
    radius = 0.5 * float(pupil_diameter_mm)
    pupil = Circle((0.0, 0.0), radius, fill=False, lw=1.5, color="black")
    ax.add_patch(pupil)
    centres = np.asarray(layout.centres_mm, float).reshape(-1, 2)
    diameters = np.asarray(layout.diameters_mm, float).reshape(-1)
    for i, ((x, y), d) in enumerate(zip(centres, diameters)):
        disc = Circle((x, y), 0.5 * d, color=colour, alpha=0.35, lw=0)
        disc.set_clip_path(pupil)
        ax.add_patch(disc)
        edge = Circle((x, y), 0.5 * d, fill=False, color=colour, lw=0.8, ls="--")
        ax.add_patch(edge)
        ax.plot([x], [y], marker="+", color=colour, ms=5)
    lim = 1.15 * max(radius, float(np.max(np.hypot(centres[:, 0], centres[:, 1]) + 0.5 * diameters)))
    ax.set_xlim(-lim, lim)
    ax.set_ylim(-lim, lim)
    ax.set_aspect("equal")
    ax.set_xlabel("x (mm)")
    ax.set_ylabel("y (mm)")
    if title:
        ax.set_title(title, fontsize=9)


def fig_layouts(layouts: dict, pupil_diameter_mm: float) -> Figure:
    """Layouts side by side, e.g. {"before": Layout, "after": Layout}; discs dashed beyond
    the pupil, which crops them."""
    n = len(layouts)
    fig = Figure(figsize=(3.3 * n, 3.4), layout="constrained")
    for i, (label, layout) in enumerate(layouts.items()):
        ax = fig.add_subplot(1, n, i + 1)
        d = np.asarray(layout.diameters_mm, float)
        title = f"{label}: {len(d)} views, d = {d.min():.3g}" + (
            f"–{d.max():.3g} mm" if d.max() - d.min() > 1e-3 else " mm")
        draw_layout(ax, layout, pupil_diameter_mm, COLOURS[(i + 1) % len(COLOURS)], title)
    return fig


def fig_through_focus(curves: dict, depths_D, title: str | None = None) -> Figure:
    """Population-mean through-focus VSOTF per rendered depth (one panel each).

    ``curves``: {label: (accommodation_D (n_depth, n_k), vsotf (n_eyes, n_depth, n_k))}
    as :func:`lfjax.layout_opt.through_focus_curves` returns; the band spans the eyes'
    10th–90th percentiles, the vertical line marks the rendered depth (correct focus).
    """
    depths = np.asarray(depths_D, float)
    n = len(depths)
    fig = Figure(figsize=(2.6 * n + 0.6, 3.2), layout="constrained")
    axes = [fig.add_subplot(1, n, i + 1) for i in range(n)]
    for j, (label, (acc, vs)) in enumerate(curves.items()):
        colour = COLOURS[(j + 1) % len(COLOURS)]
        acc = np.asarray(acc, float)
        vs = np.asarray(vs, float)
        for i, ax in enumerate(axes):
            a = acc[i]
            ok = np.isfinite(vs[:, i]).all(axis=0)
            mean = np.full(ok.shape, np.nan)
            mean[ok] = vs[:, i][:, ok].mean(axis=0)
            ax.plot(a[ok], mean[ok], color=colour, lw=1.6,
                    label=f"{label} (mean of {vs.shape[0]} eyes)" if i == 0 else None)
            if vs.shape[0] > 1:
                lo, hi = np.nanpercentile(vs[:, i][:, ok], [10, 90], axis=0)
                ax.fill_between(a[ok], lo, hi, color=colour, alpha=0.15, lw=0)
    for i, ax in enumerate(axes):
        ax.axvline(depths[i], color="black", lw=0.8, ls=":")
        ax.set_title(f"rendered at {depths[i]:g} D", fontsize=9)
        ax.set_xlabel("accommodation (D)")
        if i == 0:
            ax.set_ylabel("VSOTF (open-pupil reference)")
            ax.legend(fontsize=7, loc="lower center")
    if title:
        fig.suptitle(title, fontsize=10)
    return fig


def fig_history(history, label: str = "loss") -> Figure:
    """Objective (loss) after each solver step."""
    h = np.asarray(history, float)
    fig = Figure(figsize=(4.5, 3.0), layout="constrained")
    ax = fig.add_subplot()
    ax.plot(np.arange(h.size), h, marker="o", ms=3, color="tab:red")
    ax.set_xlabel("solver step")
    ax.set_ylabel(label)
    return fig


def save_fit_figures(fit, curves: dict, out_dir, dpi: int = 110) -> list[Path]:
    """Write layouts.png, through_focus.png and history.png of a
    :class:`lfjax.layout_opt.LayoutFit` (``curves`` as for :func:`fig_through_focus`)."""
    out = Path(out_dir)
    pupil = fit.constraints.pupil_diameter_mm
    depths = fit.train["after"]["depths_D"]
    figures = {
        "layouts": fig_layouts({"before": fit.initial_layout, "after": fit.layout}, pupil),
        "through_focus": fig_through_focus(curves, depths, f"objective: {fit.objective.name}"),
        "history": fig_history(fit.history, f"loss ({fit.objective.name})"),
    }
    paths = []
    for key, fig in figures.items():
        path = out / FIGURES[key]
        fig.savefig(path, dpi=dpi)
        paths.append(path)
    return paths


__all__ = [
    "draw_layout",
    "fig_layouts",
    "fig_through_focus",
    "fig_history",
    "save_fit_figures",
    "FIGURES",
]
