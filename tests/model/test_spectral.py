"""Spectral model (lfjax.model.spectral) and model options (lfjax.model.options)."""

import numpy as np
import pytest

import lfjax
import reference as R
from lfjax.model import spectral
from lfjax.model.options import ModelOptions


def test_lef_table_values():
    """CIE 2008 2° physiologically relevant LEF from colour-science (values as
    colour-science tabulates them): range 390–830 nm, V(555) ≈ 0.9995, peak at 555–556 nm."""
    assert spectral.lef_range_nm() == (390.0, 830.0)
    v = spectral.luminous_efficiency([400.0, 550.0, 555.0, 700.0])
    np.testing.assert_allclose(v, [0.00245219, 0.989023, 0.999461, 0.00419594], rtol=1e-5)
    wl = np.arange(540.0, 571.0)
    assert wl[np.argmax(spectral.luminous_efficiency(wl))] in (555.0, 556.0)
    # linear interpolation between the 1 nm samples
    mid = spectral.luminous_efficiency([550.5])[0]
    assert mid == pytest.approx(0.5 * (spectral.luminous_efficiency([550.0])[0]
                                       + spectral.luminous_efficiency([551.0])[0]), rel=1e-12)


def test_default_spectrum_weights():
    s = lfjax.make_spectrum()
    wl = np.asarray(s.wavelengths_nm)
    np.testing.assert_array_equal(wl, np.arange(400.0, 701.0, 10.0))
    w = np.asarray(s.weights)
    assert w.sum() == pytest.approx(1.0, abs=1e-15)
    v = spectral.luminous_efficiency(wl)
    np.testing.assert_allclose(w, v / v.sum(), rtol=1e-13)  # uniform grid: V(λ)·Δλ
    assert s.n_wavelengths == 31


def test_nonuniform_and_explicit_weights():
    wl = [450.0, 500.0, 600.0]
    s = lfjax.make_spectrum(wl, ModelOptions(sce="off"))
    v = spectral.luminous_efficiency(wl)
    widths = np.array([25.0, 75.0, 50.0])  # trapezoid cells between midpoints
    np.testing.assert_allclose(s.weights, v * widths / (v * widths).sum(), rtol=1e-13)
    s = lfjax.make_spectrum(wl, ModelOptions(sce="off"), weights=[1.0, 2.0, 1.0])
    np.testing.assert_allclose(s.weights, [0.25, 0.5, 0.25], rtol=1e-15)
    s = lfjax.make_spectrum([555.0])
    np.testing.assert_array_equal(s.weights, [1.0])


def test_lca_values_and_sign():
    """D(λ) = A (1/(λ−c) − 1/(λref−c)), A = 633.26, c = 214.10 nm, λref = 550 nm; the eye is
    more powerful (myopic, positive D) for blue; ≈ 1.5 D at 400 nm (docs/design.md#why-it-is-fast)."""
    wl = np.array([400.0, 450.0, 550.0, 650.0, 700.0])
    d = spectral.lca_dioptres(wl)
    np.testing.assert_allclose(d, R.lca_dioptres(wl), rtol=1e-14, atol=1e-15)
    assert d[2] == 0.0
    assert d[0] > d[1] > 0 > d[3] > d[4]
    assert d[0] == pytest.approx(1.5212, abs=1e-4)
    s = lfjax.make_spectrum(wl)
    np.testing.assert_allclose(s.lca_D, d, rtol=1e-14)
    opts = ModelOptions(lca_A=633.46, lca_reference_nm=570.0)
    np.testing.assert_allclose(
        spectral.lca_dioptres(wl, opts), R.lca_dioptres(wl, 633.46, 214.10, 570.0), rtol=1e-14)
    assert float(spectral.lca_dioptres(570.0, opts)) == 0.0


def test_stiles_crawford_rho():
    """ρ(λ) from the ISETBio Berendschot table (ρ(550) = 0.041 mm⁻², ρ(400) = 0.0565);
    'intensity' halves it (amplitude 10^(−ρr²/2)); 'off' is zero."""
    rho = spectral.sce_rho_per_mm2([400.0, 550.0, 555.0, 560.0])
    assert rho[0] == pytest.approx(0.0565, abs=1e-12)
    assert rho[1] == pytest.approx(0.041, abs=1e-12)
    assert rho[2] == pytest.approx(0.5 * (rho[1] + rho[3]), rel=1e-12)
    wl = [450.0, 550.0, 650.0]
    amp = lfjax.make_spectrum(wl, ModelOptions(sce="amplitude")).sce_rho_per_mm2
    inten = lfjax.make_spectrum(wl, ModelOptions(sce="intensity")).sce_rho_per_mm2
    off = lfjax.make_spectrum(wl, ModelOptions(sce="off")).sce_rho_per_mm2
    np.testing.assert_allclose(amp, spectral.sce_rho_per_mm2(wl), rtol=1e-15)
    np.testing.assert_allclose(inten, 0.5 * np.asarray(amp), rtol=1e-15)
    np.testing.assert_array_equal(off, 0.0)


def test_wavelength_range_errors():
    """Outside the LEF data (390–830 nm) always; outside the SCE table (400–700 nm) only when
    the Stiles–Crawford effect is on."""
    off = ModelOptions(sce="off")
    with pytest.raises(ValueError, match="wavelengths_nm.*390.*830"):
        lfjax.make_spectrum([385.0, 550.0], off)
    with pytest.raises(ValueError, match="wavelengths_nm.*390.*830"):
        lfjax.make_spectrum([550.0, 835.0], off)
    with pytest.raises(ValueError, match="wavelengths_nm.*400.*700.*Stiles"):
        lfjax.make_spectrum([550.0, 720.0])
    with pytest.raises(ValueError, match="wavelengths_nm.*400.*700.*Stiles"):
        lfjax.make_spectrum([395.0, 550.0], ModelOptions(sce="intensity"))
    s = lfjax.make_spectrum([395.0, 550.0, 720.0], off)  # fine without SCE
    assert s.n_wavelengths == 3
    with pytest.raises(ValueError, match="wavelengths_nm"):
        lfjax.make_spectrum([550.0, np.nan], off)


def test_spectrum_shape_and_weight_errors():
    with pytest.raises(ValueError, match="strictly increasing"):
        lfjax.make_spectrum([550.0, 500.0])
    with pytest.raises(ValueError, match="strictly increasing"):
        lfjax.make_spectrum([550.0, 550.0])
    with pytest.raises(ValueError, match="weights"):
        lfjax.make_spectrum([500.0, 550.0], weights=[1.0, -1.0])
    with pytest.raises(ValueError, match="weights"):
        lfjax.make_spectrum([500.0, 550.0], weights=[1.0])
    with pytest.raises(ValueError, match="sum to zero"):
        lfjax.make_spectrum([500.0, 550.0], weights=[0.0, 0.0])
    with pytest.raises(ValueError, match="wavelengths_nm"):
        lfjax.make_spectrum(np.zeros((2, 2)) + 550.0)


def test_model_options_validation_and_hashing():
    assert hash(ModelOptions()) == hash(ModelOptions())
    assert ModelOptions().replace(sce="off") == ModelOptions(sce="off")
    for field, bad in (("sce", "both"), ("accommodation_sa", "scaled_5mm"),
                       ("vsotf_reference", "open"), ("ncsf", "barten"), ("sce_table", "x")):
        with pytest.raises(ValueError, match=field):
            ModelOptions(**{field: bad})
    with pytest.raises(ValueError, match="lca_c_nm"):
        ModelOptions(lca_c_nm=400.0)
    with pytest.raises(ValueError, match="sa_reference_pupil_mm"):
        ModelOptions(sa_reference_pupil_mm=0.0)
    d = ModelOptions().as_dict()
    assert d["sce"] == "amplitude" and d["accommodation_sa"] == "scaled"
    assert d["sa_slope_um_per_D"] == -0.0435 and d["lca_A"] == 633.26


# ----------------------------------------------------------------------------- Gauss rule in V(λ)


def _exact_legendre_moments(k_max, start, stop, source=None):
    """∫ P_k(t) ρ dλ / ∫ ρ dλ for k = 0..k_max, t = (2λ − start − stop)/(stop − start),
    ρ = V (linear between its 1 nm samples) × the source (linear between its samples):
    exactly, piece by piece, with Legendre-series products and antiderivatives (no
    quadrature), independent of gauss_rule's discretisation."""
    from numpy.polynomial import Legendre

    wl_v, v = spectral.lef_data()
    edges = [wl_v]
    if source is not None:
        edges.append(np.asarray(source[0], float))
    edges = np.concatenate(edges)
    edges = np.unique(np.concatenate([[start, stop], edges[(edges > start) & (edges < stop)]]))
    to_t = lambda lam: (2.0 * lam - start - stop) / (stop - start)  # noqa: E731
    moments = np.zeros(k_max + 1)
    for a, b in zip(edges[:-1], edges[1:]):
        ta, tb = to_t(a), to_t(b)

        def linear(values_at):  # the table's linear piece as a series in t
            fa, fb = values_at(a), values_at(b)
            slope = (fb - fa) / (tb - ta)
            return Legendre([fa - slope * ta, slope])

        rho = linear(lambda lam: np.interp(lam, wl_v, v))
        if source is not None:
            rho = rho * linear(lambda lam: np.interp(lam, source[0], source[1]))
        for k in range(k_max + 1):
            f = (Legendre.basis(k) * rho).integ()
            moments[k] += f(tb) - f(ta)
    return moments / moments[0]


@pytest.mark.parametrize("n, start, stop, source", [
    (1, 400.0, 700.0, None),
    (5, 400.0, 700.0, None),
    (8, 400.0, 700.0, None),
    (12, 420.0, 680.5, None),
    # a tabulated source on its own breakpoints (a ramp with a kink), not V's
    (8, 400.0, 700.0, ([380.0, 512.3, 650.0, 760.0], [1.0, 2.5, 0.4, 3.0])),
])
def test_gauss_rule_exact_to_degree_2n_minus_1(n, start, stop, source):
    """The n-node rule integrates every polynomial of degree ≤ 2n − 1 against V(λ)·S(λ)
    exactly (to float64 rounding), and degree 2n not: it is the Gauss rule, not a finer
    one. Nodes increase strictly inside the interval; weights are positive and sum to 1."""
    nodes, weights = spectral.gauss_rule(n, start, stop, source)
    assert nodes.shape == weights.shape == (n,)
    assert np.all(nodes > start) and np.all(nodes < stop) and np.all(np.diff(nodes) > 0)
    assert np.all(weights > 0) and weights.sum() == pytest.approx(1.0, abs=1e-15)
    exact = _exact_legendre_moments(2 * n, start, stop, source)
    t = (2.0 * nodes - start - stop) / (stop - start)
    rule = np.array([weights @ np.polynomial.legendre.Legendre.basis(k)(t)
                     for k in range(2 * n + 1)])
    np.testing.assert_allclose(rule[: 2 * n], exact[: 2 * n], rtol=0, atol=2e-14)
    assert abs(rule[2 * n] - exact[2 * n]) > 1e-8


def test_gauss_spectrum_matches_rule_and_model():
    """gauss_spectrum: the rule's nodes as wavelengths and its weights as the spectral weights
    (not V(λ)·Δλ of the nodes), LCA and SCE as make_spectrum gives them at those nodes."""
    nodes, weights = spectral.gauss_rule(8)
    s = spectral.gauss_spectrum(8)
    np.testing.assert_allclose(np.asarray(s.wavelengths_nm), nodes, rtol=1e-12)
    np.testing.assert_allclose(np.asarray(s.weights), weights, rtol=1e-6)
    m = spectral.make_spectrum(nodes)
    np.testing.assert_allclose(np.asarray(s.lca_D), np.asarray(m.lca_D), rtol=1e-6)
    np.testing.assert_allclose(np.asarray(s.sce_rho_per_mm2), np.asarray(m.sce_rho_per_mm2), rtol=1e-6)
    assert not np.allclose(np.asarray(m.weights), weights, rtol=1e-2)


@pytest.mark.parametrize("call, name", [
    (lambda: spectral.gauss_rule(0), "n_nodes"),
    (lambda: spectral.gauss_rule(2.0), "n_nodes"),
    (lambda: spectral.gauss_rule(spectral.GAUSS_MAX_NODES + 1), "n_nodes"),
    (lambda: spectral.gauss_rule(4, 700.0, 400.0), "start_nm"),
    (lambda: spectral.gauss_rule(4, 380.0, 700.0), "start_nm"),
    (lambda: spectral.gauss_rule(4, source=([450.0, 700.0], [1.0, 1.0])), "source"),
    (lambda: spectral.gauss_rule(4, source=([400.0, 700.0], [1.0, -1.0])), "source"),
    (lambda: spectral.gauss_rule(4, source=([400.0, 700.0], [0.0, 0.0])), "source"),
])
def test_gauss_rule_errors(call, name):
    with pytest.raises(ValueError, match=name):
        call()
