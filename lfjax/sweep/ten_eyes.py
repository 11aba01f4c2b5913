"""What ten eyes cannot tell: how often a random sample of ten eyes reproduces each claim.

The paper (and ``lfjax reproduce``) judges its seven findings on ten virtual eyes plus the
Thibos average eye. A sweep of many eyes gives the distribution those ten were drawn from.
:func:`ten_eye_claims` draws ``n_draws`` samples of ``sample_size`` eyes without replacement
from a sweep's population (the average eye excluded from the draw, then appended to every
sample, since claims 4 and 5 compare against it), evaluates
:func:`lfjax.vision.claims.evaluate_claims` on each sample, and reports for every claim
the fraction of samples in which it holds, a 95 % Wilson score interval for that fraction,
the samples where it could not be evaluated, and the population's own answer (the claims
evaluated on all of the population's eyes). :func:`ten_eye_markdown` renders the table and
:func:`ten_eye_table` gives it as a pandas DataFrame (the CSV).

The interval is a Monte Carlo interval: it bounds the probability that a random sample of
this size *from this population* (the sweep's eyes) reproduces the claim, given the finite
number of draws. It says nothing about eyes outside the sweep.

Speed: the population's numbers are read from the Dataset once
(:class:`lfjax.vision.claim_core.StudyNumbers`) and each sample is a selection of its eyes
(:meth:`~lfjax.vision.claim_core.StudyNumbers.take_eyes`), judged by the claims' one
declaration (:data:`lfjax.vision.claims.CLAIMS`, through
:func:`~lfjax.vision.claims.evaluate_claims`): the same code, on the same numbers, as a
study's own verdicts, without xarray's indexing per (layout, depth) cell.
"""

from __future__ import annotations

import math
import time
import warnings
from pathlib import Path

import numpy as np

from lfjax.vision.claim_core import StudyNumbers
from lfjax.vision.claims import evaluate_claims
from lfjax.sweep.store import open_store, study_view
from lfjax.sweep.store_checks import is_store, ZARR_FORMAT

Z_95 = 1.959963984540054
"""Standard normal quantile of 0.975 (two-sided 95 % interval)."""

INTERVAL = "Wilson score interval, 95 % (z = 1.96), over the samples where the claim was evaluated"

VERDICT_CODES = {True: 1, False: 0, None: -1}
"""How a claim's ``holds`` is stored in :func:`ten_eye_claims`'s ``verdict`` (int8)."""

_CLAIM_VARIABLES = (
    "accommodation_error",
    "predicted_accommodation",
    "predicted_accommodation_continuous",
    "continuous_peak_success",
    "peak_value",
    "cutoff_frequency",
    "mtf_at_peak",
    "zernike_um",
)
"""Data variables of a study Dataset that :func:`~lfjax.vision.claims.evaluate_claims`
reads (with the coordinates ``is_average`` and ``depth_rel_cdp`` and the dimension labels).
The through-focus curves (``vsotf``, ``strehl``: an accommodation axis each) are not read
and are left out of every sample, which keeps the samples small."""


# --------------------------------------------------------------------------- statistics


def wilson_interval(successes, trials, z: float = Z_95) -> tuple[np.ndarray, np.ndarray]:
    """Wilson score interval for a binomial proportion ``successes / trials``.

    ``successes``, ``trials``: counts (scalars or arrays of one shape), 0 ≤ successes ≤
    trials. Returns (low, high) as float arrays in [0, 1]; NaN where ``trials`` is 0. Unlike
    the normal (Wald) interval it stays inside [0, 1] and is not empty at 0 or 1 successes.
    """
    k = np.asarray(successes, float)
    n = np.asarray(trials, float)
    if np.any(k < 0) or np.any(k > n):
        raise ValueError(f"successes must lie in [0, trials], got {k} of {n}")
    with np.errstate(invalid="ignore", divide="ignore"):
        p = k / n
        z2 = z * z
        denom = 1.0 + z2 / n
        centre = (p + z2 / (2.0 * n)) / denom
        half = z / denom * np.sqrt(p * (1.0 - p) / n + z2 / (4.0 * n * n))
        # at 0 (all) successes the bound is exactly 0 (1); the formula leaves round-off
        # (2.8e-17) that tables would print and that can exceed the fraction itself
        low = np.where(n > 0, np.where(k == 0, 0.0, np.clip(centre - half, 0.0, 1.0)), np.nan)
        high = np.where(n > 0, np.where(k == n, 1.0, np.clip(centre + half, 0.0, 1.0)), np.nan)
    return low, high


def draw_samples(n_population: int, n_draws: int, sample_size: int, seed: int) -> np.ndarray:
    """(n_draws, sample_size) int: positions among ``n_population`` eyes, each row drawn
    without replacement (rows independent of one another) and sorted, so a sample lists its
    eyes in the population's order. Seeded: ``numpy.random.default_rng(seed)``."""
    rng = np.random.default_rng(seed)
    out = np.empty((n_draws, sample_size), np.int64)
    for i in range(n_draws):
        out[i] = np.sort(rng.choice(n_population, size=sample_size, replace=False))
    return out


# --------------------------------------------------------------------------- the draws


def claims_view(ds_or_view, pupil_mm: float | None = None):
    """The population's study Dataset with only what the claims read.

    ``ds_or_view``: a sweep store's path, its Dataset (:func:`lfjax.sweep.open_store`; one
    pupil is chosen by ``pupil_mm``, mm) or a study view (:func:`lfjax.sweep.study_view`).
    Raises ValueError when the population has no average eye, or has eyes without results
    (a store read while incomplete without ``complete_only=True``).
    """
    import xarray as xr


    if isinstance(ds_or_view, (str, Path)):
        if not is_store(ds_or_view):
            raise ValueError(f"ds_or_view: {ds_or_view} is not an lfjax sweep store")
        ds_or_view = open_store(ds_or_view, complete_only=True)
    if not isinstance(ds_or_view, xr.Dataset):
        raise TypeError(f"ds_or_view must be a sweep store path or an xarray.Dataset, got "
                        f"{type(ds_or_view).__name__}")
    if "pupil" in ds_or_view.dims:
        if pupil_mm is None and ds_or_view.sizes["pupil"] > 1:
            raise ValueError(f"pupil_mm: the store holds pupils "
                             f"{ds_or_view.pupil.values.tolist()} mm; name one")
        view = study_view(ds_or_view, pupil_mm)
    else:
        view = ds_or_view
        stored = view.attrs.get("pupil_diameter_mm")
        if pupil_mm is not None and stored is not None and not np.isclose(pupil_mm, stored):
            raise ValueError(f"pupil_mm={pupil_mm} but the study view is of the "
                             f"{stored} mm pupil")
    missing = [n for n in _CLAIM_VARIABLES if n not in view.data_vars]
    if missing or "is_average" not in view.coords:
        raise ValueError(f"ds_or_view is not a sweep or study Dataset: it lacks "
                         f"{missing + ([] if 'is_average' in view.coords else ['is_average'])}")
    n_avg = int(view.is_average.sum())
    if n_avg != 1:
        raise ValueError(f"the population needs exactly one average eye (claims 4 and 5 compare "
                         f"against it; sweep config population.average_eye = true), found {n_avg}")
    empty = np.all(np.isnan(view.predicted_accommodation.values), axis=tuple(
        i for i, d in enumerate(view.predicted_accommodation.dims) if d != "eye"))
    if np.any(empty):
        labels = ", ".join(map(str, view.eye.values[empty][:5]))
        raise ValueError(f"{int(empty.sum())} eye(s) have no results ({labels}"
                         f"{' …' if empty.sum() > 5 else ''}): an incomplete sweep; open it with "
                         f"lfjax.sweep.open_store(path, complete_only=True)")
    keep = [n for n in view.data_vars if n in _CLAIM_VARIABLES]
    light = view[keep]
    light.attrs = dict(view.attrs)
    return light


def check_population_store(store_path, sample_size: int = 10,
                           prefer_pupil_mm: float | None = None) -> float:
    """Check, from the store's metadata alone (nothing computed, nothing large read), that
    :func:`ten_eye_claims` can run on ``store_path``; returns the pupil (mm) to use.

    The pupil: ``prefer_pupil_mm`` when the store has it, else the store's only pupil.
    Raises ValueError naming the problem: not a sweep store, no average eye, fewer complete
    virtual eyes than ``sample_size``, several pupils and none preferred.
    """
    import xarray as xr


    if not is_store(store_path):
        raise ValueError(f"{store_path} is not an lfjax sweep store (a folder written by "
                         f"`lfjax sweep`)")
    ds = xr.open_zarr(str(store_path), consolidated=False, zarr_format=ZARR_FORMAT)
    pupils = [float(p) for p in ds.pupil.values]
    if prefer_pupil_mm is not None and np.any(np.isclose(pupils, prefer_pupil_mm)):
        pupil = float(pupils[int(np.argmin(np.abs(np.subtract(pupils, prefer_pupil_mm))))])
    elif len(pupils) == 1:
        pupil = pupils[0]
    else:
        raise ValueError(f"{store_path} holds pupils {pupils} mm"
                         + (f", not {prefer_pupil_mm:g} mm" if prefer_pupil_mm is not None
                            else "") + ": name one")
    size = int(ds.attrs["chunk_size"])
    done = np.repeat(np.asarray(ds.chunk_complete.values, bool), size)[: ds.sizes["eye"]]
    is_avg = np.asarray(ds.is_average.values, bool)
    if not np.any(is_avg & done):
        raise ValueError(f"{store_path} has no complete average eye (claims 4 and 5 compare "
                         f"against it; sweep config population.average_eye = true)")
    n_virtual = int(np.sum(~is_avg & done))
    if n_virtual < sample_size:
        raise ValueError(f"sample_size={sample_size} is larger than the population of "
                         f"{store_path}: {n_virtual} complete virtual eyes")
    return pupil


def _whole_number(name: str, value, least: int) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < least:
        raise ValueError(f"{name} must be a whole number >= {least}, got {value!r}")
    return int(value)


def _draw_rows(virtual: np.ndarray, average: np.ndarray, n_draws: int, sample_size: int,
               seed: int) -> tuple[np.ndarray, int, int]:
    """(rows, n_possible, n_distinct): each row one sample's eye positions, the average eye
    last; warns when the draws must repeat samples."""
    samples = draw_samples(virtual.size, n_draws, sample_size, seed)
    n_possible = math.comb(int(virtual.size), sample_size)
    n_distinct = int(np.unique(samples, axis=0).shape[0])
    if n_possible < n_draws:
        warnings.warn(
            f"only {n_possible} distinct samples of {sample_size} exist among "
            f"{virtual.size} eyes, and {n_draws} draws repeat them ({n_distinct} distinct "
            f"drawn): the intervals, which count {n_draws} samples, overstate the "
            f"precision; use a larger population or n_draws <= {n_possible}",
            UserWarning, stacklevel=3)
    rows = np.concatenate([virtual[samples], np.broadcast_to(average, (samples.shape[0], 1))],
                          axis=1)
    return rows, n_possible, n_distinct


def _summary(view, population, verdict: np.ndarray, rows: np.ndarray, attrs: dict):
    """The result Dataset of :func:`ten_eye_claims` from its verdicts (draw, claim)."""
    import xarray as xr

    n_holds = (verdict == 1).sum(axis=0)
    n_fails = (verdict == 0).sum(axis=0)
    n_na = (verdict == -1).sum(axis=0)
    evaluated = n_holds + n_fails
    with np.errstate(invalid="ignore", divide="ignore"):
        fraction = np.where(evaluated > 0, n_holds / np.maximum(evaluated, 1), np.nan)
    low, high = wilson_interval(n_holds, evaluated)
    labels = view.eye.values
    return xr.Dataset(
        data_vars=dict(
            verdict=(("draw", "claim"), verdict, {
                "long_name": "claim verdict on the sample: 1 holds, 0 fails, -1 n/a"}),
            sample_eye=(("draw", "sample"), labels[rows[:, :-1]], {
                "long_name": "the sample's virtual eyes (the average eye is appended to each)"}),
            n_holds=("claim", n_holds.astype(np.int64)),
            n_fails=("claim", n_fails.astype(np.int64)),
            n_na=("claim", n_na.astype(np.int64), {
                "long_name": "samples on which the claim could not be evaluated"}),
            fraction_holds=("claim", fraction, {
                "long_name": "fraction of the evaluated samples on which the claim holds",
                "units": "1"}),
            ci_low=("claim", low, {"long_name": f"lower bound, {INTERVAL}", "units": "1"}),
            ci_high=("claim", high, {"long_name": f"upper bound, {INTERVAL}", "units": "1"}),
            population_verdict=("claim", np.array([c.verdict for c in population]), {
                "long_name": f"verdict on all {attrs['n_population']} virtual eyes and the "
                             f"average eye"}),
            population_result=("claim", np.array([c.result for c in population])),
            finding=("claim", np.array([c.finding for c in population])),
        ),
        coords=dict(claim=("claim", np.array([c.id for c in population])),
                    draw=np.arange(rows.shape[0]), sample=np.arange(rows.shape[1] - 1)),
        attrs=attrs,
    )


def ten_eye_claims(ds_or_view, n_draws: int = 1000, sample_size: int = 10, seed: int = 0,
                   pupil_mm: float | None = None, progress: bool = False):
    """How often a sample of ``sample_size`` eyes reproduces each of the paper's claims.

    Parameters
    ----------
    ds_or_view : a sweep store path, its Dataset or a study view (see :func:`claims_view`)
    n_draws : samples drawn, ≥ 1
    sample_size : eyes per sample (the paper: 10), 1 ≤ sample_size ≤ the population's
        virtual eyes; the average eye is appended to every sample
    seed : seed of the draws (:func:`draw_samples`); same seed, same samples
    pupil_mm : the pupil of a multi-pupil store, mm
    progress : show a progress bar (stderr)

    Returns
    -------
    xarray.Dataset with dims ``claim`` (the claims' ids), ``draw`` and ``sample``:
    ``verdict`` (draw, claim) int8 — 1 holds, 0 fails, −1 n/a (:data:`VERDICT_CODES`);
    ``sample_eye`` (draw, sample) — the eyes of each sample (labels); per claim
    ``n_holds``, ``n_fails``, ``n_na``, ``fraction_holds`` (n_holds / (n_holds + n_fails);
    NaN when never evaluated), ``ci_low``, ``ci_high`` (:func:`wilson_interval`),
    ``population_verdict`` ("holds"/"fails"/"n/a" on all eyes), ``population_result``,
    ``finding``. Attributes: ``n_draws``, ``sample_size``, ``seed``, ``n_population``
    (virtual eyes), ``pupil_mm``, ``interval``, ``seconds`` (all, s), ``draw_seconds``
    (the draws alone, s), ``draws_per_second``.
    """
    n_draws = _whole_number("n_draws", n_draws, 1)
    sample_size = _whole_number("sample_size", sample_size, 1)
    seed = _whole_number("seed", seed, 0)
    view = claims_view(ds_or_view, pupil_mm)
    is_avg = view.is_average.values
    virtual = np.flatnonzero(~is_avg)
    average = np.flatnonzero(is_avg)
    if sample_size > virtual.size:
        raise ValueError(f"sample_size={sample_size} is larger than the population "
                         f"({virtual.size} virtual eyes, the average eye not counted)")

    t0 = time.perf_counter()
    numbers = StudyNumbers.from_dataset(view)
    population = evaluate_claims(numbers)
    ids = [c.id for c in population]
    rows, n_possible, n_distinct = _draw_rows(virtual, average, n_draws, sample_size, seed)

    from tqdm.auto import tqdm

    t_draws = time.perf_counter()
    verdict = np.empty((rows.shape[0], len(ids)), np.int8)
    for i in tqdm(range(rows.shape[0]), disable=not progress, unit="draw", dynamic_ncols=True,
                  desc=f"samples of {sample_size}"):
        claims = evaluate_claims(numbers.take_eyes(rows[i]))
        verdict[i] = [VERDICT_CODES[c.holds] for c in claims]
    now = time.perf_counter()
    return _summary(view, population, verdict, rows, dict(
        n_draws=n_draws, sample_size=sample_size, seed=seed,
        n_population=int(virtual.size),
        n_possible_samples=float(n_possible), n_distinct_samples=n_distinct,
        pupil_mm=float(view.attrs.get("pupil_diameter_mm", np.nan)),
        interval=INTERVAL, seconds=float(now - t0), draw_seconds=float(now - t_draws),
        draws_per_second=float(n_draws / (now - t_draws)),
    ))


# --------------------------------------------------------------------------- presentation


def ten_eye_table(result):
    """One row per claim (pandas DataFrame): the columns of the markdown table, as numbers."""
    import pandas as pd

    a = result.attrs
    return pd.DataFrame(dict(
        claim=result.claim.values.astype(str),
        pupil_mm=a["pupil_mm"],
        sample_size=a["sample_size"],
        n_draws=a["n_draws"],
        seed=a["seed"],
        n_population=a["n_population"],
        n_holds=result.n_holds.values,
        n_fails=result.n_fails.values,
        n_na=result.n_na.values,
        fraction_holds=result.fraction_holds.values,
        ci_low=result.ci_low.values,
        ci_high=result.ci_high.values,
        population_verdict=result.population_verdict.values.astype(str),
        finding=result.finding.values.astype(str),
    ))


def _pct(x: float) -> str:
    return "–" if not math.isfinite(x) else f"{100.0 * x:.1f} %"


def ten_eye_markdown(result, this_run: list | None = None, heading: str | None = None) -> str:
    """The ten-eye table as markdown: per claim, how often it holds in the samples (with
    its interval), the samples where it was n/a, and the population's answer.

    ``this_run``: claims of one particular run (e.g. the reproduction's own ten eyes,
    :class:`lfjax.reproduce.Claim`) shown as one more column; ``heading``: a line put first.
    """
    a = result.attrs
    k = a["sample_size"]
    lines = [] if heading is None else [heading, ""]
    lines.append(
        f"From a sweep of {a['n_population']:,} virtual eyes ({a['pupil_mm']:g} mm pupil), "
        f"{a['n_draws']:,} samples of {k} eyes drawn without replacement (draw seed {a['seed']}), "
        f"the average eye added to each; every sample is judged by the criteria of "
        f"`lfjax reproduce` (`evaluate_claims`). Interval: {INTERVAL}; it is the Monte Carlo "
        f"uncertainty of the fraction for this population, not for eyes beyond the sweep.")
    lines.append("")
    cols = ["claim", "finding", f"holds in samples of {k}", "95 % interval", "n/a",
            f"all {a['n_population']:,} eyes"]
    if this_run is not None:
        cols.append("this run")
    lines.append("| " + " | ".join(cols) + " |")
    lines.append("|" + "---|" * len(cols))
    mine = {c.id: c.verdict for c in (this_run or [])}
    for i, cid in enumerate(result.claim.values):
        n_h, n_f = int(result.n_holds[i]), int(result.n_fails[i])
        frac = float(result.fraction_holds[i])
        ci = (f"{_pct(float(result.ci_low[i]))} – {_pct(float(result.ci_high[i]))}"
              if n_h + n_f else "–")
        finding = " ".join(str(result.finding.values[i]).split()).replace("|", "\\|")
        cells = [str(cid), finding,
                 f"{_pct(frac)} ({n_h}/{n_h + n_f})", ci, str(int(result.n_na[i])),
                 f"**{result.population_verdict.values[i]}**"]
        if this_run is not None:
            cells.append(mine.get(str(cid), "–"))
        lines.append("| " + " | ".join(cells) + " |")
    lines.append("")
    lines.append(f"({a['n_draws']:,} draws in {a['seconds']:.1f} s, {a['draws_per_second']:.0f} "
                 f"draws/s.)")
    return "\n".join(lines) + "\n"


__all__ = [
    "INTERVAL",
    "VERDICT_CODES",
    "Z_95",
    "check_population_store",
    "claims_view",
    "draw_samples",
    "ten_eye_claims",
    "ten_eye_markdown",
    "ten_eye_table",
    "wilson_interval",
]
