"""Lenticular views and view leakage (lfjax.display.lenticular): the beam's geometry, its
astigmatic wavefront, bad input, and gradients against finite differences (float64)."""

from __future__ import annotations

import math

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import lfjax
from lfjax.base.errors import ParameterError
from lfjax.base.zernike import wavefront_um
from lfjax.display.lenticular import (
    LenticularPanel, ViewOptics, check_display_for_layout, lenticular_near_eye, lenticular_phone,
    strip_display,
)
from lfjax.model.strips import strip_layout
from lfjax.vision.focus import metrics_at
from lfjax.vision.viewing import Viewing

def test_lenticular_phone_geometry_by_hand():
    """Gap for a 2 D CDP 350 mm away with f = 3 mm: 1/z_0 = 1/3 + 1/150; along y the beam
    diverges from the panel at 350 + z_0 mm."""
    p = lenticular_phone()
    z0 = 1.0 / (1.0 / 3.0 + 1.0 / 150.0)
    assert float(p.gap_mm) == pytest.approx(z0, rel=1e-6)
    assert float(p.cdp_D) == pytest.approx(2.0, rel=1e-6)
    assert float(p.panel_D) == pytest.approx(1000.0 / (350.0 + z0), rel=1e-6)
    assert float(p.y_defocus_D) == pytest.approx(2.0 - 1000.0 / (350.0 + z0), rel=1e-5)
    assert float(p.magnification) == pytest.approx(500.0 / 150.0, rel=1e-6)  # L / v
    assert float(p.view_pitch_mm) == pytest.approx(0.45 * 500.0 / 150.0, rel=1e-6)
    assert p.views_across(3.0) == 2
    assert float(p.eye_box_mm()) == pytest.approx(0.45 * (1 + 350.0 / z0), rel=1e-6)
    layout = p.layout(3.0)
    assert layout.n_subapertures == 2 and float(layout.diameters_mm[0]) == pytest.approx(1.5, rel=1e-6)
    near = lenticular_near_eye()
    assert float(near.y_defocus_D) == pytest.approx(1.5 - 1000.0 / (30.0 + float(near.gap_mm)), rel=1e-5)
    assert float(near.y_defocus_D) < -28.0


def test_the_beam_wavefront_is_the_y_defocus():
    """The added Zernike terms are W = Δ·y²/2 µm (y in mm) up to piston, on any eye."""
    delta, measured = -1.7, 6.0
    optics = ViewOptics(y_defocus_D=delta)
    eye = jnp.asarray(np.random.default_rng(1).normal(0, 0.1, 15))
    added = optics.beam_wavefront_um(eye, measured) - eye
    r = 0.5 * measured
    x, y = np.meshgrid(np.linspace(-0.7, 0.7, 9), np.linspace(-0.7, 0.7, 9))
    w = np.asarray(wavefront_um(added, jnp.asarray(x), jnp.asarray(y)))
    expected = delta * (y * r) ** 2 / 2
    np.testing.assert_allclose(w - w.mean(), expected - expected.mean(), atol=1e-12)
    assert optics.beam_wavefront_um(jnp.zeros(3), measured).shape == (6,)


def test_the_view_fields_are_declared_on_every_display_and_mean_nothing_when_unset():
    """DisplayOptics declares the lenticular and leakage fields (None: nothing; the kernel
    reads them, no hooks): unset, the eye's coefficients pass through untouched and no view
    mixes; set, a plain DisplayOptics does what a ViewOptics does."""
    from lfjax.display.lenslets import DisplayOptics

    eye = jnp.asarray(np.random.default_rng(2).normal(0, 0.1, 10))
    plain = DisplayOptics()
    assert plain.beam_wavefront_um(eye, 6.0) is eye and plain.view_mixing is None
    assert not plain.strips and not plain.fills_pupil
    a = jnp.asarray([[0.0, 1.0], [1.0, 0.0]])
    declared = DisplayOptics(aperture="strip", y_defocus_D=-0.8, leakage_weight=0.3, neighbours=a)
    view = ViewOptics(aperture="strip", y_defocus_D=-0.8, leakage_weight=0.3, neighbours=a)
    assert declared.strips and declared.fills_pupil
    np.testing.assert_array_equal(declared.beam_wavefront_um(eye, 6.0), view.beam_wavefront_um(eye, 6.0))
    np.testing.assert_array_equal(declared.view_mixing, view.view_mixing)
    np.testing.assert_allclose(np.asarray(view.view_mixing), [[1 / 1.3, 0.3 / 1.3], [0.3 / 1.3, 1 / 1.3]])
    assert type(view.checked()) is ViewOptics and type(declared.checked()) is DisplayOptics
    with pytest.raises(ParameterError, match=r"DisplayOptics.leakage_weight must be in \[0, 1\]"):
        DisplayOptics(leakage_weight=2.0)


@pytest.mark.parametrize("build, parameter", [
    (lambda: ViewOptics(y_defocus_D=50.0), "y_defocus_D"),
    (lambda: ViewOptics(y_defocus_D=float("nan")), "y_defocus_D"),
    (lambda: ViewOptics(leakage_weight=-0.1), "leakage_weight"),
    (lambda: ViewOptics(leakage_weight=1.5), "leakage_weight"),
    (lambda: ViewOptics(neighbours=jnp.full((2, 2), 0.5)), "neighbours"),
    (lambda: LenticularPanel(0.05, 0.45, 0.0, 3.0, 2.9, 350.0), "fill"),
    (lambda: LenticularPanel(0.05, 0.45, 1.0, 3.0, 3.5, 350.0), "gap_mm"),
    (lambda: LenticularPanel(0.05, 0.45, 1.0, 3.0, 2.9, 350.0, 2.0), "leakage_weight"),
    (lambda: check_display_for_layout(strip_display(strip_layout(3)), strip_layout(2)), "display"),
])
def test_bad_input_names_the_parameter_and_its_range(build, parameter):
    with pytest.raises(ParameterError) as info:
        build()
    assert info.value.parameter == parameter


def test_new_parameters_are_differentiable():
    """d Σ VSOTF / d (y defocus, leakage weight, strip width) against central differences."""
    eye = lfjax.average_eye(3.0)
    spectrum = lfjax.make_spectrum([550.0])
    sampling = lfjax.Sampling(2.2)
    base_layout = strip_layout(2, 2.0)  # a 2 mm pupil: small windows, a quick compile
    acc = jnp.array([[1.6, 2.3]])

    def vsotf(y_defocus, weight, width):
        layout = eqx.tree_at(lambda lay: lay.diameters_mm, base_layout, jnp.full((2,), width))
        display = strip_display(base_layout, y_defocus_D=y_defocus, leakage_weight=weight)
        return jnp.sum(
            metrics_at(
                eye,
                layout,
                [2.5],
                acc,
                Viewing(pupil_diameter_mm=2.0, cdp_D=2.0, display=display),
                spectrum=spectrum,
                sampling=sampling,
            )[0]
        )

    x0 = (jnp.asarray(-0.6), jnp.asarray(0.3), jnp.asarray(0.9))
    # one compiled program gives the values and the gradient (the differences reuse it)
    value_and_grad = jax.jit(jax.value_and_grad(vsotf, argnums=(0, 1, 2)))
    _, grads = value_and_grad(*x0)
    for i, h in ((0, 1e-4), (1, 1e-5), (2, 1e-5)):
        plus, minus = list(x0), list(x0)
        plus[i] = plus[i] + h
        minus[i] = minus[i] - h
        fd = (value_and_grad(*plus)[0] - value_and_grad(*minus)[0]) / (2 * h)
        assert float(grads[i]) == pytest.approx(float(fd), rel=1e-4, abs=1e-9)
        assert abs(float(grads[i])) > 1e-4


def test_a_cylindrical_lenslet_diffracts_along_x_only():
    """Fresnel propagation along x only: each row of a field is propagated as the 1-D field
    it is (the 2-D propagation of a y-uniform field, at its centre row), and the field's
    profile along y, sharp edges included, is kept."""
    from lfjax.base.apertures import fresnel_propagate

    n, dx, wl, z = 64, 0.05, 550e-6, 40.0
    x = (np.arange(n) - n // 2) * dx
    strip = (np.abs(x) < 0.6).astype(complex)
    rows = np.asarray([0.3, 1.0, 0.7])[:, None] * strip[None, :]
    out = np.asarray(fresnel_propagate(jnp.asarray(rows), dx, wl, z, along_y=False))
    one_d = np.asarray(fresnel_propagate(jnp.asarray(np.tile(strip, (n, 1))), dx, wl, z,
                                         extent_mm=n * dx))
    # a y-uniform field propagated in 2-D keeps its y profile away from the window's edge
    np.testing.assert_allclose(out[1], one_d[n // 2], atol=2e-2)
    np.testing.assert_allclose(out[0] / 0.3, out[1], atol=1e-12)
    assert np.max(np.abs(out[1] - strip)) > 0.05  # it did diffract
    # sharp edges along y stay sharp: no diffraction along the lenslet's axis
    g = np.where(np.abs(x) < 0.4, 1.0, 0.0)
    sharp = np.asarray(fresnel_propagate(jnp.asarray(g[:, None] * strip[None, :]), dx, wl, z,
                                         along_y=False))
    np.testing.assert_allclose(sharp, g[:, None] * out[1][None, :], atol=1e-12)
