"""What two CPU cores give `lfjax reproduce` when its layouts run in threads.

Three measurements, each side by side in one process on a warm compilation cache:

1. **Programs in two threads.** One layout's alternatives (2x2, reduced set, two variants)
   computed once, then twice at the same time in two threads: the ratio of the two walls is
   1 when the threads fill both cores, 2 when they wait for each other.
2. **The same with the host-side Zernike sizes in eager JAX** (the guards' wavefront basis
   evaluated with ``jax.numpy``, as before commit 5c740bc): eager operations from one
   thread queue behind the other thread's running program.
3. **Compilation in two threads.** Four distinct synthetic programs (250 FFT round trips on
   32 × 32) compiled one after another, then two threads at a time: XLA's compilation does
   not overlap across threads, so the cold run's compile time is not shortened by them.

    PYTHONPATH=. .venv/bin/python benchmarks/speed/threads.py
"""

from __future__ import annotations

import argparse
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

sys.path.insert(1, str(Path(__file__).resolve().parents[1]))  # benchmarks/: _common


def concurrency(eager_zernike: bool) -> tuple[float, float]:
    import jax.numpy as jnp
    import numpy as np

    import lfjax.base.sampling as sampling_module
    from lfjax.base import zernike
    from lfjax.reproduce.alternatives import ALTERNATIVES
    from lfjax.reproduce.config import StudyConfig
    from lfjax.reproduce.study import _run_studies

    if eager_zernike:
        sampling_module.zernike_basis_host = lambda n, x, y: np.asarray(
            zernike.zernike_basis(n, jnp.asarray(x), jnp.asarray(y)), float)
    config = StudyConfig(layouts=("2x2",))
    reduced = config.reduced(None)
    variants = {n: config.options.replace(**c) for n, c in list(ALTERNATIVES.items())[:2]}

    def one(_):
        return _run_studies(reduced, variants, None, True, workers=1)

    one(0)  # compiled, planned, exported
    t0 = time.perf_counter()
    one(0)
    single = time.perf_counter() - t0
    t0 = time.perf_counter()
    with ThreadPoolExecutor(2) as pool:
        list(pool.map(one, range(2)))
    return single, time.perf_counter() - t0


def compile_in_threads() -> tuple[float, float]:
    import jax
    import jax.numpy as jnp

    def lowered(k, size):
        def f(x):
            for i in range(250):
                x = jnp.fft.ifft2(jnp.fft.fft2(x) * (jnp.cos(x.real * (i + k)) + 1j)) + 0.1 * jnp.sin(x)
            return x
        return jax.jit(f).lower(jnp.ones((size, size), jnp.complex64))

    first = [lowered(k, 32) for k in range(4)]
    second = [lowered(k, 33) for k in range(4)]  # other shapes: nothing shared with the first
    t0 = time.perf_counter()
    for program in first:
        program.compile()
    sequential = time.perf_counter() - t0
    t0 = time.perf_counter()
    with ThreadPoolExecutor(2) as pool:
        list(pool.map(lambda p: p.compile(), second))
    return sequential, time.perf_counter() - t0


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--skip-compile", action="store_true")
    args = p.parse_args()
    from _common import header

    header("Layouts in threads: programs, eager host work and compilation on two cores")
    from lfjax.cli.cache import enable_compilation_cache

    enable_compilation_cache()
    single, two = concurrency(False)
    print(f"1. host sizes in NumPy:  one batch {single:.2f} s, two at once in two threads "
          f"{two:.2f} s (ratio {two / single:.2f}; 1 = both cores filled, 2 = serial)", flush=True)
    single, two = concurrency(True)
    print(f"2. host sizes eager JAX: one batch {single:.2f} s, two at once in two threads "
          f"{two:.2f} s (ratio {two / single:.2f})", flush=True)
    if not args.skip_compile:
        sequential, threaded = compile_in_threads()
        print(f"3. compiling four programs: one after another {sequential:.2f} s, two threads "
              f"{threaded:.2f} s (ratio {threaded / sequential:.2f})", flush=True)


if __name__ == "__main__":
    main()
