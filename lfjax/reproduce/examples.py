"""The example data of the paper's Figs. 4, 5 and 9: PSFs, OTFs and retinal images of single
eyes, computed after the study from the samplings and spectra it used
(:func:`compute_examples`)."""

from __future__ import annotations

import json
import math

import jax.numpy as jnp
import numpy as np

from lfjax.base.sampling import Sampling
from lfjax.kernel.optics import full_plane
from lfjax.model.eyes import Eyes, aberration_free_eye
from lfjax.model.layouts import grid_layout, open_pupil
from lfjax.model.spectral import Spectrum, gauss_spectrum, make_spectrum
from lfjax.reproduce.config import StudyConfig, study_eyes
from lfjax.reproduce.study import study_sampling, study_wavelength_rules
from lfjax.vision.images import psf_on_grid, retinal_image, snellen_e
from lfjax.vision.psf import polychromatic_otf
from lfjax.vision.viewing import Viewing


def compute_examples(ds, config: StudyConfig = StudyConfig(), stage=None):  # noqa: B008
    """Data for Figs. 4, 5 and 9 as an :class:`xarray.Dataset` (PSFs, OTFs, letters).

    Fig. 4: the aberration-free eye's polychromatic MTF (natural view, focused on the CDP).
    Fig. 5: through-focus OTFs and PSFs of the first virtual eye, natural view, at seven
    grid states centred on the CDP (CDP − 0.6 … + 0.6 D on the 0.2 D grid). Fig. 9: 2×2
    viewpoints, point rendered at the most negative depth: PSFs and retinal images of a
    Snellen E for one virtual eye at the VSOTF-predicted accommodation and at the CDP.
    ``ds``: the study's Dataset (its samplings, spectra and predicted accommodation);
    ``stage``: None, or a callable told the name of each part before it runs.
    """
    import xarray as xr

    eyes, labels = study_eyes(config)
    out, coords, attrs = {}, {}, {}
    if stage is not None:
        stage("examples: natural view")
    _natural_examples(ds, config, eyes, labels, out, coords, attrs)
    if "2x2" in ds.layout:
        if stage is not None:
            stage("examples: 2x2 viewpoints")
        _viewpoint_examples(ds, config, eyes, labels, out, coords, attrs)
    return xr.Dataset(out, coords=coords, attrs=attrs)


def layout_spectrum(ds, config: StudyConfig, name: str) -> Spectrum:
    """The spectrum the study used for layout ``name``: its Gauss rule, or its planned (else
    the configured) wavelengths, nm."""
    start, stop, _ = config.wavelengths_nm
    rules = study_wavelength_rules(ds)
    if name in rules and rules[name][0] == "gauss":
        return gauss_spectrum(int(rules[name][1]), start, stop, config.options)
    planned = json.loads(ds.attrs.get("wavelengths_json", "{}"))
    return make_spectrum(planned.get(name, config.wavelength_grid_nm), config.options)


def _natural_examples(ds, config: StudyConfig, eyes: Eyes, labels, out, coords, attrs) -> None:
    """Figs 4 and 5: natural view, the first virtual eye and the aberration-free eye."""
    cdp = config.cdp_D
    natural = study_sampling(ds, "natural") if "natural" in ds.layout else Sampling(1.0)
    # seven states on the study's grid, centred on the CDP (±0.6 D on the paper's grid)
    step = float(config.accommodation_step_D)
    states = np.round(cdp + step * np.arange(-3, 4), 9)
    states = states[states >= 0]
    rel = np.round(states - cdp, 9)
    zero = aberration_free_eye(eyes.measured_pupil_mm, eyes.n_modes)
    pair = Eyes(
        jnp.concatenate([eyes.zernike_um[:1], zero.zernike_um.astype(eyes.zernike_um.dtype)]),
        eyes.measured_pupil_mm,
    )
    stack = polychromatic_otf(pair, states, Viewing(config.pupil_diameter_mm, cdp),
                              layout=open_pupil(config.pupil_diameter_mm),
                              spectrum=layout_spectrum(ds, config, "natural"), sampling=natural,
                              options=config.options)
    L, df = stack.n_fft, stack.freq_step_cpd
    otf_half = stack.otf[:, 0]  # (2, n_states, L, Lx)
    # PSFs (pixel-integrated) on a ±8 arcmin grid
    psf_pixel = 0.2
    psf = np.asarray(psf_on_grid(otf_half[0], df, psf_pixel, 81, L))
    full = np.fft.fftshift(np.asarray(full_plane(otf_half[0], L)), axes=(-2, -1))
    f_axis = (np.arange(L) - L // 2) * df
    keep = np.abs(f_axis) <= 60.0 + 1e-9
    full = full[:, keep][:, :, keep]
    # aberration-free eye's OTF along f_y = 0 (half plane: f_x >= 0), focused on the CDP
    i_cdp = int(np.argmin(np.abs(states - cdp)))
    dl_row = np.asarray(otf_half[1, i_cdp, 0, :])
    dl_f = np.arange(dl_row.size) * df
    out["fig5_psf"] = (("fig5_state", "psf_y", "psf_x"), psf, {"units": "fraction per pixel"})
    out["fig5_otf_modulus"] = (("fig5_state", "otf_fy", "otf_fx"), np.abs(full), {"units": "1"})
    out["fig5_otf_phase"] = (("fig5_state", "otf_fy", "otf_fx"), np.angle(full), {"units": "rad"})
    out["fig4_dl_otf_real"] = (("dl_frequency",), np.real(dl_row))
    out["fig4_dl_mtf"] = (("dl_frequency",), np.abs(dl_row))
    coords["fig5_state"] = ("fig5_state", states, {"units": "D", "long_name": "accommodation"})
    coords["fig5_state_rel"] = ("fig5_state", rel, {"units": "D"})
    coords["psf_y"] = ("psf_y", (np.arange(81) - 40) * psf_pixel, {"units": "arcmin"})
    coords["psf_x"] = ("psf_x", (np.arange(81) - 40) * psf_pixel, {"units": "arcmin"})
    coords["otf_fy"] = ("otf_fy", f_axis[keep], {"units": "cpd"})
    coords["otf_fx"] = ("otf_fx", f_axis[keep], {"units": "cpd"})
    coords["dl_frequency"] = ("dl_frequency", dl_f, {"units": "cpd"})
    attrs["fig5_eye"] = labels[0]


def _viewpoint_examples(ds, config: StudyConfig, eyes: Eyes, labels, out, coords,
                        attrs) -> None:
    """Fig 9: 2×2 viewpoints, the most negative rendered depth, one eye at its VSOTF peak
    and at the CDP (an eye where the Strehl ratio picks the CDP and VSOTF the image depth,
    if there is one)."""
    cdp = config.cdp_D
    depth = float(np.min(config.depths_D))
    di = int(np.argmin(np.abs(ds.depth.values - depth)))
    sub = ds.sel(layout="2x2").isel(depth=di)
    aberrated = ~sub.is_average.values
    vs_pred = sub.predicted_accommodation.sel(metric="vsotf").values
    sr_pred = sub.predicted_accommodation.sel(metric="strehl").values
    contrast = np.abs(sr_pred - depth) - np.abs(vs_pred - depth)
    contrast = np.where(aberrated, contrast, -np.inf)
    ei = int(np.argmax(contrast)) if np.any(contrast > 0) else 0
    two = np.array([float(vs_pred[ei]), cdp])
    st2 = polychromatic_otf(eyes[ei], two, Viewing(config.pupil_diameter_mm, cdp),
                            layout=grid_layout(2, config.pupil_diameter_mm), depths_D=[depth],
                            spectrum=layout_spectrum(ds, config, "2x2"),
                            sampling=study_sampling(ds, "2x2"), options=config.options)
    otf2 = st2.otf[0, 0]  # (2, L, Lx)
    pix = 0.25
    n_psf = 97
    psf2 = np.asarray(psf_on_grid(otf2, st2.freq_step_cpd, pix, n_psf, st2.n_fft))
    letter = snellen_e(config.example_letter_arcmin, pix,
                       n_pixels=int(2 * math.ceil(1.2 * config.example_letter_arcmin / pix)))
    images = np.asarray(retinal_image(letter, pix, otf2, st2.freq_step_cpd))
    n_img = letter.shape[-1]
    out["fig9_psf"] = (("fig9_state", "psf9_y", "psf9_x"), psf2, {"units": "fraction per pixel"})
    out["fig9_letter"] = (("img_y", "img_x"), np.asarray(letter), {"units": "relative luminance"})
    out["fig9_retinal_image"] = (("fig9_state", "img_y", "img_x"), images,
                                 {"units": "relative luminance"})
    coords["fig9_state"] = ("fig9_state", two, {"units": "D", "long_name": "accommodation"})
    coords["fig9_state_name"] = ("fig9_state", ["VSOTF peak", "CDP"])
    coords["psf9_y"] = ("psf9_y", (np.arange(n_psf) - n_psf // 2) * pix, {"units": "arcmin"})
    coords["psf9_x"] = ("psf9_x", (np.arange(n_psf) - n_psf // 2) * pix, {"units": "arcmin"})
    coords["img_y"] = ("img_y", (np.arange(n_img) - n_img / 2 + 0.5) * pix, {"units": "arcmin"})
    coords["img_x"] = ("img_x", (np.arange(n_img) - n_img / 2 + 0.5) * pix, {"units": "arcmin"})
    attrs.update(fig9_eye=labels[ei], fig9_depth_D=depth,
                 fig9_letter_arcmin=float(config.example_letter_arcmin))


__all__ = ["compute_examples", "layout_spectrum"]
