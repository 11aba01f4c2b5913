"""The sampling planner: its choice passes the aliasing guard, a coarser one does not, and
its accuracy target holds against a finer sampling on small scenes."""

import numpy as np
import pytest

import lfjax
from lfjax.planner import plan_sampling
from lfjax.through_focus import through_focus

WAVELENGTHS = [450.0, 550.0, 650.0]


@pytest.mark.parametrize("n_views", [1, 2, 4])
def test_plan_passes_guard_and_coarser_step_aliases(n_views):
    layout = lfjax.grid_layout(n_views, 3.0)
    depths = [1.0, 2.0, 3.0]
    plan = plan_sampling(layout, depths_D=depths, wavelengths_nm=WAVELENGTHS)
    assert plan.sampling.freq_step_cpd > 0
    assert "df" in plan.summary()
    eye = lfjax.eyes.aberration_free_eye()
    acc = np.round(np.arange(0.0, 4.01, 0.2), 9)
    spectrum = lfjax.make_spectrum(WAVELENGTHS)
    # the planner's choice is accepted by the pipeline's aliasing guard ...
    through_focus(eye, layout, depths, acc, window_D=1.0, spectrum=spectrum,
                  sampling=plan.sampling)
    # ... and a step 25 % coarser is refused (field too small for the blur)
    coarse = lfjax.Sampling(plan.sampling.freq_step_cpd * 1.25)
    with pytest.raises(ValueError, match="aliasing"):
        through_focus(eye, layout, depths, acc, window_D=1.0, spectrum=spectrum,
                      sampling=coarse)


def test_override_that_aliases_is_refused():
    with pytest.raises(ValueError, match="freq_step_cpd"):
        plan_sampling(lfjax.grid_layout(2, 3.0), depths_D=[0.0, 4.0], freq_step_cpd=5.0)


def test_planned_vsotf_matches_finer_sampling():
    """Accuracy target: VSOTF within 1e-2 of a sampling twice as fine and the same predicted
    accommodation (the residual is the aperture-edge bias, ∝ 1/pupil samples)."""
    layout = lfjax.grid_layout(2, 3.0)
    depths = [1.0, 3.0]
    acc = np.round(np.arange(0.0, 4.01, 0.2), 9)
    spectrum = lfjax.make_spectrum(WAVELENGTHS)
    eyes = lfjax.sample_eyes(3, 2)
    plan = plan_sampling(layout, depths_D=depths, wavelengths_nm=WAVELENGTHS,
                         eyes_zernike_um=np.asarray(eyes.zernike_um))
    fine = lfjax.Sampling(plan.sampling.freq_step_cpd / 2)
    a = through_focus(eyes, layout, depths, acc, window_D=1.0, spectrum=spectrum,
                      sampling=plan.sampling)
    b = through_focus(eyes, layout, depths, acc, window_D=1.0, spectrum=spectrum, sampling=fine)
    mask = np.asarray(a.allowed)[None]
    diff = np.abs(np.asarray(a.vsotf) - np.asarray(b.vsotf))[np.broadcast_to(mask, a.vsotf.shape)]
    assert diff.max() < 1e-2
    np.testing.assert_array_equal(
        np.asarray(a.predicted_accommodation_D()), np.asarray(b.predicted_accommodation_D())
    )
