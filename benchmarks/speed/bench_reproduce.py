"""Time `lfjax reproduce` (the paper's full default study) against its transform floor.

Three runs of the command line in fresh processes (cold compilation cache, warm, warm without
alternatives), then the floor: the bare batched transforms, timed warm, in one jitted call
per band. The floor counts what the job cannot avoid computing: per wavelength an fft2 of
each pupil field (the matrix Fourier transform for the layouts the study gives it,
``StudyConfig.mft_pupil_samples``) and |.|^2, per wavelength band one rfft2 of the band's
summed PSF, for the main study and for the modelling alternatives (the reduced study, once
per variant and for its baseline). Each band's cost is one chunk of 64 fields timed (best of
9) and scaled to the study's count: read it to ±15 % (benchmarks/RESULTS.md §9).

Run:  .venv/bin/python benchmarks/speed/bench_reproduce.py [--keep-report REPORT.md |
      --floor-only [claims|vsotf]]

The floor is taken on each layout's own spectrum (the ``claims`` plan by default), and
counts the three states each continuous peak evaluates beyond the grid (``--floor-only``
prints it with and without them).
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


def _band_floor(eyes_n: int, n_states: int, n_sub: int, bands, mft_samples=None) -> float:
    """Seconds of the bare transforms for one layout: per wavelength an fft2 of each complex
    pupil field (or, with ``mft_samples``, the matrix Fourier transform of an
    mft_samples² field onto the band's n² angles) and |.|^2 summed over the band; per band
    one rfft2 of the summed PSF per (eye, state, view) — what optics._elemental_otfs_band
    does, without anything else."""
    total = 0.0
    for start, stop, n in bands:
        n_wl = stop - start
        fields = eyes_n * n_states * n_sub  # one summed PSF per (eye, state, view)
        chunk = min(fields, 64)
        m = n if mft_samples is None else int(mft_samples)

        @jax.jit
        def work(x):
            def one(acc, i):
                # the field depends on the wavelength index, or XLA hoists the transform out
                # of the loop (computing it once)
                field = x * (1.0 + 1e-3 * i).astype(x.dtype)
                if mft_samples is None:
                    spec = jnp.fft.fft2(field)
                else:
                    kernel = jnp.exp(1j * (1.0 + 1e-3 * i) * jnp.outer(
                        jnp.arange(n, dtype=jnp.float32), jnp.arange(m, dtype=jnp.float32)))
                    spec = jnp.einsum("jy,...yx,mx->...jm", kernel, field, kernel,
                                      precision=jax.lax.Precision.HIGHEST)
                return acc + jnp.real(spec) ** 2 + jnp.imag(spec) ** 2, None

            psf, _ = jax.lax.scan(one, jnp.zeros((x.shape[0], n, n), jnp.float32),
                                  jnp.arange(n_wl, dtype=jnp.float32))
            return jnp.fft.rfft2(psf)

        x = jnp.ones((chunk, m, m), jnp.complex64)
        work(x).block_until_ready()
        # one chunk, timed warm and extrapolated: the best of 9 (3 varied by up to 2x per run)
        best = min(_timed(lambda: work(x).block_until_ready()) for _ in range(9))
        total += best * fields / chunk
    return total


PEAK_STATES = 3
"""States each (eye, depth)'s continuous peak evaluates beyond the grid: ``lfjax reproduce``
refines its VSOTF peaks with ``"local"`` (lfjax.vision.peak_refinement.LOCAL_OFFSETS_D)."""


def _study_floor(config, label: str, repeat: int = 1, peaks: bool = True
                 ) -> tuple[float, dict, list[str]]:
    """Floor of one study configuration (every layout, every state of each depth's window
    and, with ``peaks``, the peak states), on each layout's own spectrum (planned for the
    claims, or fixed by the config). Returns (seconds, {layout: wavelength step nm}, lines)."""
    import lfjax
    from lfjax.reproduce.config import planned_sampling, study_eyes
    from lfjax.base.sampling import wavelength_bands

    eyes, _ = study_eyes(config)
    total, steps, lines = 0.0, {}, []
    for name, layout in lfjax.model.layouts.paper_layouts(config.pupil_diameter_mm).items():
        depths = (np.array([config.cdp_D]) if name == "natural"
                  else np.asarray(config.depths_D, float))
        sampling, wavelengths = planned_sampling(eyes, layout, depths, config, config.options)
        steps[name] = float(wavelengths[1] - wavelengths[0]) if wavelengths.size > 1 else 100.0
        mft = sampling.mft_pupil_samples if sampling.transform == "mft" else None
        grid = np.asarray(config.accommodation_D, float)
        used = np.any(np.abs(grid[None, :] - depths[:, None]) <= config.window_D + 1e-9, axis=0)
        n_states = int(used.sum()) + (PEAK_STATES * depths.size if peaks else 0)
        bands = wavelength_bands(wavelengths, layout.window_diameter_mm,
                                 config.pupil_diameter_mm, sampling)
        t = repeat * _band_floor(eyes.n_eyes, n_states, layout.n_subapertures, bands, mft)
        lines.append(f"{label} {name}: {wavelengths.size} wavelengths ({steps[name]:g} nm), "
                     f"df {sampling.freq_step_cpd:.4g} cpd, bands {bands}, "
                     + (f"MFT {mft} pupil samples, " if mft else "")
                     + f"{int(used.sum())} grid states"
                     + (f" + {PEAK_STATES * depths.size} peak states" if peaks else "")
                     + f", {layout.n_subapertures} views"
                     + (f", x {repeat} runs" if repeat > 1 else "") + f": {t:.2f} s")
        total += t
    return total, steps, lines


def floor_seconds(accuracy: str = "claims", peaks: bool = True
                  ) -> tuple[float, float, list[str]]:
    """FFT floor of the main study and of the modelling alternatives (the reduced study on
    the main study's wavelengths, once for the baseline and once per alternative)."""
    from lfjax.reproduce.alternatives import ALTERNATIVES
    from lfjax.reproduce.config import StudyConfig

    config = StudyConfig(accuracy=accuracy)
    main, steps, lines = _study_floor(config, "main", peaks=peaks)
    alternatives, _, more = _study_floor(config.reduced(steps), "alternatives",
                                         repeat=1 + len(ALTERNATIVES), peaks=peaks)
    return main, alternatives, lines + more


def _timed(fn) -> float:
    t0 = time.perf_counter()
    fn()
    return time.perf_counter() - t0


def run_cli(cache_dir: Path, extra: list[str],
            keep_report: Path | None = None) -> tuple[float, str]:
    """Wall time of ``lfjax reproduce`` in a fresh process, and its REPORT.md timing line
    (the whole REPORT.md is copied to ``keep_report`` when given)."""
    out = Path(tempfile.mkdtemp()) / "study"
    env = dict(os.environ, LFJAX_CACHE_DIR=str(cache_dir))
    env.pop("XLA_FLAGS", None)
    cmd = [sys.executable, "-m", "lfjax.cli", "reproduce", "--out", str(out), "--no-progress",
           *extra]
    t0 = time.perf_counter()
    subprocess.run(cmd, check=True, env=env, stdout=subprocess.DEVNULL)
    elapsed = time.perf_counter() - t0
    report = (out / "REPORT.md").read_text()
    if keep_report is not None:
        keep_report.write_text(report)
    timings = next((line for line in report.splitlines() if line.startswith("Timings")), "")
    shutil.rmtree(out.parent, ignore_errors=True)
    return elapsed, timings


def main():
    keep = None
    if len(sys.argv) == 3 and sys.argv[1] == "--keep-report":
        keep = Path(sys.argv[2])  # the cold run's REPORT.md (to compare verdicts across machines)
    if len(sys.argv) >= 2 and sys.argv[1] == "--floor-only":
        accuracy = sys.argv[2] if len(sys.argv) > 2 else "claims"
        print(f"command: .venv/bin/python benchmarks/speed/bench_reproduce.py --floor-only {accuracy}")
        print(f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores, "
              f"jax {jax.__version__}, {time.strftime('%Y-%m-%d %H:%M')}", flush=True)
        for peaks in (False, True):
            main_floor, alt_floor, lines = floor_seconds(accuracy, peaks)
            print("\n".join(lines))
            print(f"FFT floor ({accuracy} plan, {'with' if peaks else 'without'} peak states): "
                  f"main {main_floor:.1f} s + alternatives {alt_floor:.1f} s "
                  f"= {main_floor + alt_floor:.1f} s", flush=True)
        return
    print("command: .venv/bin/python benchmarks/speed/bench_reproduce.py")
    print(f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores, "
          f"jax {jax.__version__}, devices {jax.devices()}, {time.strftime('%Y-%m-%d %H:%M')}",
          flush=True)
    cache = Path(tempfile.mkdtemp())
    runs = {}
    for label, extra in (("cold cache, full", []), ("warm cache, full", []),
                         ("warm cache, --no-alternatives", ["--no-alternatives"])):
        runs[label] = run_cli(cache, extra, keep if label.startswith("cold") else None)
        # printed as each run ends: a run cut short by a time limit still leaves the others
        print(f"lfjax reproduce ({label}): {runs[label][0]:.1f} s\n  {runs[label][1]}",
              flush=True)
    shutil.rmtree(cache, ignore_errors=True)
    floors = {}
    for peaks in (False, True):
        main_floor, alt_floor, lines = floor_seconds("claims", peaks)
        for line in lines:
            print("  floor", line)
        label = "grid states and peak states" if peaks else "grid states only"
        floors[label] = main_floor + alt_floor
        print(f"FFT floor ({label}): main study {main_floor:.1f} s + alternatives "
              f"{alt_floor:.1f} s = {floors[label]:.1f} s", flush=True)
    for label, (t, timings) in runs.items():
        print(f"lfjax reproduce ({label}): {t:.1f} s = "
              + ", ".join(f"{t / f:.2f} x floor ({name})" for name, f in floors.items()))
        print(f"  {timings}")

if __name__ == "__main__":
    main()
