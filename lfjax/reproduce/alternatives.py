"""The modelling alternatives: choices the paper leaves open, and the claims under each.

``ALTERNATIVES`` names each choice as a :class:`~lfjax.ModelOptions` change;
:func:`run_alternatives` reruns the study on :meth:`StudyConfig.reduced
<lfjax.reproduce.config.StudyConfig.reduced>` under each of them (and a baseline on the
same reduced set, with the same states and sampling) and evaluates the claims.

The claims read only peaks: each (eye, depth) metric's grid peak, its continuous refinement,
and the MTF (cut-off frequency) at the VSOTF peak. So the alternatives evaluate only the
accommodation states within ``PRUNE_STEPS`` grid steps of the peaks a study already found (the
main study's, when :func:`lfjax.reproduce.reproduce` passes it), on a sampling planned for
those pairs alone (their blur is far smaller than the ±2 D window's, so the FFTs are smaller).
A peak that lands on the edge of the evaluated states, with unevaluated states of the window
beside it, could be hiding a higher value there: the states around it are added and the
variant is recomputed, so each grid peak is the one the full window gives (tested against
full curves in ``tests/test_alternatives.py``).

Imports :mod:`~lfjax.reproduce.config`, :mod:`~lfjax.reproduce.study` and
:mod:`~lfjax.reproduce.claims` from the package.
"""

from __future__ import annotations

import numpy as np

from ..layouts import paper_layouts
from .claims import evaluate_claims
from .config import StudyConfig, study_eyes
from .study import _planned_sampling, mask_pairs, run_study

ALTERNATIVES: dict[str, dict] = {
    "sce=intensity": {"sce": "intensity"},
    "accommodation_sa=wavefront_5mm": {"accommodation_sa": "wavefront_5mm"},
    "accommodation_sa=unscaled": {"accommodation_sa": "unscaled"},
    "lca_A=633.46": {"lca_A": 633.46},
    "wavelength_normalisation=unit_sum": {"wavelength_normalisation": "unit_sum"},
}
"""Modelling choices the paper leaves open (DESIGN.md §2b), as ``ModelOptions`` changes."""

BASELINE = "baseline (reduced)"

PRUNE_STEPS = 1
"""States within this many accommodation grid steps of a known peak are evaluated (the peak
and its neighbours: 0.2 D on the paper's grid). Elemental OTFs are computed per state for
all eyes and shared by the depths, so the cost follows the union over eyes, metrics and
depths: on the paper's default (10 eyes, depths 1 D apart) the peaks spread enough that the
union still holds 25 of the 26 states for each LF layout (8 of 21 for the natural view).
What the pruning saves there is field: the pairs it keeps need a smaller PSF field, so a
coarser frequency step (benchmarks/RESULTS.md §9). Per-eye state sets would save states too."""

MAX_WIDENINGS = 4


def _layout_depths(name: str, config: StudyConfig) -> np.ndarray:
    return np.array([config.cdp_D]) if name == "natural" else np.asarray(config.depths_D, float)


def _in_window(config: StudyConfig, depths: np.ndarray) -> np.ndarray:
    """(n_depth, n_acc): the states the full study evaluates for each depth."""
    acc = np.asarray(config.accommodation_D, float)
    return np.abs(acc[None] - depths[:, None]) <= config.window_D + 1e-9


def _widen(mask_row: np.ndarray, acc: np.ndarray, peaks_D) -> None:
    half_width = PRUNE_STEPS * float(acc[1] - acc[0]) if acc.size > 1 else 0.0
    for p in np.asarray(peaks_D, float).ravel():
        if np.isfinite(p):
            mask_row |= np.abs(acc - p) <= half_width + 1e-9


def peak_masks(ds, config: StudyConfig) -> dict[str, np.ndarray]:
    """{layout: (n_depth, n_acc) bool}: the states within ``PRUNE_STEPS`` grid steps of any eye's
    VSOTF or Strehl grid peak in ``ds`` (a study whose depths include ``config``'s), at each
    of ``config``'s depths; evaluated for both metrics (each metric's states hold the other's
    candidate peak: for 2×2 the Strehl ratio peaks at the CDP or at the rendered depth)."""
    acc = np.asarray(config.accommodation_D, float)
    if not np.allclose(np.asarray(ds.accommodation.values, float), acc):
        raise ValueError("peak_masks: the study's accommodation grid differs from the config's")
    masks = {}
    for name in config.layouts:
        depths = _layout_depths(name, config)
        mask = np.zeros((depths.size, acc.size), bool)
        for j, d in enumerate(depths):
            k = np.flatnonzero(np.isclose(ds.depth.values, d))
            if k.size != 1:
                raise ValueError(f"peak_masks: depth {d} D is not in the study")
            _widen(mask[j], acc, ds.predicted_accommodation.sel(layout=name).isel(depth=int(k[0])).values)
        masks[name] = mask & _in_window(config, depths)
    return masks


def _edge_peaks(ds, masks: dict, config: StudyConfig) -> dict[str, list]:
    """{layout: [(depth index, peak D), …]} for grid peaks beside an unevaluated state of the
    window (the full curve might be higher there)."""
    acc = np.asarray(config.accommodation_D, float)
    out = {}
    for name, mask in masks.items():
        depths = _layout_depths(name, config)
        window = _in_window(config, depths)
        hits = []
        for j, d in enumerate(depths):
            k = int(np.flatnonzero(np.isclose(ds.depth.values, d))[0])
            peaks = ds.predicted_accommodation.sel(layout=name).isel(depth=k).values.ravel()
            for p in peaks[np.isfinite(peaks)]:
                i = int(np.argmin(np.abs(acc - p)))
                for n in (i - 1, i + 1):
                    if 0 <= n < acc.size and window[j, n] and not mask[j, n]:
                        hits.append((j, float(p)))
                        break
        if hits:
            out[name] = hits
    return out


def run_alternatives(config: StudyConfig, stage=None, baseline=None, variants=None,
                     prune: bool = True, record: dict | None = None) -> dict:
    """Claims under each modelling-choice alternative on :meth:`StudyConfig.reduced`.

    ``baseline``: a study Dataset on ``config``'s grid (the main study) whose peaks say which
    states to evaluate (``prune``); without it the reduced baseline is computed on the whole
    window first. ``variants``: {name: ModelOptions changes} (default ``ALTERNATIVES``).
    ``prune=False`` evaluates every state of the window (the reference the pruning is
    tested against).

    Returns {variant: list[Claim]} with a ``"baseline (reduced)"`` entry first (the same
    states and sampling as the alternatives). ``record`` (a dict, optional) receives what was
    evaluated: {layout: {"states_per_depth", "freq_step_cpd"}} and the widenings made
    (``"widened"``).
    """
    reduced = config.reduced()
    variants = ALTERNATIVES if variants is None else variants
    masks = samplings = None
    info = {"widened": []} if record is None else record
    info.setdefault("widened", [])
    todo = {BASELINE: {}} | dict(variants)
    results = {}

    def sub_stage(name):
        return lambda layout: stage(f"alternative {name}: {layout}") if stage else None

    if prune:
        if baseline is None:
            ds0 = run_study(reduced, config.options, stage=sub_stage(BASELINE))
            results[BASELINE] = evaluate_claims(ds0, config.dof_fraction)
            todo.pop(BASELINE)
            baseline = ds0
        masks = peak_masks(baseline, reduced)
        # one sampling per layout for every variant, planned for the pruned pairs plus a
        # margin of PRUNE_STEPS (so that widening rarely changes what the field must hold)
        eyes, _ = study_eyes(reduced)
        acc = np.asarray(reduced.accommodation_D, float)
        samplings = {}
        for name, mask in masks.items():
            depths = _layout_depths(name, reduced)
            margin = mask.copy()
            for j in range(depths.size):
                _widen(margin[j], acc, acc[mask[j]])
            margin &= _in_window(reduced, depths)
            layout = paper_layouts(reduced.pupil_diameter_mm)[name]
            samplings[name] = _planned_sampling(eyes, layout, depths, reduced, config.options,
                                                pairs=mask_pairs(margin, depths, reduced))
        info.update({name: {"states_per_depth": mask.sum(axis=1).tolist(),
                            "freq_step_cpd": samplings[name].freq_step_cpd}
                     for name, mask in masks.items()})
    for name, change in todo.items():
        options = config.options.replace(**change)
        for _ in range(MAX_WIDENINGS + 1):
            ds = run_study(reduced.replace(options=options), options, stage=sub_stage(name),
                           masks=masks, samplings=samplings)
            edges = _edge_peaks(ds, masks, reduced) if masks is not None else {}
            if not edges:
                break
            acc = np.asarray(reduced.accommodation_D, float)
            for layout_name, hits in edges.items():
                for j, p in hits:
                    _widen(masks[layout_name][j], acc, [p])
                masks[layout_name] &= _in_window(reduced, _layout_depths(layout_name, reduced))
            info["widened"].append({"variant": name, "layouts": sorted(edges)})
        else:
            raise RuntimeError(f"alternative {name}: peaks still on the edge of the evaluated "
                               f"states after {MAX_WIDENINGS} widenings")
        results[name] = evaluate_claims(ds, config.dof_fraction)
    return results


__all__ = [
    "ALTERNATIVES",
    "BASELINE",
    "PRUNE_STEPS",
    "peak_masks",
    "run_alternatives",
]
