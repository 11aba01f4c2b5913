"""The phone class read for its cause (issue #38, item 4): the phone preset's 2×2 and 3×3
family members (lfjax.studies.tradeoff.panel_for_views) at 1 and 2 D through the n×n
idealisation on a widened absolute accommodation grid (0–6 D, 0.25 D), through the whole
lenslet array where its pipeline model applies (lfjax.studies.array_views: the lenslets whose
lit pixel's footprint overlaps the pupil, the eye centred on a pixel's viewing zone), and
the geometry that says which part of the answer the idealisation can carry. Called by
benchmarks/studies/lenslet_aberrations.py --part phone.
"""

from __future__ import annotations

import csv
import time
from pathlib import Path

import numpy as np

from lfjax.display.panel import phone_panel
from lfjax.model.eyes import sample_eyes
from lfjax.model.spectral import make_spectrum
from lfjax.studies.array_views import array_views, idealisation_gap
from lfjax.studies.tradeoff import panel_for_views, views_in_pupil
from lfjax.sweep.run import peak_rss_mb
from lfjax.vision.focus import through_focus
from lfjax.vision.peak_options import PeakOptions
from lfjax.vision.prepare import States
from lfjax.vision.viewing import Viewing

GRID_D = np.arange(0.0, 6.0001, 0.25)
DEPTHS_D = (1.0, 2.0)
COUNTS = (2, 3)


def geometry_rows():
    rows = []
    for n in COUNTS:
        panel = panel_for_views(phone_panel(), n)
        p = float(panel.pixel_pitch_mm)
        for offset, label in ((0.0, "pupil on a pixel edge"), (0.5 * p, "pupil centred on a pixel")):
            for gap in idealisation_gap(panel, list(DEPTHS_D) + [2.5], pixel_offset_mm=(offset, offset)):
                rows.append(dict(n=n, eye=label, lenslet_plane_D=1000.0 / float(panel.distance_mm),
                                 pixel_zone_mm=float(panel.distance_mm) * p / float(panel.gap_mm),
                                 view_mm=float(panel.view_diameter_mm), **gap))
    return rows


def run_phone(n_eyes: int, out: Path, peak_method: str = "adaptive") -> dict:
    """The idealisation for ``n_eyes`` Thibos eyes (seed 0), the whole array for the first
    eye (its cost does not depend on the population: 4–44 beams, every window the pupil);
    continuous VSOTF peaks refined by ``peak_method`` ("adaptive": only where the grid
    cannot place the peak within 0.01 D)."""
    eyes = sample_eyes(0, n_eyes)
    spectrum = make_spectrum([550.0])
    rows = []
    curves = {}
    t_all = time.time()
    for n in COUNTS:
        panel = panel_for_views(phone_panel(), n)
        optics = panel.optics()
        cdp = float(panel.cdp_D)
        # the n×n idealisation, widened to 0–6 D
        t0 = time.time()
        tf = through_focus(
            eyes,
            views_in_pupil(panel, n),
            States.grid(GRID_D, depths_D=list(DEPTHS_D)),
            Viewing(pupil_diameter_mm=panel.pupil_diameter_mm, cdp_D=cdp, display=optics),
            spectrum=spectrum,
            peaks=PeakOptions(metrics=("vsotf",), method=peak_method),
        )
        peaks = tf.continuous_accommodation_D()
        vs = np.asarray(tf.vsotf)
        for k, d in enumerate(DEPTHS_D):
            curves[("ideal", n, d)] = vs[:, k]
            for e in range(n_eyes):
                rows.append(dict(model="idealised", n=n, depth_D=d, eye=e, peak_D=float(peaks[e, k]),
                                 grid_peak_D=float(GRID_D[int(np.argmax(vs[e, k]))]),
                                 vsotf_max=float(vs[e, k].max()), n_beams=n * n))
        print(f"phone {n}x{n} idealised, 0–6 D (df {tf.sampling.freq_step_cpd:.3f} cpd): "
              f"{time.time() - t0:.0f} s; peaks (D), median and 5–95 %: "
              + "; ".join(f"{d:g} D: {np.median(peaks[:, k]):.2f} ({np.percentile(peaks[:, k], 5):.2f}–"
                          f"{np.percentile(peaks[:, k], 95):.2f})" for k, d in enumerate(DEPTHS_D))
              + f"; peak RSS {peak_rss_mb():.0f} MiB", flush=True)
        # the whole array, the eye centred on a pixel's viewing zone, the average of the
        # first eyes only (its views are many and every window is the pupil)
        p = float(panel.pixel_pitch_mm)
        for d in DEPTHS_D:
            views = array_views(panel, d, pixel_offset_mm=(0.5 * p, 0.5 * p))
            if views.n_geometric == 0:
                print(f"phone {n}x{n} array at {d:g} D: no lit beam reaches the pupil", flush=True)
                continue
            t0 = time.time()
            tfa = through_focus(
                eyes[:1],
                views.layout(),
                States.grid(GRID_D, depths_D=[d]),
                Viewing(pupil_diameter_mm=panel.pupil_diameter_mm, cdp_D=cdp, display=optics),
                spectrum=spectrum,
                peaks=PeakOptions(metrics=("vsotf",), method=peak_method),
            )
            va = np.asarray(tfa.vsotf)[0, 0]
            curves[("array", n, d)] = va[None]
            pa = float(tfa.continuous_accommodation_D()[0, 0])
            rows.append(dict(model="whole array", n=n, depth_D=d, eye=0, peak_D=pa,
                             grid_peak_D=float(GRID_D[int(np.argmax(va))]), vsotf_max=float(va.max()),
                             n_beams=views.n_geometric))
            print(f"phone {n}x{n} array at {d:g} D ({views.n_geometric} beams): {time.time() - t0:.0f} s, "
                  f"peak {pa:.2f} D; peak RSS {peak_rss_mb():.0f} MiB", flush=True)
    print(f"phone part: {time.time() - t_all:.0f} s for {n_eyes} eyes", flush=True)
    with open(out / "phone.csv", "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    geo = geometry_rows()
    with open(out / "phone_geometry.csv", "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(geo[0]))
        w.writeheader()
        w.writerows(geo)
    np.savez(out / "phone_curves.npz", grid_D=GRID_D,
             **{f"{m}_{n}x{n}_{d:g}D": v for (m, n, d), v in curves.items()})
    fig_phone(curves, rows, out / "phone_array.png")
    return dict(rows=rows, geometry=geo)


def fig_phone(curves, rows, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, len(COUNTS), figsize=(11, 4.2), sharey=False)
    lenslet_plane = 1000.0 / 350.0
    for ax, n in zip(axes, COUNTS):
        for d, colour in zip(DEPTHS_D, ("C0", "C1")):
            ideal = curves.get(("ideal", n, d))
            if ideal is not None and len(ideal) > 5:  # a population: its median and 5–95 % band
                ax.fill_between(GRID_D, np.percentile(ideal, 5, axis=0), np.percentile(ideal, 95, axis=0),
                                color=colour, alpha=0.2, lw=0)
                ax.plot(GRID_D, np.median(ideal, axis=0), color=colour, lw=1.2,
                        label=f"{n}x{n} views, point at {d:g} D: {len(ideal)} eyes, median and 5–95 %")
            elif ideal is not None:
                for i, c in enumerate(ideal):
                    ax.plot(GRID_D, c, color=colour, alpha=0.35, lw=1,
                            label=f"{n}x{n} views, point at {d:g} D" if i == 0 else None)
            arr = curves.get(("array", n, d))
            if arr is not None:
                ax.plot(GRID_D, arr[0], color=colour, lw=2.2, ls="--",
                        label=f"whole array (eye 0), point at {d:g} D")
            ax.axvline(d, color=colour, lw=0.8, ls=":")
        ax.axvline(lenslet_plane, color="k", lw=0.8)
        ax.axvspan(2.0 - 1.5, 2.0 + 1.5, color="0.93", zorder=-1)
        ax.text(lenslet_plane + 0.05, ax.get_ylim()[1] * 0.95, "lenslet plane", fontsize=8, va="top")
        ax.set_title(f"phone panel, {n}x{n} views (N = {0.877 if n == 2 else 0.39:.2f})", fontsize=10)
        ax.set_xlabel("accommodation (D); grey: the old ±1.5 D window around the CDP")
        ax.set_ylabel("VSOTF (550 nm)")
        ax.legend(fontsize=7)
    fig.suptitle("The phone class on a 0–6 D window: idealised views (solid: each eye, or a population's "
                 "median and 5–95 %) and the whole array (dashed, eye 0 centred on a pixel zone)", fontsize=10)
    fig.text(0.5, 0.01, "What the n×n idealisation carries: the resolution (the pixel's angle: 1.55 and 1.03 cpd "
             "on the CDP). Not the accommodation: each lit pixel's viewing zone at the eye (6.6, 9.9 mm) is wider "
             "than the pupil,\nso the pupil holds no n×n views; every curve, either model, is flat "
             "(VSOTF ≤ 0.024) and peaks away from the point, mostly beyond the lenslet plane; a point at 3 D lies in front "
             "of the lenslets (2.86 D) and is not rendered.", ha="center", va="bottom", fontsize=7.5)
    fig.tight_layout(rect=(0, 0.08, 1, 1))
    fig.savefig(path, dpi=110)


def fig_from_files(out: Path) -> None:
    """Redraw phone_array.png from phone_curves.npz (no computing)."""
    z = np.load(out / "phone_curves.npz")
    curves = {}
    for key in z.files:
        if key == "grid_D":
            continue
        model, views, depth = key.split("_")
        curves[(model, int(views.split("x")[0]), float(depth[:-1]))] = np.atleast_2d(z[key])
    fig_phone(curves, [], out / "phone_array.png")
