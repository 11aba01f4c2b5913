"""Stability of the continuous accommodation peak (issue #10 part A).

Which way of finding the through-focus peak is accurate, robust and cheap? Methods:

* ``grid0.2``   the 0.2 D grid maximum (``accommodation_peaks(method="grid")``)
* ``grid0.01``  the 0.01 D grid maximum (the same call on a 0.01 D grid, float32)
* ``parabola``  vertex of the parabola through the 0.2 D grid maximum and its neighbours
* ``golden``    optimistix golden section inside the grid bracket
* ``newton``    optimistix Newton on dV/da inside the grid bracket (lfjax's default)
* ``bfgs``      optimistix BFGS from the grid peak (as implemented in lfjax.vision.peaks)
* ``bfgs_cdp``  ``lfjax.vision.peak_refinement.refine_peak(method="bfgs")`` with no grid: bracket = the whole
                ±1 D window, start at the CDP (2 D)
* ``bfgs_depth`` the same, started at the rendered depth
* ``newton_depth`` (``--extra``) Newton with no grid: whole window, started at the depth

Scene: 3 mm pupil, CDP 2 D, rendered depths 0–4 D in 0.5 D, accommodation 0–5 D and only
states within ±1 D of each depth allowed (the paper's grid), by default 7 wavelengths
420–660 nm in 40 nm (``--wavelengths`` sets others; few, to stay affordable: the peaks are
compared with a reference computed on the same spectrum and sampling, so the wavelength
count does not enter the errors, only the curves' shapes through LCA), sampling
from ``lfjax.planner.plan.plan_sampling`` (guard only). Layouts: natural view (open 3 mm pupil),
2×2, 3×3, 4×4 viewpoints. The natural view has one central view and so ignores the rendered
depth (benchmarks/results/issues-noticed.md, item 3); its cases here are a real point at each
depth (``cdp_D = depth``), one call per depth, states from the same absolute 0.2 D grid
inside the window.

Reference: the metric in float64 (a subprocess with ``jax_enable_x64``), same sampling, on a
0.05 D grid over the whole window plus a 0.01 D grid within ±0.06 D of that grid's highest
sample (``run_reference`` says why this is enough); argmax over the allowed
states (resolution ±0.005 D), plus that argmax
refined by the parabola through its 0.01 D neighbours (``ref_fine``; used only to resolve
errors below 0.005 D). Errors are |peak − reference| in D.

Timing: steady time per peak is the median over eye chunks after the first (the first call
compiles; its compile time is jax's own compile events, reported separately). All methods
run interleaved chunk by chunk, so they share the machine's background load.

Run (writes peak_finding.csv, peak_finding.png, peak_failure_cases.json here; raw results
in benchmarks/_cache/peak_finding/; RESULTS.md §10 used three wavelengths, 450, 550 and
650 nm, so that every method could run on all 100 eyes in about two hours on two cores):

    .venv/bin/python benchmarks/validation/peak_finding.py --eyes 100 --solver-eyes 100 --chunk 10 \
        --wavelengths 450,550,650
    .venv/bin/python benchmarks/validation/peak_finding.py --part analyse ...  # analyse the cache
"""

from __future__ import annotations

import argparse
import csv
import datetime
import hashlib
import json
import os
import shlex
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
from lfjax.vision.peak_options import PeakOptions

HERE = Path(__file__).resolve().parent
CACHE = HERE.parent / "_cache" / "peak_finding"  # benchmarks/_cache, not committed
sys.path.insert(1, str(HERE.parent))  # benchmarks/: _common

PUPIL_MM = 3.0
CDP_D = 2.0
WINDOW_D = 1.0
DEPTHS_D = np.arange(0.0, 4.01, 0.5)
GRID_D = np.round(np.arange(0, 26) * 0.2, 9)  # 0–5 D
DENSE_STEP_D = 0.01
N_DENSE = int(round(2 * WINDOW_D / DENSE_STEP_D)) + 1  # 201 states per window
WAVELENGTHS_NM = np.arange(420.0, 681.0, 40.0)  # 7 wavelengths, 420–660 nm
LAYOUTS = ("natural", "2x2", "3x3", "4x4")
METRICS = ("vsotf", "strehl")
CHEAP = ("grid0.2", "parabola")
SOLVERS = ("grid0.01", "golden", "newton", "bfgs", "bfgs_cdp", "bfgs_depth")
EXTRA = ("newton_depth",)
COARSE_REF_STEP_D = 0.05  # the reference's stage 1 grid over the whole window
FINE_HALF = 6  # stage 2: 0.01 D states within ±0.06 D of the coarse maximum
ATOL_D = 1e-5
MAX_STEPS = 32  # accommodation_peaks' default; the direct refine_peak calls use the same
SILENT_D = 0.05  # a "successful" peak this far from the reference is a silent failure
SILENT_GRID_D = 0.105  # … for the 0.2 D grid: half its step plus the reference's resolution
WRONG_PEAK_D = 0.25  # further than this: another peak, or a wrong place altogether


def silent_threshold(method: str) -> float:
    return SILENT_GRID_D if method == "grid0.2" else SILENT_D


# ----------------------------------------------------------------------------- scene


def window_states(depth: float, step: float, n: int):
    """States of the absolute grid (multiples of ``step``) from max(0, depth − 1) upward, n of
    them, and which lie inside the ±1 D window (the rest pad to a common shape)."""
    lo = max(0.0, np.ceil(round((depth - WINDOW_D) / step, 6)) * step)
    states = np.round(lo + step * np.arange(n), 9)
    allowed = np.abs(states - depth) <= WINDOW_D + 1e-9
    return states, allowed


def layout_setup(name: str, zernike_um: np.ndarray, dense: bool = True):
    """Everything static about one layout: groups of (scene, depth slots, grids)."""
    import lfjax
    from lfjax.kernel.pipeline import Accommodation, PipelineConfig, Scene

    opts = lfjax.ModelOptions()
    spec = lfjax.make_spectrum(WAVELENGTHS_NM, opts)

    def plan(layout, cdp, depths):
        return lfjax.plan_sampling(lfjax.PlanScene(
            layout=layout, pupil_diameter_mm=PUPIL_MM, cdp_D=cdp, depths_D=depths,
            accommodation_D=GRID_D, accommodation_window_D=WINDOW_D,
            wavelengths_nm=spec.wavelengths_nm, eyes=lfjax.make_eyes(zernike_um, 3.0)),
            estimate_accuracy=False).sampling

    n_coarse = int(round(2 * WINDOW_D / 0.2)) + 1
    groups = []
    if name == "natural":
        layout = lfjax.open_pupil(PUPIL_MM)
        samplings = [plan(layout, d, [d]) for d in DEPTHS_D]
        sampling = min(samplings, key=lambda s: s.freq_step_cpd)
        for j, d in enumerate(DEPTHS_D):
            cs, ca = window_states(d, 0.2, n_coarse)
            ds, da = window_states(d, DENSE_STEP_D, N_DENSE)
            groups.append(dict(
                scene=Scene.from_layout(layout, [d], d, PUPIL_MM), slots=[j], cdp=np.array([d]),
                coarse=Accommodation.shared(cs, np.arange(cs.size)[None], opts, PUPIL_MM),
                coarse_allowed=ca[None], coarse_states=cs[None],
                dense=Accommodation.shared(ds, np.arange(ds.size)[None], opts, PUPIL_MM)
                if dense else None,
                dense_allowed=da[None], dense_states=ds[None]))
    else:
        n = int(name[0])
        layout = lfjax.grid_layout(n, PUPIL_MM)
        sampling = plan(layout, CDP_D, DEPTHS_D)
        idx = np.broadcast_to(np.arange(GRID_D.size), (DEPTHS_D.size, GRID_D.size))
        allowed = np.abs(GRID_D[None] - DEPTHS_D[:, None]) <= WINDOW_D + 1e-9
        dense_all = np.round(np.arange(0, int(round(GRID_D[-1] / DENSE_STEP_D)) + 1) * DENSE_STEP_D, 9)
        d_idx, d_states, d_allowed = [], [], []
        for d in DEPTHS_D:
            ds, da = window_states(d, DENSE_STEP_D, N_DENSE)
            d_idx.append(np.searchsorted(dense_all, ds - 1e-9))
            d_states.append(ds)
            d_allowed.append(da)
        d_idx = np.array(d_idx)
        assert np.allclose(dense_all[d_idx], np.array(d_states))
        groups.append(dict(
            scene=Scene.from_layout(layout, DEPTHS_D, CDP_D, PUPIL_MM),
            slots=list(range(DEPTHS_D.size)), cdp=np.full(DEPTHS_D.size, CDP_D),
            coarse=Accommodation.shared(GRID_D, idx, opts, PUPIL_MM), coarse_allowed=allowed,
            coarse_states=np.broadcast_to(GRID_D, idx.shape),
            dense=Accommodation.shared(dense_all, d_idx, opts, PUPIL_MM) if dense else None,
            dense_allowed=np.array(d_allowed), dense_states=np.array(d_states)))
    config = PipelineConfig.build(spec.wavelengths_nm, layout.window_diameter_mm, PUPIL_MM,
                                  sampling, opts)
    return dict(name=name, layout=layout, spectrum=spec, sampling=sampling, config=config,
                groups=groups)


def sampling_key(sampling) -> str:
    return f"df={sampling.freq_step_cpd:.6f} edge={sampling.edge_width_samples} {sampling.transform}"


# ----------------------------------------------------------------------------- reference


def _stage1_groups(name: str, zernike_um: np.ndarray):
    """The scene groups of ``layout_setup`` with the reference's coarse float64 grid
    (``COARSE_REF_STEP_D`` over the whole ±1 D window) in place of the 0.01 D one."""
    import lfjax
    from lfjax.kernel.pipeline import Accommodation

    setup = layout_setup(name, zernike_um, dense=False)
    opts = lfjax.ModelOptions()
    n = int(round(2 * WINDOW_D / COARSE_REF_STEP_D)) + 1
    all_states = np.round(np.arange(0, int(round(GRID_D[-1] / COARSE_REF_STEP_D)) + 1)
                          * COARSE_REF_STEP_D, 9)
    for g in setup["groups"]:
        rows = [window_states(float(d), COARSE_REF_STEP_D, n) for d in np.asarray(g["scene"].depths_D)]
        states = np.array([r[0] for r in rows])
        index = np.searchsorted(all_states, states - 1e-9)
        assert np.allclose(all_states[index], states)
        used = np.unique(index)  # only the states some depth uses
        g["ref_coarse"] = Accommodation.shared(all_states[used], np.searchsorted(used, index),
                                               opts, PUPIL_MM)
        g["ref_coarse_states"] = states
        g["ref_coarse_allowed"] = np.array([r[1] for r in rows])
    return setup


def _fine_states(states, values, allowed):
    """0.01 D states (``2 · FINE_HALF + 1``) around the highest sample of one coarse curve,
    and which of them lie inside the allowed window (outside ones are computed at the centre
    and masked)."""
    v = np.where(allowed, values, -np.inf)
    centre = states[int(np.argmax(v))]
    lo, hi = states[allowed].min(), states[allowed].max()
    fine = np.round(centre + DENSE_STEP_D * np.arange(-FINE_HALF, FINE_HALF + 1), 9)
    ok = (fine >= lo - 1e-9) & (fine <= hi + 1e-9)
    return np.where(ok, fine, centre), ok


def run_reference(args):
    """The float64 reference for every eye, layout and depth (subprocess with x64).

    Two stages, so that 100 eyes stay affordable on two cores (a 0.01 D grid over the whole
    ±1 D window costs 201 states per depth): stage 1, the metric on a 0.05 D grid over the
    window (the global picture: peaks, second peaks, flatness); stage 2, a 0.01 D grid within
    ±0.06 D of stage 1's highest sample, per eye. For a maximum that is smooth on the 0.05 D
    scale the true peak lies within ±0.025 D of that sample. What this cannot resolve: two
    peaks whose heights differ by less than the 0.05 D grid's sampling loss (the reference
    then refines the one the coarse grid ranks first; such cases are listed as two-peaked).
    Both stages are merged into one curve per (eye, depth) on a non-uniform grid.
    """
    import equinox as eqx
    import jax

    jax.config.update("jax_enable_x64", True)
    import jax.numpy as jnp
    import lfjax
    from _common import block
    from lfjax.model.eyes import Eyes
    from lfjax.kernel.pipeline import Accommodation, reference_normalisers, retinal_metrics

    @eqx.filter_jit
    def per_eye_states(zernike_um, pupil_mm, scene, spectrum, states_D, pair_index, sa, config,
                       reference):
        def one(z, states):
            acc = Accommodation(states, pair_index, sa[0], sa[1])
            m = retinal_metrics(Eyes(z[None], pupil_mm), scene, spectrum, acc, config, reference)
            return m.vsotf[0], m.strehl[0]

        return jax.vmap(one)(zernike_um, states_D)

    z = np.load(CACHE / "eyes.npz")["zernike_um"].astype(np.float64)
    if args.reference_eyes:
        z = z[:args.reference_eyes]
    eyes_all = lfjax.model.eyes.make_eyes(z, PUPIL_MM)
    n_eyes = z.shape[0]
    n_fine = 2 * FINE_HALF + 1
    for name in args.layouts:
        out = CACHE / f"reference_{name}.npz"
        if out.exists() and np.load(out)["vsotf"].shape[0] >= n_eyes:
            print(f"reference {name}: cached", flush=True)
            continue
        setup = _stage1_groups(name, np.asarray(z, np.float32))
        n_coarse = setup["groups"][0]["ref_coarse_states"].shape[1]
        n_all = n_coarse + n_fine
        shape = (n_eyes, DEPTHS_D.size, n_all)
        curves = {k: np.full(shape, -np.inf) for k in METRICS}
        states_out = {k: np.full(shape, np.nan) for k in METRICS}
        allowed_out = {k: np.zeros(shape, bool) for k in METRICS}
        done, seconds_before = 0, 0.0
        if out.exists():  # extend a reference made for fewer eyes (the same eyes first)
            old = np.load(out)
            done = int(old["vsotf"].shape[0])
            assert str(old["sampling"]) == sampling_key(setup["sampling"])
            for k in METRICS:
                curves[k][:done] = old[k]
                states_out[k][:done] = old[f"states_{k}"]
                allowed_out[k][:done] = old[f"allowed_{k}"]
            seconds_before = float(old["seconds"])
            print(f"reference {name}: extending {done} -> {n_eyes} eyes", flush=True)
        t0 = time.perf_counter() - seconds_before
        for start in range(done, n_eyes, args.chunk):
            eyes = eyes_all[start:start + args.chunk]
            sl = slice(start, start + eyes.n_eyes)
            for g in setup["groups"]:
                slots = g["slots"]
                m = block(retinal_metrics(eyes, g["scene"], setup["spectrum"],
                                              g["ref_coarse"], setup["config"]))
                coarse = {"vsotf": np.asarray(m.vsotf), "strehl": np.asarray(m.strehl)}
                # stage 2 windows from both metrics' coarse curves: the fine states are shared
                # by the two metrics, so each metric gets its peaks' windows refined
                fine_s = np.zeros((eyes.n_eyes, len(slots), 2, n_fine))  # 2: per metric
                fine_ok = np.zeros_like(fine_s, bool)
                for e in range(eyes.n_eyes):
                    for j in range(len(slots)):
                        for i, key in enumerate(("vsotf", "strehl")):
                            fine_s[e, j, i], fine_ok[e, j, i] = _fine_states(
                                g["ref_coarse_states"][j], coarse[key][e, j],
                                g["ref_coarse_allowed"][j])
                n_pairs = 2 * n_fine
                pair_index = np.arange(len(slots) * n_pairs).reshape(len(slots), n_pairs)
                reference = reference_normalisers(g["scene"], setup["spectrum"], g["ref_coarse"],
                                                  setup["config"])
                sa = (g["ref_coarse"].sa_c40_um_per_D, g["ref_coarse"].sa_radius_mm)
                fv, fs = block(per_eye_states(
                    jnp.asarray(eyes.zernike_um), eyes.measured_pupil_mm, g["scene"],
                    setup["spectrum"], jnp.asarray(fine_s.reshape(eyes.n_eyes, -1)),
                    jnp.asarray(pair_index), sa, setup["config"], reference))
                fine_vals = {"vsotf": np.asarray(fv).reshape(fine_s.shape),
                             "strehl": np.asarray(fs).reshape(fine_s.shape)}
                for i, key in enumerate(("vsotf", "strehl")):
                    for e in range(eyes.n_eyes):
                        for j, slot in enumerate(slots):
                            s = np.concatenate([g["ref_coarse_states"][j], fine_s[e, j, i]])
                            ok = np.concatenate([g["ref_coarse_allowed"][j], fine_ok[e, j, i]])
                            v = np.concatenate([coarse[key][e, j, :n_coarse],
                                                fine_vals[key][e, j, i]])
                            # one sorted curve: duplicate and masked states dropped, the row
                            # padded at its end (allowed = False)
                            keys = np.where(ok, np.round(s, 6), np.inf)
                            uniq, first = np.unique(keys, return_index=True)
                            keep = first[np.isfinite(uniq)]
                            order = keep[np.argsort(s[keep])]
                            curves[key][start + e, slot, :order.size] = v[order]
                            states_out[key][start + e, slot, :order.size] = s[order]
                            allowed_out[key][start + e, slot, :order.size] = True
            print(f"reference {name}: eyes ..{sl.stop - 1} {time.perf_counter() - t0:.0f} s",
                  flush=True)
        np.savez(out, **curves, **{f"states_{k}": v for k, v in states_out.items()},
                 **{f"allowed_{k}": v for k, v in allowed_out.items()},
                 sampling=sampling_key(setup["sampling"]), seconds=time.perf_counter() - t0)

# ----------------------------------------------------------------------------- methods


def _direct_fn():
    """Compiled grid-free refinement: ``refine_peak`` on the whole ±1 D window of every
    (eye, depth) from a given start (the value function is accommodation_peaks')."""
    import equinox as eqx
    import jax
    import jax.numpy as jnp
    from lfjax.vision.peak_refinement import refine_peak
    from lfjax.vision.peaks import single_state_metric
    from lfjax.kernel.pipeline import eye_coefficients, reference_normalisers

    @eqx.filter_jit
    def direct(eyes, scene, spectrum, acc, config, lower, upper, start, metric, method):
        reference = reference_normalisers(scene, spectrum, acc, config)
        value_fn = single_state_metric(eyes.measured_pupil_mm, scene, spectrum, acc, config,
                                       reference, metric)
        coefficients = eye_coefficients(eyes, config)
        shape = (coefficients.shape[0], scene.depths_D.shape[0])
        z = jnp.broadcast_to(coefficients[:, None, :], shape + coefficients.shape[-1:])
        b = lambda x: jnp.broadcast_to(jnp.asarray(x)[None, :], shape)  # noqa: E731
        solve = lambda lo, hi, s, zz, d: refine_peak(  # noqa: E731
            value_fn, lo, hi, s, (zz, d), method, ATOL_D, MAX_STEPS)
        return jax.vmap(jax.vmap(solve))(b(lower), b(upper), b(start), z, b(scene.depths_D))

    return direct


FIELDS = ("accommodation_D", "value", "success", "result", "n_steps", "second_accommodation_D",
          "at_hyperopic_limit", "at_grid_edge", "grid_value")


def call_method(method, metric, setup, g, eyes, direct):
    """One compiled call of ``method`` on one group; returns a zero-argument callable."""
    from lfjax.vision.peaks import accommodation_peaks

    spec, cfg = setup["spectrum"], setup["config"]
    if method in ("grid0.2", "parabola", "golden", "newton", "bfgs", "grid0.01"):
        dense = method == "grid0.01"
        acc = g["dense"] if dense else g["coarse"]
        allowed = g["dense_allowed"] if dense else g["coarse_allowed"]
        m = {"grid0.2": "grid", "grid0.01": "grid"}.get(method, method)
        return lambda: accommodation_peaks(
            eyes,
            g["scene"],
            spec,
            acc,
            cfg,
            metric=metric,
            peaks=PeakOptions(method=m),
            allowed=allowed,
        )
    depths = np.asarray(g["scene"].depths_D)
    lower = np.maximum(depths - WINDOW_D, 0.0)
    upper = np.minimum(depths + WINDOW_D, GRID_D[-1])
    start = g["cdp"] if method == "bfgs_cdp" else depths
    solver = method.split("_")[0]
    return lambda: direct(eyes, g["scene"], spec, g["coarse"], cfg, lower, upper, start,
                          metric, solver)


def as_record(out, n_eyes, n_slots):
    """Peaks or Peak → dict of (n_eyes, n_slots) numpy arrays."""
    peaks = hasattr(out, "at_grid_edge")  # Peaks; else a bare Peak from refine_peak
    rec = {f: np.asarray(getattr(out, f)).reshape(n_eyes, n_slots)
           for f in (FIELDS if peaks else FIELDS[:5])}
    if not peaks:
        rec["second_accommodation_D"] = np.full((n_eyes, n_slots), np.nan)
        rec["at_hyperopic_limit"] = rec["accommodation_D"] <= 10 * ATOL_D
        rec["at_grid_edge"] = np.zeros((n_eyes, n_slots), bool)
        rec["grid_value"] = np.full((n_eyes, n_slots), np.nan)
    return rec


def run_methods(args):
    import jax
    import lfjax
    from _common import CompileTimer, timed

    z = np.load(CACHE / "eyes.npz")["zernike_um"]
    eyes_all = lfjax.model.eyes.make_eyes(z, PUPIL_MM)
    direct = _direct_fn()
    methods = list(CHEAP) + list(SOLVERS) + (list(EXTRA) if args.extra else [])
    if args.methods:
        methods = [m for m in methods if m in args.methods.split(",")]
    for name in args.layouts:
        for metric in args.metrics:
            out = CACHE / f"methods_{name}_{metric}.npz"
            if out.exists() and not args.force:
                print(f"methods {name} {metric}: cached", flush=True)
                continue
            setup = layout_setup(name, z)
            res = {m: {f: np.full((z.shape[0], DEPTHS_D.size), np.nan) for f in FIELDS}
                   for m in methods}
            calls = {m: [] for m in methods}  # (seconds, n_peaks, first?)
            compile_s = {m: 0.0 for m in methods}
            first_s = {m: 0.0 for m in methods}
            n_eyes_of = {m: (args.eyes if m in CHEAP else args.solver_eyes) for m in methods}
            t_layout = time.perf_counter()
            for start in range(0, z.shape[0], args.chunk):
                eyes = eyes_all[start:start + args.chunk]
                sl = slice(start, start + eyes.n_eyes)
                for m in methods:
                    if start >= n_eyes_of[m]:
                        continue
                    if m == "bfgs_cdp" and name == "natural":
                        continue  # CDP = rendered depth: identical to bfgs_depth (copied below)
                    total, first = 0.0, not calls[m]
                    for g in setup["groups"]:
                        fn = call_method(m, metric, setup, g, eyes, direct)
                        if first:
                            with CompileTimer() as ct:
                                t, o = timed(fn)
                            compile_s[m] += ct.seconds
                            first_s[m] += t
                        else:
                            t, o = timed(fn)
                        total += t
                        rec = as_record(o, eyes.n_eyes, len(g["slots"]))
                        for f in FIELDS:
                            res[m][f][sl, g["slots"]] = rec[f]
                    calls[m].append((total, eyes.n_eyes * DEPTHS_D.size, first))
                print(f"methods {name} {metric}: eyes ..{sl.stop - 1} "
                      f"{time.perf_counter() - t_layout:.0f} s", flush=True)
            if name == "natural" and "bfgs_cdp" in methods:
                res["bfgs_cdp"] = {f: v.copy() for f, v in res["bfgs_depth"].items()}
                calls["bfgs_cdp"] = list(calls["bfgs_depth"])
                compile_s["bfgs_cdp"], first_s["bfgs_cdp"] = compile_s["bfgs_depth"], first_s["bfgs_depth"]
            flat = {}
            for m in methods:
                for f in FIELDS:
                    flat[f"{m}|{f}"] = res[m][f]
                flat[f"{m}|calls"] = np.array(calls[m], float).reshape(-1, 3)
                flat[f"{m}|compile_s"] = compile_s[m]
                flat[f"{m}|first_s"] = first_s[m]
                flat[f"{m}|n_eyes"] = n_eyes_of[m]
            np.savez(out, chunk=args.chunk, sampling=sampling_key(setup["sampling"]), **flat)
            del setup
            jax.clear_caches()


# ----------------------------------------------------------------------------- analysis


def local_maxima(v, prominence=0.05):
    """numpy twin of lfjax.vision.peaks._local_maxima on one curve (−inf = not allowed): indices of
    the global maximum and of the highest other prominent local maximum (or −1)."""
    best = int(np.argmax(v))
    left = np.concatenate([[-np.inf], v[:-1]])
    right = np.concatenate([v[1:], [-np.inf]])
    local = (v > left) & (v >= right) & np.isfinite(v)
    second, sv = -1, -np.inf
    for k in np.flatnonzero(local):
        if k == best:
            continue
        lo, hi = min(k, best), max(k, best)
        valley = np.min(v[lo:hi + 1])
        if v[k] - valley >= prominence * abs(v[k]) and v[k] > sv:
            second, sv = int(k), v[k]
    return best, second


def reference_peaks(ref, metric):
    """Per (eye, depth) from the merged float64 curves (``run_reference``): argmax,
    parabola-refined argmax, second peak, flatness, curvature, kink, and the window flags."""
    vals, states, allowed = ref[metric], ref[f"states_{metric}"], ref[f"allowed_{metric}"]
    n_e, n_d, _ = vals.shape
    out = {k: np.full((n_e, n_d), np.nan) for k in (
        "ref", "ref_fine", "ref_value", "ref_second", "ref_second_value", "ref_grid_second",
        "flat", "kink", "curvature", "win_lo", "win_hi")}
    step = DENSE_STEP_D
    for e in range(n_e):
        for d in range(n_d):
            ok = allowed[e, d]
            v, s = vals[e, d][ok], states[e, d][ok]
            best, second = local_maxima(v)
            out["ref"][e, d] = s[best]
            out["ref_value"][e, d] = v[best]
            out["win_lo"][e, d], out["win_hi"][e, d] = s.min(), s.max()
            fine = s[best]
            if 0 < best < v.size - 1 and np.allclose(np.diff(s[best - 1:best + 2]), step, atol=1e-6):
                y0, y2 = v[best - 1], v[best + 1]
                den = y0 - 2 * v[best] + y2
                if den < 0:
                    fine = s[best] + np.clip(0.5 * (y0 - y2) / den, -0.5, 0.5) * step
                # curvature −V''/V (1/D²) and a kink measure: the peak's second difference
                # against the median second difference of the 0.01 D samples within ±0.1 D
                # (smooth ≈ 1)
                out["curvature"][e, d] = -den / step**2 / v[best]
                d2 = [v[k - 1] - 2 * v[k] + v[k + 1] for k in range(1, v.size - 1)
                      if k != best and abs(s[k] - s[best]) <= 0.1 + 1e-9
                      and np.allclose(np.diff(s[k - 1:k + 2]), step, atol=1e-6)]
                if d2:
                    out["kink"][e, d] = abs(den) / max(np.median(np.abs(d2)), 1e-12)
            out["ref_fine"][e, d] = fine
            if second >= 0:
                out["ref_second"][e, d] = s[second]
                out["ref_second_value"][e, d] = v[second]
            # second peak visible on the 0.2 D grid subset?
            on_grid = np.isclose(np.round(s / 0.2) * 0.2, s, atol=1e-6)
            _, sg = local_maxima(v[on_grid])
            if sg >= 0:
                out["ref_grid_second"][e, d] = s[on_grid][sg]
            out["flat"][e, d] = (v.max() - v.min()) / v.max()
    out["hyperopic"] = (out["ref"] <= 1e-9) & (out["win_lo"] <= 1e-9)
    out["far_end"] = (np.isclose(out["ref"], out["win_hi"]) |
                      (np.isclose(out["ref"], out["win_lo"]) & (out["win_lo"] > 1e-9)))
    return out


def pct(x, q):
    return float(np.percentile(x, q)) if x.size else float("nan")


def load_all(args):
    import lfjax.vision.peak_refinement as P

    runs = []
    for name in args.layouts:
        ref_npz = np.load(CACHE / f"reference_{name}.npz")
        ref = {k: ref_npz[k] for k in ref_npz.files if k not in ("sampling", "seconds")}
        for metric in args.metrics:
            path = CACHE / f"methods_{name}_{metric}.npz"
            if not path.exists():
                continue
            npz = np.load(path)
            assert str(npz["sampling"]) == str(ref_npz["sampling"]), (name, "sampling differs")
            methods = sorted({k.split("|")[0] for k in npz.files if "|" in k},
                             key=lambda m: (CHEAP + SOLVERS + EXTRA).index(m))
            rp = reference_peaks(ref, metric)
            runs.append(dict(layout=name, metric=metric, npz=npz, methods=methods, ref=rp,
                             curves=ref[metric], states=ref[f"states_{metric}"],
                             allowed=ref[f"allowed_{metric}"]))
    del P
    return runs


def summarise(runs):
    import lfjax.vision.peak_refinement as P

    rows = []
    for metric in METRICS:
        per_metric = [r for r in runs if r["metric"] == metric]
        if not per_metric:
            continue
        methods = [m for m in CHEAP + SOLVERS + EXTRA if any(m in r["methods"] for r in per_metric)]
        for layout in ["all"] + [r["layout"] for r in per_metric]:
            sel = per_metric if layout == "all" else [r for r in per_metric if r["layout"] == layout]
            for m in methods:
                errs, fine_errs, ok, steps, codes, comp, edge, below = [], [], [], [], [], [], [], []
                eyes_used = []
                chunk_ms = []
                for r in sel:
                    if m not in r["methods"]:
                        continue
                    npz = r["npz"]
                    n = min(int(npz[f"{m}|n_eyes"]), r["ref"]["ref"].shape[0])
                    eyes_used.append(n)
                    acc = npz[f"{m}|accommodation_D"][:n]
                    errs.append(np.abs(acc - r["ref"]["ref"][:n]).ravel())
                    fine_errs.append(np.abs(acc - r["ref"]["ref_fine"][:n]).ravel())
                    ok.append(npz[f"{m}|success"][:n].astype(bool).ravel())
                    steps.append(npz[f"{m}|n_steps"][:n].ravel())
                    codes.append(npz[f"{m}|result"][:n].ravel())
                    edge.append(npz[f"{m}|at_grid_edge"][:n].astype(bool).ravel())
                    gv = npz[f"{m}|grid_value"][:n]
                    below.append((npz[f"{m}|value"][:n] < gv - 1e-6 * np.abs(gv)).ravel())
                    calls = npz[f"{m}|calls"]
                    steady = calls[calls[:, 2] == 0]
                    per_peak = steady[:, 0] / steady[:, 1] if steady.size else calls[:, 0] / calls[:, 1]
                    chunk_ms.append(per_peak * 1e3)
                    comp.append(float(npz[f"{m}|compile_s"]))
                if not errs:
                    continue
                e, ef, s = np.concatenate(errs), np.concatenate(fine_errs), np.concatenate(ok)
                st, cd, ed = np.concatenate(steps), np.concatenate(codes), np.concatenate(edge)
                # time per peak: per layout the median over steady chunks; "all" = mean over
                # layouts of those medians (every layout has the same number of peaks)
                t_ms = float(np.mean([np.median(c) for c in chunk_ms]))
                code_counts = {P.result_name(c): int(np.sum(cd == c)) for c in np.unique(cd)}
                rows.append(dict(
                    metric=metric, layout=layout, method=m,
                    n_eyes="/".join(str(x) for x in sorted(set(eyes_used))),
                    n_peaks=int(e.size),
                    success_rate=float(s.mean()),
                    solver_failures=int(np.sum(~s & ~ed)), edge_flags=int(ed.sum()),
                    err_median_D=float(np.median(e)), err_fine_median_D=float(np.median(ef)),
                    err_p95_D=pct(e, 95), err_max_D=float(e.max()),
                    ok_err_median_D=pct(e[s], 50), ok_err_fine_median_D=pct(ef[s], 50),
                    ok_err_p95_D=pct(e[s], 95), ok_err_max_D=float(e[s].max()) if s.any() else float("nan"),
                    silent_failures=int(np.sum(s & (e > silent_threshold(m)))),
                    wrong_peak=int(np.sum(e > WRONG_PEAK_D)),
                    ok_wrong_peak=int(np.sum(s & (e > WRONG_PEAK_D))),
                    below_grid_value=int(np.sum(np.concatenate(below))),
                    time_per_peak_ms=t_ms,
                    compile_s=float(np.sum(comp)) if layout != "all" else float(np.mean(comp)),
                    n_steps_mean=float(st.mean()), n_steps_max=int(st.max()),
                    result_codes=";".join(f"{k}:{v}" for k, v in code_counts.items()),
                ))
    return rows


# ----------------------------------------------------------------------------- failure cases


def case_id(r, e, d):
    return dict(layout=r["layout"], metric=r["metric"], eye_index=int(e),
                depth_D=float(DEPTHS_D[d]))


def describe(r, e, d, seed, n_eyes, zernike_um):
    ref = r["ref"]
    info = case_id(r, e, d)
    info["eye"] = dict(seed=seed, n_eyes=n_eyes, measured_pupil_mm=PUPIL_MM,
                       how=f"lfjax.sample_eyes({seed}, {n_eyes}, measured_pupil_mm={PUPIL_MM})[{e}]",
                       zernike_um=[round(float(x), 6) for x in zernike_um[e]])
    info["cdp_D"] = float(DEPTHS_D[d]) if r["layout"] == "natural" else CDP_D
    allowed = r["allowed"][e, d]
    info["window_D"] = [float(r["states"][e, d][allowed].min()), float(r["states"][e, d][allowed].max())]
    info["reference"] = dict(
        peak_D=float(ref["ref"][e, d]), peak_fine_D=round(float(ref["ref_fine"][e, d]), 5),
        value=float(ref["ref_value"][e, d]),
        second_peak_D=None if np.isnan(ref["ref_second"][e, d]) else float(ref["ref_second"][e, d]),
        second_value=None if np.isnan(ref["ref_second_value"][e, d]) else float(ref["ref_second_value"][e, d]),
        relative_range=round(float(ref["flat"][e, d]), 4),
        curvature_per_D2=None if np.isnan(ref["curvature"][e, d]) else round(float(ref["curvature"][e, d]), 3),
        kink_ratio=None if np.isnan(ref["kink"][e, d]) else round(float(ref["kink"][e, d]), 2))
    # the curve on the 0.2 D grid (float64), for a glance
    s = r["states"][e, d]
    on = allowed & np.isclose(np.round(s / 0.2) * 0.2, s, atol=1e-6)
    info["curve_0.2D_f64"] = {f"{x:.1f}": round(float(v), 5) for x, v in zip(s[on], r["curves"][e, d][on])}
    per = {}
    import lfjax.vision.peak_refinement as P
    for m in r["methods"]:
        npz = r["npz"]
        if e >= int(npz[f"{m}|n_eyes"]):
            continue
        a = float(npz[f"{m}|accommodation_D"][e, d])
        sec = float(npz[f"{m}|second_accommodation_D"][e, d])
        per[m] = dict(peak_D=round(a, 5), error_D=round(abs(a - ref["ref"][e, d]), 5),
                      value=round(float(npz[f"{m}|value"][e, d]), 6),
                      success=bool(npz[f"{m}|success"][e, d]),
                      result=P.result_name(int(npz[f"{m}|result"][e, d])),
                      n_steps=int(npz[f"{m}|n_steps"][e, d]),
                      second_peak_D=None if np.isnan(sec) else round(sec, 4),
                      at_hyperopic_limit=bool(npz[f"{m}|at_hyperopic_limit"][e, d]),
                      at_grid_edge=bool(npz[f"{m}|at_grid_edge"][e, d]))
    info["methods"] = per
    return info


def spread(r, e, d):
    """How differently the methods behave on a case (largest error, failures)."""
    npz, ref = r["npz"], r["ref"]
    worst = 0.0
    for m in r["methods"]:
        if e < int(npz[f"{m}|n_eyes"]):
            err = abs(npz[f"{m}|accommodation_D"][e, d] - ref["ref"][e, d])
            worst = max(worst, err + (0.0 if npz[f"{m}|success"][e, d] else 0.01))
    return worst


def find_failure_cases(runs, seed, n_eyes, zernike_um, solver_eyes, per_kind=3):
    """Concrete examples per failure kind, chosen among the eyes every method ran on."""
    kinds = {}

    def pick(kind, note, candidates):
        count = len(candidates)
        full = [c for c in candidates if c[2] < solver_eyes]
        candidates = sorted(full or candidates, key=lambda c: -c[0])
        seen, chosen = set(), []
        for _, r, e, d in candidates:
            key = (r["layout"], r["metric"], e)
            if key in seen:
                continue
            seen.add(key)
            chosen.append(describe(r, e, d, seed, n_eyes, zernike_um))
            if len(chosen) >= per_kind:
                break
        kinds[kind] = dict(what=note, count=count, examples=chosen)

    def cases(pred, score, metric=None, layouts=None):
        """All matching cases; examples are then picked among the first ``solver_eyes``
        eyes (where every method ran) when there are any."""
        out = []
        for r in runs:
            if (metric and r["metric"] != metric) or (layouts and r["layout"] not in layouts):
                continue
            for e in range(r["ref"]["ref"].shape[0]):
                for d in range(DEPTHS_D.size):
                    if pred(r, e, d):
                        out.append((score(r, e, d), r, e, d))
        return out

    ref = lambda r, k, e, d: r["ref"][k][e, d]  # noqa: E731
    pick("two_peaked_strehl_2x2",
         "Strehl, 2x2: a peak near the CDP and one near the rendered depth (both prominent on "
         "the dense float64 curve); examples where the two are closest in height first",
         cases(lambda r, e, d: np.isfinite(ref(r, "ref_second", e, d)),
               lambda r, e, d: ref(r, "ref_second_value", e, d) / ref(r, "ref_value", e, d),
               metric="strehl", layouts=("2x2",)))
    pick("two_peaked_other",
         "other layouts/metrics with two prominent peaks on the dense float64 curve",
         cases(lambda r, e, d: np.isfinite(ref(r, "ref_second", e, d))
               and not (r["metric"] == "strehl" and r["layout"] == "2x2"),
               lambda r, e, d: ref(r, "ref_second_value", e, d) / ref(r, "ref_value", e, d)))
    pick("flat",
         "flat curves: the metric varies by less than 15 % over the whole ±1 D window "
         "(strongly aberrated eyes); flattest first",
         cases(lambda r, e, d: ref(r, "flat", e, d) < 0.15,
               lambda r, e, d: -ref(r, "flat", e, d)))
    pick("hyperopic_limit",
         "the reference peak is at 0 D (the eye would relax beyond infinity); worst method "
         "behaviour first",
         cases(lambda r, e, d: bool(r["ref"]["hyperopic"][e, d]), spread))
    pick("far_end",
         "the reference peak is on the window's far end (depth ± 1 D, not 0 D): the true "
         "maximum lies outside the allowed states; worst method behaviour first",
         cases(lambda r, e, d: bool(r["ref"]["far_end"][e, d]), spread))
    pick("non_smooth_strehl",
         "Strehl = max of PSF samples: a kink at the peak (its second difference ≥ 5× the "
         "median second difference within ±0.1 D on the dense float64 curve); worst first",
         cases(lambda r, e, d: ref(r, "kink", e, d) >= 5,
               lambda r, e, d: ref(r, "kink", e, d), metric="strehl"))
    for m in CHEAP + SOLVERS + EXTRA:
        pick(f"silent_{m}",
             f"{m} reports success but is more than {silent_threshold(m)} D from the reference; "
             "worst first",
             cases(lambda r, e, d, m=m: m in r["methods"] and e < int(r["npz"][f"{m}|n_eyes"])
                   and bool(r["npz"][f"{m}|success"][e, d])
                   and abs(r["npz"][f"{m}|accommodation_D"][e, d] - ref(r, "ref", e, d))
                   > silent_threshold(m),
                   lambda r, e, d, m=m: abs(r["npz"][f"{m}|accommodation_D"][e, d] - ref(r, "ref", e, d))))
        pick(f"failed_{m}",
             f"{m} reports failure away from the window's ends (solver result not successful "
             "or left its bracket)",
             cases(lambda r, e, d, m=m: m in r["methods"] and e < int(r["npz"][f"{m}|n_eyes"])
                   and not bool(r["npz"][f"{m}|success"][e, d])
                   and not bool(r["npz"][f"{m}|at_grid_edge"][e, d]),
                   lambda r, e, d, m=m: abs(r["npz"][f"{m}|accommodation_D"][e, d] - ref(r, "ref", e, d))))
    kinds = {k: v for k, v in kinds.items() if v["count"]}
    return kinds


# ----------------------------------------------------------------------------- output


def write_csv(rows, path):
    cols = list(rows[0].keys())
    with open(path, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=cols)
        w.writeheader()
        for r in rows:
            w.writerow({k: (f"{v:.6g}" if isinstance(v, float) else v) for k, v in r.items()})


def plot(rows, path, wavelengths_note):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    methods = [m for m in CHEAP + SOLVERS + EXTRA if any(r["method"] == m for r in rows)]
    colours = dict(zip(methods, plt.cm.tab10(np.linspace(0, 1, 10))))
    fig, axes = plt.subplots(1, 3, figsize=(16, 5.2))
    for ax, metric in zip(axes[:2], METRICS):
        for r in rows:
            if r["metric"] != metric or r["layout"] != "all":
                continue
            x = r["time_per_peak_ms"]
            lo = max(r["ok_err_fine_median_D"], 1e-6)
            ax.errorbar([x], [lo], yerr=[[0], [max(r["ok_err_p95_D"] - lo, 0.0)]], fmt="o",
                        color=colours[r["method"]], capsize=4, ms=8)
            ax.scatter([x], [max(r["err_max_D"], 1e-6)], marker="x", color=colours[r["method"]], s=60)
            ax.annotate(r["method"], (x, lo), textcoords="offset points", xytext=(6, -12), fontsize=8)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.axhline(0.005, color="grey", lw=0.8, ls=":")
        ax.text(ax.get_xlim()[0] * 1.05, 0.0055, "reference grid resolution ±0.005 D", fontsize=7,
                color="grey")
        ax.set_xlabel("steady time per peak (ms, 2 CPU cores)")
        ax.set_ylabel("|peak − dense float64 reference| (D)")
        ax.set_title(f"{metric.upper()}: ● median (successful, vs refined ref) to 95th pct; × max (all)",
                     fontsize=9)
        ax.grid(True, which="both", alpha=0.3)
    ax = axes[2]
    width = 0.38
    for i, metric in enumerate(METRICS):
        vals = [next((r["success_rate"] for r in rows if r["metric"] == metric and r["layout"] == "all"
                      and r["method"] == m), np.nan) for m in methods]
        solver_ok = [next((1 - r["solver_failures"] / r["n_peaks"] for r in rows
                           if r["metric"] == metric and r["layout"] == "all" and r["method"] == m), np.nan)
                     for m in methods]
        xs = np.arange(len(methods)) + (i - 0.5) * width
        ax.bar(xs, vals, width, label=f"{metric}: success flag", color=f"C{i}")
        ax.scatter(xs, solver_ok, marker="_", s=200, color="k",
                   label="1 − solver failures (edge flags excluded)" if i == 0 else None)
    ax.set_xticks(np.arange(len(methods)))
    ax.set_xticklabels(methods, rotation=45, ha="right", fontsize=8)
    ax.set_ylim(0, 1.05)
    ax.set_ylabel("fraction of peaks")
    ax.set_title("success rate (the flag also fails peaks on the window's far end)", fontsize=9)
    ax.legend(fontsize=7, loc="lower left")
    fig.suptitle(f"Accommodation peak finding: 4 layouts × 9 depths × eyes, {wavelengths_note}",
                 fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def fmt(x, digits=3):
    if isinstance(x, float):
        if np.isnan(x):
            return "–"
        if x == 0:
            return "0"
        if abs(x) < 1e-3:
            return f"{x:.1e}"
        return f"{x:.{digits}g}"
    return str(x)


def markdown(rows, metric, layout="all"):
    cols = ["method", "n_eyes", "success_rate", "solver_failures", "edge_flags", "err_median_D",
            "err_fine_median_D", "err_p95_D", "err_max_D", "ok_err_fine_median_D", "ok_err_p95_D",
            "ok_err_max_D", "silent_failures", "ok_wrong_peak", "below_grid_value",
            "time_per_peak_ms", "compile_s", "n_steps_mean", "n_steps_max"]
    head = ["method", "eyes", "success", "solver fails", "edge flags", "median", "median (fine ref)",
            "p95", "max", "ok: median (fine)", "ok: p95", "ok: max", "silent", "ok but wrong peak",
            "below grid max", "ms/peak", "compile s", "steps mean", "steps max"]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for r in rows:
        if r["metric"] == metric and r["layout"] == layout:
            lines.append("| " + " | ".join(
                f"{r[c]:.1%}" if c == "success_rate" else fmt(r[c]) for c in cols) + " |")
    return "\n".join(lines)


# ----------------------------------------------------------------------------- main


def header():
    import jax

    from _common import git_state, machine_info

    info = machine_info()
    cmd = " ".join(shlex.quote(a) for a in [os.path.relpath(sys.executable)] + sys.argv)
    print("# Accommodation peak finding: stability study (issue #10 part A)")
    print(f"command : {cmd}")
    print(f"machine : {info['cpu']}, {info['cores']} cores, load avg (1 min) {info['load_avg_1m']}")
    print(f"software: python {info['python']}, jax {info['jax']} ({info['backend']}), "
          f"numpy {np.__version__}")
    print(f"date    : {datetime.datetime.now().isoformat(timespec='seconds')}")
    print(f"lfjax   : {lfjax_provenance()}")
    print(f"checkout: {git_state()}")
    print(flush=True)
    del jax


def lfjax_provenance() -> str:
    """Where lfjax was imported from and the hashes of the two files the study exercises."""
    import lfjax

    root = Path(lfjax.__file__).parent
    sums = {f: hashlib.sha1((root / f).read_bytes()).hexdigest()[:10]
            for f in ("peaks.py", "pipeline.py")}
    commit = os.environ.get("LFJAX_SNAPSHOT_COMMIT", "")
    return (f"{root}{f' (export of commit {commit})' if commit else ''}; sha1 "
            + ", ".join(f"{k} {v}" for k, v in sums.items()))


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--eyes", type=int, default=100, help="eyes for the cheap methods and the reference")
    p.add_argument("--solver-eyes", type=int, default=20,
                   help="eyes (the first of them) for the solvers and the 0.01 D grid")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--chunk", type=int, default=5, help="eyes per compiled call")
    p.add_argument("--layouts", default=",".join(LAYOUTS))
    p.add_argument("--metrics", default=",".join(METRICS))
    p.add_argument("--part", default="all", choices=("all", "reference", "methods", "analyse"))
    p.add_argument("--extra", action="store_true", help="also the grid-free Newton from the depth")
    p.add_argument("--reference-eyes", type=int, default=0,
                   help="float64 reference for the first N eyes only (0: all); errors are "
                        "measured on the eyes that have one")
    p.add_argument("--force", action="store_true", help="re-run cached method results")
    p.add_argument("--methods", default="", help="only these methods (development)")
    p.add_argument("--tag", default="", help="cache sub-folder (development runs)")
    p.add_argument("--wavelengths", default="",
                   help="comma-separated wavelengths, nm (default: 420–660 nm in 40 nm); the "
                        "reference uses the same, so the count sets cost, not the errors")
    args = p.parse_args()
    args.layouts = args.layouts.split(",")
    args.metrics = args.metrics.split(",")
    args.solver_eyes = min(args.solver_eyes, args.eyes)
    global CACHE, WAVELENGTHS_NM
    suffix = ""
    if args.wavelengths:
        WAVELENGTHS_NM = np.array([float(w) for w in args.wavelengths.split(",")])
        if WAVELENGTHS_NM.size < 1 or np.any((WAVELENGTHS_NM < 380) | (WAVELENGTHS_NM > 780)):
            p.error("--wavelengths must list wavelengths in 380–780 nm")
        suffix = "_wl" + "-".join(f"{w:g}" for w in WAVELENGTHS_NM)
    CACHE = CACHE / (args.tag or f"seed{args.seed}_eyes{args.eyes}{suffix}")
    CACHE.mkdir(parents=True, exist_ok=True)
    t_start = time.perf_counter()
    if args.part != "reference":
        header()
    if args.part in ("all", "reference", "methods"):
        eyes_path = CACHE / "eyes.npz"
        if not eyes_path.exists():
            import lfjax

            z = np.asarray(lfjax.sample_eyes(args.seed, args.eyes, measured_pupil_mm=PUPIL_MM).zernike_um,
                           np.float32)
            np.savez(eyes_path, zernike_um=z, seed=args.seed)
    if args.part == "reference":
        run_reference(args)
        return
    if args.part in ("all", "methods"):
        t0 = time.perf_counter()
        run_methods(args)
        print(f"methods: {time.perf_counter() - t0:.0f} s", flush=True)
    if args.part == "all":
        cmd = [sys.executable, __file__, "--part", "reference", "--eyes", str(args.eyes),
               "--reference-eyes", str(args.reference_eyes),
               "--seed", str(args.seed), "--chunk", str(args.chunk), "--layouts",
               ",".join(args.layouts)] + (["--tag", args.tag] if args.tag else []) + (
                   ["--wavelengths", args.wavelengths] if args.wavelengths else [])
        t0 = time.perf_counter()
        subprocess.run(cmd, check=True)
        print(f"reference (float64, subprocess): {time.perf_counter() - t0:.0f} s", flush=True)
    analyse(args)
    print(f"\ntotal wall time of this command: {time.perf_counter() - t_start:.0f} s")


def analyse(args):
    z = np.load(CACHE / "eyes.npz")["zernike_um"]
    runs = load_all(args)
    rows = summarise(runs)
    out_dir = HERE if not args.tag else CACHE
    write_csv(rows, out_dir / "peak_finding.csv")
    wl = f"{WAVELENGTHS_NM.size} wavelength{'s' if WAVELENGTHS_NM.size > 1 else ''} " + (
        f"{WAVELENGTHS_NM[0]:.0f}–{WAVELENGTHS_NM[-1]:.0f} nm / {WAVELENGTHS_NM[1] - WAVELENGTHS_NM[0]:.0f} nm"
        if WAVELENGTHS_NM.size > 1 else f"{WAVELENGTHS_NM[0]:.0f} nm")
    plot(rows, out_dir / "peak_finding.png", wl)
    kinds = find_failure_cases(runs, args.seed, args.eyes, z, args.solver_eyes)
    ref_seconds = {name: float(np.load(CACHE / f"reference_{name}.npz")["seconds"])
                   for name in args.layouts if (CACHE / f"reference_{name}.npz").exists()}
    doc = dict(
        about="Failure cases of accommodation peak finding (benchmarks/validation/peak_finding.py, "
              "issue #10 "
              "part A). Each example names the eye (seed, index, coefficients), layout, rendered "
              "depth and metric, the float64 0.01 D reference, and what every method returned.",
        scene=dict(pupil_mm=PUPIL_MM, cdp_D=CDP_D, natural_view="cdp_D = rendered depth",
                   window_D=WINDOW_D, grid_D=[0.0, 5.0, 0.2], wavelengths_nm=WAVELENGTHS_NM.tolist(),
                   options="lfjax.ModelOptions() defaults",
                   sampling="lfjax.planner.plan.plan_sampling(..., estimate_accuracy=False) per layout"),
        methods_note=dict(atol_D=ATOL_D, max_steps=MAX_STEPS, silent_threshold_D=SILENT_D),
        reference_seconds=ref_seconds,
        kinds=kinds)
    with open(out_dir / "peak_failure_cases.json", "w") as f:
        json.dump(doc, f, indent=1)
    print(f"\nscene: 3 mm pupil, CDP 2 D (natural view: a real point, cdp = depth), depths 0–4 D / 0.5, "
          f"states 0–5 D within ±1 D, {wl}; eyes: seed {args.seed}, {args.eyes} for grid0.2/parabola, "
          f"first {args.solver_eyes} for the rest; chunk {args.chunk} eyes per call")
    for metric in args.metrics:
        print(f"\n## {metric.upper()}, all layouts\n")
        print(markdown(rows, metric))
        for layout in args.layouts:
            print(f"\n### {metric.upper()}, {layout}\n")
            print(markdown(rows, metric, layout))
    print("\n## failure cases (benchmarks/validation/peak_failure_cases.json)\n")
    for k, v in kinds.items():
        ex = "; ".join(f"{x['layout']} {x['metric']} eye {x['eye_index']} depth {x['depth_D']:g}"
                       for x in v["examples"])
        print(f"- {k} ({v['count']} cases): {ex}")
    print(f"\nreference seconds per layout: {ref_seconds}")


if __name__ == "__main__":
    main()
