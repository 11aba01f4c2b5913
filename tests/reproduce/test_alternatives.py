"""The alternatives' baseline read from the main study instead of computed again.

The reduced set's baseline is the main study on the reduced depths. Each (eye, depth)'s
numbers come from elemental OTFs shared by every depth and from that depth's own shifts and
peak, so they cannot depend on which other depths are evaluated beside it: the selection
must equal a fresh run on the reduced set (float32 rounding apart), and its claims must be
the claims of that fresh run.
"""

import numpy as np
import pytest

from lfjax.reproduce.alternatives import ALTERNATIVES, BASELINE, _baseline_from_study, run_alternatives
from lfjax.reproduce.config import StudyConfig
from lfjax.reproduce.study import run_study, study_wavelength_rules
from lfjax.vision.claims import evaluate_claims

# Half-dioptre depths in the main study, integers only in the reduced set; 30 nm steps in
# both (the reduced set's vsotf grid is max(step, 20 nm)), so the spectra agree. Two
# wavelengths, 540 and 570 nm (the quick study's 400-700 nm would be 11, each its own FFT
# band of the compiled programs): the selection's equality holds wavelength by wavelength.
CONFIG = StudyConfig.quick(n_eyes=1, layouts=("2x2",), wavelengths_nm=(540.0, 570.0, 30.0),
                           depth_offsets_D=(-2.0, -1.5, 0.0, 1.0))


@pytest.fixture(scope="module")
def study():
    return run_study(CONFIG)


def test_baseline_selected_from_the_study_equals_a_fresh_reduced_run(study, monkeypatch):
    reduced = CONFIG.reduced(study_wavelength_rules(study))
    selected = _baseline_from_study(study, CONFIG, reduced, study_wavelength_rules(study))
    assert selected is not None
    fresh = run_study(reduced)
    np.testing.assert_allclose(selected.depth.values, fresh.depth.values)
    for name in ("vsotf", "strehl"):
        np.testing.assert_allclose(selected[name].values, fresh[name].values, rtol=2e-5,
                                   atol=1e-7, equal_nan=True)
    np.testing.assert_array_equal(selected.predicted_accommodation.values,
                                  fresh.predicted_accommodation.values)
    np.testing.assert_allclose(selected.predicted_accommodation_continuous.values,
                               fresh.predicted_accommodation_continuous.values, atol=1e-4,
                               equal_nan=True)
    np.testing.assert_allclose(selected.cutoff_frequency.values, fresh.cutoff_frequency.values,
                               rtol=1e-5, equal_nan=True)
    ours = evaluate_claims(selected, CONFIG.dof_fraction)
    theirs = evaluate_claims(fresh, CONFIG.dof_fraction)
    assert [(c.id, c.holds, c.result) for c in ours] == [(c.id, c.holds, c.result) for c in theirs]

    # run_alternatives takes it, and computes only the alternatives themselves (one here)
    import lfjax.reproduce.alternatives as alternatives

    computed = []
    real = alternatives.run_study_variants
    one = dict(list(ALTERNATIVES.items())[-1:])
    monkeypatch.setattr(alternatives, "ALTERNATIVES", one)
    monkeypatch.setattr(alternatives, "run_study_variants",
                        lambda config, variants, stage=None: computed.extend(variants)
                        or real(config, variants, stage))
    claims = run_alternatives(CONFIG, wavelength_rules=study_wavelength_rules(study),
                              study=study)
    assert list(claims) == [BASELINE, *one]
    assert computed == list(one)
    assert [(c.id, c.holds, c.result) for c in claims[BASELINE]] == [
        (c.id, c.holds, c.result) for c in ours]


def test_baseline_not_read_from_a_study_that_cannot_stand_for_it(study):
    rules = study_wavelength_rules(study)
    reduced = CONFIG.reduced(rules)
    assert _baseline_from_study(study, CONFIG, reduced, rules) is not None
    lacking = study.isel(depth=[1, 2, 3])  # no -2 D relative to the CDP
    assert _baseline_from_study(lacking, CONFIG, reduced, rules) is None
    assert _baseline_from_study(None, CONFIG, reduced, rules) is None
    finer = CONFIG.replace(wavelengths_nm=(400.0, 700.0, 10.0))  # reduced set: 20 nm
    assert _baseline_from_study(study, finer, finer.reduced(), None) is None
    other = CONFIG.replace(options=CONFIG.options.replace(lca_A=633.46))
    assert _baseline_from_study(study, other, other.reduced(rules), rules) is None
    assert _baseline_from_study(study, CONFIG.replace(layouts=("natural", "2x2")),
                                CONFIG.replace(layouts=("natural", "2x2")).reduced(rules),
                                rules) is None


def test_layouts_in_threads_give_the_numbers_of_one_after_another():
    """``workers``: the layouts computed at once in threads give every number bit for bit
    as computed one after another; the threads start (and report) the larger layout first,
    and the Dataset keeps the configuration's order."""
    from lfjax.base.errors import ParameterError
    from lfjax.reproduce.study import layout_workers

    two = CONFIG.replace(layouts=("natural", "2x2"))
    stages = {1: [], 2: []}
    runs = {n: run_study(two, stage=stages[n].append, workers=n) for n in (1, 2)}
    assert stages[1] == ["natural", "2x2"] and stages[2] == ["2x2", "natural"]
    assert list(runs[2].layout.values) == ["natural", "2x2"]
    for name in ("vsotf", "strehl", "predicted_accommodation_continuous", "cutoff_frequency",
                 "radial_mtf"):
        np.testing.assert_array_equal(runs[1][name].values, runs[2][name].values)
    assert layout_workers(None, 1) == 1
    for bad in (0, 1.5, True):
        with pytest.raises(ParameterError, match="workers"):
            layout_workers(bad, 2)

