"""Speed against accuracy for a reduced paper study (issue #5 chart).

Configuration: 2 virtual eyes + average eye, 2x2 viewpoints in a 3 mm pupil, CDP 2 D,
rendered depths 1, 2, 3 D, accommodation 0-4 D in 0.2 D steps within +-1 D of each depth.
Reference: float64, frequency step a quarter of the planner's, 5 nm wavelength steps, the
planner's aperture edge. The planner is asked for VSOTF error <= 1e-3 on this scene. Each other case changes one knob from the planner's choice.
Knobs: frequency step (field), wavelength step (5/10/20/50 nm), float32 vs float64,
aperture edge width. Error = max |VSOTF - VSOTF_ref| over allowed states, and the largest
change of predicted accommodation (D). Time = warm wall time of one through_focus call.

Run:  .venv/bin/python benchmarks/speed/speed_accuracy.py   (writes speed_accuracy.csv/.png here)
"""

from __future__ import annotations

import csv
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent


def run_case(df: float, wl_step: float, x64: bool, edge: float, check: bool = True,
             transform: str = "fft", mft_samples: int = 64, max_order: int = 4):
    import jax

    jax.config.update("jax_enable_x64", x64)
    import lfjax
    from lfjax.vision.focus import through_focus

    eyes = lfjax.sample_eyes(1, 2)
    eyes = lfjax.model.eyes.make_eyes(
        np.concatenate([np.asarray(eyes.zernike_um), np.asarray(lfjax.average_eye().zernike_um)]),
        3.0,
    )
    n_keep = (max_order + 1) * (max_order + 2) // 2
    eyes = lfjax.model.eyes.make_eyes(np.asarray(eyes.zernike_um)[:, :n_keep], 3.0)
    layout = lfjax.grid_layout(2, 3.0)
    depths = [1.0, 2.0, 3.0]
    acc = np.round(np.arange(0.0, 4.01, 0.2), 9)
    spectrum = lfjax.make_spectrum(np.arange(400.0, 700.1, wl_step))
    sampling = lfjax.Sampling(df, edge_width_samples=edge, transform=transform,
                              mft_pupil_samples=mft_samples)
    states = lfjax.States.grid(acc, depths, window_D=1.0)
    kwargs = dict(spectrum=spectrum, sampling=sampling, check_aliasing=check)
    t0 = time.perf_counter()
    tf = through_focus(eyes, layout, states, **kwargs)
    tf.vsotf.block_until_ready()
    compile_s = time.perf_counter() - t0
    times = []
    for _ in range(2):
        t0 = time.perf_counter()
        tf = through_focus(eyes, layout, states, **kwargs)
        tf.vsotf.block_until_ready()
        times.append(time.perf_counter() - t0)
    return (
        np.asarray(tf.vsotf, float),
        np.asarray(tf.predicted_accommodation_D(), float),
        min(times),
        compile_s,
    )


def child(args):
    df, wl_step, x64, edge = float(args[0]), float(args[1]), args[2] == "1", float(args[3])
    transform, mft_samples, max_order = args[5], int(args[6]), int(args[7])
    vs, peak, t, c = run_case(df, wl_step, x64, edge, check=False, transform=transform,
                              mft_samples=mft_samples, max_order=max_order)
    np.savez(args[4], vsotf=vs, peak=peak, time=t, compile=c)


def main():
    import lfjax
    from lfjax.planner import PlanScene, Targets, plan_sampling

    eyes = lfjax.sample_eyes(1, 2)
    zernike = np.concatenate([np.asarray(eyes.zernike_um), np.asarray(lfjax.average_eye().zernike_um)])
    plan = plan_sampling(PlanScene(
        lfjax.grid_layout(2, 3.0), depths_D=[1.0, 2.0, 3.0],
        accommodation_D=np.round(np.arange(0.0, 4.01, 0.2), 9), accommodation_window_D=1.0,
        wavelengths_nm=np.arange(400.0, 700.1, 10.0), eyes=lfjax.make_eyes(zernike, 3.0),
    ), Targets(vsotf=1e-3))
    df0 = plan.sampling.freq_step_cpd
    print(plan.summary())
    # (name, df, wavelength step, x64, edge, transform, mft samples, Zernike order)
    e0 = plan.sampling.edge_width_samples
    cases = [("reference", df0 / 4, 5.0, True, e0, "fft", 64, 4)]
    for f in (0.5, 0.75, 1.0, 1.25, 1.6):
        cases.append((f"df x{f}", df0 * f, 10.0, False, e0, "fft", 64, 4))
    # the planner's own "one step cheaper" (the next rung of its 2^(1/8) ladder)
    cases.append(("one step cheaper", df0 * 2 ** (1 / 8), 10.0, False, e0, "fft", 64, 4))
    for step in (5.0, 20.0, 50.0):
        cases.append((f"{step:g} nm", df0, step, False, e0, "fft", 64, 4))
    cases.append(("float64", df0, 10.0, True, e0, "fft", 64, 4))
    cases.append(("edge 0.5", df0, 10.0, False, 0.5, "fft", 64, 4))
    cases.append(("edge 1.0", df0, 10.0, False, 1.0, "fft", 64, 4))
    for n in (32, 64, 128):
        cases.append((f"MFT {n}", df0, 10.0, False, e0, "mft", n, 4))
    for order in (2, 3):
        cases.append((f"Zernike n<={order}", df0, 10.0, False, e0, "fft", 64, order))
    results = {}
    for name, df, step, x64, edge, transform, mft_n, order in cases:
        out = HERE / f"_sa_{len(results)}.npz"
        cmd = [sys.executable, __file__, "--child", str(df), str(step), "1" if x64 else "0",
               str(edge), str(out), transform, str(mft_n), str(order)]
        subprocess.run(cmd, check=True, env=dict(os.environ))
        with np.load(out) as r:
            results[name] = (df, step, x64, edge, r["vsotf"], r["peak"], float(r["time"]),
                             float(r["compile"]))
        out.unlink()
        print(f"{name:12s} df={df:.3f} step={step:g} x64={x64} edge={edge} "
              f"time={results[name][6]:.2f}s")
    ref_vs, ref_peak = results["reference"][4], results["reference"][5]
    rows = []
    for name, (df, step, x64, edge, vs, peak, t, c) in results.items():
        mask = np.isfinite(ref_vs) & np.isfinite(vs)
        err = float(np.max(np.abs(vs[mask] - ref_vs[mask])))
        dpeak = float(np.max(np.abs(peak - ref_peak)))
        rows.append(dict(case=name, freq_step_cpd=round(df, 4), wavelength_step_nm=step,
                         float64=x64, edge_width_samples=edge, time_s=round(t, 3),
                         compile_s=round(c, 2), max_abs_vsotf_error=err,
                         max_peak_change_D=dpeak, planner=(name == "df x1.0")))
    with open(HERE / "speed_accuracy.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 5))
    for r in rows:
        if r["case"] == "reference":
            continue
        marker = "*" if r["planner"] else "o"
        ax.scatter(r["time_s"], max(r["max_abs_vsotf_error"], 1e-7), s=160 if r["planner"] else 40,
                   marker=marker, color="C3" if r["planner"] else "C0")
        ax.annotate(r["case"], (r["time_s"], max(r["max_abs_vsotf_error"], 1e-7)),
                    textcoords="offset points", xytext=(4, 4), fontsize=8)
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.axhline(1e-3, color="grey", ls=":", label="target 1e-3")
    ax.set_xlabel("time per through-focus call (s, warm, 2 CPU cores)")
    ax.set_ylabel("max |VSOTF − VSOTF_ref|")
    ax.set_title("lfjax speed vs accuracy (2×2, 3 eyes, 3 depths); ★ = planner")
    ax.legend()
    fig.tight_layout()
    fig.savefig(HERE / "speed_accuracy.png", dpi=110)
    print("wrote", HERE / "speed_accuracy.csv", HERE / "speed_accuracy.png")


if __name__ == "__main__":
    if len(sys.argv) > 1 and sys.argv[1] == "--child":
        child(sys.argv[2:])
    else:
        main()
