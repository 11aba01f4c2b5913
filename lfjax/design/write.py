"""A design's files: the buildable specification (every number with its unit), the JSON
record with its provenance (:func:`lfjax._version.stamp`) and the drawing of the array."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from lfjax._version import stamp
from lfjax.base.files import atomic_write_text, staged_output
from lfjax.display.panel import Panel
from lfjax.model.layout_files import jsonable
from lfjax.model.layout_plots import draw_layout


# ----------------------------------------------------------------------------- specification


DESIGN_FORMAT = "lfjax-design/1"


def panel_specification(panel: Panel, wavelength_nm: float = 550.0) -> dict:
    """A buildable specification of ``panel``: every number under a key that names its
    unit, as ``{"value": x, "unit": "mm"}``."""
    units = {
        "pixel_pitch_mm": "mm", "pixel_fill": "emitting area fraction", "lenslet_pitch_mm": "mm",
        "lenslet_aperture_mm": "mm", "fill": "aperture/pitch", "focal_length_mm": "mm",
        "gap_mm": "mm", "viewing_distance_mm": "mm", "design_pupil_mm": "mm",
    }
    values = {
        "pixel_pitch_mm": panel.pixel_pitch_mm, "pixel_fill": panel.pixel_fill,
        "lenslet_pitch_mm": panel.lenslet_pitch_mm, "lenslet_aperture_mm": panel.aperture_mm,
        "fill": panel.fill, "focal_length_mm": panel.focal_length_mm, "gap_mm": panel.gap_mm,
        "viewing_distance_mm": panel.distance_mm, "design_pupil_mm": panel.pupil_diameter_mm,
    }
    build = {k: {"value": float(np.asarray(v)), "unit": units[k]} for k, v in values.items()}
    build["pixel_count"] = {"value": list(panel.pixel_count), "unit": "pixels (horizontal, vertical)"}
    build["aperture_shape"] = {"value": panel.aperture, "unit": None}
    derived_units = {
        "cdp_D": "D", "magnification": "unitless", "view_pitch_mm": "mm (in the pupil)",
        "view_diameter_mm": "mm (in the pupil)", "views_across_pupil": "views",
        "views_per_side": "views", "fresnel_number": f"unitless at {wavelength_nm:g} nm",
        "pixel_arcmin": "arcmin", "emitter_arcmin": "arcmin", "lenslet_arcmin": "arcmin",
        "nyquist_cpd": "cpd", "pixel_nyquist_cpd": "cpd", "pixels_per_lenslet": "pixels",
        "eye_box_mm": "mm", "emitter_sweep_mm": "mm (at the eye)", "depth_step_D": "D", "f_number": "unitless", "active_width_mm": "mm",
        "active_height_mm": "mm", "lenslets_horizontal": "lenslets",
        "lenslets_vertical": "lenslets", "field_of_view_h_deg": "degrees",
        "field_of_view_v_deg": "degrees",
    }
    derived = {k: {"value": v, "unit": derived_units[k]} for k, v in panel.summary(wavelength_nm).items()}
    return {"build": build, "derived": derived}


def _score_units(score: dict | None) -> dict | None:
    if score is None:
        return None
    units = {"image_at_peak": "VSOTF (open-pupil reference)", "relative_accommodation_rmse_D": "D",
             "accommodation_rmse_D": "D", "accommodation_gain": "unitless",
             "peak_success_fraction": "fraction", "loss": "objective units", "penalty": "objective units",
             "n_eyes": "eyes", "perceivable_cpd_median": "cpd", "perceivable_cpd_p05": "cpd",
             "perceivable_cpd_p95": "cpd", "perceivable_cpd_by_depth": "cpd (median per depth)"}
    return {k: {"value": v, "unit": units[k]} for k, v in score.items()}


def design_record(result, command: str | None = None) -> dict:
    """``design.json``'s record of an n×n design (a :class:`lfjax.design.report.DesignResult`):
    every count's specification and scores, every number with its unit, the chosen count
    marked, and the provenance stamp (:func:`lfjax._version.stamp`, with ``command``)."""
    best = result.best
    held_out = bool(result.provenance.get("n_test_eyes")) or any(f.test is not None for f in result.fits)
    designs = []
    for f in result.fits:
        designs.append({
            "views_per_side": f.n_per_side,
            "status": f.status, "refused": f.refused, "failed": f.failed,
            "specification": None if f.panel is None else panel_specification(f.panel),
            "start_specification": None if f.start is None else panel_specification(f.start),
            "held_out" if held_out else "training": _score_units(f.score),
            "start_held_out" if held_out else "start_training": _score_units(f.start_test),
            "notes": f.notes, "loss_history": f.history, "fit_time_s": round(f.time_s, 2),
            "unreported": f.unreported,
        })
    record = {
        "format": DESIGN_FORMAT,
        "chosen_views_per_side": None if best is None else best.n_per_side,
        "cdp_D": {"value": result.cdp_D, "unit": "D"},
        "depths_D": {"value": result.depths_D, "unit": "D"},
        "objective": dict(result.objective.as_dict(), name=result.objective.name),
        "constraints": {k: {"value": v, "unit": u} for (k, v), u in zip(
            result.constraints.as_dict().items(), ("mm", "aperture/pitch", "unitless", "unitless", "mm"))},
        "designs": designs,
        "provenance": stamp(**result.provenance, command=command),
    }
    if result.constraints.lens_form is not None:
        record["constraints"]["lens_form"] = {"value": result.constraints.lens_form, "unit": None}
        record["constraints"]["refractive_index"] = {"value": result.constraints.refractive_index,
                                                     "unit": "unitless"}
    return record


def save_design(result, out_dir, command: str | None = None, force: bool = False) -> list[Path]:
    """Write a design's files into ``out_dir``, all or none (staged, then moved into
    place: :func:`~lfjax.base.files.staged_output`; ``force``:
    into a folder with files in it): ``design.json``, ``result.record(command)`` (every
    count's specification and scores, every number with its unit; the chosen count marked),
    and ``design.png``, ``result.figure()`` (the chosen count's lenses and its views in the
    pupil; not written when no count has a panel, e.g. only 1×1, which is refused before it
    is built: ``design.json`` is then the one file). ``result``: an n×n design
    (:class:`lfjax.design.report.DesignResult`) or a lenticular one
    (:class:`lfjax.design.lenticular.LenticularDesign`). Returns the paths."""
    out = Path(out_dir)
    record = result.record(command)
    names = ["design.json"]
    with staged_output(out, force) as stage:  # every file, or none
        atomic_write_text(stage / "design.json", json.dumps(jsonable(record), indent=2) + "\n")
        fig = result.figure()
        if fig is not None:
            try:
                fig.savefig(stage / "design.png", dpi=110)
            finally:
                import matplotlib.pyplot as plt

                plt.close(fig)
            names.append("design.png")
    return [out / name for name in names]


def fig_design(panel: Panel, n_per_side: int):
    """Two panels: the lenslet array in front of the pixels (a 3×3-lenslet patch, side
    view of the gap underneath), and the n×n views in the design pupil."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Circle, Rectangle

    du, a = float(panel.lenslet_pitch_mm), float(panel.aperture_mm)
    p = float(panel.pixel_pitch_mm)
    fig, (ax0, ax1) = plt.subplots(1, 2, figsize=(10, 4.6))
    extent = 1.5 * du
    n_pix = int(math.ceil(2 * extent / p))
    if n_pix <= 400:  # draw the pixel grid where it is visible
        for k in range(n_pix + 1):
            c = -extent + k * p
            ax0.axvline(c, color="0.85", lw=0.4)
            ax0.axhline(c, color="0.85", lw=0.4)
    for i in (-1, 0, 1):
        for j in (-1, 0, 1):
            ax0.add_patch(Rectangle((i * du - du / 2, j * du - du / 2), du, du, fill=False, ec="0.4"))
            shape = (Circle((i * du, j * du), a / 2) if panel.aperture == "circle"
                     else Rectangle((i * du - a / 2, j * du - a / 2), a, a))
            shape.set(fc="tab:blue", alpha=0.35, ec="tab:blue")
            ax0.add_patch(shape)
    ax0.set_xlim(-extent, extent)
    ax0.set_ylim(-extent, extent)
    ax0.set_aspect("equal")
    ax0.set_xlabel("mm on the lenslet plane")
    s = panel.summary()
    ax0.set_title(f"lenslets: pitch {du:.4g} mm, aperture {a:.4g} mm, f {float(panel.focal_length_mm):.4g} mm,\n"
                  f"gap {float(panel.gap_mm):.4g} mm, at {float(panel.distance_mm):.4g} mm; "
                  f"pixels {p * 1000:.3g} µm ({s['pixels_per_lenslet']:.1f} per lenslet)", fontsize=8)
    draw_layout(ax1, panel.layout(n_per_side), panel.pupil_diameter_mm,
                title=f"{n_per_side}x{n_per_side} views in the {panel.pupil_diameter_mm:g} mm pupil: "
                      f"pitch {s['view_pitch_mm']:.3g} mm, CDP {s['cdp_D']:.3g} D,\n"
                      f"Fresnel number {s['fresnel_number']:.3g}, pixel {s['pixel_arcmin']:.3g}', "
                      f"eye box {s['eye_box_mm']:.3g} mm")
    ax1.title.set_fontsize(8)
    fig.tight_layout()
    return fig




__all__ = ["DESIGN_FORMAT", "panel_specification", "design_record", "save_design", "fig_design"]
