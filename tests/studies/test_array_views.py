"""lfjax.studies.array_views: the whole lenslet array rendering a point."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from lfjax.base.errors import ParameterError
from lfjax.studies.array_views import array_through_focus, array_views, idealisation_gap
from lfjax.model.eyes import average_eye
from lfjax.model.layouts import subaperture_pitch_mm
from lfjax.display.panel import Panel, near_eye_microdisplay, phone_panel
from lfjax.vision.resolution import perceivable_cutoff_at_peak
from lfjax.base.sampling import Sampling
from lfjax.model.spectral import make_spectrum
from lfjax.vision.focus import through_focus
from lfjax.vision.prepare import States
from lfjax.vision.viewing import Viewing

def _fine_pixels(panel: Panel, pitch_mm: float = 1e-9) -> Panel:
    return dataclasses.replace(panel, pixel_pitch_mm=pitch_mm)


@pytest.mark.parametrize("depth", [0.0, 0.5, 1.5, 3.0])
def test_ideal_beams_follow_the_papers_equation_1(depth):
    """With vanishing pixels the lit beams are the ideal chief rays: neighbouring lenslets'
    beams are Δu·z_r/(z_r − z_m) apart in the pupil (the paper's Eq. 1, implemented
    independently in lfjax.model.layouts), parallel (Δu apart) for a point at infinity, and they
    carry no tilt."""
    panel = _fine_pixels(near_eye_microdisplay())
    views = array_views(panel, depth)
    du, zm = float(panel.lenslet_pitch_mm), float(panel.distance_mm)
    step = du if depth == 0 else float(subaperture_pitch_mm(du, 1.0 / depth, zm / 1000.0))
    order = np.lexsort(views.lenslet_index.T)
    idx, q = views.lenslet_index[order], views.centres_mm[order]
    same_row = (idx[1:, 1] == idx[:-1, 1]) & (idx[1:, 0] == idx[:-1, 0] + 1)
    assert np.any(same_row)
    assert np.allclose(np.diff(q[:, 0])[same_row], step, rtol=1e-6)
    assert np.allclose(views.centres_mm, views.ideal_centres_mm, atol=1e-6)
    assert np.max(np.abs(views.tilt_arcmin)) < 1e-3


def test_on_the_cdp_the_central_beams_are_the_panels_layout():
    panel = _fine_pixels(near_eye_microdisplay())
    views = array_views(panel, float(panel.cdp_D))
    layout = panel.layout()
    for c in np.asarray(layout.centres_mm):
        assert np.min(np.hypot(*(views.centres_mm - c).T)) < 1e-6
    # 2.87 views across: beyond the 2×2, eight more footprints overlap the 3 mm pupil
    assert views.n_geometric == 12 and layout.n_subapertures == 4


@pytest.mark.parametrize("make", [near_eye_microdisplay, phone_panel])
def test_pixel_quantisation_bounds(make):
    """Lighting the pixel δ = x̂ − x from the ideal one (|δ| ≤ p/2 per axis) moves the
    footprint by δ·z_m/z_0 and tilts the beam by ε = (u − q̂)/z_m + q̂/z_r =
    (δ/z_0)·(1 − z_m/z_r): at most half a pixel's angle p/(2·z_0·M) on the CDP, scaled by
    (1 − z_m·D)/(1 − z_m·D_c) (z_m in m) at depth D."""
    panel = make()
    p, zm, z0 = float(panel.pixel_pitch_mm), float(panel.distance_mm), float(panel.gap_mm)
    dc = float(panel.cdp_D)
    for depth in (0.5, dc, 2.5):
        views = array_views(panel, depth, pixel_offset_mm=(0.013, -0.007))
        move = np.abs(views.centres_mm - views.ideal_centres_mm)
        assert np.all(move <= zm * p / (2 * z0) * (1 + 1e-9))
        bound = 0.5 * float(panel.pixel_arcmin()) * (1 - zm * depth / 1000) / (1 - zm * dc / 1000)
        assert np.all(np.abs(views.tilt_arcmin) <= bound * (1 + 1e-6))
        # and the tilt is exactly (δ/z_0)(1 − z_m/z_r) with δ read back from the footprint
        delta = -(views.centres_mm - views.ideal_centres_mm) * z0 / zm
        want = delta / z0 * (1 - zm * depth / 1000) * 180 * 60 / math.pi
        assert np.allclose(views.tilt_arcmin, want, rtol=1e-6, atol=1e-9)


def test_emitter_samples_cover_the_emitter_sweep():
    """m×m samples of one emitter (side w = p·√fill) sit at ±w/3 and 0 for m = 3: their
    footprints span 2/3 of the emitter sweep z_m·w/z_0 at the eye, centred on the
    pixel-centre beam."""
    panel = dataclasses.replace(near_eye_microdisplay(), pixel_fill=0.64)
    sweep = float(panel.emitter_sweep_mm())
    assert sweep == pytest.approx(float(panel.distance_mm) * float(panel.pixel_pitch_mm) * 0.8
                                  / float(panel.gap_mm), rel=1e-6)
    one = array_views(panel, 1.0)
    many = array_views(panel, 1.0, emitter_samples=3)
    centre = np.argmin(np.hypot(*one.centres_mm.T))  # a central lenslet: all its samples kept
    mine = np.all(many.lenslet_index == one.lenslet_index[centre], axis=1)
    assert mine.sum() == 9
    block = many.centres_mm[mine]
    assert np.ptp(block[:, 0]) == pytest.approx(sweep * 2 / 3, rel=1e-6)
    assert np.allclose(block.mean(axis=0), one.centres_mm[centre], atol=1e-9)
    with pytest.raises(ValueError, match="emitter_samples"):
        array_views(panel, 1.0, emitter_samples=0)
    with pytest.raises(ValueError, match="lower diffraction_widths"):
        array_views(panel, 1.0, diffraction_widths=1e6)


def test_low_fresnel_numbers_reach_the_pupil_by_diffraction():
    near = array_views(near_eye_microdisplay(), 1.0)
    half = 0.5 * float(phone_panel().pixel_pitch_mm)
    phone = array_views(phone_panel(), 2.0, diffraction_widths=4.0, pixel_offset_mm=(half, half))
    assert near.fresnel_number > 10 and near.n_views == near.n_geometric
    assert phone.fresnel_number < 1 and phone.n_views > phone.n_geometric > 0
    with pytest.raises(ValueError, match=r"depth_D must be in \[0, 33.33\) D"):
        array_views(near_eye_microdisplay(), 40.0)


def test_array_through_focus_is_the_idealisation_when_the_array_makes_the_n_by_n_views():
    """With fill 0.9 the 2×2 tangent views' neighbours' footprints miss the pupil, and with
    vanishing pixels every beam is ideal: for a point on the CDP the whole array then
    renders exactly the n×n idealisation. Off the CDP its footprints sit where the chief
    rays through the point cross the pupil, scaled by (1 − z_m·D_c)/(1 − z_m·D) from the
    idealisation's fixed grid (z_m in m)."""
    base = Panel.with_cdp(cdp_D=1.5, pixel_pitch_mm=1e-9, lenslet_pitch_mm=3.0 / 2 / 1.0471204,
                          focal_length_mm=3.3, distance_mm=30.0, fill=0.9, diffraction="off")
    cdp = float(base.cdp_D)
    assert array_views(base, cdp).n_geometric == 4
    off = array_views(base, 1.0)
    ratio = (1 - 0.03 * cdp) / (1 - 0.03 * 1.0)
    assert np.allclose(np.sort(off.centres_mm[:, 0]), np.sort(np.asarray(base.layout().centres_mm)[:, 0]) * ratio)
    eye = average_eye()
    spectrum = make_spectrum(np.array([550.0]))
    acc = np.array([1.0, 1.5, 2.0])
    kwargs = dict(spectrum=spectrum, sampling=Sampling(2.0))
    (views, got), = array_through_focus(eye, base, [cdp], acc, **kwargs)
    want = through_focus(eye, base.layout(), States.grid(acc, [cdp]),
                         Viewing(pupil_diameter_mm=3.0, cdp_D=cdp, display=base.optics()), **kwargs)
    assert views.n_geometric == 4
    assert np.allclose(np.asarray(got.vsotf), np.asarray(want.vsotf), rtol=1e-9, atol=1e-12)
    assert np.all(np.isfinite(np.asarray(got.vsotf)))
    # the perceivable resolution of that through-focus result: on the CDP, the lower of the
    # MTF's cut-off at the peak and the pixels' Nyquist frequency (vanishing here)
    cut = np.asarray(perceivable_cutoff_at_peak(want, base))
    optical = np.asarray(want.cutoff_cpd("vsotf"))
    assert cut.shape == (1, 1) and np.allclose(cut, optical, rtol=1e-9)


def test_where_the_pixels_fall_decides_what_a_phone_panel_shows():
    """The phone preset has 8.1 pixels per lenslet and 2.3 lenslet pitches per pixel beam
    spacing at the eye (z_m·p/z_0 = 6.6 mm against a 3 mm pupil): with the pixel grid's
    phase at zero, the on-axis CDP point falls between two pixels of every lenslet and no
    pixel centre's beam enters the pupil; shifted half a pixel, every central lenslet's
    does. Sampling the emitters shows light entering in both cases (their sweep is 6.6 mm,
    beyond the 1.5 mm views), which the n×n idealisation with a pixel blur cannot tell
    apart."""
    panel = phone_panel()
    half = 0.5 * float(panel.pixel_pitch_mm)
    between = array_views(panel, 2.0)
    centred = array_views(panel, 2.0, pixel_offset_mm=(half, half))
    assert float(panel.emitter_sweep_mm()) > 4 * float(panel.view_diameter_mm)
    assert between.n_geometric == 0 and centred.n_geometric >= 4
    assert array_views(panel, 2.0, emitter_samples=4).n_geometric > 0


def test_every_lit_beam_is_counted_however_far_its_lenslet():
    """A point at infinity (D = 0, ideal rays parallel: q_k = u_k, x_k = u_k) on lenslets
    (10 + 1/3) pixels apart, pixel centres on multiples of p: lenslet k's lit pixel is
    u_k's nearest, δ_k = 0, −p/3, +p/3 for k ≡ 0, 1, 2 (mod 3) on each axis, so its beam
    lands at u_k + S·(0, 1, −1) with S = (p/3)·z_m/z_0 = 3 mm — nine sub-lattices of
    pitch 3Δu, counted here in closed form. Lenslets up to (pupil + footprint)/2 + S from
    the axis send beams into the pupil; the search once stopped short of S and the count
    depended on diffraction_widths (21 against 33 geometric beams for the phone's 3x3 at
    1 D; 65 there are)."""
    p = 0.03
    panel = Panel.with_cdp(cdp_D=2.0, pixel_pitch_mm=p, lenslet_pitch_mm=(10 + 1 / 3) * p,
                           focal_length_mm=1.0, distance_mm=300.0, fill=1.0, diffraction="off")
    du, d, pupil = float(panel.lenslet_pitch_mm), float(panel.view_diameter_mm), 3.0
    shift = p / 3 * float(panel.distance_mm) / float(panel.gap_mm)
    assert shift > 3.0 and float(panel.pupil_diameter_mm) == pupil
    k = np.arange(-40, 41)
    q1 = k * du + shift * np.array([0.0, 1.0, -1.0])[k % 3]  # where each beam lands, one axis
    qx, qy = np.meshgrid(q1, q1)
    expected = int(np.sum(np.hypot(qx, qy) < 0.5 * (pupil + d)))
    ideal = int(np.sum(np.hypot(*np.meshgrid(k * du, k * du)) < 0.5 * (pupil + d)))
    for widths in (0.0, 2.0, 20.0):
        views = array_views(panel, 0.0, lattice_offset=(0.0, 0.0), pixel_offset_mm=(-p / 2, -p / 2),
                            diffraction_widths=widths)
        assert views.n_geometric == expected, (widths, views.n_geometric, expected)
    assert expected != ideal  # the pixel grid, not the ideal rays, decides which beams enter
    far = np.max(np.abs(views.lenslet_centres_mm[views.geometric]))
    assert far > 0.5 * (pupil + d)  # some come from lenslets whose ideal footprint misses
    # the phone's 3x3 at 1 D (RESULTS §28): the same count whatever the diffraction search
    from lfjax.studies.tradeoff import panel_for_views

    phone = panel_for_views(phone_panel(), 3)
    half = 0.5 * float(phone.pixel_pitch_mm)
    counts = {array_views(phone, 1.0, pixel_offset_mm=(half, half), diffraction_widths=w).n_geometric
              for w in (0.0, 2.0, 20.0)}
    gap, = idealisation_gap(phone, [1.0], pixel_offset_mm=(half, half))
    assert counts == {gap["n_array"]}


def test_idealisation_gap():
    """Vanishing pixels, fill 0.9, on the CDP: no gap at all; off the CDP the footprints
    move by the Eq. 1 scaling, |q|·|ratio − 1| for the idealised centre |q| = 0.75·√2 mm;
    the phone panel's lit beams miss the pupil (inf) and its emitters sweep 4× a view."""
    base = Panel.with_cdp(cdp_D=1.5, pixel_pitch_mm=1e-9, lenslet_pitch_mm=3.0 / 2 / 1.0471204,
                          focal_length_mm=3.3, distance_mm=30.0, fill=0.9, diffraction="off")
    on, off = idealisation_gap(base, [1.5, 1.0])
    assert on["n_array"] == on["n_idealised"] == 4
    assert on["footprint_shift_mm"] < 1e-6 and on["tilt_arcmin"] < 1e-4
    ratio = (1 - 0.03 * 1.5) / (1 - 0.03 * 1.0)
    assert off["footprint_shift_mm"] == pytest.approx(0.75 * math.sqrt(2) * abs(ratio - 1), rel=1e-4)
    phone, = idealisation_gap(phone_panel(), [2.0])
    assert phone["footprint_shift_mm"] == math.inf and phone["emitter_sweep_ratio"] > 4


def test_near_eye_pixels_quantise_the_rendered_depth():
    """The near-eye preset's pixels subtend 8.1′ at the eye, while a view 0.52 mm from the
    pupil centre turns by only 0.52 mrad = 1.8′ per dioptre of rendered depth: lighting the
    nearest pixel, the central lenslets light the same pixels for points at 0.5, 1.5 and 2.5 D —
    the same footprints, the depth carried only by sub-pixel tilts the renderer cannot
    make. (The pipeline's idealisation shifts every view continuously.)"""
    panel = near_eye_microdisplay()
    rows = []
    for d in (0.5, 1.5, 2.5):
        views = array_views(panel, d, diffraction_widths=0.0)
        central = np.all(np.abs(views.lenslet_centres_mm) < 0.6, axis=1)  # the 2×2 lenslets
        order = np.lexsort(views.lenslet_index[central].T)
        rows.append((views.centres_mm[central][order], views.ideal_centres_mm[central][order]))
    assert all(r[0].shape == (4, 2) for r in rows)
    assert all(np.allclose(r[0], rows[0][0], atol=1e-12) for r in rows)
    assert not np.allclose(rows[0][1], rows[2][1], atol=1e-3)
    parallax_arcmin_per_D = 0.5236 * 1e-3 * 180 * 60 / math.pi
    assert parallax_arcmin_per_D < 0.25 * float(panel.pixel_arcmin())


def _sweep_panel(distance_mm: float) -> Panel:
    """The display study's 2×2 lenslet array (3 mm pupil, CDP 2 D, f/5) at ``distance_mm``,
    with vanishing pixels (an ideal renderer)."""
    from lfjax.display.lenslets import lenslets_for_layout

    lenslets = lenslets_for_layout(2, 3.0, 2.0, distance_mm, f_number=5.0)
    pitch = float(lenslets.pitch_mm)
    return Panel(pitch * 1e-6, pitch, 1.0, float(lenslets.focal_length_mm), float(lenslets.gap_mm),
                 distance_mm)


@pytest.mark.parametrize("fresnel_number", [0.05, 1.0, 20.0])
def test_disc_fresnel_field_matches_the_on_axis_closed_form(fresnel_number):
    """On the axis the disc's Fresnel field is 1 − exp(iπN) (N = ρ₀²/(λz)); far off the
    axis (N even: 0, the bright ring's dark centre); inside a large-N disc, away from the
    axis, it is ≈ 1 with Fresnel ripple."""
    from lfjax.studies.array_views import disc_fresnel_field

    radius, wavelength = 0.5, 550.0
    distance = radius**2 / (wavelength * 1e-6 * fresnel_number)
    on_axis = complex(disc_fresnel_field(radius, wavelength, distance, np.array([0.0]))[0])
    assert abs(on_axis - (1 - np.exp(1j * np.pi * fresnel_number))) < 1e-6
    if fresnel_number >= 20:
        inside = disc_fresnel_field(radius, wavelength, distance, np.linspace(0.05, 0.3, 6))
        assert np.all(np.abs(np.abs(inside) - 1) < 0.3)


def test_disc_fresnel_field_agrees_with_the_pipelines_propagator():
    """The quadrature and lfjax.base.apertures.fresnel_propagate (a padded FFT convolution of a
    sampled, soft-edged disc) give the same field across and beyond the disc."""
    import jax.numpy as jnp

    from lfjax.base.apertures import fresnel_propagate
    from lfjax.studies.array_views import disc_fresnel_field

    radius, wavelength, distance, dx, n = 0.4, 550.0, 300.0, 0.01, 256
    x = (np.arange(n) - n // 2) * dx
    xx, yy = np.meshgrid(x, x)
    r = np.hypot(xx, yy)
    soft = 1.0 / (1.0 + np.exp(-(radius - r) / (0.25 * dx)))
    fft_field = np.asarray(fresnel_propagate(jnp.asarray(soft, jnp.complex128), dx, wavelength * 1e-6,
                                             distance))
    quad = disc_fresnel_field(radius, wavelength, distance, r)
    inside = r < 1.0
    assert np.max(np.abs(fft_field - quad)[inside]) < 0.02


def test_the_independent_views_computation_reproduces_the_pipelines_idealised_curves():
    """array_vs_views' idealised 2×2 (diffracted beams by quadrature, host FFTs) against the
    pipeline's through_focus with the same panel's optics at 550 nm: the VSOTF curves agree
    to < 1 % of their peak (measured 0.26 %); the whole array at 1 D off the CDP brings
    more lenslets' beams into the pupil than the four views."""
    from lfjax.studies.array_views import array_vs_views

    panel = _sweep_panel(300.0)
    eye = average_eye()
    acc = np.array([0.5, 1.0, 1.5])
    tf = through_focus(
        eye,
        panel.layout(2),
        States.grid(acc, depths_D=[1.0]),
        Viewing(pupil_diameter_mm=3.0, cdp_D=float(panel.cdp_D), display=panel.optics()),
        spectrum=make_spectrum([550.0]),
        sampling=Sampling(0.5),
    )
    pipeline = np.asarray(tf.vsotf)[0, 0]
    curves = array_vs_views(np.asarray(eye.zernike_um[0]), float(eye.measured_pupil_mm), panel, 1.0,
                            acc, freq_step_cpd=0.5)
    ours = curves["idealised"].vsotf
    assert np.max(np.abs(ours - pipeline)) < 0.01 * np.max(pipeline)
    assert curves["idealised"].n_views == 4 and curves["array"].n_views > 4
    assert curves["array"].dropped_energy_fraction < 1e-3


# ----------------------------------------------------------------------------- checked inputs


def _avv_args(**changes):
    """array_vs_views' arguments at a tiny size (the study's 2x2 array at 300 mm, the
    average eye, a 4 cpd step: 26x26 pupil samples), with ``changes``."""
    eye = average_eye()
    args = dict(zernike_um=np.asarray(eye.zernike_um[0]), measured_pupil_mm=3.0,
                panel=_sweep_panel(300.0), depth_D=1.0, accommodation_D=[1.0, 2.0],
                freq_step_cpd=4.0, diffraction_widths=0.0)
    args.update(changes)
    return args


def _avv(**changes):
    """array_vs_views on :func:`_avv_args`; its beam fields (``diffraction_widths``,
    ``min_view_energy``, ``pixel_offset_mm``) go into one ArrayBeams."""
    from lfjax.studies.array_views import ArrayBeams, array_vs_views

    a = _avv_args(**changes)
    beams = ArrayBeams(**{k: a.pop(k) for k in ("diffraction_widths", "min_view_energy",
                                                 "pixel_offset_mm") if k in a})
    return array_vs_views(a.pop("zernike_um"), a.pop("measured_pupil_mm"), a.pop("panel"),
                          a.pop("depth_D"), a.pop("accommodation_D"), beams=beams, **a)


@pytest.mark.parametrize("changes, message", [
    # each of these returned NaN curves, or raised a bare ZeroDivisionError / scipy's
    # "Target length must be positive", before the checks (issue #37)
    (dict(zernike_um=np.full(15, np.nan)), "zernike_um must be finite, got NaN or inf at modes [0, 1"),
    (dict(chunk=-1), "chunk must be an integer >= 1 (views transformed together), got -1"),
    (dict(chunk=0), "chunk must be an integer >= 1"),
    (dict(measured_pupil_mm=0.0), "measured_pupil_mm must be finite and in (0, inf], got 0.0"),
    (dict(measured_pupil_mm=2.0), "measured_pupil_mm = 2 mm is smaller than the panel's design pupil 3 mm"),
    (dict(freq_step_cpd=0.0), "freq_step_cpd must be finite and in (0, inf], got 0.0"),
    (dict(freq_step_cpd=-0.5), "freq_step_cpd must be finite and in (0, inf], got -0.5"),
    (dict(freq_step_cpd=8.0), "freq_step_cpd must be in (0, 5.95] cpd (the 3 mm pupil spans at least 16"),
    (dict(depth_D=20.0), "depth_D: every rendered depth must lie in the model's range [0, 10] D"),
    (dict(accommodation_D=[1.0, 50.0]), "accommodation_D: every accommodation state must lie in the "
                                        "model's range [0, 10] D"),
    (dict(accommodation_D=[np.nan]), "accommodation_D must be finite"),
    (dict(accommodation_D=[]), "accommodation_D must hold at least one state"),
    (dict(pixel_offset_mm=(0.0, np.inf)), "pixel_offset_mm must be two finite numbers"),
    (dict(min_view_energy=1.0), "min_view_energy must be in [0, 1), got 1.0"),
])
def test_array_vs_views_refuses_every_bad_argument_by_name(changes, message):
    with pytest.raises(ParameterError) as err:
        _avv(**changes)
    assert str(err.value).startswith(message), str(err.value)


def test_array_vs_views_estimates_its_memory_and_refuses_what_cannot_fit():
    """A fine step allocated 18 GB before the check: now its memory is estimated first and a
    step that cannot fit is refused, saying which step would; the estimate bounds the peak
    tracemalloc measures (one tiny run)."""
    import tracemalloc

    from lfjax.studies.array_views import array_views, array_vs_views_bytes

    panel = _sweep_panel(300.0)
    n = array_views(panel, 1.0, diffraction_widths=0.0).n_views
    with pytest.raises(ParameterError) as err:
        _avv(freq_step_cpd=0.01, available_bytes=2e9)
    text = str(err.value)
    assert text.startswith(f"freq_step_cpd = 0.01 cpd would need ~") and "1.86 GiB available" in text
    suggested = float(text.split("freq_step_cpd >= ")[1].split(" cpd")[0])
    assert array_vs_views_bytes(panel, n, 550.0, suggested, 1) <= 2e9
    assert array_vs_views_bytes(panel, n, 550.0, suggested / 1.1, 1) > 2e9  # and not much coarser
    tracemalloc.start()
    try:
        _avv()
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak <= array_vs_views_bytes(panel, n, 550.0, 4.0, 32)


def test_array_vs_views_gives_finite_curves_for_random_valid_inputs():
    """Seeded property test: 6 random valid inputs (eyes, depth, states, pixel grid
    offset, chunk) at the tiny size give finite VSOTF curves and energies."""
    from lfjax.model.eyes import sample_eyes

    rng = np.random.default_rng(37)
    for _ in range(6):
        z = np.asarray(sample_eyes(int(rng.integers(0, 2**31)), 1).zernike_um[0])
        out = _avv(zernike_um=z, depth_D=float(rng.uniform(0.0, 3.0)),
                   accommodation_D=np.sort(rng.uniform(0.0, 4.0, 2)),
                   pixel_offset_mm=tuple(rng.uniform(-0.01, 0.01, 2)),
                   chunk=int(rng.integers(1, 8)))
        for curves in out.values():
            assert np.all(np.isfinite(curves.vsotf)) and np.all(np.isfinite(curves.energy))
            assert curves.n_views >= 1
