"""lfjax.vision.prepare: every input of a computation checked before any work, and no NaN
for an input it accepts (issue #37: "nothing bogus")."""

from __future__ import annotations

import numpy as np
import pytest

import lfjax
from lfjax.base.errors import ParameterError
from lfjax.base.sampling import AliasingError
from lfjax.model.eyes import sample_eyes
from lfjax.model.layouts import Layout, make_layout
from lfjax.model.spectral import make_spectrum
from lfjax.vision.focus import metrics_at, through_focus
from lfjax.vision.prepare import States
from lfjax.vision.viewing import Viewing

SPECTRUM = make_spectrum([550.0])
SAMPLING = lfjax.Sampling(0.75)  # a ±40 arcmin field: holds most random blurs below


def _no_planning(monkeypatch):
    """A refusal must come before the planner (the first work) is asked anything."""
    import lfjax.vision.prepare as prepare

    def planned(*args, **kwargs):
        raise AssertionError("planned before the inputs were checked")

    monkeypatch.setattr(prepare, "plan_sampling", planned)


def test_a_layout_made_for_a_larger_pupil_is_refused_naming_the_layout_pupil_and_distance(
        monkeypatch):
    """One view at 2.5 mm from the centre, made for a 6 mm pupil: on a 3 mm calculation
    pupil it brings no light (through_focus gave VSOTF exactly 1.0, the sweep stored it,
    and with another reference it is 0/0 = NaN). Refused before any work."""
    _no_planning(monkeypatch)
    far = make_layout([[2.5, 0.0], [0.0, 0.0]], [1.0, 1.0], 6.0, name="made for 6 mm")
    eyes = sample_eyes(0, 1)
    with pytest.raises(ParameterError) as err:
        through_focus(eyes, far, States.around([2.0]), Viewing(pupil_diameter_mm=3.0, cdp_D=2.0))
    assert err.value.parameter == "layout"
    assert str(err.value).startswith(
        "layout 'made for 6 mm' has 1 of its 2 views entirely outside the 3 mm pupil "
        "(pupil_diameter_mm; a view must reach |centre| - diameter/2 < 1.5 mm): "
        "view 0 at (2.5, 0) mm, diameter 1 mm, 0.5 mm outside.")
    with pytest.raises(ParameterError, match="entirely outside the 3 mm pupil"):
        metrics_at(eyes, far, [2.0], [[2.0]], Viewing(pupil_diameter_mm=3.0, cdp_D=2.0))
    # a view the pupil crops (partly outside) is the model's: accepted
    make_layout([[1.5, 0.0]], [1.0], 3.0)


@pytest.mark.parametrize(
    "call, parameter",
    [
        (lambda e: through_focus(e, None, States.around([20.0]), Viewing(cdp_D=2.0)), "depths_D"),
        (
            lambda e: through_focus(
                e, None, States.grid([1.0, 50.0], depths_D=[2.0]), Viewing(cdp_D=2.0)
            ),
            "accommodation_D",
        ),
        (
            lambda e: through_focus(e, None, States.around([9.5]), Viewing(cdp_D=9.0)),
            "accommodation_offsets_D",
        ),  # 9.5 + 1
        (lambda e: through_focus(e, None, States.around([2.0]), Viewing(cdp_D=20.0)), "cdp_D"),
        (lambda e: metrics_at(e, lfjax.open_pupil(3.0), [50.0], [[2.0]]), "depths_D"),
        (lambda e: metrics_at(e, lfjax.open_pupil(3.0), [2.0], [[20.0]]), "accommodation_D"),
    ],
)
def test_depths_and_states_beyond_the_models_range_are_refused(monkeypatch, call, parameter):
    _no_planning(monkeypatch)
    with pytest.raises(ParameterError) as err:
        call(sample_eyes(0, 1))
    assert err.value.parameter == parameter
    assert "must lie in the model's range [0, 10] D" in str(err.value)


def _random_layout(rng) -> Layout:
    """4 views of one window (1.5 mm: one compiled shape), each reaching into the 3 mm pupil."""
    angle = rng.uniform(0, 2 * np.pi, 4)
    radius = rng.uniform(0.0, 1.2, 4)
    centres = np.stack([radius * np.cos(angle), radius * np.sin(angle)], axis=1)
    return Layout(centres, rng.uniform(0.4, 1.5, 4), 1.5, "random")


def test_no_nan_for_any_accepted_input_of_the_public_entry_points():
    """A seeded property test: 24 random valid inputs (eyes, view layouts, CDP, depths,
    accommodation states, in the model's range) to metrics_at and through_focus, at one
    tiny shape (one eye, one wavelength, 4 views, a fixed sampling: each program compiles
    once). Every input is either refused with a named error (here the sampling's aliasing
    guard, for blur its field cannot hold) or gives finite values in [0, 1.5]; most are
    accepted."""
    rng = np.random.default_rng(37)
    accepted = 0
    for i in range(24):
        eyes = sample_eyes(int(rng.integers(0, 2**31)), 1)
        layout = _random_layout(rng)
        cdp = float(rng.uniform(0.0, 4.0))
        depth = float(rng.uniform(0.0, 4.0))
        acc = np.sort(rng.uniform(0.0, 5.0, 3))
        try:
            vsotf, strehl = metrics_at(
                eyes,
                layout,
                [depth],
                acc[None, :],
                Viewing(pupil_diameter_mm=3.0, cdp_D=cdp),
                spectrum=SPECTRUM,
                sampling=SAMPLING,
            )
            tf = through_focus(
                eyes,
                layout,
                States.grid(acc, depths_D=[depth]),
                Viewing(pupil_diameter_mm=3.0, cdp_D=cdp),
                spectrum=SPECTRUM,
                sampling=SAMPLING,
            )
        except (ParameterError, AliasingError):
            continue
        accepted += 1
        for values in (vsotf, strehl, tf.vsotf, tf.strehl, tf.radial_mtf):
            values = np.asarray(values)
            assert np.all(np.isfinite(values)), (i, cdp, depth, acc)
            assert values.min() >= -0.5 and values.max() <= 1.5, (i, values)
        np.testing.assert_allclose(np.asarray(tf.vsotf), np.asarray(vsotf), atol=1e-5)
    assert accepted >= 16, accepted
