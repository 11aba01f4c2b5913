"""Issue #2 — polychromatic OTFs per second for one eye, and the FFT floor beside it.

Workload: the Thibos (2002) average eye, natural view (open 3 mm pupil), CDP 2 D, rendered
depth = CDP, 31 wavelengths (400–700 nm / 10 nm, V(λ), LCA, SCE) × 26 accommodation
states (0–5 D / 0.2 D), default ``lfjax.Sampling()`` (df = 1 cpd), float32 (complex64).
The aliasing guard is ON for lfjax (these states pass it at the default sampling).

Floors (the FFT work alone, one jitted batched call each; input fields made before timing):

* ``floor, uniform window``: 31 × 26 fft2 of (L, L) complex64, |·|², rfft2 of the real
  (L, L) result, summed over wavelength, L = the window of the shortest wavelength — the
  transforms of an implementation with one window for every wavelength.
* ``floor, lfjax's windows``: the same, but each wavelength band on the window lfjax itself
  uses for it (``lfjax.base.sampling.wavelength_bands`` where it exists: long wavelengths have a
  smaller OTF support and get a smaller window) — exactly the transforms lfjax performs.

lfjax's time above the floor is the pupil-function evaluation (Zernike basis, SCE, edges,
exp), the spectral sum, the rendering and the host-side guard.

Run:  .venv/bin/python benchmarks/speed/bench_core.py [--repeats 5]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(1, str(Path(__file__).resolve().parents[1]))  # benchmarks/: _common

from _common import (  # noqa: E402
    fmt_s, header, interleaved_min, markdown_table, timed, timed_first,
)


def lfjax_bands(spectrum, window_mm, pupil_mm, sampling):
    """((start, stop, n_fft), …) as lfjax uses them, or one band when lfjax has no banding."""
    wl = np.asarray(spectrum.wavelengths_nm)
    try:
        from lfjax.base.sampling import wavelength_bands
    except ImportError:
        return ((0, wl.size, sampling.window_size(window_mm, float(wl.min()), pupil_mm)),)
    return tuple(tuple(int(v) for v in b) for b in wavelength_bands(wl, window_mm, pupil_mm, sampling))


def make_floor(bands, n_acc, n_sub=1):
    """Jitted fft2 → |·|² → rfft2 over (n_λ_band, n_acc·n_sub, L_b, L_b) fields per band."""
    import jax
    import jax.numpy as jnp

    @jax.jit
    def floor(fields):
        out = []
        for f in fields:
            s = jnp.fft.fft2(f)
            psf = jnp.real(s) ** 2 + jnp.imag(s) ** 2
            out.append(jnp.sum(jnp.fft.rfft2(psf), axis=0))
        return out

    return floor


def make_fields(bands, n_batch, pupil_window, seed=0):
    import jax

    rng = np.random.default_rng(seed)
    fields = []
    for start, stop, n_fft in bands:
        n_p = pupil_window(n_fft)
        f = np.zeros((stop - start, n_batch, n_fft, n_fft), np.complex64)
        f[..., :n_p, :n_p] = (
            rng.standard_normal((stop - start, n_batch, n_p, n_p))
            + 1j * rng.standard_normal((stop - start, n_batch, n_p, n_p))
        ).astype(np.complex64)
        fields.append(jax.device_put(f))
    return fields


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=5)
    args = ap.parse_args(argv)
    header("bench_core: polychromatic OTFs/s (issue #2)")

    import jax.numpy as jnp

    import lfjax
    from lfjax.kernel.optics import pupil_window_size
    from lfjax.model.spectral import make_spectrum

    eye = lfjax.average_eye(3.0)
    acc = np.round(np.arange(0.0, 5.01, 0.2), 9)
    spectrum = make_spectrum()
    sampling = lfjax.Sampling()
    n_wl, n_acc = spectrum.n_wavelengths, acc.size
    n_fft = sampling.window_size(3.0, float(np.min(spectrum.wavelengths_nm)), 3.0)
    bands = lfjax_bands(spectrum, 3.0, 3.0, sampling)
    uniform = ((0, n_wl, n_fft),)
    print(
        f"workload: 1 eye, natural view (3 mm), {n_wl} wavelengths x {n_acc} accommodation "
        f"states (0-5 D), CDP 2 D, df = {sampling.freq_step_cpd} cpd, "
        f"field = {sampling.field_arcmin:.0f} arcmin, aliasing guard ON, float32"
    )
    print(f"windows : uniform L = {n_fft} (n_pupil = {pupil_window_size(n_fft, sampling)}); "
          f"lfjax's bands (start, stop, L) = {bands}")

    def run_lfjax():
        return lfjax.polychromatic_otf(
            eye,
            acc,
            lfjax.Viewing(pupil_diameter_mm=3.0, cdp_D=2.0),
            spectrum=spectrum,
            sampling=sampling,
            check_aliasing=True,
        ).otf

    t_first, c_first, otf = timed_first(run_lfjax)
    assert otf.shape[-3:] == (n_acc, n_fft, n_fft // 2 + 1), otf.shape
    assert bool(jnp.all(jnp.isfinite(otf)))

    pw = lambda n: pupil_window_size(n, sampling)  # noqa: E731
    floor_u, fields_u = make_floor(uniform, n_acc), make_fields(uniform, n_acc, pw)
    floor_b, fields_b = make_floor(bands, n_acc), make_fields(bands, n_acc, pw, seed=1)
    t_fu_first, c_fu, _ = timed_first(floor_u, fields_u)
    t_fb_first, c_fb, _ = timed_first(floor_b, fields_b)

    best = interleaved_min(
        {
            "lfjax": run_lfjax,
            "floor_uniform": lambda: floor_u(fields_u),
            "floor_bands": lambda: floor_b(fields_b),
        },
        args.repeats,
    )
    t_l, t_fu, t_fb = best["lfjax"], best["floor_uniform"], best["floor_bands"]
    n_tr = n_wl * n_acc
    first = {"lfjax": t_first, "floor_uniform": t_fu_first, "floor_bands": t_fb_first}
    comp = {"lfjax": c_first, "floor_uniform": c_fu, "floor_bands": c_fb}
    names = {
        "lfjax": "lfjax.polychromatic_otf (guard on)",
        "floor_uniform": f"floor, uniform window ({n_tr}× fft2+rfft2 of {n_fft}²)",
        "floor_bands": f"floor, lfjax's windows {[b[2] for b in bands]}",
    }
    rows = []
    for k in ("lfjax", "floor_uniform", "floor_bands"):
        rows.append({
            "what": names[k],
            "steady (min)": fmt_s(best[k]),
            "first call": fmt_s(first[k]),
            "compile (measured)": fmt_s(comp[k]),
            "poly OTFs/s": f"{n_acc / best[k]:.1f}",
            "mono OTFs/s": f"{n_tr / best[k]:.0f}",
            "÷ uniform floor": f"{best[k] / t_fu:.2f}",
            "÷ lfjax-window floor": f"{best[k] / t_fb:.2f}",
        })
    cols = list(rows[0])
    print(f"\nmin of {args.repeats} interleaved repeats (A B C A B C …); 'poly OTF' = one "
          f"accommodation state summed over {n_wl} wavelengths; 'mono' = one (λ, state)\n")
    print(markdown_table(rows, cols))
    print(
        f"\nRESULT lfjax {n_acc / t_l:.1f} polychromatic OTFs/s ({n_tr / t_l:.0f} monochromatic/s); "
        f"lfjax / floor(uniform window) = {t_l / t_fu:.2f}x ; "
        f"lfjax / floor(lfjax's windows) = {t_l / t_fb:.2f}x ; compile {c_first:.1f} s (jax trace+lower+XLA, measured in the first call)"
    )
    return best


if __name__ == "__main__":
    t0 = time.perf_counter()
    main()
    print(f"\ntotal wall time {time.perf_counter() - t0:.1f} s")
