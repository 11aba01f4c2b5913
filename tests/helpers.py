"""Shared test helpers: standard inputs, analytic references, grid utilities and finite
differences."""

from __future__ import annotations

import math
from functools import lru_cache

import jax
import jax.numpy as jnp
import numpy as np

import lfjax
import reference as R
from lfjax.model.layouts import Layout

DEG = 180.0 / math.pi
RAD_TO_ARCMIN = 180.0 * 60.0 / math.pi

PLAIN = lfjax.ModelOptions(sce="off", accommodation_sa="off", lca_A=0.0)
"""Pure diffraction: no Stiles-Crawford, no accommodation SA, no LCA."""

C20_PER_D_3MM = 9.0 / (16.0 * math.sqrt(3.0))  # µm of c(2,0) per dioptre on a 3 mm pupil


@lru_cache(maxsize=None)
def spectrum_550_plain():
    return lfjax.make_spectrum([550.0], PLAIN)


def dl_eye(n_modes: int = 15):
    return lfjax.model.eyes.aberration_free_eye(3.0, n_modes)


def marechal_rows():
    """(ANSI j, RMS µm) of the single-mode eyes of ``marechal_eyes`` rows 1, 2, ..."""
    return [(j, sigma) for sigma in (0.02, 0.04) for j in (3, 4, 6, 12, 14)]


def marechal_eyes():
    """Row 0 aberration-free, then one eye per ``marechal_rows`` entry (3 mm measured)."""
    rows = marechal_rows()
    z = np.zeros((1 + len(rows), 15))
    for i, (j, sigma) in enumerate(rows, start=1):
        z[i, j] = sigma
    return lfjax.model.eyes.make_eyes(z, 3.0)


def defocus_eyes():
    """[aberration-free, +1 D (myopic), −1 D] eyes on a 3 mm measured pupil."""
    z = np.zeros((3, 15))
    z[1, 4] = +C20_PER_D_3MM
    z[2, 4] = -C20_PER_D_3MM
    return lfjax.model.eyes.make_eyes(z, 3.0)


# ----------------------------------------------------------------------------- grids
def fft_index(n: int) -> np.ndarray:
    """Integer frequency index k of each FFT-order sample."""
    return np.fft.fftfreq(n, 1.0 / n).round().astype(int)


def crop_full(otf_full: np.ndarray, n: int) -> np.ndarray:
    """FFT-order (..., L, L) plane restricted to the frequencies of an n-sample grid."""
    big = otf_full.shape[-1]
    idx = fft_index(n) % big
    return otf_full[..., idx[:, None], idx[None, :]]


def pupil_samples(d_mm: float, wavelength_nm: float, freq_step_cpd: float) -> float:
    """Pupil samples across a d mm aperture on lfjax's grid: d / (λ df)."""
    return d_mm / (wavelength_nm * 1e-6 * freq_step_cpd * DEG)


def cutoff_cpd(d_mm: float, wavelength_nm: float) -> float:
    return d_mm / (wavelength_nm * 1e-6) / DEG


def dl_axis_error(otf_full, freq_step_cpd, d_mm, wavelength_nm) -> float:
    """max |MTF − analytic| along the f_x and f_y axes of a full-plane OTF."""
    n = otf_full.shape[-1]
    f = np.abs(fft_index(n)) * freq_step_cpd
    mtf = R.diffraction_limited_mtf(f / cutoff_cpd(d_mm, wavelength_nm))
    return float(max(np.abs(np.abs(otf_full[0, :]) - mtf).max(),
                     np.abs(np.abs(otf_full[:, 0]) - mtf).max()))


def dl_otf_2d(n: int, freq_step_cpd: float, d_mm: float, wavelength_nm: float):
    """Analytic diffraction-limited OTF on the full FFT-order plane."""
    k = fft_index(n) * freq_step_cpd
    f = np.hypot(k[None, :], k[:, None])
    return R.diffraction_limited_mtf(f / cutoff_cpd(d_mm, wavelength_nm))


def ramp(n: int, freq_step_cpd: float, shift_rad) -> np.ndarray:
    """exp(−2πi f·Δθ) on the full FFT-order plane (Δθ = (x, y) rad)."""
    f = fft_index(n) * freq_step_cpd * DEG  # cycles/rad
    return np.exp(-2j * np.pi * (f[None, :] * shift_rad[0] + f[:, None] * shift_rad[1]))


def phase_centroid_arcmin(otf_full, freq_step_cpd):
    """PSF centroid (arcmin) from the OTF phase at ±df (reference.otf_phase_centroid_arcmin)."""
    return R.otf_phase_centroid_arcmin(np.asarray(otf_full), freq_step_cpd)


# ----------------------------------------------------------------------------- reference
def reference_for(zernike_um, spectrum, accommodation_D, cdp_D, depth_D, layout, n_freq,
                  freq_step_cpd, options=lfjax.ModelOptions(), measured_pupil_mm=3.0,
                  pupil_mm=3.0, supersample=4):
    """tests/reference.py's OTF for lfjax-style inputs (spectral weights, ρ(λ) and LCA
    constants taken from the lfjax objects; SA per ``options.accommodation_sa``)."""
    if options.accommodation_sa not in ("scaled", "off"):
        raise NotImplementedError("the reference implements the 'scaled' SA form only")
    z = np.array(zernike_um, float)
    if options.zero_piston_tilt:
        z[:3] = 0.0
    return R.reference_otf(
        z, measured_pupil_mm, pupil_mm, np.asarray(spectrum.wavelengths_nm),
        np.asarray(spectrum.weights), accommodation_D, cdp_D, depth_D,
        np.asarray(layout.centres_mm), np.asarray(layout.diameters_mm), n_freq,
        freq_step_cpd, sce_rho_per_mm2=np.asarray(spectrum.sce_rho_per_mm2),
        sa_slope_um_per_D=options.sa_slope_um_per_D if options.accommodation_sa == "scaled"
        else 0.0,
        lca_A=options.lca_A, lca_c_nm=options.lca_c_nm, lca_ref_nm=options.lca_reference_nm,
        supersample=supersample,
    )


# ----------------------------------------------------------------------------- gradients
def directional_fd(f, x, v, eps):
    """Central difference of scalar f along direction v (pytrees of arrays)."""
    plus = jax.tree_util.tree_map(lambda a, b: a + eps * b, x, v)
    minus = jax.tree_util.tree_map(lambda a, b: a - eps * b, x, v)
    return (float(f(plus)) - float(f(minus))) / (2.0 * eps)


def tree_vdot(a, b) -> float:
    return float(sum(jnp.vdot(x, y) for x, y in zip(jax.tree_util.tree_leaves(a),
                                                    jax.tree_util.tree_leaves(b))))


def random_direction(key, tree):
    leaves, treedef = jax.tree_util.tree_flatten(tree)
    keys = jax.random.split(key, len(leaves))
    return jax.tree_util.tree_unflatten(
        treedef, [jax.random.normal(k, jnp.shape(x), jnp.result_type(float))
                  for k, x in zip(keys, leaves)])


def layout_from(centres_mm, diameters_mm, window_diameter_mm):
    """Layout from (possibly traced) arrays, bypassing make_layout's host validation."""
    return Layout(centres_mm, diameters_mm, float(window_diameter_mm))


# ------------------------------------------------------------------ notebooks


def percent_cells(text):
    """(cell_type, source) pairs of a jupytext percent-format script."""
    cells, kind, lines = [], None, []
    body = text.split("# ---\n", 2)[-1] if text.startswith("# ---") else text

    def flush():
        if kind is not None:
            src = "\n".join(lines).strip("\n")
            if kind == "markdown":
                src = "\n".join(ln[2:] if ln.startswith("# ") else ln.lstrip("#")
                                for ln in src.splitlines())
            cells.append((kind, src))

    for line in body.splitlines():
        if line.startswith("# %%"):
            flush()
            kind, lines = ("markdown" if "[markdown]" in line else "code"), []
        else:
            lines.append(line)
    flush()
    return cells


def committed_notebook_outputs(notebook_path):
    """Check that a committed notebook equals its jupytext percent twin (the ``.py`` beside
    it) and carries outputs without errors; returns those outputs."""
    import nbformat

    nb = nbformat.read(notebook_path, as_version=4)
    twin = notebook_path.with_suffix(".py").read_text()
    assert [(c.cell_type, c.source) for c in nb.cells] == percent_cells(twin)
    outputs = [o for c in nb.cells if c.cell_type == "code" for o in c.get("outputs", [])]
    assert outputs and not [o for o in outputs if o.output_type == "error"]  # committed with outputs
    return outputs


def execute_notebook_tiny(notebook_path, workdir):
    """Run a notebook top to bottom at LFJAX_NOTEBOOK_SIZE=tiny in ``workdir``; returns
    (outputs, images, stream text) after checking that no cell raised."""
    import os

    import nbformat
    from nbclient import NotebookClient

    nb = nbformat.read(notebook_path, as_version=4)
    os.environ["LFJAX_NOTEBOOK_SIZE"] = "tiny"
    try:
        NotebookClient(nb, timeout=600, kernel_name="python3",
                       resources={"metadata": {"path": str(workdir)}}).execute()
    finally:
        del os.environ["LFJAX_NOTEBOOK_SIZE"]
    outputs = [o for c in nb.cells if c.cell_type == "code" for o in c.get("outputs", [])]
    assert not [o for o in outputs if o.output_type == "error"]
    images = [o for o in outputs if "image/png" in o.get("data", {})]
    text = "".join(o.get("text", "") for o in outputs if o.output_type == "stream")
    return outputs, images, text


# ------------------------------------------------------------------ reference comparisons

MISMODELLED = {
    "sce_as_intensity": dict(sce="intensity"),
    "accommodation_sa_off": dict(accommodation_sa="off"),
    "lca_off": dict(lca_A=0.0),
}
"""Deliberate modelling errors a reference comparison must see (ModelOptions changes)."""


CV_BOUND = 0.7
"""Bound of the control-variate residual, in units of e_0 (the aberration-free eye's
fast − reference difference, its aperture-edge error). Not derived: the residual is the
edge error's modulation by the aberration phase at the aperture edges, measured 0.21–0.33
e_0 with the paper's options and up to 0.59 e_0 with the unscaled accommodation SA (its
steeper phase at the rim); every deliberately mis-modelled reference leaves ≥ 0.83 e_0
(both asserted: this file and test_focus.py). The bound sits between."""
