"""Cost of continuous peaks in through_focus: grid only, 'local' refinement, optimistix Newton.

Scene: 4 seeded eyes, 3×3 views, CDP 2 D, rendered depths 0, 0.5, 1, 2.5, 3 D, the 0–5 D
grid (0.2 D) with a ±1 D window, 5 wavelengths (450–650 nm), guard sampling. First call
(compile + run) and a second call (steady), and the largest difference of each method's
peaks from Newton's (D).

    python benchmarks/speed/bench_peak_cost.py
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import jax
import numpy as np

import lfjax
from lfjax.vision.focus import through_focus

sys.path.insert(1, str(Path(__file__).resolve().parents[1]))  # benchmarks/: _common

from _common import header  # noqa: E402
from lfjax.vision.peak_options import PeakOptions
from lfjax.vision.prepare import States

def main():
    header("continuous-peak cost in through_focus")
    eyes = lfjax.sample_eyes(0, 4)
    spectrum = lfjax.make_spectrum(np.arange(450, 651, 50.0))
    grid = np.round(np.arange(0, 26) * 0.2, 9)
    peaks = {}
    print("| method | first call | second call |")
    print("| --- | --- | --- |")
    for method in ("grid", "local", "newton"):
        times = []
        for _ in range(2):
            t0 = time.perf_counter()
            tf = through_focus(
                eyes,
                lfjax.grid_layout(3),
                States.grid(grid, depths_D=[0.0, 0.5, 1.0, 2.5, 3.0], window_D=1.0),
                spectrum=spectrum,
                peaks=PeakOptions(metrics=("vsotf",), method=method, second_peaks=False),
            )
            jax.block_until_ready(tf.vsotf)
            times.append(time.perf_counter() - t0)
        peaks[method] = tf.continuous_accommodation_D()
        assert bool(np.all(np.asarray(tf.peaks["vsotf"].success))), method
        print(f"| {method} | {times[0]:.2f} s | {times[1]:.2f} s |")
    for method in ("grid", "local"):
        print(f"max |{method} − newton| = {np.abs(peaks[method] - peaks['newton']).max():.2e} D")


if __name__ == "__main__":
    main()
