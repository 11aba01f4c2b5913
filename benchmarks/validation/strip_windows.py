"""Strips on narrow transforms against the square, pupil-wide windows: same OTFs, less work.

A strip view (a lenticular display's) is as wide as one view along x and as tall as the
pupil along y. ``PipelineConfig.build(widest_view_mm=…)`` gives its wavelength bands
FFTs with fewer columns (the strip's width) than rows (the pupil's height); before, every
strip was transformed on a square window the size of the pupil. For a few strip scenes this
runs :func:`lfjax.vision.orientation.orientation_through_focus` both ways, side by side in
one process — each way called twice, the second call timed (compiled; the work a study
repeats per scene) — and prints the seconds and the largest difference of everything the
HPO study reads.

Run:  PYTHONPATH=. python benchmarks/validation/strip_windows.py [--eyes 8]
"""

from __future__ import annotations

import argparse
import contextlib
import sys
import time
from pathlib import Path

import jax
import numpy as np

sys.path.insert(1, str(Path(__file__).resolve().parents[1]))  # benchmarks/: _common

from _common import header  # noqa: E402

import lfjax.vision.prepare as prepare_module  # noqa: E402
from lfjax.base.sampling import Sampling  # noqa: E402
from lfjax.display.lenticular import strip_display  # noqa: E402
from lfjax.model.eyes import sample_eyes  # noqa: E402
from lfjax.model.spectral import make_spectrum  # noqa: E402
from lfjax.model.strips import strip_layout  # noqa: E402
from lfjax.vision.orientation import BANDS, orientation_through_focus  # noqa: E402
from lfjax.vision.prepare import States
from lfjax.vision.viewing import Viewing

@contextlib.contextmanager
def square_windows():
    """The pipeline as it was: strips on square, pupil-wide windows (the widest view is
    not passed on, so no window is narrowed)."""
    build = prepare_module.PipelineConfig.build

    def square(*args, widest_view_mm=None, **kwargs):
        return build(*args, **kwargs)

    prepare_module.PipelineConfig.build = square
    try:
        yield
    finally:
        prepare_module.PipelineConfig.build = build


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--eyes", type=int, default=8)
    args = parser.parse_args(argv)
    header("Strips on narrow transforms against square windows")
    eyes = sample_eyes(jax.random.PRNGKey(0), args.eyes, 3.0)
    spectrum = make_spectrum([450.0, 550.0, 650.0])
    grid = list(np.arange(0.0, 4.51, 0.5))
    cases = [("1x3 strips", 3, 1.0, {}),
             ("1x2 strips, y defocus -0.83 D, leakage 0.3", 2, 1.0,
              dict(y_defocus_D=-0.83, leakage_weight=0.3)),
             ("1x4 strips, width 1.4 x pitch", 4, 1.4, {})]
    for name, n, ratio, kw in cases:
        layout = strip_layout(n, 3.0, width_mm=ratio * 3.0 / n)
        display = strip_display(layout, **kw)
        out, seconds = {}, {}
        for kind in ("square", "narrow"):
            with square_windows() if kind == "square" else contextlib.nullcontext():
                for _ in range(2):  # the first call compiles
                    t = time.perf_counter()
                    r = orientation_through_focus(
                        eyes,
                        layout,
                        States.grid(grid, [1.0, 2.0, 3.0]),
                        Viewing(pupil_diameter_mm=3.0, cdp_D=2.0, display=display),
                        spectrum=spectrum,
                        sampling=Sampling(0.6),
                        eye_chunk=4,
                    )
                    jax.block_until_ready(r.vsotf)
                    seconds[kind] = time.perf_counter() - t
            out[kind] = r
        a, b = out["square"], out["narrow"]
        d_vsotf = max(float(np.max(np.abs(np.asarray(a.vsotf[i]) - np.asarray(b.vsotf[i]))))
                      for i in range(len(BANDS)))
        d_mtf = max(float(np.max(np.abs(np.asarray(a.mtf_x) - np.asarray(b.mtf_x)))),
                    float(np.max(np.abs(np.asarray(a.mtf_y) - np.asarray(b.mtf_y)))))
        d_peak = max(float(np.max(np.abs(a.peak_D(band) - b.peak_D(band)))) for band in BANDS)
        print(f"{name}: square {seconds['square']:.1f} s, narrow {seconds['narrow']:.1f} s "
              f"(ratio {seconds['square'] / seconds['narrow']:.2f}); largest differences: VSOTF "
              f"{d_vsotf:.1e}, MTF {d_mtf:.1e}, peaks {d_peak:.1e} D", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
