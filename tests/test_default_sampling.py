"""One default sampling for one scene: ``metrics_at`` and ``through_focus`` plan the same
frequency step for the same scene, so they agree at a shared (depth, state) point (the
planner's VSOTF target is 1e-3; before the shared rule they differed by 1.7e-3)."""

import numpy as np

import lfjax
from lfjax.vision.focus import metrics_at, through_focus


def test_metrics_at_and_through_focus_agree_at_one_point():
    eyes = lfjax.sample_eyes(0, 1)
    layout = lfjax.grid_layout(2, 3.0)
    spectrum = lfjax.make_spectrum(np.array([450.0, 550.0, 650.0]))
    tf = through_focus(eyes, layout, depths_D=[1.0], pupil_diameter_mm=3.0, cdp_D=2.0,
                       spectrum=spectrum)  # default offsets -1 ... +1 D around the depth
    k = int(np.argmin(np.abs(np.asarray(tf.accommodation_D)[0] - 1.2)))
    state = float(np.asarray(tf.accommodation_D)[0, k])
    vsotf, strehl = metrics_at(eyes, layout, [1.0], [[state]], pupil_diameter_mm=3.0, cdp_D=2.0,
                               spectrum=spectrum)
    assert abs(float(vsotf[0, 0, 0]) - float(tf.vsotf[0, 0, k])) < 1e-5
    assert abs(float(strehl[0, 0, 0]) - float(tf.strehl[0, 0, k])) < 1e-5


def test_aliasing_error_carries_the_safe_step():
    """The aliasing check raises a ValueError subclass with the largest safe step as a
    number (callers retry with it; nobody parses the message), and that step passes."""
    import pytest

    from lfjax.kernel.optics import field_check

    eyes = lfjax.sample_eyes(0, 1)
    layout = lfjax.grid_layout(2, 3.0)
    spectrum = lfjax.make_spectrum(np.array([550.0]))
    with pytest.raises(lfjax.AliasingError) as caught:
        through_focus(eyes, layout, depths_D=[0.0], accommodation_D=[3.0], cdp_D=2.0,
                      spectrum=spectrum, sampling=lfjax.Sampling(5.0))
    err = caught.value
    assert isinstance(err, ValueError)
    assert err.freq_step_cpd == 5.0 and 0 < err.max_freq_step_cpd < 5.0
    assert err.radius_arcmin > 0.5 * lfjax.Sampling(5.0).field_arcmin
    field_check(np.asarray(eyes.zernike_um), 3.0, 3.0, 2.0, [3.0], [0.0], layout, spectrum,
                 lfjax.Sampling(err.max_freq_step_cpd * 0.999))  # does not raise
