"""The HPO and cross-talk study (lfjax.studies.hpo): its gain and threshold readings, its
configuration's refusals, and its notebook."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import helpers as H
from lfjax.base.errors import ParameterError
from lfjax.studies.hpo import HpoConfig, gain, threshold_crossing

NOTEBOOK = Path(__file__).resolve().parents[2] / "notebooks" / "hpo_crosstalk.ipynb"


def test_gain_is_the_least_squares_slope():
    depths = np.array([0.0, 1.0, 2.0, 3.0])
    rng = np.random.default_rng(0)
    peaks = 0.3 + 0.7 * depths + rng.normal(0, 0.01, (5, 4))
    expected = [np.polyfit(depths, p, 1)[0] for p in peaks]
    np.testing.assert_allclose(gain(peaks, depths), expected, rtol=1e-12)
    assert gain(np.full(4, 2.0), depths) == 0.0


def test_threshold_crossing_interpolates_or_says_none():
    assert threshold_crossing([0, 0.5, 1.0], [0.9, 0.7, 0.1], 0.5) == pytest.approx(0.5 + 0.5 * 0.2 / 0.6)
    assert threshold_crossing([0, 1], [0.9, 0.8], 0.5) is None
    assert threshold_crossing([0, 1], [0.5, 0.1], 0.5) == 0.0


@pytest.mark.parametrize("kwargs, parameter", [
    ({"n_eyes": 1}, "n_eyes"), ({"widths": (0.0, 1.0)}, "widths"),
    ({"leakage_weights": (0.0, 1.5)}, "leakage_weights"),
    ({"crosstalk_depths_D": (2.0,)}, "crosstalk_depths_D"), ({"gain_threshold": 1.0}, "gain_threshold"),
    ({"spectral_nodes": 0}, "spectral_nodes"), ({"spectral_nodes": 2.5}, "spectral_nodes"),
    ({"accommodation_D": (1.5, 2.0, 2.5, 3.0)}, "accommodation_D"),
    ({"accommodation_D": (0.0, 2.0, 1.0, 4.0)}, "accommodation_D"),
])
def test_config_refuses_what_it_cannot_model(kwargs, parameter):
    with pytest.raises(ParameterError) as info:
        HpoConfig(**kwargs)
    assert info.value.parameter == parameter


def test_spectrum_is_the_gauss_rule_unless_uniform_samples_are_asked():
    spectrum, record = HpoConfig(spectral_nodes=5).spectrum()
    assert len(record["wavelengths_nm"]) == 5 and record["rule"].startswith("Gauss")
    assert abs(sum(record["weights"]) - 1.0) < 1e-6
    assert 400.0 < min(record["wavelengths_nm"]) < max(record["wavelengths_nm"]) < 700.0
    _, record = HpoConfig(spectral_nodes=None, wavelengths_nm=(500.0, 550.0, 600.0)).spectrum()
    assert record["rule"] == "uniform" and record["wavelengths_nm"] == [500.0, 550.0, 600.0]


def test_notebook_matches_its_script_twin():
    outputs = H.committed_notebook_outputs(NOTEBOOK)
    assert len([o for o in outputs if "image/png" in o.get("data", {})]) >= 2


def test_notebook_executes(tmp_path):
    """notebooks/hpo_crosstalk.ipynb runs top to bottom at its tiny size."""
    _, images, text = H.execute_notebook_tiny(NOTEBOOK, tmp_path)
    assert len(images) >= 2
    assert "y defocus" in text and "x-band peaks" in text
