"""Fewer wavelengths for the same answer? Gauss quadrature in V(λ) against uniform steps.

The pipeline sums Σ_λ w_λ OTF_λ, a quadrature of ∫ V(λ) OTF_λ dλ. On a uniform grid
(``lfjax.make_spectrum``: rectangle weights V(λ)·Δλ) the 400 and 700 nm ends carry 0.05 %
and 0.09 % of the weight at full transform cost. A Gauss rule for the weight V(λ) (nodes
and weights from the Lanczos recurrence on the 1 nm CIE table, 400–700 nm) puts its nodes
where V is large. This experiment compares both against a 5 nm reference on real eyes,
with the pipeline itself (not the planner's aberration-free proxy): continuous VSOTF peaks
(``local``), VSOTF over the window, and cut-offs at the reference's grid peak. An
experiment (RESULTS §19); the feature it led to is ``lfjax.model.spectral.gauss_rule``
(exact moments of the piecewise-linear weight, not this 1 nm point sum), chosen per layout by
the planner with ``Overrides(spectral_rule="auto")`` and validated by ``spectral_rule.py``
(RESULTS §23).

Run:  .venv/bin/python benchmarks/validation/spectral_quadrature.py [natural|2x2|3x3|4x4 ...]
"""

from __future__ import annotations

import os
import platform
import sys
import time

import jax
import jax.numpy as jnp
import numpy as np

import lfjax
from lfjax.model.spectral import luminous_efficiency, make_spectrum
from lfjax.vision.focus import _cutoff_at_index, through_focus
from lfjax.vision.peak_options import PeakOptions
from lfjax.vision.prepare import States
from lfjax.vision.viewing import Viewing

UNIFORM_STEPS_NM = (25.0, 30.0)
GAUSS_NODES = (5, 6, 7, 8, 9)


def gauss_v_rule(n: int, lo: float = 400.0, hi: float = 700.0):
    """n-node Gauss rule for the weight V(λ) on [lo, hi] nm: (nodes nm, weights summing 1)."""
    x = np.arange(lo, hi + 0.5, 1.0)
    w = luminous_efficiency(x)
    q = np.sqrt(w) / np.linalg.norm(np.sqrt(w))
    basis, alpha, beta = [q], [], []
    for _ in range(n):  # Lanczos on diag(x), fully re-orthogonalised
        v = x * basis[-1]
        alpha.append(basis[-1] @ v)
        for b in basis:
            v -= (b @ v) * b
        beta.append(np.linalg.norm(v))
        basis.append(v / beta[-1])
    jacobi = np.diag(alpha) + np.diag(beta[:-1], 1) + np.diag(beta[:-1], -1)
    nodes, vectors = np.linalg.eigh(jacobi)
    return nodes, vectors[0] ** 2


def compare(layout_name: str, n_eyes: int = 6) -> None:
    eyes = lfjax.sample_eyes(0, n_eyes, measured_pupil_mm=6.0)
    layout = None if layout_name == "natural" else lfjax.grid_layout(
        int(layout_name[0]), pupil_diameter_mm=3.0)
    depths = [2.0] if layout_name == "natural" else [0.0, 1.0, 2.0, 3.0, 4.0]
    grid = np.round(np.arange(0.0, 5.01, 0.2), 9)

    def run(spectrum, sampling):
        return through_focus(
            eyes,
            layout,
            States.grid(grid, depths_D=depths, window_D=2.0),
            Viewing(pupil_diameter_mm=3.0, cdp_D=2.0),
            spectrum=spectrum,
            sampling=sampling,
            peaks=PeakOptions(metrics=("vsotf",), method="local", second_peaks=False),
        )

    reference = run(make_spectrum(np.arange(400.0, 701.0, 5.0)), None)
    sampling = reference.sampling  # every rule on the reference's frequency grid
    index = jnp.asarray(reference.peak_index("vsotf"))
    peaks = reference.continuous_accommodation_D()
    cutoffs = np.asarray(_cutoff_at_index(reference.radial_mtf, index, reference.radial_freq_cpd, 0.05))
    allowed = np.asarray(reference.allowed)
    print(f"{layout_name}: {n_eyes} eyes, depths {depths} D, df {sampling.freq_step_cpd:.4g} cpd; "
          f"against 400-700 nm in 5 nm steps", flush=True)
    rules = [(f"uniform {s:g} nm", make_spectrum(np.arange(400.0, 701.0, s)))
             for s in UNIFORM_STEPS_NM]
    rules += [(f"Gauss-V {n}", make_spectrum(*gauss_v_rule(n)[:1], weights=gauss_v_rule(n)[1]))
              for n in GAUSS_NODES]
    for label, spectrum in rules:
        tf = run(spectrum, sampling)
        dp = np.nanmax(np.abs(tf.continuous_accommodation_D() - peaks))
        dv = np.max(np.abs(np.where(allowed, np.asarray(tf.vsotf) - np.asarray(reference.vsotf), 0.0)))
        dc = np.abs(np.asarray(_cutoff_at_index(tf.radial_mtf, index, tf.radial_freq_cpd, 0.05))
                    - cutoffs)
        wl = np.asarray(spectrum.wavelengths_nm)
        print(f"  {label:15s} {wl.size:2d} wavelengths ({wl.min():.0f}-{wl.max():.0f} nm): "
              f"peaks max |d| {dp:.1e} D, VSOTF max |d| {dv:.1e}, cut-offs max |d| "
              f"{dc.max():.3f} cpd (median {np.median(dc):.3f})", flush=True)


def main() -> None:
    names = sys.argv[1:] or ["natural", "2x2", "4x4"]
    print("command: .venv/bin/python benchmarks/validation/spectral_quadrature.py "
          + " ".join(names))
    print(f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores, "
          f"jax {jax.__version__}, {time.strftime('%Y-%m-%d %H:%M')}", flush=True)
    for name in names:
        compare(name)


if __name__ == "__main__":
    main()
