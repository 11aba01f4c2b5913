"""Modelling alternatives evaluated only near known peaks give the verdicts full curves give."""

import numpy as np

from lfjax.reproduce import StudyConfig, run_study
from lfjax.reproduce.alternatives import BASELINE, run_alternatives


def test_pruned_alternatives_give_the_full_curves_verdicts():
    """Quick study (2 eyes + the average eye, depths CDP−2/CDP/CDP+2, 0.5 D states, 30 nm),
    natural view, 2×2 and 3×3, baseline and one alternative: the claims under pruned states
    (each peak and its grid neighbours in the main study, their own sampling) equal those of the
    whole ±2 D window, and fewer states are computed."""
    config = StudyConfig.quick(layouts=("natural", "2x2", "3x3"))
    variants = {"accommodation_sa=unscaled": {"accommodation_sa": "unscaled"}}
    main = run_study(config)
    record: dict = {}
    pruned = run_alternatives(config, baseline=main, variants=variants, record=record)
    full = run_alternatives(config, variants=variants, prune=False)
    assert list(pruned) == list(full) == [BASELINE, *variants]
    for name in full:
        got = {c.id: c.verdict for c in pruned[name]}
        want = {c.id: c.verdict for c in full[name]}
        assert got == want, name
    n_acc = np.asarray(config.accommodation_D).size
    evaluated = {k: v["states_per_depth"] for k, v in record.items() if k != "widened"}
    assert set(evaluated) == set(config.layouts)
    # every LF depth evaluates fewer states than the full window (±2 D: up to 9 of 11)
    assert all(max(v) < 9 for v in evaluated.values()), evaluated
    assert all(min(v) >= 1 for v in evaluated.values()) and n_acc == 11
