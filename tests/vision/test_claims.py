"""The paper's claims (lfjax.vision.claims.evaluate_claims) on synthetic study Datasets
built just inside and just outside each criterion, and the ten-eye version
(lfjax.sweep.ten_eyes) on a synthetic population whose answer per sample is known.
Covers lfjax.vision.claims (the registry), lfjax.vision.claim_core (Interval,
StudyNumbers), lfjax.vision.claims_accommodation (claims 1–4) and
lfjax.vision.claims_resolution (claims 5–7); their margins are tests/vision/test_claim_margins.py.

The synthetic Dataset has the variables and coordinates a study (or a sweep's study view)
has; every claim holds on the baseline, and each case moves one number across one
criterion's edge. Verdicts are asserted exactly: "holds", "fails" or "n/a" (the data
cannot decide the claim).

Covers: lfjax.vision.claim_core, lfjax.vision.claims_accommodation, lfjax.vision.claims_resolution
"""

from __future__ import annotations

import numpy as np
import pytest
import xarray as xr

from lfjax.vision.claim_core import Interval, StudyNumbers
from lfjax.vision.claims import CLAIMS, evaluate_claims
from lfjax.sweep import ten_eyes as te

CDP = 2.0
LAYOUTS = ["natural", "2x2", "3x3", "4x4"]
REL = np.round(np.arange(-2.0, 2.01, 0.5), 9)
NATURAL_ERRORS = [-0.2, -0.1, 0.0, 0.1]  # max |error| 0.2 D, mean −0.05 D
CUTOFF_PEAK = {"2x2": 30.0, "3x3": 28.0, "4x4": 26.0}  # falls with density (claim 7)
CUTOFF_SLOPE = {"2x2": 6.0, "3x3": 5.0, "4x4": 4.0}  # DOF 2.0, 2.24, 2.6 D (claim 6)
FREQ = np.arange(0.0, 81.0)


def _idx(values, value):
    return int(np.flatnonzero(np.isclose(values, value))[0])


class Study:
    """Arrays of a synthetic study (numpy, editable) → :meth:`dataset`.

    Baseline (every claim holds): 4 aberrated eyes + the average eye; LF layouts predict
    the rendered depth on the grid, 0.1 D in front of it by the continuous peaks (+0.05 D
    at 0 D, the hyperopic limit); Strehl agrees except 2x2 beyond ±1 D, where it picks the
    CDP; natural view (CDP only) errors ``NATURAL_ERRORS``; cut-offs fall linearly from
    ``CUTOFF_PEAK`` at the CDP with ``CUTOFF_SLOPE`` cpd/D; the average eye's MTF 0.4
    against the eyes' 0.3.
    """

    def __init__(self, layouts=LAYOUTS, rel=REL, n_eyes=4, natural_errors=NATURAL_ERRORS):
        self.layouts, self.rel = list(layouts), np.asarray(rel, float)
        self.depths = np.round(CDP + self.rel, 9)
        self.n_eyes = n_eyes
        n_l, n_e, n_d = len(self.layouts), n_eyes + 1, self.rel.size
        self.pred = np.full((n_l, n_e, n_d, 2), np.nan)
        self.cont = np.full((n_l, n_e, n_d, 2), np.nan)
        self.cutoff = np.full((n_l, n_e, n_d, 2), np.nan)
        self.mtf = np.full((n_l, n_e, n_d, 2, FREQ.size), np.nan)
        for li, name in enumerate(self.layouts):
            if name == "natural":
                if np.any(np.isclose(self.rel, 0.0)):
                    k = _idx(self.rel, 0.0)
                    errors = list(natural_errors) + [0.0]  # the average eye at the CDP
                    self.pred[li, :, k, :] = CDP + np.asarray(errors)[:, None]
                    self.cont[li, :, k, 0] = self.pred[li, :, k, 0]
                    self.cutoff[li, :, k, :] = 40.0
                    self.mtf[li, :, k] = 0.3
                    self.mtf[li, -1, k] = 0.4
                continue
            self.pred[li, :, :, :] = self.depths[None, :, None]
            self.cont[li, :, :, 0] = self.depths - 0.1
            self.cont[li, :, self.depths < 1e-9, 0] = 0.05
            if name == "2x2":
                far = np.abs(self.rel) > 1.0 + 1e-9
                self.pred[li, :, far, 1] = CDP
            self.cutoff[li] = (CUTOFF_PEAK[name] - CUTOFF_SLOPE[name] * np.abs(self.rel))[
                None, :, None]
            self.mtf[li] = 0.3
            self.mtf[li, -1] = 0.4

    def li(self, name):
        return self.layouts.index(name)

    def di(self, rel):
        return _idx(self.rel, rel)

    def dataset(self) -> xr.Dataset:
        n_e = self.n_eyes + 1
        labels = [f"eye{i:02d}" for i in range(self.n_eyes)] + ["average"]
        d4 = ("layout", "eye", "depth", "metric")
        error = self.pred - self.depths[None, None, :, None]
        return xr.Dataset(
            data_vars=dict(
                predicted_accommodation=(d4, self.pred),
                accommodation_error=(d4, error),
                predicted_accommodation_continuous=(d4, self.cont),
                continuous_peak_success=(d4, np.isfinite(self.cont)),
                peak_value=(d4, np.where(np.isfinite(self.pred), 0.5, np.nan)),
                cutoff_frequency=(d4, self.cutoff),
                mtf_at_peak=(d4 + ("frequency",), self.mtf),
                zernike_um=(("eye", "zernike_j"), np.zeros((n_e, 15))),
            ),
            coords=dict(
                layout=self.layouts, eye=labels, depth=self.depths,
                depth_rel_cdp=("depth", self.rel), metric=["vsotf", "strehl"],
                frequency=FREQ, zernike_j=np.arange(15),
                is_average=("eye", np.arange(n_e) == self.n_eyes),
            ),
            attrs=dict(cdp_D=CDP, measured_pupil_mm=3.0, pupil_diameter_mm=3.0),
        )


def verdicts(study: Study) -> dict[str, str]:
    """{claim id: verdict} of evaluate_claims on the synthetic study's Dataset."""
    return {c.id: c.verdict for c in evaluate_claims(study.dataset())}


def test_baseline_every_claim_holds():
    assert verdicts(Study()) == {str(i): "holds" for i in range(1, 8)}


def test_registry_declares_each_claim_once():
    assert [rule.id for rule in CLAIMS] == [str(i) for i in range(1, 8)]
    assert len({type(rule) for rule in CLAIMS}) == 7
    with pytest.raises(AttributeError):  # frozen: a threshold is changed where declared
        CLAIMS[0].mean_error = Interval()
    ds = Study().dataset()
    numbers = StudyNumbers.from_dataset(ds)
    assert [c.result for c in evaluate_claims(numbers)] == [c.result for c in evaluate_claims(ds)]


def test_interval_answers_a_value_and_a_range():
    negative = Interval(lo=-0.25, hi=0.0, hi_open=True)  # claim 1's mean error
    assert negative.holds(-0.25) and negative.holds(-1e-12)
    assert not negative.holds(0.0) and not negative.holds(-0.2501)
    assert negative.holds(np.array([-0.1, -0.2])) and not negative.holds(np.array([-0.1, 0.0]))
    assert negative.possible(-0.1, -0.05) == {True}
    assert negative.possible(-0.4, -0.3) == {False} and negative.possible(0.0, 0.1) == {False}
    assert negative.possible(-0.1, 0.0) == {True, False}
    assert negative.possible(-0.3, 0.1) == {True, False}  # holds inside, fails at both ends
    assert Interval(lo=0.9).possible(0.9, 0.9) == {True}


def test_study_needs_an_average_eye():
    ds = Study().dataset()
    with pytest.raises(ValueError, match="average eye"):
        evaluate_claims(ds.isel(eye=np.flatnonzero(~ds.is_average.values)))


# ----------------------------------------------------------------------------- claim 1


def _natural(errors):
    return Study(natural_errors=errors)


@pytest.mark.parametrize("errors, want", [
    ([-0.2, -0.1, 0.0, 0.1], "holds"),        # max |error| = 0.2 D
    ([-0.21, -0.1, 0.0, 0.1], "fails"),       # one eye 0.21 D away
    # binary fractions, so that 2 D + error − 2 D and the mean are exact
    ([-0.125, 0.125, -0.0625, 0.0615], "holds"),  # mean −0.00025 D < 0
    ([-0.125, 0.125, -0.0625, 0.0625], "fails"),  # mean exactly 0: not negative
    ([0.2, 0.2, 0.2, 0.2], "fails"),          # within 0.2 D but positive
])
def test_claim1_natural_view(errors, want):
    assert verdicts(_natural(errors))["1"] == want


def test_claim1_undecided():
    assert verdicts(Study(layouts=["2x2", "3x3", "4x4"]))["1"] == "n/a"
    off_cdp = Study(rel=[-2.0, -1.0, 1.0, 2.0])  # no depth on the CDP
    assert verdicts(off_cdp)["1"] == "n/a"
    s = Study()
    s.pred[s.li("natural"), 1, s.di(0.0), 0] = np.nan  # an eye without a prediction
    assert verdicts(s)["1"] == "n/a"


# ----------------------------------------------------------------------------- claim 2


def _continuous_error(study, name, rel, error):
    study.cont[study.li(name), :-1, study.di(rel), 0] = study.depths[study.di(rel)] + error


def test_claim2_small():
    for error, want in ((-0.25, "holds"), (-0.2501, "fails")):
        s = Study()
        for r in s.rel:
            _continuous_error(s, "3x3", r, error if s.depths[s.di(r)] > 0 else -0.1)
        assert verdicts(s)["2"] == want, error


@pytest.mark.parametrize("error, want", [(-1e-6, "holds"), (0.0, "fails"), (0.01, "fails")])
def test_claim2_negative(error, want):
    s = Study()
    _continuous_error(s, "4x4", 1.0, error)
    assert verdicts(s)["2"] == want


def test_claim2_zero_dioptre_depth_is_exempt_from_negative():
    s = Study()
    _continuous_error(s, "2x2", -2.0, 0.05)  # rendered at 0 D: positive allowed
    assert verdicts(s)["2"] == "holds"


@pytest.mark.parametrize("error, want", [(-0.15, "holds"), (-0.1501, "fails")])
def test_claim2_constant(error, want):
    s = Study()  # errors +0.05 (0 D) and −0.1: range 0.15 D; one depth moved
    _continuous_error(s, "2x2", 0.5, error)
    assert verdicts(s)["2"] == want


def test_claim2_undecided():
    assert verdicts(Study(layouts=["natural"]))["2"] == "n/a"
    s = Study()
    s.cont[s.li("3x3"), :, s.di(1.0), 0] = np.nan  # no continuous peak at one depth
    assert verdicts(s)["2"] == "n/a"
    s.cont[s.li("4x4"), :-1, s.di(1.5), 0] += 0.4  # a part that fails still fails
    assert verdicts(s)["2"] == "fails"
    only_zero = Study(rel=[-2.0])  # every depth at 0 D: "negative" cannot be judged
    assert verdicts(only_zero)["2"] == "n/a"


# ----------------------------------------------------------------------------- claim 3


@pytest.mark.parametrize("name, rel, offset, want", [
    ("3x3", 0.5, 0.2, "holds"), ("3x3", 0.5, 0.21, "fails"),
    ("2x2", 1.0, -0.2, "holds"), ("2x2", 1.0, -0.21, "fails"),  # ±1 D is not beyond 1 D
    ("2x2", 1.5, 0.5, "holds"),  # beyond ±1 D part (a) does not apply
])
def test_claim3_strehl_agrees(name, rel, offset, want):
    s = Study()
    s.pred[s.li(name), :-1, s.di(rel), 1] += offset
    assert verdicts(s)["3"] == want


@pytest.mark.parametrize("at_depth, want", [(2, "holds"), (3, "fails")])
def test_claim3_two_by_two_picks_the_cdp(at_depth, want):
    """At −1.5 D from the CDP half the eyes' Strehl peaks must be closer to the CDP."""
    s = Study()
    k = s.di(-1.5)
    s.pred[s.li("2x2"), :at_depth, k, 1] = s.depths[k]
    assert verdicts(s)["3"] == want


def test_claim3_undecided():
    assert verdicts(Study(layouts=["natural", "3x3", "4x4"]))["3"] == "n/a"
    # 2x2 present, no depth beyond ±1 D (a sweep with offsets −1, 0, 1): part (b) undecided
    near = Study(rel=[-1.0, -0.5, 0.0, 0.5, 1.0])
    assert verdicts(near)["3"] == "n/a"
    near.pred[near.li("4x4"), :-1, 0, 1] += 0.5  # part (a) fails: the claim fails
    assert verdicts(near)["3"] == "fails"


# ----------------------------------------------------------------------------- claim 4


CELLS = [("2x2", r) for r in REL] + [("3x3", r) for r in REL] + [("4x4", r) for r in REL]


@pytest.mark.parametrize("n_cells, offset, want", [
    (3, 0.2, "holds"),   # 28/28 cells within 0.2 D
    (2, 0.21, "holds"),  # 26/28 ≥ 90 %
    (3, 0.21, "fails"),  # 25/28 < 90 %
])
def test_claim4_average_eye_predicts_the_mean(n_cells, offset, want):
    s = Study()
    for name, r in CELLS[:: 9][:n_cells]:
        s.pred[s.li(name), -1, s.di(r), 0] += offset
    assert verdicts(s)["4"] == want


def test_claim4_undecided():
    s = Study()
    s.pred[:, -1] = np.nan  # the average eye has no prediction anywhere
    assert verdicts(s)["4"] == "n/a"


# ----------------------------------------------------------------------------- claim 5


@pytest.mark.parametrize("n_cells, value, want", [
    (2, 0.3, "holds"),          # equal is not better: 26/28
    (3, 0.3, "fails"),          # 25/28
    (3, 0.3 + 1e-9, "holds"),   # just better: 28/28
])
def test_claim5_average_eye_mtf_is_better(n_cells, value, want):
    s = Study()
    for name, r in CELLS[4:: 9][:n_cells]:
        s.mtf[s.li(name), -1, s.di(r), 0] = value
    assert verdicts(s)["5"] == want


def test_claim5_reads_zero_to_sixty_cpd_only():
    s = Study()
    s.mtf[:, :-1, :, :, FREQ > 60.0] = 0.9  # beyond 60 cpd: ignored
    assert verdicts(s)["5"] == "holds"
    s.mtf[:, :-1, :, :, FREQ == 60.0] = 9.0  # 60 cpd itself counts: mean 0.43 > 0.4
    assert verdicts(s)["5"] == "fails"


def test_claim5_undecided():
    s = Study()
    s.mtf[:, -1] = np.nan
    assert verdicts(s)["5"] == "n/a"


# ----------------------------------------------------------------------------- claim 6


def _cutoff(study, name, peak, slope):
    study.cutoff[study.li(name)] = (peak - slope * np.abs(study.rel))[None, :, None]


@pytest.mark.parametrize("slope_3x3, want", [
    (5.6, "holds"),   # DOF 11.2/5.6 = 2.0 D = the 2x2's: never decreases
    (5.7, "fails"),   # 1.965 D < 2.0 D
])
def test_claim6_dof_never_decreases(slope_3x3, want):
    s = Study()
    _cutoff(s, "3x3", 28.0, slope_3x3)
    assert verdicts(s)["6"] == want


def test_claim6_strictly_grows_from_2x2_to_4x4():
    s = Study()
    _cutoff(s, "3x3", 28.0, 5.6)
    _cutoff(s, "4x4", 26.0, 5.2)  # DOF 2.0 D everywhere: not grown
    assert verdicts(s)["6"] == "fails"
    _cutoff(s, "4x4", 26.0, 5.19)
    assert verdicts(s)["6"] == "holds"


def test_claim6_censored_depth_of_field():
    s = Study()
    _cutoff(s, "4x4", 26.0, 0.5)  # reaches both ends: DOF >= 4 D, a lower bound
    assert verdicts(s)["6"] == "holds"
    for name in ("2x2", "3x3"):  # every DOF >= 4 D: growth cannot be seen
        _cutoff(s, name, CUTOFF_PEAK[name], 0.5)
    assert verdicts(s)["6"] == "n/a"
    _cutoff(s, "3x3", 28.0, 5.0)  # an exact 3x3 DOF below the 2x2's lower bound
    assert verdicts(s)["6"] == "fails"


def test_claim6_undecided():
    assert verdicts(Study(layouts=["natural", "2x2"]))["6"] == "n/a"
    assert verdicts(Study(rel=[0.0, 1.0]))["6"] == "n/a"
    s = Study()
    s.cutoff[s.li("3x3"), :, s.di(1.5), 0] = np.nan
    assert verdicts(s)["6"] == "n/a"


# ----------------------------------------------------------------------------- claim 7


@pytest.mark.parametrize("peak_3x3, want", [(29.99, "holds"), (30.0, "fails"), (31.0, "fails")])
def test_claim7_cutoff_at_cdp_falls(peak_3x3, want):
    s = Study()
    _cutoff(s, "3x3", peak_3x3, 5.0)
    assert verdicts(s)["7"] == want


@pytest.mark.parametrize("factor, want", [(1.02, "holds"), (1.025, "fails")])
def test_claim7_best_at_the_cdp_within_two_percent(factor, want):
    s = Study()
    s.cutoff[s.li("4x4"), :, s.di(0.5), 0] = 26.0 * factor
    assert verdicts(s)["7"] == want


def test_claim7_undecided():
    assert verdicts(Study(rel=[-2.0, -1.0, 1.0, 2.0]))["7"] == "n/a"
    assert verdicts(Study(layouts=["natural", "4x4"]))["7"] == "n/a"
    s = Study()
    s.cutoff[s.li("2x2"), :, s.di(0.0), 0] = np.nan
    assert verdicts(s)["7"] == "n/a"


# ----------------------------------------------------------------------------- ten eyes


def _population(n_eyes=12, bad_eye=5, layouts=LAYOUTS):
    """12 virtual eyes + the average eye; eye ``bad_eye`` focuses the natural-view CDP
    point 0.5 D nearer than it, so claim 1 holds exactly on the samples without it."""
    errors = [-0.1] * n_eyes
    errors[bad_eye] = 0.5
    s = Study(layouts=layouts, n_eyes=n_eyes, natural_errors=errors)
    return s.dataset()


def test_ten_eye_claims_count_each_sample_by_its_own_criterion():
    ds = _population()
    # samples of 6 of the 12 eyes leave the bad eye out half the time
    result = te.ten_eye_claims(ds, n_draws=40, sample_size=6, seed=1)
    claims = list(result.claim.values)
    without_bad = np.array(["eye05" not in row for row in result.sample_eye.values])
    assert 0 < without_bad.sum() < without_bad.size  # both kinds of sample were drawn
    verdict = result.verdict.values
    np.testing.assert_array_equal(verdict[:, claims.index("1")], without_bad.astype(int))
    for cid in ("2", "3", "4", "5", "6", "7"):  # independent of the natural view
        assert np.all(verdict[:, claims.index(cid)] == 1), cid
    i1 = claims.index("1")
    assert int(result.n_holds[i1]) == without_bad.sum()
    assert int(result.n_fails[i1]) == without_bad.size - without_bad.sum()
    assert float(result.fraction_holds[i1]) == pytest.approx(without_bad.mean())
    assert float(result.ci_low[i1]) < without_bad.mean() < float(result.ci_high[i1])
    assert result.population_verdict.values[i1] == "fails"  # all 12 eyes: the bad one in


def test_ten_eye_claims_keep_undecided_samples_apart():
    result = te.ten_eye_claims(_population(layouts=["2x2", "3x3", "4x4"]), n_draws=5,
                               sample_size=10, seed=0)
    i1 = list(result.claim.values).index("1")
    assert int(result.n_na[i1]) == 5 and int(result.n_holds[i1] + result.n_fails[i1]) == 0
    assert np.isnan(float(result.fraction_holds[i1]))
    assert result.population_verdict.values[i1] == "n/a"
    assert np.all(result.verdict.values[:, i1] == te.VERDICT_CODES[None])
