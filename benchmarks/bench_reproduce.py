"""Time `lfjax reproduce` (the paper's full default study) against its FFT floor.

The floor is the bare batched FFT work of the main study (all eyes, all layouts, every
accommodation state used, every wavelength on its band's window, every subaperture):
fft2 of the complex pupil field, |.|², rfft2 of the PSF — the transforms lfjax performs —
in one jitted call per band, timed warm. The modelling alternatives in the report are extra
work on top of that (listed separately by the CLI's own stage timings in REPORT.md).

Run:  .venv/bin/python benchmarks/bench_reproduce.py
"""

from __future__ import annotations

import os
import platform
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np


def floor_seconds() -> tuple[float, list[str]]:
    import lfjax
    from lfjax.reproduce.config import StudyConfig, _planned_sampling, study_eyes
    from lfjax.sampling import wavelength_bands

    config = StudyConfig()
    eyes, _ = study_eyes(config)
    wl = np.asarray(config.wavelength_grid_nm, float)
    total, lines = 0.0, []
    for name, layout in lfjax.layouts.paper_layouts(config.pupil_diameter_mm).items():
        depths = np.array([config.cdp_D]) if name == "natural" else (
            config.cdp_D + np.asarray(config.depth_offsets_D, float))
        sampling = _planned_sampling(eyes, layout, depths, config, config.options)
        grid = np.asarray(config.accommodation_D, float)
        used = np.any(np.abs(grid[None, :] - depths[:, None]) <= config.window_D + 1e-9, axis=0)
        n_states = int(used.sum())
        bands = wavelength_bands(wl, layout.window_diameter_mm, config.pupil_diameter_mm, sampling)
        t_layout = 0.0
        for start, stop, n in bands:
            batch = eyes.n_eyes * n_states * layout.n_subapertures * (stop - start)

            @jax.jit
            def work(x):
                spec = jnp.fft.fft2(x)
                psf = jnp.real(spec) ** 2 + jnp.imag(spec) ** 2
                return jnp.sum(jnp.fft.rfft2(psf), axis=0)

            # chunks of at most 256 fields keep memory bounded; time scales linearly
            chunk = min(batch, 256)
            x = jnp.ones((chunk, n, n), jnp.complex64)
            work(x).block_until_ready()
            best = min(
                _timed(lambda: work(x).block_until_ready()) for _ in range(3)
            )
            t_layout += best * batch / chunk
        lines.append(
            f"{name}: df {sampling.freq_step_cpd} cpd, bands {bands}, {n_states} states, "
            f"{layout.n_subapertures} subapertures, floor {t_layout:.1f} s"
        )
        total += t_layout
    return total, lines


def _timed(fn) -> float:
    t0 = time.perf_counter()
    fn()
    return time.perf_counter() - t0


def run_cli(cache_dir: Path, extra: list[str]) -> float:
    out = Path(tempfile.mkdtemp()) / "study"
    env = dict(os.environ, LFJAX_CACHE_DIR=str(cache_dir))
    env.pop("XLA_FLAGS", None)
    cmd = [sys.executable, "-m", "lfjax.cli", "reproduce", "--out", str(out), "--no-progress",
           *extra]
    t0 = time.perf_counter()
    subprocess.run(cmd, check=True, env=env, stdout=subprocess.DEVNULL)
    elapsed = time.perf_counter() - t0
    shutil.rmtree(out.parent, ignore_errors=True)
    return elapsed


def main():
    print("command: .venv/bin/python benchmarks/bench_reproduce.py")
    print(f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores, "
          f"jax {jax.__version__}, {time.strftime('%Y-%m-%d %H:%M')}")
    floor, lines = floor_seconds()
    for line in lines:
        print("  floor", line)
    print(f"FFT floor of the main study: {floor:.1f} s")
    cache = Path(tempfile.mkdtemp())
    for label, extra in (("cold cache, full", []), ("warm cache, full", []),
                         ("warm cache, --no-alternatives", ["--no-alternatives"])):
        t = run_cli(cache, extra)
        print(f"lfjax reproduce ({label}): {t:.1f} s = {t / floor:.2f} x floor")
    shutil.rmtree(cache, ignore_errors=True)


if __name__ == "__main__":
    main()
