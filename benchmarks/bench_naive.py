"""Issue #5 — lfjax against the pipeline a careful user would write (naive_pipeline.py).

Reduced configuration, both pipelines in this process on the same inputs: one aberrated
eye (first seeded Thibos 2002 draw, 3 mm), the 2×2 layout, CDP 2 D, 3 rendered depths
(2.0, 2.3, 2.6 D), 6 accommodation states (2.0–3.0 D / 0.2 D; this eye's own refraction
puts its peaks ≈ 0.2 D above the rendered depth, inside the grid), 7 wavelengths (400–700 nm
/ 50 nm, V(λ) weights, LCA, SCE), frequency step 1 cpd (60 arcmin field; the naive common
grid is lfjax's window for 2×2, so both OTFs live on the same frequencies).
Reports the speed ratio, max |ΔVSOTF|, whether the predicted accommodation agrees, the
naive pipeline's cost per PSF (by stage), and an extrapolation of both to the paper's full
study (11 eyes × 4 layouts × 9 depths × ±1 D window, 31 wavelengths).

Run:  .venv/bin/python benchmarks/bench_naive.py [--repeats 2]
      .venv/bin/python benchmarks/bench_naive.py --part study-eye [--layouts 4x4] [--df 0.9]
      (one eye through the paper's whole grid in both pipelines; about 30 min)
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np

from _common import _DF_RE, fmt_s, header, markdown_table, timed, timed_first
from naive_pipeline import NaiveConfig, through_focus_naive, zernike_ansi

DEPTHS = [2.0, 2.3, 2.6]
STATES = np.round(np.arange(2.0, 3.01, 0.2), 9)
WAVELENGTHS = np.arange(400.0, 701.0, 50.0)
DF = 1.0


def study_psf_count(layouts, depths, acc_grid, window, n_eyes, n_wl):
    """Monochromatic subaperture PSFs a per-PSF pipeline computes for the full study."""
    per_layout = {}
    for name, lay in layouts.items():
        states = sum(int(np.sum(np.abs(acc_grid - d) <= window + 1e-9)) for d in depths)
        n_sub = lay.n_subapertures
        per_layout[name] = n_eyes * n_sub * states * n_wl + n_sub * n_wl  # + reference
    return per_layout


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=2)
    ap.add_argument("--df", type=float, default=0.9,
                    help="study-eye: frequency step, cpd (0.9 as in RESULTS §2b; lowered per layout "
                         "to 2 decimals where the aliasing guard asks)")
    ap.add_argument("--layouts", default="natural,2x2,3x3,4x4",
                    help="study-eye: comma-separated subset of the paper's layouts")
    ap.add_argument("--part", choices=["reduced", "study-eye"], default="reduced",
                    help="reduced: the small side-by-side case (default); study-eye: one eye "
                         "through the paper's whole grid in both pipelines (~30 min)")
    args = ap.parse_args(argv)
    header(f"bench_naive --part {args.part}: lfjax vs the careful per-PSF numpy pipeline (issue #5)")
    if args.part == "study-eye":
        return study_eye(args)

    import jax.numpy as jnp
    from scipy.ndimage import map_coordinates

    import lfjax
    from lfjax.layouts import grid_layout, paper_layouts
    from lfjax.optics import sa_c40_um
    from lfjax.spectral import make_spectrum
    from lfjax.through_focus import through_focus
    from lfjax.zernike import zernike_mode

    # --- the same eye, layout, spectrum and sampling for both
    eye = lfjax.sample_eyes(0, 1, 3.0)
    coeffs = np.asarray(eye.zernike_um[0], float)
    n_modes = coeffs.size
    layout = grid_layout(2, 3.0)
    spec = make_spectrum(WAVELENGTHS)
    sampling = lfjax.Sampling(DF)
    try:
        from lfjax.sampling import wavelength_bands

        n_common = max(b[2] for b in wavelength_bands(WAVELENGTHS, layout.window_diameter_mm, 3.0, sampling))
    except ImportError:
        n_common = sampling.window_size(layout.window_diameter_mm, 400.0, 3.0)
    field_arcmin = 60.0 / DF
    # pupil grid: PSF field at 400 nm = 1.25 × the common field (no wrap), N·dx ≥ 2 × pupil
    dx = 400e-6 / (1.25 * field_arcmin / (180 * 60 / math.pi))
    n_grid = 384
    assert n_grid * dx >= 6.0, n_grid * dx
    cfg = NaiveConfig(dx_mm=dx, n_pupil_grid=n_grid, common_n=n_common,
                      common_pixel_arcmin=field_arcmin / n_common)
    # independent Zernike code agrees with lfjax's (sanity)
    rng = np.random.default_rng(1)
    x, y = rng.uniform(-0.7, 0.7, (2, 50))
    for j in range(n_modes):
        ref = np.asarray(zernike_mode(j, jnp.asarray(x), jnp.asarray(y)))
        mine = zernike_ansi(j, np.hypot(x, y), np.arctan2(y, x))
        assert np.allclose(ref, mine, atol=2e-5 * max(1, np.abs(ref).max())), j
    spectrum_np = (
        np.asarray(spec.wavelengths_nm), np.asarray(spec.weights), np.asarray(spec.lca_D),
        np.asarray(spec.sce_rho_per_mm2), lambda a: float(sa_c40_um(a, 3.0)),
    )
    lay_np = (np.asarray(layout.centres_mm), np.asarray(layout.diameters_mm))
    print(f"config: 1 eye, 2x2, depths {DEPTHS} D, states {STATES.tolist()} D, "
          f"{WAVELENGTHS.size} wavelengths, df = {DF} cpd, common grid {n_common}² at "
          f"{cfg.common_pixel_arcmin:.4f} arcmin; naive pupil grid {n_grid}² at dx = {dx * 1e3:.2f} µm "
          f"(N·dx = {n_grid * dx:.2f} mm; PSF pixel {400e-6 / (n_grid * dx) * 3437.75:.3f}–"
          f"{700e-6 / (n_grid * dx) * 3437.75:.3f} arcmin from 400 to 700 nm), cubic-spline resampling")

    def run_lfjax():
        return through_focus(eye, layout, depths_D=DEPTHS, accommodation_D=STATES, pupil_diameter_mm=3.0,
                             cdp_D=2.0, spectrum=spec, sampling=sampling)

    def run_naive():
        cfg.timers = {k: 0.0 for k in cfg.timers}
        cfg.n_psf = 0
        return through_focus_naive(cfg, coeffs, n_modes, lay_np, DEPTHS, STATES, spectrum_np)

    t_first, c_first, res = timed_first(run_lfjax)
    t_l, t_n = float("inf"), float("inf")
    for _ in range(args.repeats):
        t, res = timed(run_lfjax)
        t_l = min(t_l, t)
        t0 = time.perf_counter()
        vs_naive, pred_naive = run_naive()
        t = time.perf_counter() - t0
        if t < t_n:
            t_n, timers, n_psf = t, dict(cfg.timers), cfg.n_psf
    vs_l = np.asarray(res.vsotf[0])
    pred_l = np.asarray(res.predicted_accommodation_D()[0])
    dv = np.abs(vs_l - vs_naive)

    print(f"\n## reduced configuration, min of {args.repeats} interleaved repeats\n")
    rows = [
        {"pipeline": "lfjax.through_focus (jit, float32)", "time": fmt_s(t_l),
         "first call (compile)": f"{fmt_s(t_first)} ({fmt_s(c_first)})",
         "monochromatic PSFs": "—", "per PSF": "—"},
        {"pipeline": "naive per-PSF numpy/scipy (float64)", "time": fmt_s(t_n), "first call (compile)": "—",
         "monochromatic PSFs": n_psf, "per PSF": fmt_s(t_n / n_psf)},
    ]
    print(markdown_table(rows, list(rows[0])))
    print(f"\nspeed ratio naive / lfjax (steady) = {t_n / t_l:.0f}x ; incl. lfjax's compile: "
          f"{t_n / t_first:.1f}x")
    print("\nnaive cost per PSF by stage: " + ", ".join(
        f"{k} {fmt_s(v / n_psf)}" for k, v in timers.items()))
    rows = []
    for a, d in enumerate(DEPTHS):
        rows.append({
            "depth (D)": d,
            "VSOTF lfjax": " ".join(f"{v:.3f}" for v in vs_l[a]),
            "VSOTF naive": " ".join(f"{v:.3f}" for v in vs_naive[a]),
            "max |Δ|": f"{dv[a].max():.4f}",
            "predicted acc. lfjax / naive (D)": f"{pred_l[a]:.1f} / {pred_naive[a]:.1f}",
        })
    print(f"\n## agreement (states {STATES.tolist()} D)\n")
    print(markdown_table(rows, list(rows[0])))
    same = bool(np.allclose(pred_l, pred_naive))
    print(f"\nRESULT max |ΔVSOTF| = {dv.max():.4f} (relative to the peak {vs_l.max():.3f}: "
          f"{dv.max() / vs_l.max():.1%}); predicted accommodation equal at every depth: {same}")
    # accuracy of each against a converged run: lfjax at a quarter of the step (its edge and
    # field errors fall ∝ step², so the reference is ~16× closer than either pipeline)
    ref = through_focus(eye, layout, depths_D=DEPTHS, accommodation_D=STATES, pupil_diameter_mm=3.0,
                        cdp_D=2.0, spectrum=spec, sampling=lfjax.Sampling(DF / 4))
    vs_ref = np.asarray(ref.vsotf[0])
    err_l, err_n = np.abs(vs_l - vs_ref).max(), np.abs(vs_naive - vs_ref).max()
    print(f"RESULT accuracy against lfjax at df/4 = {DF / 4} cpd: max |ΔVSOTF| lfjax {err_l:.1e}, "
          f"naive {err_n:.1e} (naive / lfjax error = {err_n / err_l:.1f})")

    # --- extrapolation to the paper's full study (an extrapolation, not a measurement)
    acc_grid = np.round(np.arange(0.0, 5.01, 0.2), 9)
    depths = np.round(np.arange(0.0, 4.01, 0.5), 9)
    layouts = paper_layouts(3.0)
    counts = study_psf_count(layouts, depths, acc_grid, 1.0, 11, 31)
    df_study = 0.9  # what the guard accepts for the full grid (bench_lightfield --part grid)
    per_stage = (timers["pupil"] + timers["fft"]) / n_psf  # independent of the common grid
    rows, total = [], 0.0
    for name, lay in layouts.items():
        try:
            from lfjax.sampling import wavelength_bands

            L = max(b[2] for b in wavelength_bands(np.arange(400.0, 701, 10), lay.window_diameter_mm,
                                                   3.0, lfjax.Sampling(df_study)))
        except ImportError:
            L = lfjax.Sampling(df_study).window_size(lay.window_diameter_mm, 400.0, 3.0)
        # resampling cost on this layout's common grid, measured here (5 calls)
        k = np.linspace(0, n_grid - 1, L)
        yy, xx = np.meshgrid(k, k, indexing="ij")
        dens = np.random.default_rng(0).random((n_grid, n_grid))
        t_rs = min(timed(map_coordinates, dens, [yy, xx], order=3)[0] for _ in range(5))
        per_psf = per_stage + t_rs + timers["otf+metric"] / n_psf
        t = counts[name] * per_psf
        total += t
        rows.append({"layout": name, "common grid L": L, "PSFs": f"{counts[name]:,}",
                     "per PSF (pupil+FFT measured, resample at L measured)": fmt_s(per_psf),
                     "extrapolated time": f"{t / 3600:.2f} h"})
    print("\n## EXTRAPOLATION (not measured) of the naive pipeline to the paper's full study: "
          "11 eyes × 9 depths (0–4 D / 0.5) × states within ±1 D (0.2 D grid, ≥ 0 D) × 31 λ, "
          f"df = {df_study} cpd, same pupil grid N = {n_grid}\n")
    print(markdown_table(rows, list(rows[0])))
    print(f"\nRESULT naive full study ≈ {total / 3600:.1f} h on this machine "
          f"({sum(counts.values()):,} monochromatic PSFs); compare lfjax's measured full grid "
          f"(bench_lightfield.py --part grid)")
    return {"lfjax_s": t_l, "naive_s": t_n, "max_dv": float(dv.max()), "same_pred": same,
            "naive_full_h": total / 3600}


def study_eye(args):
    """One eye through the paper's whole grid (4 layouts × 9 depths × states within ±1 D ×
    31 λ) in both pipelines, each layout timed on its own; then lfjax's 11-eye study in the
    same process. The naive pipeline has nothing to share between eyes (only its reference,
    once per layout, is eye-independent), so its study time is 11 × this eye's, less 10
    references — the only step here that is scaled rather than run."""
    from lfjax.layouts import paper_layouts
    from lfjax.optics import sa_c40_um
    from lfjax.sampling import wavelength_bands
    from lfjax.spectral import make_spectrum
    from lfjax.through_focus import through_focus

    import lfjax

    depths = np.round(np.arange(0.0, 4.01, 0.5), 9)
    acc = np.round(np.arange(0.0, 5.01, 0.2), 9)
    window, n_eyes = 1.0, 11
    wl = np.arange(400.0, 701.0, 10.0)
    spec = make_spectrum(wl)
    eyes = lfjax.sample_eyes(0, n_eyes, 3.0)  # the study's eye batch; the naive run takes eye 0
    eye0 = lfjax.sample_eyes(0, 1, 3.0)
    assert np.allclose(np.asarray(eyes.zernike_um[0]), np.asarray(eye0.zernike_um[0]))
    coeffs = np.asarray(eye0.zernike_um[0], float)
    spectrum_np = (np.asarray(spec.wavelengths_nm), np.asarray(spec.weights), np.asarray(spec.lca_D),
                   np.asarray(spec.sce_rho_per_mm2), lambda a: float(sa_c40_um(a, 3.0)))
    n_grid = 384
    print(f"config: eye 0 of lfjax.sample_eyes(0, {n_eyes}, 3.0); layouts {args.layouts}; depths "
          f"{depths.tolist()} D; states {acc[0]}–{acc[-1]} / 0.2 D within ±{window} D; {wl.size} λ; "
          f"df = {args.df} cpd; naive pupil grid {n_grid}², float64\n", flush=True)

    def lfjax_run(e, lay, df=None):
        s = lfjax.Sampling(df) if df is not None else sampling
        return through_focus(e, lay, depths_D=depths, accommodation_D=acc, window_D=window,
                             pupil_diameter_mm=3.0, cdp_D=2.0, spectrum=spec, sampling=s)

    rows, tot_l1, tot_n1, tot_l11, tot_ref = [], 0.0, 0.0, 0.0, 0.0
    for name, lay in paper_layouts(3.0).items():
        if name not in args.layouts.split(","):
            continue
        df = args.df
        while True:  # the first (compiling) call; a step the guard refuses is lowered as it asks
            try:
                t_first, t_compile, res = timed_first(lfjax_run, eye0, lay, df)
                break
            except ValueError as err:
                m = _DF_RE.search(str(err))
                if not m:
                    raise
                df = math.floor(float(m.group(1)) * 100) / 100
        sampling = lfjax.Sampling(df)
        field_arcmin = 60.0 / df
        dx = 400e-6 / (1.25 * field_arcmin / (180 * 60 / math.pi))
        assert n_grid * dx >= 6.0, n_grid * dx
        n_common = max(b[2] for b in wavelength_bands(wl, lay.window_diameter_mm, 3.0, sampling))
        cfg = NaiveConfig(dx_mm=dx, n_pupil_grid=n_grid, common_n=n_common,
                          common_pixel_arcmin=field_arcmin / n_common)
        lay_np = (np.asarray(lay.centres_mm), np.asarray(lay.diameters_mm))
        t_l1 = min(timed(lfjax_run, eye0, lay)[0] for _ in range(args.repeats))
        t0 = time.perf_counter()
        vs_n, pred_n = through_focus_naive(cfg, coeffs, coeffs.size, lay_np, depths, acc, spectrum_np,
                                           window_D=window)
        t_n1 = time.perf_counter() - t0
        # the naive reference (eye-independent) once more, to subtract it when scaling to 11 eyes
        cfg_ref = NaiveConfig(dx_mm=dx, n_pupil_grid=n_grid, common_n=n_common,
                              common_pixel_arcmin=field_arcmin / n_common)
        t0 = time.perf_counter()
        through_focus_naive(cfg_ref, coeffs, coeffs.size, lay_np, [], acc, spectrum_np)
        t_ref = time.perf_counter() - t0
        t_first11, t_compile11, res11 = timed_first(lfjax_run, eyes, lay)
        t_l11 = min(timed(lfjax_run, eyes, lay)[0] for _ in range(args.repeats))
        t_l1 = min(t_l1, min(timed(lfjax_run, eye0, lay)[0] for _ in range(args.repeats)))
        vs_l = np.asarray(res.vsotf[0])
        mask = np.isfinite(vs_n)
        dv = np.abs(vs_l - vs_n)[mask].max()
        pred_l = np.asarray(res.predicted_accommodation_D()[0])
        agree = int(np.sum(np.isclose(pred_l, pred_n)))
        assert np.allclose(np.asarray(res11.vsotf[0]), vs_l, atol=1e-5, equal_nan=True)  # eye 0 in the batch
        tot_l1, tot_n1, tot_l11, tot_ref = tot_l1 + t_l1, tot_n1 + t_n1, tot_l11 + t_l11, tot_ref + t_ref
        rows.append({"layout": name, "df (cpd)": df, "naive PSFs": f"{cfg.n_psf:,}", "naive, 1 eye": fmt_s(t_n1), "naive reference": fmt_s(t_ref),
                     "lfjax, 1 eye": fmt_s(t_l1), "ratio, 1 eye": f"{t_n1 / t_l1:.0f}×",
                     "lfjax, 11 eyes (compile)": f"{fmt_s(t_l11)} ({fmt_s(t_compile11)})",
                     "max |ΔVSOTF|": f"{dv:.4f}", "same prediction": f"{agree}/{len(depths)}"})
        print(markdown_table(rows[-1:], list(rows[-1])), flush=True)
    print("\n## one eye through the paper's grid, both pipelines measured\n")
    print(markdown_table(rows, list(rows[0])))
    naive11 = n_eyes * tot_n1 - (n_eyes - 1) * tot_ref
    print(f"\nRESULT one eye, whole grid: naive {tot_n1:.0f} s, lfjax {tot_l1:.2f} s → {tot_n1 / tot_l1:.0f}×")
    print(f"RESULT 11-eye study: lfjax measured {tot_l11:.1f} s (steady); naive = 11 × {tot_n1:.0f} s − "
          f"10 × {tot_ref:.1f} s (its eye-independent reference) = {naive11 / 3600:.2f} h → "
          f"{naive11 / tot_l11:.0f}× (steady)")
    return {"naive_1eye_s": tot_n1, "lfjax_1eye_s": tot_l1, "lfjax_11_s": tot_l11, "naive_11_s": naive11}


if __name__ == "__main__":
    t0 = time.perf_counter()
    main()
    print(f"\ntotal wall time {time.perf_counter() - t0:.1f} s")
