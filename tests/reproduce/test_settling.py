"""Settling verdicts at the reference spectrum (lfjax.reproduce.settling) and putting
recomputed layouts in place (lfjax.reproduce.study.replace_layouts), without computing:
synthetic study Datasets, and the study's computation replaced by a recorder.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
import xarray as xr

import lfjax.reproduce.settling as settling
from lfjax.model.options import ModelOptions
from lfjax.reproduce.config import StudyConfig
from lfjax.reproduce.study import replace_layouts
from lfjax.vision.claim_core import Claim

LAYOUTS = ["natural", "2x2", "3x3"]


def study(value: float, n_freq: int, rule: str = "gauss", layouts=LAYOUTS) -> xr.Dataset:
    """A Dataset with the study's per-layout variables (every number ``value``; MTFs 1 at
    0 cpd falling to 0 at the last of ``n_freq`` frequencies) and its per-layout attributes."""
    n_l = len(layouts)
    mtf = np.broadcast_to(np.linspace(1.0, 0.0, n_freq), (n_l, 2, 3, 4, n_freq)).astype(np.float32)
    return xr.Dataset(
        data_vars=dict(
            vsotf=(("layout", "eye", "depth", "accommodation"), np.full((n_l, 2, 3, 4), value)),
            radial_mtf=(("layout", "eye", "depth", "accommodation", "frequency"), mtf.copy()),
            mtf_at_peak=(("layout", "eye", "depth", "metric", "frequency"), mtf[..., :2, :].copy()),
            cutoff_frequency=(("layout", "eye", "depth", "metric"), np.full((n_l, 2, 3, 2), value)),
            zernike_um=(("eye", "zernike_j"), np.full((2, 3), value)),
            n_wavelengths=(("layout",), np.full(n_l, 5 if rule == "gauss" else 16)),
            spectral_rule=(("layout",), np.asarray([rule] * n_l)),
        ),
        coords=dict(layout=layouts, frequency=np.arange(float(n_freq))),
        attrs=dict(sampling_json=json.dumps({n: {"freq_step_cpd": value} for n in layouts}),
                   wavelengths_json=json.dumps({n: [value] for n in layouts})),
    )


def test_replace_layouts_puts_the_named_layouts_in_place():
    planned = study(1.0, n_freq=5)
    planned["vsotf"][0] = np.nan  # the natural view: computed at one depth only
    planned["radial_mtf"][0, :, 1:] = np.nan
    planned["mtf_at_peak"][0, :, 1:] = np.nan
    out = replace_layouts(planned, study(2.0, n_freq=7, rule="uniform", layouts=["2x2"]))
    assert out.frequency.size == 7  # the longer axis
    assert np.all(out.vsotf.sel(layout="2x2") == 2.0)
    assert np.all(out.vsotf.sel(layout="3x3") == 1.0)
    assert list(out.spectral_rule.values) == ["gauss", "uniform", "gauss"]  # not cut to "unifo"
    assert list(out.n_wavelengths.values) == [5, 16, 5]
    assert np.all(out.zernike_um == 1.0)  # not per layout: untouched
    # the planned layouts' MTFs are 0 beyond their own grid where computed, NaN where not
    mtf = out.radial_mtf.sel(layout="3x3")
    assert np.all(mtf.isel(frequency=slice(5, None)) == 0.0)
    assert np.all(np.isnan(out.radial_mtf.sel(layout="natural").isel(depth=1)))
    assert np.all(out.radial_mtf.sel(layout="natural").isel(depth=0, frequency=6) == 0.0)
    assert json.loads(out.attrs["wavelengths_json"]) == {"natural": [1.0], "2x2": [2.0], "3x3": [1.0]}
    assert json.loads(out.attrs["sampling_json"])["2x2"] == {"freq_step_cpd": 2.0}
    assert json.loads(out.attrs["reference_layouts_json"]) == ["2x2"]
    assert np.all(planned.vsotf.sel(layout="2x2") == 1.0)  # the input is not changed
    again = replace_layouts(out, study(3.0, n_freq=3, layouts=["3x3"]))
    assert json.loads(again.attrs["reference_layouts_json"]) == ["2x2", "3x3"]
    assert again.frequency.size == 7


def test_replace_layouts_refuses_a_layout_the_dataset_lacks():
    with pytest.raises(ValueError, match="4x4"):
        replace_layouts(study(1.0, 5), study(2.0, 5, layouts=["4x4"]))


class Recorder:
    """Stands in for the study's computation: records each call and returns the layout
    at ``value`` 2 (the reference's numbers)."""

    def __init__(self):
        self.calls = []

    def __call__(self, config, variants, stage=None, workers=None):
        self.calls.append((config, dict(variants)))
        return {name: study(2.0, 5, "uniform", layouts=list(config.layouts)) for name in variants}


def fake_claims(ds, dof_fraction=None):
    """Claim 1 turns on 2x2 while 2x2's numbers are the plan's (1), claim 2 on nothing."""
    return [Claim("1", "", "", "", bool(float(ds.vsotf.sel(layout="2x2").mean()) > 1.5)),
            Claim("2", "", "", "", True)]


def fake_undecided(ds, resolution=None, dof_fraction=None):
    return {"1": ("2x2",)}


@pytest.fixture
def recorder(monkeypatch):
    rec = Recorder()
    monkeypatch.setattr(settling, "run_study_variants", rec)
    monkeypatch.setattr(settling, "evaluate_claims", fake_claims)
    monkeypatch.setattr(settling, "undecided_layouts", fake_undecided)
    return rec


def test_settle_computes_the_unsettled_layouts_at_the_reference(recorder):
    config = StudyConfig(layouts=tuple(LAYOUTS))
    options = {"a": ModelOptions(), "b": ModelOptions(sce="intensity")}
    datasets = {name: study(1.0, 5) for name in options}
    out, claims = settling.settle(datasets, options, config.reference(), 0.8, workers=1)
    assert len(recorder.calls) == 1  # one batch for the one layout, both variants
    config_used, variants = recorder.calls[0]
    assert config_used.layouts == ("2x2",) and config_used.accuracy == "vsotf"
    assert variants == options
    for name in options:
        assert json.loads(out[name].attrs["reference_layouts_json"]) == ["2x2"]
        first = claims[name][0]
        assert first.holds is True  # evaluated again on the reference's numbers
        assert first.unsettled == () and first.reference_layouts == ("2x2",)
        assert claims[name][1].unsettled == claims[name][1].reference_layouts == ()
    assert np.all(datasets["a"].vsotf == 1.0)  # the planned Datasets are not changed


def test_mark_unsettled_leaves_the_reference_alone(recorder):
    ds = study(1.0, 5)
    ds.attrs["accuracy_plan"] = "vsotf"
    claims = settling.mark_unsettled(fake_claims(ds), ds)
    assert all(c.unsettled == () for c in claims)
    ds.attrs["accuracy_plan"] = "claims"
    claims = settling.mark_unsettled(fake_claims(ds), ds)
    assert claims[0].unsettled == ("2x2",) and claims[1].unsettled == ()


def test_settle_verdicts_is_checked_and_reference_is_the_fixed_grid():
    with pytest.raises(ValueError, match="settle_verdicts"):
        StudyConfig(settle_verdicts="yes")
    with pytest.raises(ValueError, match="settle_verdicts needs accuracy='claims'"):
        StudyConfig(settle_verdicts=True, accuracy="vsotf")
    config = StudyConfig(wavelength_rules=(("2x2", "gauss", 5),), settle_verdicts=True)
    ref = config.reference()
    assert ref.accuracy == "vsotf" and ref.wavelength_rules == () and not ref.settle_verdicts
    assert ref.reduced().wavelengths_nm == (400.0, 700.0, 20.0)  # --accuracy vsotf's reduced set
