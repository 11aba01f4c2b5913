"""Lenslet aberrations over a population (issue #38, item 3) and the phone class read through
the whole lenslet array (item 4).

Run:  python benchmarks/studies/lenslet_aberrations.py [--part aberrations|phone|both|report]
          [--eyes 100] [--phone-eyes 100] [--panels near-eye phone] [--out DIR]
          [--sampling bucketed|common] [--peak-method adaptive|auto] [--jobs 2]

``--jobs 2`` (default) runs the panels' aberration scans as two processes side by side (one
process uses one core): 100 eyes in 757 and 491 CPU s (RESULTS §28).

Part "aberrations": for each preset panel of lfjax.display.panel (its own n×n views, lenslet
diffraction and emitters, 550 nm), the Thibos eyes (seed 0) at the CDP and ±1 D, states
±1.5 D in 0.25 D with continuous VSOTF peaks, once per lenslet aberration: a given
spherical coefficient W040 (rim, µm) on axis, and the plano-convex lenslets of the preset
(n = 1.5, curved face towards the eye, lfjax.display.aberrations) at field angles 0–15°.
Each case runs at the step the field guard plans for its own aberration (cases within
2^(1/4) in step share the finer: one compiled program per bucket; ``--sampling common``:
every case at the most aberrated case's step, the first form, 3× the arithmetic for the
same answer, benchmarks/validation/lenslet_sampling.py), and each continuous peak is
refined only where the grid cannot place it within 0.01 D (``peak_method="adaptive"``).
Thresholds: the smallest aberration that moves the population's median
predicted accommodation by 0.1 D, or its median perceivable cut-off (MTF 0.05 at the peak,
capped at the panel's sampling limit) by 10 %, from the aberration-free case, interpolated
linearly between scanned values.

Part "phone": the phone preset's 2×2 and 3×3 family members (lfjax.studies.tradeoff.panel_for_views)
at 1 and 2 D, through the n×n idealisation and through the whole array
(lfjax.studies.array_views.array_through_focus), on an absolute accommodation grid 0–6 D
(the ±1.5 D window widened), 550 nm.

Writes DIR/aberrations.csv, DIR/phone.csv, DIR/REPORT.md and the figures
DIR/lenslet_aberrations.png and DIR/phone_array.png.
"""

from __future__ import annotations

import argparse
import csv
import math
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(1, str(Path(__file__).resolve().parents[1]))  # benchmarks/: _common

from _common import header  # noqa: E402

from lfjax.display.aberrations import LensletAberration, panel_aberration  # noqa: E402
from lfjax.display.panel import PRESETS  # noqa: E402
from lfjax.model.eyes import sample_eyes  # noqa: E402
from lfjax.model.options import ModelOptions  # noqa: E402
from lfjax.model.spectral import make_spectrum  # noqa: E402
from lfjax.sweep.run import peak_rss_mb  # noqa: E402
from lfjax.vision.focus import through_focus  # noqa: E402
from lfjax.vision.prepare import States, default_sampling  # noqa: E402
from lfjax.vision.resolution import perceivable_cutoff_at_peak  # noqa: E402
from lfjax.vision.peak_options import PeakOptions
from lfjax.vision.viewing import Viewing

HERE = Path(__file__).resolve().parent
SA_SCAN_UM = (0.0, 0.1, 0.25, 0.5, 1.0)
FIELD_SCAN_DEG = (0.0, 5.0, 10.0, 15.0)
ACC_SHIFT_D = 0.1
CUTOFF_CHANGE = 0.10


def _cases(panel):
    cases = [dict(kind="spherical", value=w, aberration=LensletAberration(spherical_um=w)) for w in SA_SCAN_UM]
    for theta in FIELD_SCAN_DEG:
        ab = panel_aberration(panel, field_angle_deg=theta)
        cases.append(dict(kind="field", value=theta, aberration=ab))
    return cases


STEP_BUCKET_RATIO = 2 ** 0.25
"""Cases whose own planned frequency steps lie within this ratio of the bucket's coarsest
share one sampling (the finest among them): one compiled program per bucket instead of one
per case, at most 1.41× the arithmetic of each case's own step (one planner rung is 2^(1/8))."""


def _buckets(steps, ratio: float = STEP_BUCKET_RATIO) -> list[list[int]]:
    """Indices of ``steps`` (cpd) grouped from the coarsest down: each group holds the steps
    within ``ratio`` of its coarsest; a group runs at its finest step."""
    order = sorted(range(len(steps)), key=lambda i: -steps[i])
    groups: list[list[int]] = []
    for i in order:
        if groups and steps[groups[-1][0]] / steps[i] <= ratio * (1 + 1e-9):
            groups[-1].append(i)
        else:
            groups.append([i])
    return groups


def _case_samplings(panel, layout, cases, eyes, depths, offsets, spectrum, sampling_mode: str):
    """The sampling each case runs with: ``"common"`` (every case at the most aberrated
    case's planned step, the study's first form) or ``"bucketed"`` (each case planned for
    its own aberration, grouped by :func:`_buckets`). Each planned step is the field
    guard's for that case alone (lfjax.vision.prepare.default_sampling, milliseconds), so no
    case runs coarser than its own plan."""
    states = States.around(depths, offsets)
    own = [
        default_sampling(
            eyes,
            layout,
            states,
            Viewing(
                pupil_diameter_mm=panel.pupil_diameter_mm,
                cdp_D=float(panel.cdp_D),
                display=panel.optics().with_aberration(c["aberration"]),
            ),
            spectrum=spectrum,
            options=ModelOptions(),
        )
        for c in cases
    ]
    steps = [s.freq_step_cpd for s in own]
    groups = [list(range(len(cases)))] if sampling_mode == "common" else _buckets(steps)
    chosen = [None] * len(cases)
    for g in groups:
        finest = min(g, key=lambda i: steps[i])
        for i in g:
            chosen[i] = own[finest]
    return chosen, groups


def run_aberrations(panels, n_eyes: int, out: Path, sampling_mode: str = "bucketed",
                    peak_method: str = "adaptive") -> list[dict]:
    eyes = sample_eyes(0, n_eyes)
    spectrum = make_spectrum([550.0])
    offsets = np.arange(-1.5, 1.5001, 0.25)
    rows = []
    for name in panels:
        panel = PRESETS[name]()
        layout = panel.layout()
        cdp = float(panel.cdp_D)
        depths = np.array([cdp - 1.0, cdp, cdp + 1.0])
        cases = _cases(panel)
        samplings, groups = _case_samplings(panel, layout, cases, eyes, depths, offsets, spectrum, sampling_mode)
        print(f"{name}: {len(groups)} sampling(s), steps (cpd) "
              + ", ".join(f"{samplings[g[0]].freq_step_cpd:.3f} for {len(g)} case(s)" for g in groups), flush=True)
        t_panel = time.time()
        for g in groups:
            for i in g:
                case = cases[i]
                sampling = samplings[i]
                t0 = time.time()
                display = panel.optics().with_aberration(case["aberration"])
                tf = through_focus(
                    eyes,
                    layout,
                    States.around(depths, offsets),
                    Viewing(pupil_diameter_mm=panel.pupil_diameter_mm, cdp_D=cdp, display=display),
                    spectrum=spectrum,
                    sampling=sampling,
                    peaks=PeakOptions(metrics=("vsotf",), method=peak_method),
                )
                acc = tf.continuous_accommodation_D()
                perceivable = np.asarray(perceivable_cutoff_at_peak(tf, panel), float)
                optical = np.asarray(tf.cutoff_cpd(), float)
                ab = case["aberration"]
                for e in range(n_eyes):
                    for k, d in enumerate(depths):
                        rows.append(dict(panel=name, kind=case["kind"], value=case["value"],
                                         spherical_um=float(ab.spherical_um), coma_um=float(ab.coma_um),
                                         astigmatism_um=float(ab.astigmatism_um),
                                         field_curvature_um=float(ab.field_curvature_um),
                                         eye=e, depth_D=float(d), accommodation_D=float(acc[e, k]),
                                         perceivable_cpd=float(perceivable[e, k]), optical_cpd=float(optical[e, k]),
                                         freq_step_cpd=float(tf.sampling.freq_step_cpd)))
                print(f"{name} {case['kind']} {case['value']:g} (df {tf.sampling.freq_step_cpd:.3f} cpd): "
                      f"{time.time() - t0:.1f} s, median acc − depth {np.median(acc - depths[None]):+.3f} D, "
                      f"median perceivable {np.median(perceivable):.2f} cpd, peak RSS {peak_rss_mb():.0f} MiB",
                      flush=True)
        print(f"{name}: {time.time() - t_panel:.0f} s for {n_eyes} eyes", flush=True)
    with open(out / "aberrations.csv", "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    return rows


def _threshold(values, changes, limit):
    """Smallest scanned-value interpolation where |change| first reaches ``limit`` (None: never;
    the first value when it is reached there already)."""
    if abs(changes[0]) >= limit:
        return values[0]
    for i in range(1, len(values)):
        if abs(changes[i]) >= limit:
            a, b = abs(changes[i - 1]), abs(changes[i])
            return values[i - 1] + (values[i] - values[i - 1]) * (limit - a) / (b - a)
    return None


def summarise(rows) -> list[dict]:
    out = []
    for name in dict.fromkeys(r["panel"] for r in rows):
        for kind in ("spherical", "field"):
            sel = [r for r in rows if r["panel"] == name and r["kind"] == kind]
            values = sorted(dict.fromkeys(r["value"] for r in sel))
            base = {(r["eye"], r["depth_D"]): r for r in rows
                    if r["panel"] == name and r["kind"] == "spherical" and r["value"] == 0.0}
            for v in values:
                here = [r for r in sel if r["value"] == v]
                dacc = np.array([r["accommodation_D"] - base[(r["eye"], r["depth_D"])]["accommodation_D"] for r in here])
                rel = np.array([r["perceivable_cpd"] / base[(r["eye"], r["depth_D"])]["perceivable_cpd"] - 1 for r in here])
                err = np.array([r["accommodation_D"] - r["depth_D"] for r in here])
                out.append(dict(panel=name, kind=kind, value=v, spherical_um=here[0]["spherical_um"],
                                astigmatism_um=here[0]["astigmatism_um"], coma_um=here[0]["coma_um"],
                                field_curvature_um=here[0]["field_curvature_um"],
                                acc_shift_median_D=float(np.median(dacc)),
                                acc_shift_p95_D=float(np.percentile(np.abs(dacc), 95)),
                                acc_error_median_D=float(np.median(err)),
                                perceivable_median_cpd=float(np.median([r["perceivable_cpd"] for r in here])),
                                optical_median_cpd=float(np.median([r["optical_cpd"] for r in here])),
                                perceivable_change_median=float(np.median(rel))))
    return out


def thresholds(summary):
    res = []
    for name in dict.fromkeys(s["panel"] for s in summary):
        for kind, unit in (("spherical", "µm W040"), ("field", "deg")):
            s = [x for x in summary if x["panel"] == name and x["kind"] == kind]
            v = [x["value"] for x in s]
            res.append(dict(panel=name, kind=kind, unit=unit,
                            acc=_threshold(v, [x["acc_shift_median_D"] for x in s], ACC_SHIFT_D),
                            cutoff=_threshold(v, [x["perceivable_change_median"] for x in s], CUTOFF_CHANGE)))
    return res


def fig_aberrations(summary, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    panels = list(dict.fromkeys(s["panel"] for s in summary))
    fig, axes = plt.subplots(2, 2, figsize=(10, 7))
    for col, kind, xlabel in ((0, "spherical", "lenslet spherical aberration W040 at the view's rim (µm)"),
                              (1, "field", "field angle of the point (deg), plano-convex lenslets n = 1.5")):
        for name in panels:
            s = [x for x in summary if x["panel"] == name and x["kind"] == kind]
            v = [x["value"] for x in s]
            # on the ±1.5 D window's edge (the adaptive refinement's local stencil, moved
            # inside the bracket at the window's end, places such a peak 0.02 D inside it)
            pinned = all(abs(abs(x["acc_error_median_D"]) - 1.5) <= 0.025 for x in s)
            label = name + (" (peaks pinned on the ±1.5 D window's edge)" if pinned else "")
            axes[0, col].plot(v, [x["acc_shift_median_D"] for x in s], "o-", label=label)
            axes[1, col].plot(v, [100 * x["perceivable_change_median"] for x in s], "o-",
                              label=name + (" (at its 1.55 cpd sampling limit)" if pinned else ""))
        axes[0, col].axhspan(-ACC_SHIFT_D, ACC_SHIFT_D, color="0.9")
        axes[1, col].axhspan(-100 * CUTOFF_CHANGE, 100 * CUTOFF_CHANGE, color="0.9")
        axes[0, col].set_ylabel("median shift of predicted accommodation (D)")
        axes[1, col].set_ylabel("median change of perceivable cut-off (%)")
        axes[1, col].set_xlabel(xlabel)
        axes[0, col].legend(fontsize=8)
        axes[1, col].legend(fontsize=8)
    fig.suptitle("Lenslet aberrations: the presets' 2×2 views, Thibos eyes, CDP and ±1 D, 550 nm "
                 "(grey: within 0.1 D / 10 %)", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def _read_csv(path):
    with open(path) as fh:
        rows = list(csv.DictReader(fh))
    for r in rows:
        for k, v in r.items():
            try:
                r[k] = float(v)
            except ValueError:
                pass
    return rows


def report(out: Path) -> str:
    """REPORT.md from the CSVs in ``out`` (the tables of results page 28)."""
    lines = []
    if (out / "aberrations.csv").exists():
        rows = _read_csv(out / "aberrations.csv")
        summary = summarise(rows)
        n_eyes = len({r["eye"] for r in rows})
        lines += [f"## Lenslet aberrations ({n_eyes} eyes, CDP and ±1 D, 550 nm)", "",
                  "| panel | case | W040 µm | W131 µm | W222 µm | W220 µm | Δ accommodation D median (95 % of abs) "
                  "| accommodation − depth D median | perceivable cpd median (change) | optical cut-off cpd median |",
                  "|---|---|---|---|---|---|---|---|---|---|"]
        for s in summary:
            case = f"W040 = {s['value']:g} µm" if s["kind"] == "spherical" else f"plano-convex, {s['value']:g}°"
            lines.append(f"| {s['panel']} | {case} | {s['spherical_um']:.3f} | {s['coma_um']:.3f} | "
                         f"{s['astigmatism_um']:.3f} | {s['field_curvature_um']:.3f} | "
                         f"{s['acc_shift_median_D']:+.3f} ({s['acc_shift_p95_D']:.3f}) | {s['acc_error_median_D']:+.3f} | "
                         f"{s['perceivable_median_cpd']:.2f} ({100 * s['perceivable_change_median']:+.1f} %) | "
                         f"{s['optical_median_cpd']:.2f} |")
        lines += ["", "| panel | scan | moves accommodation by 0.1 D at | moves perceivable cut-off by 10 % at |",
                  "|---|---|---|---|"]
        for t in thresholds(summary):
            f = (lambda v: "beyond the scan" if v is None else f"{v:.3g} {t['unit']}")
            lines.append(f"| {t['panel']} | {t['kind']} | {f(t['acc'])} | {f(t['cutoff'])} |")
        lines.append("")
    if (out / "phone.csv").exists():
        rows = _read_csv(out / "phone.csv")
        ideal = [r for r in rows if r["model"] == "idealised"]
        n_eyes = len({r["eye"] for r in ideal})
        lines += [f"## The phone class on 0–6 D (550 nm; idealisation: {n_eyes} eyes, whole array: eye 0)", "",
                  "| views | point D | continuous peak D, median (5–95 %) | peaks within 0.25 D of the point "
                  "| peaks beyond the lenslet plane (2.86 D) | peaks on the grid's ends (0, 6 D) | VSOTF max, median |",
                  "|---|---|---|---|---|---|---|"]
        for key in dict.fromkeys((r["n"], r["depth_D"]) for r in ideal):
            sel = [r for r in ideal if (r["n"], r["depth_D"]) == key]
            pk = np.array([r["peak_D"] for r in sel])
            lines.append(f"| {int(key[0])}x{int(key[0])} | {key[1]:g} | {np.median(pk):.2f} "
                         f"({np.percentile(pk, 5):.2f}–{np.percentile(pk, 95):.2f}) | "
                         f"{np.mean(np.abs(pk - key[1]) <= 0.25):.0%} | {np.mean(pk > 1000.0 / 350.0):.0%} | "
                         f"{np.mean((pk <= 0.01) | (pk >= 5.99)):.0%} | "
                         f"{np.median([r['vsotf_max'] for r in sel]):.3f} |")
        lines += ["", "| model | views | point D | eye | continuous peak D | grid peak D | VSOTF max | beams |",
                  "|---|---|---|---|---|---|---|---|"]
        for r in rows:
            if r["model"] == "idealised" and r["eye"] >= 3:
                continue  # the first eyes, beside the whole array's eye 0
            lines.append(f"| {r['model']} | {int(r['n'])}x{int(r['n'])} | {r['depth_D']:g} | {int(r['eye'])} | "
                         f"{r['peak_D']:.2f} | {r['grid_peak_D']:.2f} | {r['vsotf_max']:.3f} | {int(r['n_beams'])} |")
        lines.append("")
    if (out / "phone_geometry.csv").exists():
        rows = _read_csv(out / "phone_geometry.csv")
        lines += ["| views | eye | point D | lit beams in the pupil (array / idealised) | pixel zone at the eye mm "
                  "| view mm | emitter sweep / view | largest beam tilt ′ | Fresnel N |", "|---|---|---|---|---|---|---|---|---|"]
        for r in rows:
            lines.append(f"| {int(r['n'])}x{int(r['n'])} | {r['eye']} | {r['depth_D']:g} | {int(r['n_array'])} / "
                         f"{int(r['n_idealised'])} | {r['pixel_zone_mm']:.2f} | {r['view_mm']:.2f} | "
                         f"{r['emitter_sweep_ratio']:.1f} | {r['tilt_arcmin']:.1f} | {r['fresnel_number']:.2f} |")
    text = "\n".join(lines) + "\n"
    (out / "REPORT.md").write_text(text)
    return text


def run_panels_apart(args) -> list[dict]:
    """The aberration scan with each panel in its own process (``args.jobs`` at a time: one
    process uses one core), their CSVs joined in panel order into ``args.out``."""
    with tempfile.TemporaryDirectory() as tmp:
        folders, pending = [], list(args.panels)
        while pending:
            batch, pending = pending[:args.jobs], pending[args.jobs:]
            procs = []
            for name in batch:
                folder = Path(tmp) / name
                folders.append(folder)
                procs.append(subprocess.Popen(
                    [sys.executable, str(Path(__file__).resolve()), "--part", "aberrations", "--panels", name,
                     "--eyes", str(args.eyes), "--out", str(folder), "--sampling", args.sampling,
                     "--peak-method", args.peak_method, "--jobs", "1"]))
            for name, proc in zip(batch, procs):
                if proc.wait() != 0:
                    raise RuntimeError(f"the {name} panel's scan failed (exit status {proc.returncode})")
        lines = []
        for folder in folders:
            text = (folder / "aberrations.csv").read_text().splitlines()
            lines += text if not lines else text[1:]
        (args.out / "aberrations.csv").write_text("\n".join(lines) + "\n")
    return _read_csv(args.out / "aberrations.csv")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--part", choices=["aberrations", "phone", "both", "report"], default="both")
    parser.add_argument("--eyes", type=int, default=100)
    parser.add_argument("--phone-eyes", type=int, default=100)
    parser.add_argument("--panels", nargs="+", default=["near-eye", "phone"], choices=sorted(PRESETS))
    parser.add_argument("--out", type=Path, default=HERE / "lenslet_aberrations")
    parser.add_argument("--sampling", choices=["bucketed", "common"], default="bucketed",
                        help="bucketed (default): each case planned for its own aberration, cases within "
                             "2^(1/4) in step sharing the finer; common: every case at the most aberrated "
                             "case's step (the study's first form, 3x the arithmetic)")
    parser.add_argument("--jobs", type=int, default=2,
                        help="processes for the aberration scans, one panel each (default 2: a process "
                             "uses one core; 1: the panels in turn, in this process)")
    parser.add_argument("--peak-method", default="adaptive",
                        help="continuous VSOTF peak refinement (lfjax.vision.peaks): adaptive (default: "
                             "refine only where the grid's estimate may be 0.01 D off) or auto (Newton everywhere)")
    args = parser.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    if args.part == "report":
        rows = _read_csv(args.out / "aberrations.csv")
        fig_aberrations(summarise(rows), args.out / "lenslet_aberrations.png")
        if (args.out / "phone_curves.npz").exists():
            from phone_array import fig_from_files  # noqa: E402

            fig_from_files(args.out)
        print(report(args.out))
        return 0
    header("lenslet aberrations and the phone class (issue #38, items 3-4)")
    t0 = time.time()
    if args.part in ("aberrations", "both"):
        if args.jobs > 1 and len(args.panels) > 1:
            rows = run_panels_apart(args)
        else:
            rows = run_aberrations(args.panels, args.eyes, args.out, args.sampling, args.peak_method)
        summary = summarise(rows)
        for s in summary:
            print({k: (round(v, 4) if isinstance(v, float) else v) for k, v in s.items()})
        for t in thresholds(summary):
            print("threshold", t)
        fig_aberrations(summary, args.out / "lenslet_aberrations.png")
        print(f"aberrations: {time.time() - t0:.0f} s, peak RSS {peak_rss_mb():.0f} MiB", flush=True)
    if args.part in ("phone", "both"):
        from phone_array import run_phone  # noqa: E402  (benchmarks/studies/phone_array.py)

        run_phone(args.phone_eyes, args.out, args.peak_method)
    report(args.out)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
