"""The blur of the rest of the scene (lfjax.vision.scene_blur): the natural-viewing reference
against through_focus of the open pupil, and the equivalent defocus's own zero and sign."""

from pathlib import Path

import numpy as np

import helpers as H

from lfjax.base.sampling import Sampling
from lfjax.kernel.metrics import radial_mtf
from lfjax.model.eyes import average_eye
from lfjax.model.options import ModelOptions
from lfjax.model.spectral import monochromatic_spectrum
from lfjax.vision.focus import through_focus
from lfjax.vision.scene_blur import natural_otfs, rest_of_scene
from lfjax.vision.prepare import States
from lfjax.vision.viewing import Viewing

def test_natural_reference_is_the_open_pupil_at_the_same_defocus():
    # A real point at 1.3 D, the eye at 2.5 D (defocus a − d = 1.2 D), against through_focus
    # of the open pupil whose CDP is elsewhere (2 D) and whose accommodation gives the same
    # defocus (3.2 D): the accommodation SA is switched off, since it follows the absolute
    # accommodation and the two differ there by design.
    options = ModelOptions(accommodation_sa="off")
    eye = average_eye(3.0)
    spectrum = monochromatic_spectrum(600.0, options)
    sampling = Sampling(freq_step_cpd=1.0)
    otf = natural_otfs(eye, 2.5, [1.3], (spectrum,), sampling, options=options)[0, 0]
    tf = through_focus(
        eye,
        None,
        States.grid([3.2], depths_D=[2.0]),
        Viewing(pupil_diameter_mm=3.0, cdp_D=2.0),
        spectrum=spectrum,
        sampling=sampling,
        options=options,
    )
    mine = np.asarray(radial_mtf(otf, otf.shape[-2], 1.0)[0], float)
    np.testing.assert_allclose(mine, np.asarray(tf.radial_mtf[0, 0, 0], float), atol=2e-5)
    # the defocus is really there: 1.2 D less 0.2 D of LCA at 600 nm puts the first zero
    # near 9 cpd on a 3 mm pupil, where a focused eye keeps an MTF of about 0.8
    assert mine[8] < 0.1


def test_equivalent_defocus_of_natural_viewing_is_the_true_defocus_with_its_sign():
    # Natural viewing against itself: the measure's zero. Nearer and farther points than the
    # accommodation (laser primaries: one wavelength per channel keeps this small).
    grid = np.round(np.arange(-1.5, 1.5 + 1e-9, 0.1), 6)
    out = rest_of_scene(average_eye(3.0), None, 2.0, [1.05, 2.62], "laser", grid_defocus_D=grid)
    np.testing.assert_allclose(out["equivalent_defocus_D"], [-0.95, 0.62], atol=0.02)
    np.testing.assert_array_equal(np.sign(out["equivalent_defocus_D"]), [-1.0, 1.0])
    np.testing.assert_allclose(out["mtf_ratio"], 1.0, rtol=1e-6)
    # LCA: red is sharper for the farther point, blue for the nearer one
    assert out["cue_natural"][0] > 0 > out["cue_natural"][1]


NOTEBOOK = Path(__file__).resolve().parents[2] / "notebooks" / "scene_blur.ipynb"


def test_notebook_matches_its_script_twin():
    outputs = H.committed_notebook_outputs(NOTEBOOK)
    assert len([o for o in outputs if "image/png" in o.get("data", {})]) >= 2


def test_notebook_executes(tmp_path):
    """notebooks/scene_blur.ipynb runs top to bottom at its tiny size (one layout, laser
    primaries, a 32×32 scene)."""
    _, images, text = H.execute_notebook_tiny(NOTEBOOK, tmp_path)
    assert len(images) >= 2
    assert "equivalent" in text and "colour cue" in text
