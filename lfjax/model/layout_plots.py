"""Figures of a layout fit (:mod:`lfjax.layout_opt`): layouts, through-focus VSOTF, history.

Host-only (numpy, matplotlib). Each ``fig_*`` function returns a
:class:`matplotlib.figure.Figure` built without pyplot (no global state, any backend);
:func:`save_fit_figures` writes them as PNG.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from typing import TYPE_CHECKING

from lfjax.base.apertures import CIRCLE, SQUARE, aperture_shape

if TYPE_CHECKING:
    from matplotlib.figure import Figure

COLOURS = ("tab:grey", "tab:red", "tab:blue", "tab:green")
FIGURES = {"layouts": "layouts.png", "through_focus": "through_focus.png", "history": "history.png"}


def _new_figure(**kwargs) -> Figure:
    """A matplotlib Figure, imported when first drawn: ``import lfjax`` does not pay for
    matplotlib (0.7 s)."""
    from matplotlib.figure import Figure

    return Figure(**kwargs)


def draw_layout(ax, layout, pupil_diameter_mm: float, colour: str = "tab:red", title: str | None = None,
                aperture: str = CIRCLE.name):
    """Subapertures (filled, cropped by the pupil) and the pupil outline on ``ax`` (mm), in
    the shape ``aperture`` (a name of :data:`lfjax.base.apertures.APERTURES`): discs,
    squares, or — for a shape spanning the pupil's height — vertical strips ``d`` wide (a
    1×n HPO layout, :mod:`lfjax.model.strips`), their edges drawn within the pupil."""
    from matplotlib.patches import Circle, Rectangle

    declared = aperture_shape(aperture)
    radius = 0.5 * float(pupil_diameter_mm)
    pupil = Circle((0.0, 0.0), radius, fill=False, lw=1.5, color="black")
    ax.add_patch(pupil)
    centres = np.asarray(layout.centres_mm, float).reshape(-1, 2)
    diameters = np.asarray(layout.diameters_mm, float).reshape(-1)
    for i, ((x, y), d) in enumerate(zip(centres, diameters)):
        if declared.spans_pupil_height or declared == SQUARE:
            low, height = (-radius, 2.0 * radius) if declared.spans_pupil_height else (y - 0.5 * d, d)
            shape = dict(xy=(x - 0.5 * d, low), width=d, height=height)
            area, edge = (Rectangle(**shape, color=colour, alpha=0.35, lw=0),
                          Rectangle(**shape, fill=False, color=colour, lw=0.8, ls="--"))
            if declared.spans_pupil_height:  # its ends are the pupil's: drawn only within it
                edge.set_clip_path(pupil)
        else:
            area = Circle((x, y), 0.5 * d, color=colour, alpha=0.35, lw=0)
            edge = Circle((x, y), 0.5 * d, fill=False, color=colour, lw=0.8, ls="--")
        area.set_clip_path(pupil)
        ax.add_patch(area)
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
    fig = _new_figure(figsize=(3.3 * n, 3.4), layout="constrained")
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
    fig = _new_figure(figsize=(2.6 * n + 0.6, 3.2), layout="constrained")
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
    fig = _new_figure(figsize=(4.5, 3.0), layout="constrained")
    ax = fig.add_subplot()
    ax.plot(np.arange(h.size), h, marker="o", ms=3, color="tab:red")
    ax.set_xlabel("solver step")
    ax.set_ylabel(label)
    return fig


def fig_front(front, pupil_diameter_mm: float) -> Figure:
    """The trade-off of a :class:`lfjax.layout_opt.Front`: held-out accommodation RMSE (D;
    the display's share: each eye's error less its own error on the CDP) against held-out image quality at each eye's predicted accommodation (mean VSOTF), the
    fitted points joined in order of tolerance, the tangent n×n grids (squares) and natural
    viewing (star) marked, each fitted layout drawn small beside its point."""
    rows = front.table()
    fig = _new_figure(figsize=(8.0, 5.6), layout="constrained")
    ax = fig.add_subplot()
    fitted = [r for r in rows if r["tolerance_D"] is not None]
    refs = [r for r in rows if r["tolerance_D"] is None]
    x = np.array([r["image_at_peak"] for r in fitted])
    y = np.array([r["relative_accommodation_rmse_D"] for r in fitted])
    ax.plot(x, y, "-o", color="tab:red", ms=6, label="fitted (tolerance in D)")
    for r in fitted:
        ax.annotate(f"{r['tolerance_D']:.2g}", (r["image_at_peak"], r["relative_accommodation_rmse_D"]),
                    textcoords="offset points", xytext=(6, -12), fontsize=7, color="tab:red")
    for r in refs:
        marker = "*" if r["name"] == "natural" else "s"
        ax.plot([r["image_at_peak"]], [r["relative_accommodation_rmse_D"]], marker, color="tab:blue", ms=9)
        ax.annotate(r["name"] if r["name"] == "natural" else f"tangent {r['name']}",
                    (r["image_at_peak"], r["relative_accommodation_rmse_D"]), textcoords="offset points",
                    xytext=(6, 4), fontsize=8, color="tab:blue")
    allx = np.array([r["image_at_peak"] for r in rows])
    ally = np.array([r["relative_accommodation_rmse_D"] for r in rows])
    padx = 0.15 * max(np.ptp(allx), 0.05)
    pady = 0.15 * max(np.ptp(ally), 0.05)
    ax.set_xlim(allx.min() - padx, allx.max() + 2.5 * padx)
    ax.set_ylim(max(ally.min() - pady, 0.0), ally.max() + 2.5 * pady)
    ax.set_xlabel("image quality at the predicted accommodation (held-out mean VSOTF)")
    ax.set_ylabel("display's accommodation error, RMSE (D, held-out)")
    n_eyes = (front.fits[0].test or front.fits[0].train)["after"]["n_eyes"]
    ax.set_title(f"accommodation against image quality ({n_eyes} held-out eyes)", fontsize=10)
    ax.legend(fontsize=8, loc="upper left")
    # layouts drawn beside their points, in axes coordinates
    size = 0.13
    for r, fit in zip(fitted, front.fits):
        px, py = ax.transAxes.inverted().transform(
            ax.transData.transform((r["image_at_peak"], r["relative_accommodation_rmse_D"])))
        inset = ax.inset_axes([min(px + 0.02, 1 - size), min(py + 0.02, 1 - size), size, size])
        draw_layout(inset, fit.layout, pupil_diameter_mm)
        inset.set_axis_off()
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
    "fig_front",
    "save_fit_figures",
    "FIGURES",
]
