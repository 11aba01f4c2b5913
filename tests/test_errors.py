"""Bad input: each is a ValueError that names the offending parameter (before any compile
where the value is known on the host)."""

import equinox as eqx
import jax.numpy as jnp
import numpy as np
import pytest

import helpers as H
import lfjax
from lfjax.model import layouts
from lfjax.base import zernike
from lfjax.vision.focus import metrics_at, through_focus
from lfjax.vision.viewing import Viewing

SPEC = H.spectrum_550_plain
SAMPLING = lfjax.Sampling(2.0)
LAYOUT_2X2 = lfjax.grid_layout(2, 3.0)


def _viewing(args) -> Viewing:
    """The Viewing of a case's pupil and CDP (a bad value is refused here, where it is built)."""
    return Viewing(pupil_diameter_mm=args.pop("pupil_diameter_mm"), cdp_D=args.pop("cdp_D"))


def _otf(**kw):
    args = dict(eyes=H.dl_eye(), accommodation_D=[2.0], pupil_diameter_mm=3.0, cdp_D=2.0,
                spectrum=SPEC(), sampling=SAMPLING, options=H.PLAIN)
    args.update(kw)
    return lfjax.polychromatic_otf(viewing=_viewing(args), **args)


def _tf(**kw):
    """through_focus of one case: ``accommodation_D`` (a grid for every depth) or
    ``accommodation_offsets_D`` (states around each depth) build its States."""
    args = dict(eyes=H.dl_eye(), layout=LAYOUT_2X2, depths_D=[2.0], accommodation_D=[2.0],
                pupil_diameter_mm=3.0, cdp_D=2.0, spectrum=SPEC(), sampling=SAMPLING,
                options=H.PLAIN)
    args.update(kw)
    viewing = _viewing(args)
    depths, grid = args.pop("depths_D"), args.pop("accommodation_D")
    offsets = args.pop("accommodation_offsets_D", None)
    window = args.pop("window_D", None)
    states = (lfjax.States.grid(grid, depths, window) if grid is not None
              else lfjax.States.around(depths, offsets))
    return through_focus(args.pop("eyes"), args.pop("layout"), states, viewing, **args)


# ----------------------------------------------------------------------------- pupil


@pytest.mark.parametrize("pupil", [0.0, -1.0, np.nan])
def test_non_positive_pupil_with_layout(pupil):
    with pytest.raises(ValueError, match=r"Viewing.pupil_diameter_mm must lie in \(0, 10\] mm"):
        _otf(pupil_diameter_mm=pupil, layout=lfjax.open_pupil(3.0))
    with pytest.raises(ValueError, match=r"Viewing.pupil_diameter_mm must lie in \(0, 10\] mm"):
        _tf(pupil_diameter_mm=pupil)
    with pytest.raises(ValueError, match="pupil_diameter_mm must be > 0"):
        lfjax.monochromatic_psf(np.zeros(6), 3.0, pupil, 550.0, 0.1, 16)


@pytest.mark.parametrize("pupil", [0.0, -1.0, np.nan])
def test_non_positive_pupil_natural_view_names_the_pupil(pupil):
    with pytest.raises(ValueError, match="pupil_diameter_mm"):
        _otf(pupil_diameter_mm=pupil)
    with pytest.raises(ValueError, match="pupil_diameter_mm"):
        _tf(pupil_diameter_mm=pupil, layout=None)


def test_pupil_larger_than_measured():
    with pytest.raises(ValueError, match="pupil_diameter_mm=3.5 exceeds the measured pupil"):
        _otf(pupil_diameter_mm=3.5)
    with pytest.raises(ValueError, match="pupil_diameter_mm=3.5 exceeds"):
        _tf(pupil_diameter_mm=3.5, layout=None)
    with pytest.raises(ValueError, match="pupil_diameter_mm=3.5 exceeds"):
        metrics_at(
            H.dl_eye(),
            LAYOUT_2X2,
            np.array([2.0]),
            np.array([[2.0]]),
            Viewing(pupil_diameter_mm=3.5),
            spectrum=SPEC(),
            sampling=SAMPLING,
            options=H.PLAIN,
        )
    with pytest.raises(ValueError, match="exceeds"):
        lfjax.monochromatic_psf(np.zeros(6), 3.0, 3.2, 550.0, 0.1, 16)
    # equal to the measured pupil is fine (validated on the host, nothing compiled)
    lfjax.kernel.optics.validate_pupil(3.0, 3.0)


# ----------------------------------------------------------------------------- wavelengths


def test_wavelengths_outside_the_data():
    """Outside the CIE 2008 LEF (390–830 nm) always; outside the Stiles–Crawford table
    (400–700 nm) when SCE is on (the default); the MFT PSF takes 380–830 nm."""
    with pytest.raises(ValueError, match="wavelengths_nm.*390.*830"):
        lfjax.make_spectrum([380.0, 550.0], lfjax.ModelOptions(sce="off"))
    with pytest.raises(ValueError, match="wavelengths_nm.*390.*830"):
        lfjax.make_spectrum([550.0, 840.0], lfjax.ModelOptions(sce="off"))
    with pytest.raises(ValueError, match="wavelengths_nm.*400.*700"):
        lfjax.make_spectrum([390.0, 550.0])
    with pytest.raises(ValueError, match="wavelengths_nm.*400.*700"):
        lfjax.make_spectrum([550.0, 710.0], lfjax.ModelOptions(sce="amplitude"))
    with pytest.raises(ValueError, match="wavelength_nm"):
        lfjax.monochromatic_psf(np.zeros(6), 3.0, 3.0, 300.0, 0.1, 16)


# ----------------------------------------------------------------------------- eyes


def test_unknown_zernike_order():
    with pytest.raises(ValueError, match="radial order"):
        zernike.nm_from_ansi(10**6)
    with pytest.raises(ValueError, match="radial order"):
        lfjax.Eyes(jnp.zeros((1, zernike.n_modes_for_order(zernike.MAX_RADIAL_ORDER) + 1)),
                   3.0)


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_non_finite_coefficients(bad):
    z = np.zeros((1, 6))
    z[0, 4] = bad
    with pytest.raises(ValueError, match="non-finite"):
        lfjax.model.eyes.make_eyes(z, 3.0)
    with pytest.raises(ValueError, match="zernike_um contains non-finite"):
        lfjax.Eyes(jnp.asarray(z), 3.0)  # refused where it is built, as by make_eyes
    # eqx.tree_at builds no new Eyes (no check): the entry points check again
    eyes = eqx.tree_at(lambda e: e.zernike_um, lfjax.Eyes(jnp.zeros((1, 6)), 3.0),
                       jnp.asarray(z))
    with pytest.raises(ValueError, match="zernike_um contains non-finite"):
        _otf(eyes=eyes)
    with pytest.raises(ValueError, match="zernike_um contains non-finite"):
        _tf(eyes=eyes)
    with pytest.raises(ValueError, match="zernike_um contains non-finite"):
        lfjax.monochromatic_psf(z[0], 3.0, 3.0, 550.0, 0.1, 16)


# ----------------------------------------------------------------------------- sampling


def test_sampling_too_coarse_for_the_defocus():
    """5 D accommodation with the CDP at 2 D (3 D of defocus on a 3 mm pupil: ±17.8 arcmin
    of blur) does not fit the ±7.5 arcmin field of df = 4 cpd."""
    coarse = lfjax.Sampling(4.0)
    with pytest.raises(ValueError, match="aliasing.*freq_step_cpd"):
        _otf(accommodation_D=[5.0], sampling=coarse)
    with pytest.raises(ValueError, match="aliasing"):
        _tf(accommodation_D=[5.0], sampling=coarse, layout=None)
    with pytest.raises(ValueError, match="aliasing"):
        _tf(depths_D=[0.0, 4.0], accommodation_D=[0.0, 4.0], layout=LAYOUT_2X2,
            sampling=lfjax.Sampling(1.5))  # display shifts of 2×2 views, 4 D apart
    with pytest.raises(ValueError, match="aliasing"):
        metrics_at(
            H.dl_eye(),
            LAYOUT_2X2,
            np.array([2.0]),
            np.array([[5.0]]),
            spectrum=SPEC(),
            sampling=coarse,
            options=H.PLAIN,
        )


def test_bad_sampling_values():
    for kw, name in (({"freq_step_cpd": 0.0}, "freq_step_cpd"),
                     ({"freq_step_cpd": np.inf}, "freq_step_cpd"),
                     ({"n_fft": 4}, "n_fft"), ({"n_fft": 64.5}, "n_fft"),
                     ({"edge_width_samples": 0.0}, "edge_width_samples"),
                     ({"edge_width_samples": 5.0}, "edge_width_samples")):
        with pytest.raises(ValueError, match=name):
            lfjax.Sampling(**kw)
    with pytest.raises(ValueError, match="n_fft=64 cannot hold"):
        SAMPLING.__class__(2.0, n_fft=64).window_size(3.0, 550.0, 3.0)


# ----------------------------------------------------------------------------- light field


def test_bad_layouts():
    with pytest.raises(ValueError, match="1 of its 2 views entirely outside the 3 mm pupil.*view 1 at \\(2, 0\\) mm"):
        lfjax.make_layout([[0.0, 0.0], [2.0, 0.0]], [1.0, 0.9], 3.0)
    with pytest.raises(ValueError, match="entirely outside"):
        lfjax.make_layout([[0.0, 1.5 + 0.5]], [1.0], 3.0)  # touching from outside
    with pytest.raises(ValueError, match="diameters_mm must be > 0"):
        lfjax.make_layout([[0.0, 0.0]], [-0.9], 3.0)
    with pytest.raises(ValueError, match="diameters_mm must be > 0"):
        lfjax.make_layout([[0.0, 0.0], [0.5, 0.0]], [1.0, 0.0], 3.0)
    with pytest.raises(ValueError, match="finite"):
        lfjax.make_layout([[np.nan, 0.0]], [1.0], 3.0)
    with pytest.raises(ValueError, match="diameters_mm"):
        lfjax.make_layout([[0.0, 0.0], [0.5, 0.0]], [1.0], 3.0)
    with pytest.raises(ValueError, match="centres_mm"):
        layouts.Layout(jnp.zeros((2, 3)), jnp.ones(2), 1.0)
    with pytest.raises(ValueError, match="n_per_side"):
        lfjax.grid_layout(0, 3.0)
    with pytest.raises(ValueError, match="pitch_mm"):
        lfjax.hex_layout(0.0, 3.0)
    with pytest.raises(ValueError, match="rendered_distance_m"):
        layouts.subaperture_pitch_mm(0.1, 0.5, 0.5)


def test_rendered_depth_beyond_infinity_through_focus():
    with pytest.raises(ValueError, match="depths_D must be >= 0"):
        _tf(depths_D=[-0.5], accommodation_D=[0.5])
    with pytest.raises(ValueError, match="depths_D must be >= 0"):
        _tf(depths_D=[1.0, -0.1], accommodation_D=None, accommodation_offsets_D=[0.0, 0.2])
    with pytest.raises(ValueError, match="depths_D"):
        _tf(depths_D=[np.nan])
    with pytest.raises(ValueError, match="cdp_D: every CDP must lie in the model's range"):
        _tf(cdp_D=-0.5)


def test_rendered_depth_beyond_infinity_polychromatic_otf():
    with pytest.raises(ValueError, match="depths_D"):
        _otf(depths_D=[-0.5], accommodation_D=[0.5], cdp_D=0.5)


def test_accommodation_grids_without_allowed_states():
    with pytest.raises(ValueError, match="accommodation grid excludes every allowed state"):
        _tf(depths_D=[0.2], accommodation_D=None, accommodation_offsets_D=[-0.6, -0.4],
            cdp_D=0.5)
    with pytest.raises(ValueError, match="accommodation_D must be >= 0"):
        _tf(depths_D=[0.2], accommodation_D=[-0.6, -0.4], cdp_D=0.5)
    with pytest.raises(ValueError, match="window_D"):
        _tf(depths_D=[0.2, 3.0], accommodation_D=[0.0, 0.2], window_D=0.5, cdp_D=0.5)
    with pytest.raises(ValueError, match="states must be lfjax.States built by States.grid or "
                                         "States.around"):
        through_focus(H.dl_eye(), LAYOUT_2X2, lfjax.States.every([2.0], [2.0]))
    with pytest.raises(ValueError, match="accommodation_D must be a 1-D grid"):
        _tf(accommodation_D=np.zeros((2, 2)))


def test_unknown_metric_name(natural_tf):
    with pytest.raises(ValueError, match="metric must be"):
        natural_tf.predicted_accommodation_D("mtf")


# ----------------------------------------------------------------------------- the error type


def test_a_parameter_error_names_the_parameter_and_renders_other_names():
    import pickle

    from lfjax.base.errors import ParameterError

    err = ParameterError("front", "{front} needs held-out eyes ({test_eyes} >= {n})", n=1)
    assert isinstance(err, ValueError) and err.parameter == "front"
    assert str(err) == "front needs held-out eyes (test_eyes >= 1)"
    assert err.parameters == ("front", "test_eyes")
    assert err.naming({"front": "--front", "test_eyes": "--test-eyes"}) == \
        "--front needs held-out eyes (--test-eyes >= 1)"
    assert err.naming({"front": "--front"}) == "--front needs held-out eyes (test_eyes >= 1)"
    # values are shown, never parsed as names; an owner qualifies library names only
    odd = ParameterError("fill", "{fill} must be in (0, 1], got {got}", owner="Panel", got="{x}")
    assert str(odd) == "Panel.fill must be in (0, 1], got {x}" and odd.parameters == ("fill",)
    assert odd.naming({"fill": "--fill"}) == "--fill must be in (0, 1], got {x}"
    back = pickle.loads(pickle.dumps(odd))
    assert type(back) is ParameterError and str(back) == str(odd) and back.owner == "Panel"
