"""Same answer for less arithmetic: the lenslet-aberration study (issue #38, items 3–4) at each
case's own sampling and adaptive peaks, against its first form (every case at the most
aberrated case's frequency step, Newton-refined peaks everywhere).

Run:  python benchmarks/validation/lenslet_sampling.py [--new DIR] [--eyes 8]

Without ``--new`` it runs the study's aberration scan at its defaults (bucketed sampling,
``peak_method="adaptive"``) for the first ``--eyes`` Thibos eyes (seed 0; the draw of n eyes
begins with the draw of fewer) into a temporary folder; with ``--new DIR`` it reads
DIR/aberrations.csv (and DIR/phone.csv) — e.g. the 100-eye study's own output, whose first
eyes are the reference's. The reference: ``lenslet_sampling/reference_*.csv``, the study's
output at commit 323bec6 (8 eyes, the common step 0.273 cpd for the near-eye panel and
0.459 cpd for the phone, Newton peaks; the phone's idealised views for 3 eyes, Newton).

Prints, per panel and case, the largest difference over the common eyes and depths in the
predicted accommodation (D), and the relative differences in the perceivable and optical
cut-offs; then the differences in what the study reports (the median shift from the
aberration-free case, the median perceivable change, the thresholds), against the
study's thresholds (0.1 D, 10 %).
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(1, str(HERE.parent))  # benchmarks/: _common, which the study imports
sys.path.insert(1, str(HERE.parent / "studies"))  # the study's script

from lenslet_aberrations import _read_csv, run_aberrations, summarise, thresholds  # noqa: E402

REFERENCE = HERE / "lenslet_sampling"


def _key(r):
    return (r["panel"], r["kind"], r["value"], int(r["eye"]), round(r["depth_D"], 4))


def compare(new_rows, ref_rows) -> dict:
    ref = {_key(r): r for r in ref_rows}
    eyes = sorted({int(r["eye"]) for r in ref_rows} & {int(r["eye"]) for r in new_rows})
    common = [r for r in new_rows if _key(r) in ref]
    print(f"{len(common)} (panel, case, eye, depth) rows in common; eyes {eyes[0]}–{eyes[-1]}")
    print("| panel | case | step cpd new / ref | max |Δ accommodation| D | max |Δ perceivable| % "
          "| max |Δ optical cut-off| % |")
    print("|---|---|---|---|---|---|")
    worst = dict(acc=0.0, perc=0.0, opt=0.0)
    for case in dict.fromkeys((r["panel"], r["kind"], r["value"]) for r in common):
        sel = [r for r in common if (r["panel"], r["kind"], r["value"]) == case]
        da = max(abs(r["accommodation_D"] - ref[_key(r)]["accommodation_D"]) for r in sel)
        dp = max(abs(r["perceivable_cpd"] / ref[_key(r)]["perceivable_cpd"] - 1) for r in sel)
        do = max(abs(r["optical_cpd"] / ref[_key(r)]["optical_cpd"] - 1) for r in sel)
        worst = dict(acc=max(worst["acc"], da), perc=max(worst["perc"], dp), opt=max(worst["opt"], do))
        print(f"| {case[0]} | {case[1]} {case[2]:g} | {sel[0]['freq_step_cpd']:.3f} / "
              f"{ref[_key(sel[0])]['freq_step_cpd']:.3f} | {da:.4f} | {100 * dp:.2f} | {100 * do:.2f} |")
    # what the study reads, on the common eyes alone
    sub_new, sub_ref = summarise(common), summarise([ref[_key(r)] for r in common])
    print("\n| panel | case | median Δ acc. D new / ref | median perceivable change % new / ref |")
    print("|---|---|---|---|")
    worst_summary = dict(acc=0.0, perc=0.0)
    for a, b in zip(sub_new, sub_ref):
        worst_summary["acc"] = max(worst_summary["acc"], abs(a["acc_shift_median_D"] - b["acc_shift_median_D"]))
        worst_summary["perc"] = max(worst_summary["perc"],
                                    abs(a["perceivable_change_median"] - b["perceivable_change_median"]))
        print(f"| {a['panel']} | {a['kind']} {a['value']:g} | {a['acc_shift_median_D']:+.4f} / "
              f"{b['acc_shift_median_D']:+.4f} | {100 * a['perceivable_change_median']:+.2f} / "
              f"{100 * b['perceivable_change_median']:+.2f} |")
    print("\nthresholds (new / ref):")
    for a, b in zip(thresholds(sub_new), thresholds(sub_ref)):
        print(f"  {a['panel']} {a['kind']}: 0.1 D at {a['acc']} / {b['acc']} {a['unit']}; "
              f"10 % at {a['cutoff']} / {b['cutoff']} {a['unit']}")
    print(f"\nworst per row: accommodation {worst['acc']:.4f} D, perceivable {100 * worst['perc']:.2f} %, "
          f"optical cut-off {100 * worst['opt']:.2f} %; in the medians the study reports: "
          f"{worst_summary['acc']:.4f} D, {100 * worst_summary['perc']:.2f} % (thresholds 0.1 D, 10 %)")
    return dict(rows=worst, summary=worst_summary)


def compare_phone(new_rows, ref_rows) -> float:
    ref = {(r["model"], r["n"], r["depth_D"], r["eye"]): r for r in ref_rows}
    diffs = [(k, abs(r["peak_D"] - ref[k]["peak_D"])) for r in new_rows
             if (k := (r["model"], r["n"], r["depth_D"], r["eye"])) in ref]
    for k, d in diffs:
        print(f"  phone {k[0]} {int(k[1])}x{int(k[1])} at {k[2]:g} D, eye {int(k[3])}: |Δ peak| {d:.4f} D")
    worst = max(d for _, d in diffs)
    print(f"phone: worst |Δ continuous peak| {worst:.4f} D over {len(diffs)} rows")
    return worst


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--new", type=Path, help="a folder holding the study's aberrations.csv (and phone.csv)")
    parser.add_argument("--eyes", type=int, default=8)
    args = parser.parse_args(argv)
    print("command: python benchmarks/validation/lenslet_sampling.py " + " ".join(sys.argv[1:] if argv is None
                                                                                  else argv), flush=True)
    if args.new is None:
        folder = Path(tempfile.mkdtemp())
        new_rows = run_aberrations(["near-eye", "phone"], args.eyes, folder)
    else:
        folder = args.new
        new_rows = _read_csv(folder / "aberrations.csv")
    compare(new_rows, _read_csv(REFERENCE / "reference_aberrations_8eyes.csv"))
    if (folder / "phone.csv").exists():
        compare_phone(_read_csv(folder / "phone.csv"), _read_csv(REFERENCE / "reference_phone_3eyes.csv"))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
