"""The default sweep against its transform floor, layout by layout, in one process.

For each (pupil, layout) task of the default sweep (``lfjax sweep --template``, or the
TOML given), on one chunk of eyes, warm (best of ``--repeat``):

* the chunk function with the config's peak method (default ``local``) and with
  ``vertex`` (no state beyond the grid), side by side, so the refinement's share is a ratio
  measured in one sitting;
* the floor: the bare transforms the grid cannot avoid — per (eye, state, view,
  wavelength) an fft2 of the pupil field on its band's window and |.|², summed over the
  band, and one rfft2 of the band's PSF — in one jitted call per band, on the task's own
  bands (the floor of ``bench_reproduce.py``);
* the same floor for the peak states (``lfjax.sweep.guard.refinement_states`` per depth).

Prints seconds per eye and the projection to 1,000 eyes.

Run:  .venv/bin/python benchmarks/speed/sweep_floor.py [CONFIG.toml] [--repeat N]
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import platform
import sys
import tempfile
import time
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np


def _best(fn, repeat: int) -> float:
    fn()
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times)


def transform_floor(n_fields: int, n_sub: int, bands, repeat: int) -> float:
    """Seconds of the bare transforms of ``n_fields`` (eye, state) pairs × ``n_sub`` views
    on ``bands`` ((start, stop, n_fft), …), as the kernel does them: per wavelength a
    complex fft2 of the pupil field and |.|², summed over the band, then one rfft2 of the
    band's PSF (bench_reproduce.py's floor, beside this script); one chunk of at most 64 fields
    timed and scaled."""
    total = 0.0
    for start, stop, n in bands:
        fields = n_fields * n_sub
        chunk = min(fields, 64)
        n_wl = stop - start

        @jax.jit
        def work(x):
            def one(acc, i):
                # the field depends on the wavelength index, or XLA hoists the transform
                spec = jnp.fft.fft2(x * (1.0 + 1e-3 * i).astype(x.dtype))
                return acc + jnp.real(spec) ** 2 + jnp.imag(spec) ** 2, None

            psf, _ = jax.lax.scan(one, jnp.zeros(x.shape, jnp.float32),
                                  jnp.arange(n_wl, dtype=jnp.float32))
            return jnp.fft.rfft2(psf)

        x = (jax.random.normal(jax.random.PRNGKey(0), (chunk, n, n)) + 0j).astype(jnp.complex64)
        total += _best(lambda: work(x).block_until_ready(), repeat) * fields / chunk
    return total


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("config", nargs="?", help="sweep TOML (default: the template)")
    parser.add_argument("--repeat", type=int, default=2)
    args = parser.parse_args()

    from lfjax.sweep import ChunkEvaluator, build_tasks, population
    from lfjax.sweep.compute import sweep_spectrum
    from lfjax.sweep.config_files import config_template, load_config
    from lfjax.sweep.guard import refinement_states

    if args.config is None:
        path = Path(tempfile.mkdtemp()) / "sweep.toml"
        path.write_text(config_template())
    else:
        path = Path(args.config)
    config = load_config(path)
    print("command: .venv/bin/python benchmarks/speed/sweep_floor.py"
          + (f" {args.config}" if args.config else "") + f" --repeat {args.repeat}")
    print(f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores, "
          f"jax {jax.__version__}, {time.strftime('%Y-%m-%d %H:%M')}", flush=True)
    eyes, _ = population(config)
    spectrum = sweep_spectrum(config)
    tasks = build_tasks(config, eyes, spectrum)
    methods = (config.peak_method, "vertex")
    evaluators = {m: ChunkEvaluator(dataclasses.replace(config, peak_method=m),
                                    eyes.measured_pupil_mm, spectrum) for m in methods}
    size = int(config.chunk_size)
    z = np.asarray(eyes.zernike_um)[:size]
    print(f"{spectrum.n_wavelengths} wavelengths, chunk of {size} eyes, peaks "
          f"{config.peak_method} ({refinement_states(config)} states per eye and depth)")
    totals = dict.fromkeys(("method", "vertex", "floor_grid", "floor_peaks"), 0.0)
    for task in tasks:
        timed = {m: _best(lambda ev=ev: ev.evaluate(task, z), args.repeat) / size
                 for m, ev in evaluators.items()}
        pc = task.pipeline_config
        n_sub = int(task.layout.n_subapertures)
        n_states = int(task.accommodation.states_D.shape[0])
        refined = len(task.depth_slots) * refinement_states(config)
        floor_grid = transform_floor(n_states, n_sub, pc.bands, args.repeat)
        floor_peaks = transform_floor(refined, n_sub, pc.bands, args.repeat) if refined else 0.0
        print(f"{task.pupil_mm:g} mm {task.layout_label}: bands {pc.bands}, {n_states} states "
              f"+ {refined} peak states x {n_sub} views | {config.peak_method} "
              f"{timed[config.peak_method]:.3f} s/eye, vertex {timed['vertex']:.3f} s/eye | "
              f"floor grid {floor_grid:.3f} + peaks {floor_peaks:.3f} s/eye", flush=True)
        totals["method"] += timed[config.peak_method]
        totals["vertex"] += timed["vertex"]
        totals["floor_grid"] += floor_grid
        totals["floor_peaks"] += floor_peaks
    floor = totals["floor_grid"] + totals["floor_peaks"]
    print(f"total: {config.peak_method} {totals['method']:.2f} s/eye "
          f"({totals['method'] * 1000 / 60:.0f} min per 1,000 eyes), vertex "
          f"{totals['vertex']:.2f} s/eye ({totals['vertex'] * 1000 / 60:.0f} min); floor grid "
          f"{totals['floor_grid']:.2f} s/eye ({totals['floor_grid'] * 1000 / 60:.0f} min), "
          f"with peak states {floor:.2f} s/eye ({floor * 1000 / 60:.0f} min); "
          f"{config.peak_method} = {totals['method'] / floor:.2f} x its floor")
    sys.stdout.flush()


if __name__ == "__main__":
    main()
