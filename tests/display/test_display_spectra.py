"""Display spectra (lfjax.display.spectra): emission × V(λ) on the fewest wavelengths that
carry it (the reduced spectrum's VSOTF against the full one's), white balance, and bad
input."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from lfjax.display import spectra as ds
from lfjax.model import spectral
from lfjax.model.options import ModelOptions
from lfjax.vision.viewing import Viewing

def _spectrum(name, channel, **kwargs):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # CRT red's far-red tail (tested below)
        return ds.display_spectrum(name, channel, **kwargs)


def _full_spectrum(name, channel, options=ModelOptions()):
    """The display's emission × V(λ) on every fine sample of its own grid inside the
    computed range, unreduced (the spectrum the reduced one stands for)."""
    primaries = ds.display_primaries(name)
    wl = primaries.wavelengths_nm
    w = ds._fine_weights(wl, primaries.emission @ ds.channel_drive(primaries, channel))
    lo, hi = spectral.computed_range_nm(options)
    inside = (wl >= lo) & (wl <= hi) & (w > 0)
    return spectral.make_spectrum(wl[inside], options, weights=w[inside] / w[inside].sum())


def test_reduced_spectrum_gives_the_full_spectrums_vsotf():
    """What the reduction promises: the LCD white on its 25 wavelengths (default
    weight_tolerance 1e-3: at most 0.1 % of the V-weighted power moved to a neighbour,
    each cell's power at its centroid) gives the VSOTF of the same light on all 61 fine
    samples (5 nm) within that tolerance, for two eyes in natural view accommodated at and
    ±0.3 D around the 2 D point. Measured 4.5e-4. The reduction is real: fewer than half the
    wavelengths."""
    import jax.numpy as jnp

    import lfjax
    from lfjax.vision.focus import metrics_at

    full, reduced = _full_spectrum("lcd", "white"), _spectrum("lcd", "white")
    assert reduced.n_wavelengths < full.n_wavelengths / 2

    def vsotf(spectrum):
        v, _ = metrics_at(
            lfjax.sample_eyes(3, 2),
            lfjax.open_pupil(3.0),
            jnp.asarray([2.0]),
            jnp.asarray([[1.7, 2.0, 2.3]]),
            Viewing(pupil_diameter_mm=3.0, cdp_D=2.0),
            spectrum=spectrum,
            sampling=lfjax.Sampling(2.0),
        )
        return np.asarray(v)

    v_full = vsotf(full)
    assert 0.3 < v_full.min() and v_full.max() < 0.95  # neither saturated nor tiny
    assert np.abs(vsotf(reduced) - v_full).max() <= 1e-3


@pytest.mark.parametrize("name", ds.DISPLAY_NAMES)
def test_white_mix_keeps_the_photometric_centroid_and_weight(name):
    """Σw = 1 and Σwλ within 0.1 nm of the fine grid's emission × V(λ) centroid."""
    primaries = ds.display_primaries(name)
    drive = ds.channel_drive(primaries, "white")
    wl = primaries.wavelengths_nm
    inside = (wl >= 400.0) & (wl <= 700.0)
    wl = wl[inside]
    fine = (primaries.emission @ drive)[inside] * spectral.luminous_efficiency(wl)
    inside = np.ones(wl.size, bool)
    centroid = np.sum(fine[inside] * wl[inside]) / np.sum(fine[inside])
    s = _spectrum(name, "white")
    w, lam = np.asarray(s.weights), np.asarray(s.wavelengths_nm)
    assert w.sum() == pytest.approx(1.0, abs=1e-12)
    assert np.all(np.diff(lam) > 0) and lam.min() >= 400.0 and lam.max() <= 700.0
    assert np.sum(w * lam) == pytest.approx(centroid, abs=0.1)


@pytest.mark.parametrize("name", ["crt", "lcd", "oled"])
def test_white_drive_has_the_d65_chromaticity(name):
    primaries = ds.display_primaries(name)
    drive = ds.channel_drive(primaries, "white")
    assert np.all(drive > 0)
    X, Y, Z = ds.emission_XYZ(primaries.wavelengths_nm, primaries.emission @ drive)
    assert Y == pytest.approx(1.0, rel=1e-9)
    assert (X / (X + Y + Z), Y / (X + Y + Z)) == pytest.approx(ds.D65_XY, abs=1e-9)


def test_laser_lines_are_one_wavelength_each():
    s = _spectrum("laser", "white")
    np.testing.assert_allclose(np.sort(np.asarray(s.wavelengths_nm)), sorted(ds.LASER_PEAKS_NM), atol=0.5)
    for channel, peak in zip(("red", "green", "blue"), ds.LASER_PEAKS_NM):
        assert float(_spectrum("laser", channel).wavelengths_nm[0]) == pytest.approx(peak, abs=0.5)


def test_user_spectrum_on_the_cell_grid_is_kept_unchanged():
    """Flat emission sampled on 400–700 nm at 10 nm, no tolerance: the paper's V(λ) spectrum."""
    wl = np.arange(400.0, 701.0, 10.0)
    s = ds.user_spectrum(wl, np.ones_like(wl), weight_tolerance=0.0, step_nm=10.0)
    reference = spectral.make_spectrum(wl)
    np.testing.assert_allclose(np.asarray(s.wavelengths_nm), wl, atol=1e-9)
    np.testing.assert_allclose(np.asarray(s.weights), np.asarray(reference.weights), rtol=1e-9)


def test_narrow_primaries_need_fewer_wavelengths_than_a_broad_spectrum():
    """"Model no more than a scene needs": a single OLED primary is a third of the paper's 31
    wavelengths, a laser line one."""
    assert _spectrum("oled", "green").n_wavelengths <= 10 < spectral.make_spectrum().n_wavelengths
    assert _spectrum("laser", "green").n_wavelengths == 1


def test_weight_outside_the_computed_range_is_merged_with_a_warning():
    with pytest.warns(UserWarning, match="outside the computed range"):
        s = ds.display_spectrum("crt", "red")
    assert float(np.max(np.asarray(s.wavelengths_nm))) <= 700.0


@pytest.mark.parametrize("call, match", [
    (lambda: ds.user_spectrum([750.0, 760.0, 770.0], [1.0, 1.0, 1.0]), "computed range"),
    (lambda: ds.user_spectrum([900.0, 910.0], [1.0, 1.0], ModelOptions(sce="off")), "no weight"),
    (lambda: ds.user_spectrum([500.0, 490.0], [1.0, 1.0]), "strictly increasing"),
    (lambda: ds.user_spectrum([500.0, 510.0], [1.0, -1.0]), "non-negative"),
    (lambda: ds.display_spectrum("plasma"), "allowed"),
    (lambda: ds.display_spectrum("oled", "cyan"), "allowed"),
    (lambda: ds.display_spectrum("oled", [0.0, 0.0, 0.0]), "not all zero"),
    (lambda: ds.display_spectrum("oled", weight_tolerance=1.0), "weight_tolerance"),
    (lambda: ds.gaussian_primaries([620.0, 530.0, 300.0], 30.0), "peaks_nm"),
    (lambda: ds.gaussian_primaries([620.0, 530.0, 460.0], 0.0), "fwhm_nm"),
])
def test_bad_spectrum_input_is_named(call, match):
    with pytest.raises(ValueError, match=match):
        call()


def test_the_planner_plans_for_a_display_spectrum_as_weighted():
    """PlanScene(spectral_weights=...) guards the blur of the spectrum actually shown
    (its weights decide which wavelengths may be left out) and hands it back."""
    import lfjax
    from lfjax.planner import FieldGuard, PlanScene, plan_sampling

    layout = lfjax.grid_layout(2, 3.0)
    # violet + green in equal parts: V(λ) would weigh 400 nm at 0.25 % and leave it out
    scene = dict(depths_D=[1.0, 3.0], wavelengths_nm=[400.0, 560.0])
    kwargs = dict(estimate_accuracy=False, guard=FieldGuard(wrap_tolerance=0.01))
    plan = plan_sampling(PlanScene(layout, spectral_weights=[0.5, 0.5], **scene), **kwargs)
    np.testing.assert_allclose(np.asarray(plan.spectrum().weights), [0.5, 0.5])
    as_v = plan_sampling(PlanScene(layout, **scene), **kwargs)
    assert plan.blur_radius_arcmin > as_v.blur_radius_arcmin  # 400 nm's LCA blur is guarded
    assert plan.sampling.freq_step_cpd < as_v.sampling.freq_step_cpd
    with pytest.raises(ValueError, match="spectral_weights needs wavelengths_nm"):
        PlanScene(layout, spectral_weights=[1.0])
