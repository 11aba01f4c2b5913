"""The design report's settings side by side: one panel's held-out report at ``full`` (31
wavelengths, ``local`` peaks), ``fast`` (11 wavelengths, vertex peaks; the default) and
``fit`` (the fit's 550 nm), on the same eyes (RESULTS §21).

    python benchmarks/validation/design_report_setting.py near-eye 2 1 2 20 full,fast,fit [design.json]

Arguments: preset, views per side, depth range (low, high, D), held-out eyes, settings; the
panel is the count's starting array, or the count's fitted panel from a design.json. Prints
per setting the report's time, its sampling, the scores, and the peaks' differences from
the first setting listed (D, per eye and depth).
"""

from __future__ import annotations

import json
import resource
import sys
import time

import numpy as np

from lfjax.cli import cache
from lfjax.design.box import design_problem, panel_from_box, report_problem, start_box, with_display
from lfjax.design.fit import design_cdp_D, design_panel
from lfjax.design.report import perceivable_resolution
from lfjax.design.settings import DesignConstraints
from lfjax.display.panel import Panel
from lfjax.layout_opt import evaluate_layout
from lfjax.model.eyes import Eyes, sample_eyes


def main(argv):
    preset, n, lo, hi, n_test, modes = argv[0], int(argv[1]), float(argv[2]), float(argv[3]), int(argv[4]), argv[5].split(",")
    print("command: python benchmarks/validation/design_report_setting.py " + " ".join(argv), flush=True)
    cache.enable_compilation_cache()
    cdp = design_cdp_D((lo, hi))
    panel = design_panel(preset, cdp)
    depths = np.linspace(lo, hi, 3)
    c = DesignConstraints()
    train, test = sample_eyes(0, 10), sample_eyes(1, n_test)
    planning = Eyes(np.concatenate([np.asarray(train.zernike_um), np.asarray(test.zernike_um)]),
                    train.measured_pupil_mm)  # as fit_design plans (training and held-out eyes)
    problem = design_problem(panel, n, train, depths, cdp, c, None, (550.0,), "fit", planning, None)
    candidate = panel_from_box(start_box(panel, n, cdp, c), panel, n, cdp, c)
    if len(argv) > 6:
        record = json.loads(open(argv[6]).read())
        build = next(d for d in record["designs"] if d["views_per_side"] == n)["specification"]["build"]
        candidate = Panel(*(build[k]["value"] for k in ("pixel_pitch_mm", "lenslet_pitch_mm", "fill",
                                                         "focal_length_mm", "gap_mm", "viewing_distance_mm",
                                                         "pixel_fill")),
                          pixel_count=tuple(build["pixel_count"]["value"]),
                          pupil_diameter_mm=panel.pupil_diameter_mm, aperture=panel.aperture,
                          diffraction=panel.diffraction)
    first = None
    for mode in modes:
        report = report_problem(problem, test, mode)
        t = time.perf_counter()
        ev = evaluate_layout(candidate.layout(n), with_display(report, candidate))
        t_eval = time.perf_counter() - t
        t = time.perf_counter()
        cpd = perceivable_resolution(candidate, n, report, ev["values"]["peak_D"])
        t_cpd = time.perf_counter() - t
        print(f"{mode}: eval {t_eval:.1f} s + perceivable {t_cpd:.1f} s; FFT {report.config.n_fft}, "
              f"df {report.config.freq_step_cpd:.4g} cpd, {np.asarray(report.spectrum.wavelengths_nm).size} "
              f"wavelengths, peaks {report.peak_method}; loss {ev['loss']:.5f}, VSOTF@peak "
              f"{ev['image_at_peak']:.5f}, display's acc. RMSE {ev['relative_accommodation_rmse_D']:.4f} D, "
              f"gain {ev['accommodation_gain']:.3f}, peaks in window {ev['peak_success_fraction']:.3f}, "
              f"perceivable median {np.median(cpd):.3f} cpd; peak RSS "
              f"{resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1e6:.2f} GB", flush=True)
        if first is None:
            first = (mode, ev, cpd)
            continue
        name, ev0, cpd0 = first
        ok = ev["values"]["peak_success"] & ev0["values"]["peak_success"]
        d = np.abs(ev["values"]["peak_D"] - ev0["values"]["peak_D"])[ok]
        print(f"   against {name} (peaks inside the window in both, {ok.sum()} of {ok.size}): "
              f"|d peak| max {d.max():.4f} D, median {np.median(d):.4f} D; d acc. RMSE "
              f"{ev['relative_accommodation_rmse_D'] - ev0['relative_accommodation_rmse_D']:+.4f} D; "
              f"d VSOTF@peak {ev['image_at_peak'] - ev0['image_at_peak']:+.5f}; |d cpd| max "
              f"{np.max(np.abs(cpd - cpd0)):.3f}", flush=True)


if __name__ == "__main__":
    main(sys.argv[1:])
