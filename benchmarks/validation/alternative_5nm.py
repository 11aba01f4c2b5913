"""The alternative whose verdicts differ between the study's plan and ``--accuracy vsotf``,
computed against a 5 nm spectrum: which side is right?

§26 found 40 of 42 alternative verdicts identical between the default study (each layout's
Gauss rule for V(λ)) and the ``--accuracy vsotf`` reference, whose alternatives run at
20 nm steps. Both differences are under ``accommodation_sa=unscaled`` and sit on a
threshold (claim 5: 14 or 15 of 16 cells; claim 6: the 4x4 depth of field censored at
2.82 or 2.83 D). This script runs that one alternative on the reduced set at 5 nm steps
(61 wavelengths, every peak refined with ``"local"``) and at the 20 nm steps of the
reference, and prints each claim's verdict and result beside the default study's
(``--study-alternatives``: an ``alternatives.csv`` from ``lfjax reproduce``).

    PYTHONPATH=. .venv/bin/python benchmarks/validation/alternative_5nm.py \
        --study-alternatives OUT/alternatives.csv --out benchmarks/validation/alternative_5nm.log
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

sys.path.insert(1, str(Path(__file__).resolve().parents[1]))  # benchmarks/: _common

VARIANT = "accommodation_sa=unscaled"


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--study-alternatives", type=Path, required=True,
                   help="alternatives.csv of a default `lfjax reproduce` run")
    p.add_argument("--steps", type=float, nargs="+", default=[20.0, 5.0],
                   help="wavelength steps (nm) to compute the alternative at")
    p.add_argument("--out", type=Path, default=None, help="also write the table here")
    args = p.parse_args()
    from _common import header

    header("accommodation_sa=unscaled: verdicts at 5 nm against the plan and the 20 nm reference")
    import pandas as pd

    from lfjax.cli.cache import enable_compilation_cache
    from lfjax.reproduce.alternatives import ALTERNATIVES
    from lfjax.reproduce.config import StudyConfig
    from lfjax.reproduce.study import run_study_variants
    from lfjax.vision.claims import evaluate_claims

    enable_compilation_cache()
    study = pd.read_csv(args.study_alternatives)
    study = study[study.variant == VARIANT].astype({"claim": str}).set_index("claim")
    rows = {}
    for step in args.steps:
        config = StudyConfig(accuracy="vsotf", wavelengths_nm=(400.0, 700.0, step))
        reduced = config.reduced().replace(wavelengths_nm=(400.0, 700.0, step))
        t0 = time.perf_counter()
        ds = run_study_variants(reduced, {VARIANT: config.options.replace(**ALTERNATIVES[VARIANT])})[VARIANT]
        seconds = time.perf_counter() - t0
        rows[step] = {c.id: c for c in evaluate_claims(ds, config.dof_fraction)}
        print(f"{step:g} nm: {int(ds.n_wavelengths.max())} wavelengths, {seconds:.0f} s", flush=True)
    lines = ["| claim | study (Gauss rule) | " + " | ".join(f"{s:g} nm" for s in args.steps) + " |",
             "|---|---|" + "---|" * len(args.steps)]
    for claim in study.index:
        cells = [f"{study.loc[claim, 'verdict']}: {study.loc[claim, 'result']}"]
        cells += [f"{rows[s][claim].verdict}: {rows[s][claim].result}" if claim in rows[s] else "—"
                  for s in args.steps]
        lines.append(f"| {claim} | " + " | ".join(c.replace('|', '/') for c in cells) + " |")
    text = "\n".join(lines)
    print(text)
    if args.out is not None:
        args.out.write_text(text + "\n")


if __name__ == "__main__":
    main()
