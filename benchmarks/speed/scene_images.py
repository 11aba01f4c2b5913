"""Retinal image of a 512×512 three-primary scene with 8 layers, warm: the issue's ≤ 30 s on
2 cores. Times the whole call (OTFs of 8 depths × 3 primaries + compositing with occlusion)
for natural viewing and a 3×3 display, the accommodation given (its prediction, a separate
through-focus computation, is timed once on its own), after one warm-up call.

    python benchmarks/speed/scene_images.py [--size 512] [--layers 8] [--repeats 2]
"""

from __future__ import annotations

import argparse
import resource
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import jax  # noqa: E402
import numpy as np  # noqa: E402

from _common import header  # noqa: E402
from lfjax.model.eyes import average_eye  # noqa: E402
from lfjax.model.layouts import grid_layout  # noqa: E402
from lfjax.vision import scene_images as si  # noqa: E402


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("--size", type=int, default=512)
    p.add_argument("--layers", type=int, default=8)
    p.add_argument("--repeats", type=int, default=2)
    p.add_argument("--pixel-arcmin", type=float, default=1.0)
    args = p.parse_args()
    header("retinal image of a scene with depth")
    eye = average_eye(3.0)
    img, _ = si.demo_scene(args.size)
    y = np.linspace(0, 1, args.size)[:, None] * np.ones((1, args.size))
    depth = 0.5 + 4.5 * y  # a floor receding: every layer populated
    scene = si.LayeredScene.from_depth_map(img, depth, args.pixel_arcmin, args.layers)
    for name, display in (("natural", "natural"), ("3x3", grid_layout(3))):
        t0 = time.perf_counter()
        first = si.retinal_scene(eye, scene, display=display, fixation_D=2.0)
        jax.block_until_ready(first["retina"])
        cold = time.perf_counter() - t0
        warm = []
        for _ in range(args.repeats):
            t0 = time.perf_counter()
            out = si.retinal_scene(eye, scene, display=display,
                                   accommodation_D=first["accommodation_D"])
            jax.block_until_ready(out["retina"])
            warm.append(time.perf_counter() - t0)
        print(f"{name:8s} {args.size}x{args.size}, {len(out['depths_D'])} layers, 3 primaries: "
              f"first call (with the accommodation prediction, compiling) {cold:.1f} s, "
              f"warm {min(warm):.2f} s (min of {args.repeats}; all {[round(w, 2) for w in warm]}), "
              f"accommodation {first['accommodation_D']:.3f} D, df {out['freq_step_cpd']:.3f} cpd")
    rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(f"peak RSS {rss:.0f} MiB")


if __name__ == "__main__":
    main()
