"""Does lfjax give the CPU's numbers on an accelerator? Through-focus on a small scene, saved
or compared.

On NVIDIA GPUs since Ampere, JAX computes float32 matrix products in TF32 (10-bit mantissa)
unless told otherwise; lfjax asks for full precision in every product (tests/test_precision.py).
This script measures what that is worth: it computes the VSOTF, Strehl ratio and continuous
VSOTF peaks of 3 seeded eyes for the natural view, 2×2 and 4×4 (5 depths, the 0–5 D grid with
a ±1 D window, 7 wavelengths, "local" peaks), saves them, and compares a run on another
device against the saved ones.

    .venv/bin/python benchmarks/validation/device_precision.py --save ref_cpu.npz   # on the CPU
    python3 benchmarks/validation/device_precision.py --compare ref_cpu.npz         # on the GPU
"""

from __future__ import annotations

import argparse
import time

import jax
import numpy as np

import lfjax
from lfjax.vision.focus import through_focus
from lfjax.vision.peak_options import PeakOptions
from lfjax.vision.prepare import States

LAYOUTS = ("natural", "2x2", "4x4")


def compute() -> dict[str, np.ndarray]:
    eyes = lfjax.sample_eyes(0, 3)
    spectrum = lfjax.make_spectrum(np.arange(400.0, 701.0, 50.0))
    grid = np.round(np.arange(0, 26) * 0.2, 9)
    layouts = lfjax.model.layouts.paper_layouts(3.0)
    out = {"zernike_um": np.asarray(eyes.zernike_um)}
    for name in LAYOUTS:
        depths = [2.0] if name == "natural" else [0.5, 1.0, 2.0, 3.0, 3.5]
        t0 = time.perf_counter()
        tf = through_focus(
            eyes,
            layouts[name],
            States.grid(grid, depths_D=depths, window_D=1.0),
            spectrum=spectrum,
            peaks=PeakOptions(metrics=("vsotf",), method="local", second_peaks=False),
        )
        out[f"{name}_vsotf"] = np.asarray(tf.vsotf)
        out[f"{name}_strehl"] = np.asarray(tf.strehl)
        out[f"{name}_peak_D"] = np.asarray(tf.peaks["vsotf"].accommodation_D)
        out[f"{name}_grid_peak_D"] = tf.predicted_accommodation_D("vsotf")
        print(f"{name}: {time.perf_counter() - t0:.1f} s (incl. compilation)", flush=True)
    return out


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--save", help="write the results to this .npz")
    ap.add_argument("--compare", help="compare with the results in this .npz")
    args = ap.parse_args()
    print(f"jax {jax.__version__}, devices {jax.devices()}, lfjax from {lfjax.__file__}",
          flush=True)
    now = compute()
    if args.save:
        np.savez(args.save, **now)
    if args.compare:
        ref = dict(np.load(args.compare))
        dz = np.max(np.abs(now["zernike_um"] - ref["zernike_um"]))
        print(f"eyes' Zernike coefficients: max |Δ| {dz:.1e} um")
        for name in LAYOUTS:
            dv = np.nanmax(np.abs(now[f"{name}_vsotf"] - ref[f"{name}_vsotf"]))
            ds = np.nanmax(np.abs(now[f"{name}_strehl"] - ref[f"{name}_strehl"]))
            dp = np.nanmax(np.abs(now[f"{name}_peak_D"] - ref[f"{name}_peak_D"]))
            same = np.mean(now[f"{name}_grid_peak_D"] == ref[f"{name}_grid_peak_D"])
            print(f"{name}: max |ΔVSOTF| {dv:.1e}, max |ΔStrehl| {ds:.1e}, continuous peaks "
                  f"max |Δ| {dp:.1e} D, grid peaks equal {same:.0%}", flush=True)


if __name__ == "__main__":
    main()
