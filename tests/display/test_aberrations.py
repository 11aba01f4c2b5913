"""Lenslet aberrations (lfjax.display.aberrations): the thin-lens Seidel sums against exact ray
traces, the view's wavefront against the same terms in the eye's Zernike coefficients, zero
aberration bit for bit, finite-difference gradients and bad input."""

from __future__ import annotations

import math
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import helpers as H
import lfjax
from lfjax.base.errors import ParameterError
from lfjax.display.aberrations import (
    LensletAberration,
    lenslet_aberration,
    panel_aberration,
    seidel_coefficients,
)
from lfjax.display.lenslets import DisplayOptics
from lfjax.display.panel import near_eye_microdisplay
from lfjax.model.eyes import aberration_free_eye
from lfjax.vision.focus import metrics_at
from lfjax.vision.viewing import Viewing

WL = [550.0]
OPTIONS = lfjax.ModelOptions()
SAMPLING = lfjax.Sampling(1.5, edge_width_samples=0.25)


# ----------------------------------------------------------------------------- Seidel sums


def _refract(d, normal, n1, n2):
    cos_i = d @ normal
    mu = n1 / n2
    cos_t = math.sqrt(1.0 - mu * mu * (1.0 - cos_i * cos_i))
    return mu * d + (cos_t - mu * cos_i) * normal


def _sphere(p, d, zc, radius, n1, n2):
    oc = p - np.array([0.0, zc])
    b = oc @ d
    root = math.sqrt(b * b - (oc @ oc - radius * radius))
    vertex = zc - radius
    hits = [p + s * d for s in (-b - root, -b + root)]
    q = min(hits, key=lambda h: abs(h[1] - vertex))
    normal = (q - np.array([0.0, zc])) / abs(radius)
    return q, _refract(d, normal if normal @ d > 0 else -normal, n1, n2)


def _plane(p, d, z, n1, n2):
    q = p + (z - p[1]) / d[1] * d
    return q, _refract(d, np.array([0.0, 1.0]), n1, n2)


def _trace(y, f, n, convex_to_eye, vergence, half_aperture):
    """Exact meridional ray (x, z) through a plano-convex lens of thin focal length f, light
    from the eye side converging on a point 1/vergence beyond the lens; returns the ray
    after the lens. Thickness: the sag of the aperture (zero edge thickness)."""
    radius = (n - 1.0) * f
    t = radius - math.sqrt(radius**2 - half_aperture**2)
    d = np.array([-y * vergence, 1.0])
    d /= np.linalg.norm(d)
    p = np.array([y, 0.0]) - d
    if convex_to_eye:
        p, d = _sphere(p, d, radius, radius, 1.0, n)
        return _plane(p, d, t, n, 1.0)
    p, d = _plane(p, d, 0.0, 1.0, n)
    return _sphere(p, d, t - radius, -radius, n, 1.0)


@pytest.mark.parametrize("vergence", [0.0, 0.05])
@pytest.mark.parametrize("form, convex_to_eye", [("plano-convex-eye", True), ("plano-convex-panel", False)])
def test_spherical_aberration_matches_an_exact_ray_trace(vergence, form, convex_to_eye):
    """The transverse ray error at the paraxial image of the pixel is −z'·∂W/∂y: for
    W = W040 (y/Y)⁴ it is 4 z' W040 y³/Y⁴ towards the axis (an undercorrected lens, W040 > 0).
    Exact rays through plano-convex lenses of either orientation, collimated (V = 0) and
    converging (V = 0.05/mm, C = −1.33), agree with the thin-lens S_I to 0.3 %."""
    f, n, half = 3.3, 1.5, 0.1
    w040_mm = float(seidel_coefficients(f, 2 * half, vergence, refractive_index=n, lens_form=form)
                    ["spherical_um"]) * 1e-3
    p0, d0 = _trace(1e-5, f, n, convex_to_eye, vergence, half)
    z_image = p0[1] - p0[0] * d0[1] / d0[0]
    for y in (0.02, 0.04):
        p, d = _trace(y, f, n, convex_to_eye, vergence, half)
        error = p[0] + (z_image - p[1]) * d[0] / d[1]
        assert error < 0  # the marginal ray crosses the axis before the paraxial image
        assert -error / y**3 == pytest.approx(4.0 * z_image * w040_mm / half**4, rel=3e-3)


def test_seidel_coefficients_forms_and_field():
    """Classical values: W040 = 0.268·y⁴/f³ for the best form at infinite conjugate (n = 1.5)
    and about 3.9 times more for a plano-convex lenslet the wrong way round; astigmatism and
    field curvature θ²y²/(2f) and θ²y²/(4nf), independent of the form; a pinhole has none."""
    f, a = 3.0, 0.6
    y4f3 = (a / 2) ** 4 / f**3 * 1e3
    best = seidel_coefficients(f, a, lens_form="best-form")
    good = seidel_coefficients(f, a, lens_form="plano-convex-eye")
    bad = seidel_coefficients(f, a, lens_form="plano-convex-panel")
    assert float(best["spherical_um"]) == pytest.approx(0.2679 * y4f3, rel=1e-3)
    assert float(good["spherical_um"]) == pytest.approx(7.0 / 24.0 * y4f3, rel=1e-9)
    assert float(bad["spherical_um"]) / float(good["spherical_um"]) == pytest.approx(36.0 / (28.0 / 3.0))
    theta = math.radians(10.0)
    for form in ("biconvex", "plano-convex-panel"):
        c = seidel_coefficients(f, a, lens_form=form, field_angle_deg=10.0)
        assert float(c["astigmatism_um"]) == pytest.approx(theta**2 * (a / 2) ** 2 / (2 * f) * 1e3)
        assert float(c["field_curvature_um"]) == pytest.approx(theta**2 * (a / 2) ** 2 / (6 * f) * 1e3)
    pinhole = seidel_coefficients(math.inf, a, 0.01, field_angle_deg=20.0)
    assert all(float(v) == 0.0 for v in pinhole.values())


# ----------------------------------------------------------------------------- in the pipeline


def _metrics(display, eye=None, layout=None):
    layout = lfjax.grid_layout(2, 3.0) if layout is None else layout
    eye = lfjax.average_eye(3.0) if eye is None else eye
    acc = np.array([[0.6, 1.4], [1.8, 2.4]])
    out = metrics_at(
        eye,
        layout,
        [1.0, 2.0],
        acc,
        Viewing(pupil_diameter_mm=3.0, cdp_D=2.0, display=display),
        spectrum=lfjax.make_spectrum(WL),
        sampling=SAMPLING,
        options=OPTIONS,
    )
    return np.asarray(out[0]), np.asarray(out[1])


@pytest.mark.parametrize("diffraction", ["off", "fresnel"])
def test_zero_aberration_changes_nothing_bit_for_bit(diffraction):
    """None and an all-zero LensletAberration both give the numbers without one, bit for bit."""
    plain = DisplayOptics(diffraction, "circle", 400.0, 0.5)
    base = _metrics(plain)
    for zero in (None, LensletAberration(), lenslet_aberration(3.3, 1.0, field_angle_deg=0.0,
                                                               spherical_um=0.0)):
        got = _metrics(plain.with_aberration(zero))
        np.testing.assert_array_equal(got[0], base[0])
        np.testing.assert_array_equal(got[1], base[1])


def test_a_full_pupil_view_carries_the_aberration_as_the_eyes_zernike_terms():
    """One view filling the 3 mm pupil: W040ρ⁴ + W222ρ²cos²φ (field along +x) is, up to
    piston, c(4,0) = W040/(6√5), c(2,0) = W040/(2√3) + W222/(4√3), c(2,2) = W222/(2√6) of
    the eye (OSA j = 12, 4, 5), on the view's own radius."""
    w040, w222 = 0.3, 0.2
    layout = lfjax.make_layout([[0.0, 0.0]], [3.0], 3.0)
    eye = lfjax.average_eye(3.0)
    lens = DisplayOptics().with_aberration(LensletAberration(spherical_um=w040, astigmatism_um=w222))
    shifted = np.array(eye.zernike_um, float)
    shifted[..., 12] += w040 / (6 * math.sqrt(5))
    shifted[..., 4] += w040 / (2 * math.sqrt(3)) + w222 / (4 * math.sqrt(3))
    shifted[..., 5] += w222 / (2 * math.sqrt(6))
    as_eye = lfjax.make_eyes(shifted, 3.0)
    got = _metrics(lens, eye, layout)
    expected = _metrics(None, as_eye, layout)
    np.testing.assert_allclose(got[0], expected[0], rtol=1e-9, atol=1e-12)
    assert np.abs(got[0] - _metrics(None, eye, layout)[0]).max() > 0.05  # and it matters


def test_positive_spherical_aberration_moves_a_views_focus_farther():
    """An undercorrected lenslet (W040 > 0) sends the rim's rays as from beyond the CDP: the
    eye's best focus for a single view moves to lower dioptres."""
    layout = lfjax.make_layout([[0.0, 0.0]], [3.0], 3.0)
    eye = aberration_free_eye(3.0)
    acc = np.linspace(1.0, 2.6, 9)[None]
    spectrum = lfjax.make_spectrum(WL)

    def peak(display):
        v = np.asarray(
            metrics_at(
                eye,
                layout,
                [2.0],
                acc,
                Viewing(pupil_diameter_mm=3.0, cdp_D=2.0, display=display),
                spectrum=spectrum,
                sampling=SAMPLING,
                options=OPTIONS,
            )[0]
        )[0, 0]
        return acc[0, int(np.argmax(v))]

    assert peak(None) == pytest.approx(2.0)
    assert peak(DisplayOptics().with_aberration(LensletAberration(spherical_um=0.4))) < 2.0


def test_aberration_gradients_match_finite_differences():
    """d Σ VSOTF / d (W040, W131, W222, W220, ψ) against central differences (float64),
    through the diffracted beams' source phase (the geometric views' wavefront is the eye's
    Zernike terms: test_a_full_pupil_view_carries_the_aberration_as_the_eyes_zernike_terms)."""
    diffraction = "fresnel"
    eye = lfjax.average_eye(3.0)
    acc = jnp.array([[1.2, 1.8]])
    spectrum = lfjax.make_spectrum(WL)
    layout = lfjax.grid_layout(2, 3.0)
    base = jnp.array([0.2, 0.1, 0.15, 0.05, 0.3])

    def f(c):
        display = DisplayOptics(diffraction, "circle", 400.0).with_aberration(LensletAberration(*c))
        return jnp.sum(
            metrics_at(
                eye,
                layout,
                [1.4],
                acc,
                Viewing(pupil_diameter_mm=3.0, cdp_D=2.0, display=display),
                spectrum=spectrum,
                sampling=SAMPLING,
                options=OPTIONS,
            )[0]
        )

    grad = np.asarray(jax.grad(f)(base))
    h = 1e-4
    for i in range(5):
        e = jnp.zeros(5).at[i].set(h)
        fd = float((f(base + e) - f(base - e)) / (2 * h))
        assert grad[i] == pytest.approx(fd, rel=2e-3, abs=1e-8), i
    assert np.all(np.abs(grad[:4]) > 1e-5)


def test_panel_aberration_is_differentiable_in_the_lens_numbers():
    """d W / d (refractive index, field angle) of the preset's lenslets against differences,
    and the field guard holds the aberration's rays (a wider field than without it)."""
    panel = near_eye_microdisplay()

    def total(n, theta):
        ab = panel_aberration(panel, refractive_index=n, field_angle_deg=theta)
        return ab.spherical_um + ab.coma_um + ab.astigmatism_um + ab.field_curvature_um

    g = jax.grad(total, argnums=(0, 1))(1.5, 8.0)
    for i, (args_p, args_m) in enumerate((((1.5 + 1e-5, 8.0), (1.5 - 1e-5, 8.0)),
                                          ((1.5, 8.0 + 1e-5), (1.5, 8.0 - 1e-5)))):
        fd = (total(*args_p) - total(*args_m)) / 2e-5
        assert float(g[i]) == pytest.approx(float(fd), rel=1e-5)
    optics = panel.optics()
    layout = panel.layout()
    assert optics.aberration_slope_rad(layout.diameters_mm) == 0.0
    slope = optics.with_aberration(panel_aberration(panel, field_angle_deg=10.0)).aberration_slope_rad(
        layout.diameters_mm)
    assert slope > 4 * 0.505e-3 / 0.52  # at least the spherical term's rim ray angle


@pytest.mark.parametrize("build, match", [
    (lambda: LensletAberration(spherical_um=float("nan")), r"spherical_um must be in \[-100, 100\] µm"),
    (lambda: LensletAberration(astigmatism_um=150.0), r"astigmatism_um must be in \[-100, 100\] µm"),
    (lambda: LensletAberration(coma_um=[0.1, 0.2]), r"coma_um must be a scalar"),
    (lambda: lenslet_aberration(3.0, 0.5, refractive_index=1.0), r"refractive_index must be in \(1, 4\]"),
    (lambda: lenslet_aberration(3.0, 0.5, field_angle_deg=75.0), r"field_angle_deg must be in \[0, 60\] deg"),
    (lambda: lenslet_aberration(-3.0, 0.5), r"focal_length_mm must be in \(0, inf\] mm"),
    (lambda: lenslet_aberration(3.0, 0.0), r"aperture_mm must be in \(0, 1000\] mm"),
    (lambda: lenslet_aberration(3.0, 0.5, -0.1), r"image_vergence_per_mm must be in \[0, 1000\] 1/mm"),
    (lambda: lenslet_aberration(3.0, 0.5, lens_form="meniscus"), r"lens_form must be one of"),
    (lambda: lenslet_aberration(3.0, 0.5, field_azimuth_deg=400.0), r"field_azimuth_deg must be in"),
    (lambda: DisplayOptics(aberration=0.3), r"DisplayOptics.aberration must be a LensletAberration"),
])
def test_bad_aberration_input_names_the_parameter_unit_and_range(build, match):
    with pytest.raises(ParameterError, match=match):
        build()


# ----------------------------------------------------------------------------- the notebook

NOTEBOOK = Path(__file__).resolve().parents[2] / "notebooks" / "lenslet_aberrations.ipynb"


def test_notebook_matches_its_script_twin():
    outputs = H.committed_notebook_outputs(NOTEBOOK)
    assert len([o for o in outputs if "image/png" in o.get("data", {})]) >= 2


def test_notebook_executes(tmp_path):
    """notebooks/lenslet_aberrations.ipynb runs top to bottom at its tiny size."""
    _, images, text = H.execute_notebook_tiny(NOTEBOOK, tmp_path)
    assert len(images) >= 2
    assert "plano-convex n = 1.5, 10° off axis" in text
