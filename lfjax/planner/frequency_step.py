"""The frequency step (and, for the MFT, the pupil samples) a plan needs: down the ladder from
the field guard's step until the proxy's error estimates meet every target, the cheaper of
FFT and MFT by the cost model, and one step cheaper in each dimension with why it fails.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from lfjax.base.sampling import Sampling
from lfjax.base.units import DEGREES_PER_RADIAN
from lfjax.base.zernike import n_modes_for_order
from lfjax.model.spectral import make_spectrum
from lfjax.planner.cost import cost_s
from lfjax.planner.ladder import STEPS_PER_OCTAVE, ladder_up
from lfjax.planner.proxy import Estimates, Proxy
from lfjax.planner.state import PlanningState

MFT_PUPIL_LADDER = (16, 20, 24, 28, 32, 40, 48, 56, 64, 80, 96, 112, 128, 160, 192, 256)
"""Pupil samples across the MFT window the planner chooses from."""


def guard_only_sampling(p: PlanningState) -> tuple:
    """The field guard's step (or the one given, if the guard accepts it); no proxy."""
    freq_step_cpd = p.overrides.freq_step_cpd
    df = float(freq_step_cpd) if freq_step_cpd is not None else p.df_top
    if df > p.df_guard * p.guard.margin:
        raise ValueError(
            f"freq_step_cpd={df} aliases: the scene's blur ({p.radius:.1f} arcmin) needs "
            f"freq_step_cpd <= {p.df_guard * p.guard.margin:.3g} cpd")
    sampling = Sampling(df, edge_width_samples=p.overrides.edge_width_samples)
    bands = p.bands(sampling)
    p.reasons.append(f"field guard only (estimate_accuracy=False): df {df:.4g} cpd")
    p.errors.update(pupil=float("nan"), psf_wrap=float("nan"), total=float("nan"))
    return sampling, bands, {}, {}


def accuracy_sampling(p: PlanningState) -> tuple:
    """The frequency step (and the MFT's pupil samples) the proxy's estimates accept, the
    cheaper neighbours and why they fail, and the plan's error totals."""
    s, t, o = p.scene, p.targets, p.overrides
    spectrum = make_spectrum(p.wl, s.options, weights=p.weights)
    proxy = Proxy(s, spectrum, o.edge_width_samples)
    pairs = (s.pair_acc, s.pair_depth)  # all of them: the error peaks anywhere
    if o.freq_step_cpd is not None:
        if o.freq_step_cpd > p.df_guard * p.guard.margin:
            raise ValueError(
                f"freq_step_cpd={o.freq_step_cpd} aliases: the scene's blur ({p.radius:.1f} arcmin) "
                f"needs freq_step_cpd <= {p.df_guard * p.guard.margin:.3g} cpd"
            )
        df_candidates = [float(o.freq_step_cpd)]
    else:
        df_candidates = [p.df_top / 2.0 ** (k / STEPS_PER_OCTAVE) for k in range(0, 24)]
    estimates = Estimates(proxy, pairs, df_candidates[0],
                          p.budget if math.isfinite(p.budget) else 1e-3)
    # what the wavelength step left of the D / cpd targets (all of them for a given spectrum)
    peak_budget = cutoff_budget = None
    if t.peak_D is not None:
        peak_budget = t.peak_D - np.nan_to_num(p.errors.get("spectral_peak_D", 0.0))
    if t.cutoff_cpd is not None:
        cutoff_budget = t.cutoff_cpd - np.nan_to_num(p.errors.get("spectral_cutoff_cpd", 0.0))
    fft_plan, mft_field = _search_frequency_step(p, estimates, df_candidates, peak_budget,
                                                 cutoff_budget)
    df_fft, e_pupil_fft, wrap_fft = fft_plan

    n_modes = np.shape(s.eyes_zernike_um)[-1] if s.eyes is not None else 15
    if p.order_kept is not None:
        n_modes = min(n_modes, n_modes_for_order(p.order_kept))
    n_states = s.accommodation.size
    fft_sampling = Sampling(df_fft, edge_width_samples=o.edge_width_samples)
    fft_bands = p.bands(fft_sampling)
    cost = {"fft": cost_s(fft_bands, s.layout.n_subapertures, n_states, n_modes, fft_sampling)}
    mft_plan = _plan_mft(p, estimates, mft_field, df_fft, cost, n_states, n_modes)
    use_mft = mft_plan is not None and (
        o.transform == "mft" or (o.transform == "auto" and cost["mft"] < cost["fft"])
    )
    cheaper: dict = {}
    errors, budget = p.errors, p.budget
    if use_mft:
        sampling, errors["pupil"], errors["psf_wrap"], bands = mft_plan
        p.reasons.append(
            f"MFT: {sampling.mft_pupil_samples} pupil samples (VSOTF error {errors['pupil']:.2g}), "
            f"df {sampling.freq_step_cpd:.4g} cpd; modelled {cost['mft']:.3g} s vs FFT {cost['fft']:.3g} s per eye"
        )
        m = sampling.mft_pupil_samples
        cheaper_m = max([x for x in MFT_PUPIL_LADDER if x < m], default=None)
        if cheaper_m is not None:
            e = estimates.mft(sampling.freq_step_cpd, cheaper_m)
            cheaper["pupil"] = (dataclasses.replace(sampling, mft_pupil_samples=cheaper_m),
                                f"{cheaper_m} MFT pupil samples: VSOTF error {e:.2g} > budget {budget:.2g}")
    else:
        sampling, errors["pupil"], errors["psf_wrap"], bands = fft_sampling, e_pupil_fft, wrap_fft, fft_bands
        d_min, wl = s.smallest_diameter_mm, p.wl
        p.reasons.append(
            f"FFT: df {df_fft:.4g} cpd → {d_min / (float(wl.max()) * 1e-6 * df_fft * DEGREES_PER_RADIAN):.1f} "
            f"pupil samples across the smallest subaperture ({d_min:.3g} mm) at {wl.max():g} nm; "
            f"proxy VSOTF error {e_pupil_fft:.2g} (budget {budget:.2g}), wrapped PSF/peak "
            f"{wrap_fft:.2g} (tolerance {t.psf:g})"
            + (f"; MFT would cost {cost['mft']:.3g} s vs {cost['fft']:.3g} s per eye (modelled)"
               if "mft" in cost else "")
        )
    if o.freq_step_cpd is None:
        _one_step_cheaper(p, estimates, sampling, use_mft, peak_budget, cutoff_budget, cheaper)
    if t.peak_D is not None and not use_mft:
        errors["peak_D"] = np.nan_to_num(errors.get("spectral_peak_D", 0.0)) + \
            estimates.peak_shift(sampling.freq_step_cpd)
        p.reasons.append(f"peaks: proxy shift ≤ {errors['peak_D']:.2g} D (target {t.peak_D:g} D)")
    if t.cutoff_cpd is not None and not use_mft:
        errors["cutoff_cpd"] = np.nan_to_num(errors.get("spectral_cutoff_cpd", 0.0)) + \
            estimates.cutoff_shift(sampling.freq_step_cpd, t.cutoff_threshold)
        p.reasons.append(f"cut-offs: proxy shift ≤ {errors['cutoff_cpd']:.2g} cpd "
                         f"(target {t.cutoff_cpd:g} cpd)")
    errors["total"] = errors["pupil"] + errors["zernike"] + (
        errors["spectral"] if np.isfinite(errors["spectral"]) else 0.0)
    return sampling, bands, cost, cheaper


def _search_frequency_step(p: PlanningState, estimates: Estimates, df_candidates, peak_budget,
                           cutoff_budget):
    """Down the ladder from the guard's step: the FFT's first step that meets every target
    and whose wrapped PSF is within ``Targets.psf`` — (df, VSOTF error, wrapped PSF) — and,
    unless the transform is the FFT, the MFT's field step (df, wrapped, truncation error) or
    None."""
    t, o, budget = p.targets, p.overrides, p.budget
    freq_step_cpd, transform = o.freq_step_cpd, o.transform
    fft_plan = None
    mft_field = None
    found_at = None
    for i, df in enumerate(df_candidates):
        if fft_plan is not None and (mft_field is not None or transform == "fft" or i > found_at + 3):
            break
        e_pupil = estimates.vsotf(df)
        meets = e_pupil <= budget
        if meets and peak_budget is not None:
            meets = estimates.peak_shift(df) <= peak_budget
        if meets and cutoff_budget is not None:
            meets = estimates.cutoff_shift(df, t.cutoff_threshold) <= cutoff_budget
        want_fft = fft_plan is None and (meets or freq_step_cpd is not None)
        want_mft = transform != "fft" and mft_field is None
        if not (want_fft or want_mft):
            continue  # the PSF on twice the field is the costly part: only where it decides
        wrapped, truncation = estimates.psf(df)
        psf_ok = wrapped <= t.psf
        # MFT truncates the PSF at the field edge: it may need a finer step than the FFT
        if want_mft and ((psf_ok and truncation <= 0.25 * budget) or freq_step_cpd is not None):
            mft_field = (df, wrapped, truncation)
        if want_fft and (psf_ok or freq_step_cpd is not None):
            fft_plan, found_at = (df, e_pupil, wrapped), i
    if fft_plan is None:
        raise ValueError(
            f"no frequency step down to {df_candidates[-1]:.3g} cpd meets Targets.vsotf="
            f"{t.vsotf} and Targets.psf={t.psf:g}; loosen the target"
        )
    return fft_plan, mft_field


def _plan_mft(p: PlanningState, estimates: Estimates, mft_field, df_fft: float, cost: dict,
              n_states: int, n_modes: int):
    """The MFT's plan — (Sampling, VSOTF error, wrapped PSF, bands) — at its field step, with
    the fewest pupil samples that meet the VSOTF budget (or those given); None when the
    transform is the FFT or no field step was found. Adds the MFT's cost to ``cost``."""
    s, o = p.scene, p.overrides
    if o.transform not in ("auto", "mft") or mft_field is None:
        return None
    df_mft = mft_field[0]
    mft_budget = p.budget  # the MFT proxy truncates the PSF itself: its error includes the field's
    if o.mft_pupil_samples is not None:
        ladder = [o.mft_pupil_samples]
    else:
        # start just below the samples the FFT plan puts across the largest view
        fft_samples = s.largest_diameter_mm / (float(p.wl.max()) * 1e-6 * df_fft * DEGREES_PER_RADIAN)
        start = max([i for i, m in enumerate(MFT_PUPIL_LADDER) if m <= 0.6 * fft_samples], default=0)
        while start > 0 and estimates.mft(df_mft, MFT_PUPIL_LADDER[start]) <= mft_budget:
            start -= 1
        ladder = list(MFT_PUPIL_LADDER[start:])
    for m in ladder:
        e = estimates.mft(df_mft, m)
        if e <= mft_budget or o.mft_pupil_samples is not None:
            sampling = Sampling(df_mft, edge_width_samples=o.edge_width_samples, transform="mft",
                                mft_pupil_samples=m)
            bands = p.bands(sampling)
            cost["mft"] = cost_s(bands, s.layout.n_subapertures, n_states, n_modes, sampling)
            return sampling, e, mft_field[1], bands
    return None


def _one_step_cheaper(p: PlanningState, estimates: Estimates, sampling: Sampling, use_mft: bool,
                      peak_budget, cutoff_budget, cheaper: dict) -> None:
    """The frequency step one ladder step cheaper, and the reason it fails (in ``cheaper``)."""
    t, budget, df_guard = p.targets, p.budget, p.df_guard
    up = ladder_up(sampling.freq_step_cpd)
    if up > df_guard:
        cheaper["field"] = (dataclasses.replace(sampling, freq_step_cpd=up),
                            f"df {up:.4g} cpd: refused by the aliasing guard (needs ≤ {df_guard:.4g})")
        return
    e, (wrapped_up, _) = estimates.vsotf(up), estimates.psf(up)
    if not use_mft:
        if e > budget:
            cheaper["pupil"] = (dataclasses.replace(sampling, freq_step_cpd=up),
                                f"df {up:.4g} cpd: VSOTF error {e:.2g} > budget {budget:.2g}")
        elif peak_budget is not None and estimates.peak_shift(up) > peak_budget:
            cheaper["pupil"] = (dataclasses.replace(sampling, freq_step_cpd=up),
                                f"df {up:.4g} cpd: peaks shift {estimates.peak_shift(up):.2g} D "
                                f"> {peak_budget:.2g} D")
        elif (cutoff_budget is not None
              and estimates.cutoff_shift(up, t.cutoff_threshold) > cutoff_budget):
            cheaper["pupil"] = (dataclasses.replace(sampling, freq_step_cpd=up),
                                f"df {up:.4g} cpd: cut-offs shift "
                                f"{estimates.cutoff_shift(up, t.cutoff_threshold):.2g} cpd "
                                f"> {cutoff_budget:.2g} cpd")
    if wrapped_up > t.psf:
        cheaper["field"] = (dataclasses.replace(sampling, freq_step_cpd=up),
                            f"df {up:.4g} cpd: wrapped PSF/peak {wrapped_up:.2g} > {t.psf:g}")



__all__ = ["guard_only_sampling", "accuracy_sampling", "MFT_PUPIL_LADDER"]
