"""Which claims a study's numbers settle (lfjax.vision.claims.undecided_layouts, over the
ranges of lfjax.vision.claim_margins), on synthetic study Datasets: a baseline far from
every threshold settles all seven claims; each case puts one claim's numbers within the
planned spectrum's resolution of its threshold (flagged, with the layouts it turns on) and
then just beyond it (settled).

Each flagged case also checks the premise: the numbers moved within the resolution
(:class:`Resolution`) in the flagged direction do give evaluate_claims the other verdict.
"""

from __future__ import annotations

import numpy as np
import pytest
import xarray as xr

from lfjax.vision.claim_margins import Resolution
from lfjax.vision.claims import undecided_layouts
from lfjax.vision.claims import evaluate_claims

CDP = 2.0
LAYOUTS = ["natural", "2x2", "3x3", "4x4"]
REL = np.array([-2.0, -1.0, 0.0, 1.0, 2.0])
ACC = np.round(np.arange(0.0, 5.01, 0.2), 9)
FREQ = np.arange(0.0, 81.0)
N_EYES = 4
PEAK = {"natural": 40.0, "2x2": 30.0, "3x3": 26.0, "4x4": 22.0}  # cpd at the CDP
SLOPE = {"natural": 0.0, "2x2": 6.0, "3x3": 4.4, "4x4": 3.0}  # cpd/D: DOF 2.0, 2.36, 2.93 D
R = Resolution()


class Study:
    """A synthetic study (numpy arrays, editable) → :meth:`dataset`. Baseline: every eye
    predicts the rendered depth (the natural view: errors −0.2, 0, 0, 0 D at the CDP), the
    parabola's vertex on the grid peak, continuous peaks 0.1 D in front (0.05 D at 0 D),
    Strehl peaked like VSOTF except 2x2 beyond ±1 D (at the CDP; its neighbours 0.08 below),
    cut-offs ``PEAK`` at the CDP falling ``SLOPE`` cpd/D, the average eye's MTF 0.4 against
    the eyes' 0.3."""

    def __init__(self):
        self.depths = CDP + REL
        shape = (len(LAYOUTS), N_EYES + 1, REL.size)
        self.pred = np.full(shape + (2,), np.nan)
        self.cont = np.full(shape + (2,), np.nan)
        self.cutoff = np.full(shape + (2,), np.nan)
        self.mtf = np.full(shape + (2, FREQ.size), np.nan)
        for li, name in enumerate(LAYOUTS):
            slots = [2] if name == "natural" else list(range(REL.size))
            for di in slots:
                self.pred[li, :, di, :] = self.depths[di]
                self.cont[li, :, di, 0] = self.depths[di] - 0.1 if self.depths[di] > 0 else 0.05
                self.cutoff[li, :, di, :] = PEAK[name] - SLOPE[name] * abs(REL[di])
                self.mtf[li, :, di] = 0.3
                self.mtf[li, -1, di] = 0.4
            if name == "2x2":
                self.pred[li, :, [0, 4], 1] = CDP
        self.pred[0, 0, 2, :] = CDP - 0.2  # the natural view's errors
        self.vertex = self.pred.copy()
        self.strehl = np.full(shape + (ACC.size,), np.nan)
        for idx in np.ndindex(*shape):
            p = self.pred[idx + (1,)]
            if np.isfinite(p):
                window = np.abs(ACC - self.depths[idx[2]]) <= 2.0 + 1e-9
                self.strehl[idx] = np.where(window, 0.6 - 2.0 * (ACC - p) ** 2, np.nan)

    def li(self, name):
        return LAYOUTS.index(name)

    def dataset(self) -> xr.Dataset:
        labels = [f"eye{i}" for i in range(N_EYES)] + ["average"]
        d4 = ("layout", "eye", "depth", "metric")
        return xr.Dataset(
            data_vars=dict(
                predicted_accommodation=(d4, self.pred),
                predicted_accommodation_parabolic=(d4, self.vertex),
                accommodation_error=(d4, self.pred - self.depths[None, None, :, None]),
                predicted_accommodation_continuous=(d4, self.cont),
                continuous_peak_success=(d4, np.isfinite(self.cont)),
                peak_value=(d4, np.where(np.isfinite(self.pred), 0.5, np.nan)),
                cutoff_frequency=(d4, self.cutoff),
                mtf_at_peak=(d4 + ("frequency",), self.mtf),
                strehl=(("layout", "eye", "depth", "accommodation"), self.strehl),
                zernike_um=(("eye", "zernike_j"), np.zeros((N_EYES + 1, 15))),
            ),
            coords=dict(layout=LAYOUTS, eye=labels, depth=self.depths,
                        depth_rel_cdp=("depth", REL), metric=["vsotf", "strehl"],
                        accommodation=ACC, frequency=FREQ, zernike_j=np.arange(15),
                        is_average=("eye", np.arange(N_EYES + 1) == N_EYES)),
            attrs=dict(cdp_D=CDP, measured_pupil_mm=3.0, config_dof_fraction=0.8),
        )


def verdict(study: Study, claim: str) -> str:
    return {c.id: c.verdict for c in evaluate_claims(study.dataset())}[claim]


def test_baseline_settles_every_claim():
    s = Study()
    assert {c.id: c.verdict for c in evaluate_claims(s.dataset())} == {
        "1": "holds", "2": "holds", "3": "holds", "4": "holds", "5": "holds", "6": "holds",
        "7": "holds"}
    assert undecided_layouts(s.dataset()) == {}


def test_claim1_grid_peak_on_a_midpoint():
    s = Study()
    s.vertex[0, 0, 2, 0] = s.pred[0, 0, 2, 0] - 0.1 + 0.5 * R.vertex_D  # 0.2 D error, nearly 0.3
    assert undecided_layouts(s.dataset()) == {"1": ("natural",)}
    s.pred[0, 0, 2, :] -= 0.2  # where the reference may put it: 0.4 D, the claim fails
    assert verdict(s, "1") == "fails"
    s = Study()
    s.vertex[0, 0, 2, 0] = s.pred[0, 0, 2, 0] - 0.1 + 2.0 * R.vertex_D
    assert undecided_layouts(s.dataset()) == {}


@pytest.mark.parametrize("error, flagged", [(-0.5 * R.mean_peak_D, True),
                                            (-2.0 * R.mean_peak_D, False)])
def test_claim2_mean_error_near_zero(error, flagged):
    s = Study()
    s.cont[s.li("3x3"), :, 3, 0] = s.depths[3] + error  # 1 D behind the CDP: must stay < 0
    assert verdict(s, "2") == "holds"
    assert undecided_layouts(s.dataset()) == ({"2": ("3x3",)} if flagged else {})
    if flagged:
        s.cont[s.li("3x3"), :, 3, 0] += R.mean_peak_D
        assert verdict(s, "2") == "fails"


@pytest.mark.parametrize("gap, flagged", [(0.5 * R.strehl_gap, True), (2.0 * R.strehl_gap, False)])
def test_claim3_strehl_peak_that_may_move(gap, flagged):
    s = Study()
    li = s.li("3x3")
    s.pred[li, 0, 3, 1] += 0.8  # mean Strehl − mean VSOTF = 0.2 D: on the threshold
    s.strehl[li, 0, 3] = np.where(np.isfinite(s.strehl[li, 0, 3]), 0.1, np.nan)
    k = int(np.argmin(np.abs(ACC - s.pred[li, 0, 3, 1])))
    s.strehl[li, 0, 3, k] = 0.6
    s.strehl[li, 0, 3, k + 1] = 0.6 - gap  # one step further from the VSOTF peak
    assert verdict(s, "3") == "holds"
    assert undecided_layouts(s.dataset()) == ({"3": ("3x3",)} if flagged else {})
    s.pred[li, 0, 3, 1] += 0.2
    assert verdict(s, "3") == "fails"


@pytest.mark.parametrize("ratio, flagged", [(1.0 + 0.2 * R.mtf_ratio, True),
                                            (1.0 + 2.0 * R.mtf_ratio, False)])
def test_claim5_cells_near_equal(ratio, flagged):
    s = Study()
    cells = [("3x3", 0), ("3x3", 1), ("4x4", 2)]  # 3 of 16 cells: 13/16 < 90 %
    for name, di in cells:
        s.mtf[s.li(name), -1, di] = 0.3 * ratio
    assert verdict(s, "5") == "holds"
    assert undecided_layouts(s.dataset()) == ({"5": ("3x3", "4x4")} if flagged else {})
    for name, di in cells:
        s.mtf[s.li(name), -1, di] = 0.3 * (ratio - R.mtf_ratio)
    assert verdict(s, "5") == ("fails" if flagged else "holds")


@pytest.mark.parametrize("slope, flagged", [(5.19, True), (4.8, False)])
def test_claim6_depths_of_field_close(slope, flagged):
    s = Study()
    li = s.li("3x3")  # DOF 2×0.2×26/slope: 2.004 D (the 2x2's 2.0 D + 0.004) or 2.17 D
    s.cutoff[li, :, :, :] = (26.0 - slope * np.abs(REL))[None, :, None]
    assert verdict(s, "6") == "holds"
    assert undecided_layouts(s.dataset()) == ({"6": ("2x2", "3x3")} if flagged else {})
    s.cutoff[li, :, :, :] = (26.0 - (slope + 0.05) * np.abs(REL))[None, :, None]
    assert verdict(s, "6") == ("fails" if flagged else "holds")


@pytest.mark.parametrize("cdp_3x3, flagged", [(30.0 - R.mean_cutoff_cpd, True),
                                              (30.0 - 3 * R.mean_cutoff_cpd, False)])
def test_claim7_cutoffs_at_the_cdp_close(cdp_3x3, flagged):
    s = Study()
    li = s.li("3x3")
    slope = SLOPE["3x3"] * cdp_3x3 / PEAK["3x3"]  # the same depth of field (claim 6)
    s.cutoff[li, :, :, :] = (cdp_3x3 - slope * np.abs(REL))[None, :, None]
    assert verdict(s, "7") == "holds"
    assert undecided_layouts(s.dataset()) == ({"7": ("2x2", "3x3")} if flagged else {})


def test_resolution_refuses_a_negative_or_infinite_value():
    with pytest.raises(ValueError, match="mtf_ratio"):
        Resolution(mtf_ratio=-0.1)
    with pytest.raises(ValueError, match="vertex_D"):
        Resolution(vertex_D=float("inf"))


@pytest.mark.parametrize("slope", [5.19, 4.8])
def test_claim6_beyond_the_corner_limit_searches_a_subset(monkeypatch, slope):
    """Beyond MAX_CORNER_DEPTHS depths claim 6 tries only the box's two uniform corners (of
    2^n): what it flags is then a subset of what the full search flags, and a baseline far
    from the threshold stays settled."""
    from lfjax.vision import claims_resolution

    s = Study()
    s.cutoff[s.li("3x3"), :, :, :] = (26.0 - slope * np.abs(REL))[None, :, None]
    full = undecided_layouts(s.dataset()).get("6", ())
    monkeypatch.setattr(claims_resolution, "MAX_CORNER_DEPTHS", REL.size - 1)
    capped = undecided_layouts(s.dataset()).get("6", ())
    assert set(capped) <= set(full)
    assert undecided_layouts(Study().dataset()) == {}
