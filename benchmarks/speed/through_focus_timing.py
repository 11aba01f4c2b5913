"""Warm time of one through-focus call, to compare commits in one sitting.

Scene: 2×2 viewpoints, eleven eyes (seed 0 and the average eye), 9 rendered depths 0–4 D,
accommodation 0–5 D in 0.2 D steps within ±2 D, 400–700 nm in 10 nm steps, df 0.8409 cpd.
Prints the first call (compilation included) and the best of two later calls, grid only
and with ``local`` continuous VSOTF peaks. Written against the public API of every commit
since RESULTS §9, so that each commit can run it from its own worktree:

    git worktree add /tmp/c COMMIT && (cd /tmp/c && PYTHONPATH=. python PATH/through_focus_timing.py)
"""

from __future__ import annotations

import time

import jax
import numpy as np

import lfjax
from lfjax.model.eyes import append_average_eye
from lfjax.vision.focus import through_focus

EYES = append_average_eye(lfjax.sample_eyes(0, 10))
LAYOUT = lfjax.grid_layout(2, 3.0)
DEPTHS_D = np.round(2.0 + np.arange(-2, 2.01, 0.5), 9)
ACCOMMODATION_D = np.round(np.arange(0, 5.001, 0.2), 9)
SPECTRUM = lfjax.make_spectrum(np.arange(400, 700.1, 10.0))
SAMPLING = lfjax.Sampling(0.8408964152537145)
LOCAL = lfjax.PeakOptions(metrics=("vsotf",), method="local", second_peaks=False)


def seconds(peaks: lfjax.PeakOptions = lfjax.PeakOptions()) -> float:
    """Wall time (s) of one through_focus call, results ready."""
    t0 = time.perf_counter()
    tf = through_focus(EYES, LAYOUT, lfjax.States.grid(ACCOMMODATION_D, DEPTHS_D, window_D=2.0),
                       lfjax.Viewing(pupil_diameter_mm=3.0, cdp_D=2.0), spectrum=SPECTRUM,
                       sampling=SAMPLING, peaks=peaks)
    jax.block_until_ready(tf.vsotf)
    return time.perf_counter() - t0


if __name__ == "__main__":
    grid_cold = seconds()
    grid_warm = min(seconds() for _ in range(2))
    local_cold = seconds(LOCAL)
    local_warm = min(seconds(LOCAL) for _ in range(2))
    print(f"grid: cold {grid_cold:.1f} warm {grid_warm:.2f} | "
          f"local: cold {local_cold:.1f} warm {local_warm:.2f}")
