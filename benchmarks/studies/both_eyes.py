"""The population answer of issue #53 at a reduced size: which viewers and rendered depths
a display keeps inside the zone of comfort (Shibata et al. 2011), against a stereo display.

Paper's scene: CDP 2 D, rendered depths 0–4 D (9), 3 mm pupil. Displays: natural viewing, a
stereo display with its screen at the CDP, near-eye light-field displays with 2×2, 3×3 and
4×4 views per eye. Viewers from ``lfjax.binocular.sample_viewers``: corrected pairs (no
anisometropia: the Thibos eyes are well corrected), the same viewers with the population's
uncorrected anisometropia (KNHANES 2010 law), and with a fixed 0.5, 1 and 2 D anisometropia
(right eye more hyperopic) for the near-eye 3×3 and the stereo display. Each eye's through-focus is computed once; the
combinations (mean VSOTF, better eye, dominant right eye) and the CA/C cross-link (0.13 D per
prism dioptre, Hirani & Firth 2009) are derived from the same curves.

    PYTHONPATH=. python benchmarks/studies/both_eyes.py --viewers 10 --out benchmarks/studies/both_eyes
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

import lfjax
from lfjax.binocular import (BinocularOptions, NaturalViewing, NearEyeDisplay, StereoDisplay,
                             binocular_through_focus, sample_viewers)
from lfjax.binocular.comfort import inside_zone, shibata_zone
from lfjax.binocular.focus import consensual_accommodation
from lfjax.binocular.geometry import cross_linked_accommodation_D
from lfjax.binocular.population import spherical_equivalent_per_um
from lfjax.binocular.viewer import binocular_statistics

DEPTHS = np.linspace(0.0, 4.0, 9)
CDP = 2.0
COMBINATIONS = {"mean VSOTF": BinocularOptions(),
                "better eye": BinocularOptions(combination="better_eye"),
                "dominant right eye": BinocularOptions(combination="dominant_eye")}


def summary(acc, ipd, ca_c=0.0):
    """Fraction inside per depth, the depths with ≥ 90 % inside, median conflict."""
    acc = np.asarray(cross_linked_accommodation_D(acc, DEPTHS[None], ipd[:, None], ca_c))
    inside = np.asarray(inside_zone(DEPTHS[None], shibata_zone(acc)))
    fraction = inside.mean(axis=0)
    return dict(fraction_inside=fraction.round(3).tolist(),
                depths_90_D=DEPTHS[fraction >= 0.9 - 1e-9].tolist(),
                median_conflict_D=np.median(DEPTHS[None] - acc, axis=0).round(3).tolist())


def run(n_viewers: int, seed: int, out: Path) -> dict:
    spectrum = lfjax.make_spectrum(np.arange(400.0, 701.0, 30.0))
    viewing = lfjax.Viewing(3.0, CDP)
    displays = {"natural": NaturalViewing(), "stereo (screen at 2 D)": StereoDisplay(CDP)}
    displays |= {f"near-eye {n}x{n}": NearEyeDisplay(lfjax.grid_layout(n)) for n in (2, 3, 4)}
    results, timing, viewers_of = {}, {}, {}
    groups = [("corrected", sample_viewers(seed, n_viewers, anisometropia_D=0.0), list(displays)),
              ("population anisometropia", sample_viewers(seed, n_viewers), list(displays))]
    groups += [(f"anisometropia {a:g} D", sample_viewers(seed, n_viewers, anisometropia_D=a),
                ["stereo (screen at 2 D)", "near-eye 3x3"]) for a in (0.5, 1.0, 2.0)]
    per_um = spherical_equivalent_per_um(3.0)
    for group, viewers, names in groups:
        ipd = np.asarray(viewers.ipd_mm, float)
        viewers_of[group] = dict(ipd_mm=ipd.round(2).tolist(), anisometropia_D=(per_um * np.asarray(
            viewers.right.zernike_um[:, 4] - viewers.left.zernike_um[:, 4])).round(3).tolist())
        for name in names:
            t = time.perf_counter()
            r = binocular_through_focus(viewers, displays[name], DEPTHS, viewing, spectrum=spectrum)
            timing[f"{group} / {name}"] = round(time.perf_counter() - t, 1)
            entry = {}
            for label, options in COMBINATIONS.items():
                acc, driver, _ = consensual_accommodation(r.left_vsotf, r.right_vsotf,
                                                          r.states_D, r.allowed, options)
                entry[label] = summary(acc, ipd)
                if label == "better eye":
                    entry[label]["right eye drives"] = float(np.mean(driver == 1))
            entry["mean VSOTF + CA/C 0.13"] = summary(r.accommodation_D, ipd,
                                                      binocular_statistics()["ca_c_D_per_prism_D"])
            entry["per viewer: conflict (D) at each depth, mean VSOTF"] = r.conflict_D.round(
                2).tolist()
            entry["per viewer: left, right VSOTF at the pair's accommodation, mean VSOTF"] = [
                r.left_vsotf_at_pair.round(3).tolist(), r.right_vsotf_at_pair.round(3).tolist()]
            results[f"{group} / {name}"] = entry
            print(group, "/", name, timing[f"{group} / {name}"], "s", flush=True)
    out.mkdir(parents=True, exist_ok=True)
    record = dict(n_viewers=n_viewers, seed=seed, depths_D=DEPTHS.tolist(), cdp_D=CDP,
                  wavelengths_nm=np.asarray(spectrum.wavelengths_nm).tolist(),
                  seconds=timing, viewers=viewers_of, results=results)
    (out / "both_eyes.json").write_text(json.dumps(record, indent=1))
    figure(results, out / "both_eyes.png", n_viewers)
    return record


def figure(results, path: Path, n_viewers: int) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(6.4, 3.8))
    for key, entry in results.items():
        if key.startswith("corrected"):
            ax.plot(DEPTHS, entry["mean VSOTF"]["fraction_inside"], marker="o",
                    label=key.split(" / ")[1])
    ax.axhline(0.9, color="grey", lw=0.8, ls="--")
    ax.set_xlabel("rendered depth (D); CDP / screen at 2 D")
    ax.set_ylabel("fraction of viewers inside\nthe zone of comfort")
    ax.set_title(f"{n_viewers} corrected viewers, Shibata et al. (2011) zone, mean-VSOTF "
                 "accommodation",
                 fontsize=9)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--viewers", type=int, default=10)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--out", type=Path, default=Path("benchmarks/studies/both_eyes"))
    args = parser.parse_args()
    t = time.perf_counter()
    record = run(args.viewers, args.seed, args.out)
    print(json.dumps(record["results"], indent=1))
    print(f"total {time.perf_counter() - t:.1f} s")


if __name__ == "__main__":
    main()
