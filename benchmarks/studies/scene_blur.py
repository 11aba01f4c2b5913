"""The blur of the rest of the scene and its colour cue over a population (issue 39), and the
figures of the results page: the authors' question for the average eye (PSFs), the population
figure and table, and retinal images of a three-depth scene, display against natural.

    python benchmarks/studies/scene_blur.py [--eyes 100] [--seed 0] [--out benchmarks/studies/scene_blur]

The default is the issue's 100 eyes (average eye + 99 Thibos et al. 2002 eyes, 3 mm);
``--eyes 1`` runs the average eye alone.
"""

from __future__ import annotations

import argparse
import json
import resource
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import matplotlib  # noqa: E402

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from _common import header  # noqa: E402
from lfjax.model.eyes import append_average_eye, average_eye, sample_eyes  # noqa: E402
from lfjax.model.layouts import grid_layout  # noqa: E402
from lfjax.studies.scene_blur import (  # noqa: E402
    MEASURES,
    SceneBlurConfig,
    cue_agreement,
    run_scene_blur,
    save_scene_blur_figures,
    scene_blur_table,
)
from lfjax.vision import scene_images as si  # noqa: E402
from lfjax.vision.images import psf_on_grid  # noqa: E402
from lfjax.vision.scene_blur import rest_of_scene  # noqa: E402


def psf_figure(out: Path) -> str:
    """The authors' question for the average eye: CDP 2 D, fixated 4 D, a point at 0 D."""
    eye = average_eye(3.0)
    rows = [("natural", None)] + [(f"{n}x{n}", grid_layout(n)) for n in (2, 3, 4)]
    fig, ax = plt.subplots(len(rows), 3, figsize=(7.5, 2.4 * len(rows)))
    from lfjax.vision.scene_images import predicted_accommodation
    a_display = {}
    for r, (name, layout) in enumerate(rows):
        a = predicted_accommodation(eye, layout, 4.0, cdp_D=2.0)
        a_display[name] = a
        res = rest_of_scene(eye, layout, a, [0.0], "oled", cdp_D=2.0,
                            grid_defocus_D=np.round(np.arange(-5.5, -1.5, 0.1), 6))
        psf = np.asarray(psf_on_grid(res["display_otf"][:, 0], res["freq_step_cpd"], 0.5, 81))
        for c, colour in enumerate(("red", "green", "blue")):
            ax[r, c].imshow(psf[c], origin="lower", cmap="magma",
                            extent=[-20.25, 20.25, -20.25, 20.25])
            ax[r, c].set_xticks([]), ax[r, c].set_yticks([])
            if r == 0:
                ax[r, c].set_title(colour)
        ax[r, 0].set_ylabel(f"{name}\na = {a:.2f} D\neq. {res['equivalent_defocus_D'][0]:+.2f} D",
                            fontsize=8)
    fig.suptitle("A point at 0 D, the eye at its predicted accommodation for a point rendered "
                 "at 4 D\n(CDP 2 D; natural row: a real point at 4 D fixated; 40 arcmin "
                 "fields; 'eq.': equivalent natural defocus, true −a)", fontsize=8)
    fig.tight_layout()
    path = out / "scene_blur_psf_0D.png"
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return str(path)


def scene_figure(out: Path, n: int = 192) -> str:
    """A scene at three depths (4, 2, 0.5 D), display (3×3, CDP 2 D) against natural, both with
    the eye at the 3×3 display's predicted accommodation for the mid depth."""
    eye = average_eye(3.0)
    img, depth = si.demo_scene(n)
    a = si.predicted_accommodation(eye, grid_layout(3), 2.0, cdp_D=2.0)
    panels = [("scene", np.moveaxis(img, 0, -1))]
    for name, display in (("natural", "natural"), ("3x3 display", grid_layout(3)),
                          ("2x2 display", grid_layout(2))):
        r = si.retinal_scene(eye, si.LayeredScene.from_depth_map(img, depth, 0.75),
                             display=display, accommodation_D=a)
        panels.append((name, np.clip(np.moveaxis(np.asarray(r["retina"]), 0, -1), 0, 1)))
    fig, ax = plt.subplots(1, len(panels), figsize=(3.2 * len(panels), 3.5))
    for k, (name, im) in enumerate(panels):
        ax[k].imshow(im, origin="lower")
        ax[k].set_title(name, fontsize=9)
        ax[k].set_xticks([]), ax[k].set_yticks([])
    fig.suptitle(f"Depths 4 D (block), 2 D (grating), 0.5 D (checkerboard); eye at {a:.2f} D "
                 f"(fixating 2 D), {n * 0.75:.0f} arcmin wide, OLED primaries", fontsize=9)
    fig.tight_layout()
    path = out / "scene_blur_retina.png"
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return str(path)


def _replace_rows(out: Path, part: dict, seconds: float, n_eyes: int) -> tuple[dict, float]:
    """The results in ``out`` with the displays of ``part`` computed again (same eyes)."""
    meta = json.loads((out / "scene_blur.json").read_text())
    if meta["n_eyes"] != n_eyes:
        raise SystemExit(f"{out} holds {meta['n_eyes']} eyes; rerun rows with --eyes {meta['n_eyes']}")
    whole = dict(np.load(out / "scene_blur.npz"))
    names = list(meta["config"]["displays"])
    labels = list(meta["labels"])
    for j, name in enumerate(part["config"]["displays"]):
        i = names.index(name)
        for key in MEASURES + ("true_defocus_D", "accommodation_D", "cdp_D"):
            whole[key][i] = part[key][j]
        labels[i] = part["labels"][j]
    config = dict(meta["config"], accommodation_offsets_D=part["config"]["accommodation_offsets_D"])
    print(f"replaced the rows of {', '.join(part['config']['displays'])} ({seconds:.0f} s); "
          f"the other displays as computed before ({meta['seconds']:.0f} s)")
    return {**whole, "labels": labels, "config": config}, meta["seconds"]


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("--eyes", type=int, default=100)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--out", default=str(Path(__file__).resolve().parent / "scene_blur"))
    p.add_argument("--skip-figures", action="store_true")
    p.add_argument("--displays", nargs="+", default=None, metavar="NAME",
                   help="compute only these displays and replace their rows in OUT's results "
                        "(the same eyes: --eyes and --seed as the run that wrote them)")
    args = p.parse_args()
    header("blur of the rest of the scene")
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    eyes = average_eye(3.0)
    if args.eyes > 1:
        eyes = append_average_eye(sample_eyes(args.seed, args.eyes - 1, 3.0))
    t0 = time.perf_counter()
    config = SceneBlurConfig() if args.displays is None else SceneBlurConfig(
        displays=tuple(args.displays))
    result = run_scene_blur(eyes, config)
    seconds = time.perf_counter() - t0
    if args.displays is not None:
        result, seconds = _replace_rows(out, result, seconds, eyes.n_eyes)
    arrays = {k: v for k, v in result.items() if isinstance(v, np.ndarray)}
    np.savez(out / "scene_blur.npz", **arrays)
    (out / "scene_blur.json").write_text(json.dumps(
        dict(labels=result["labels"], config=result["config"], seconds=seconds,
             n_eyes=eyes.n_eyes), indent=1))
    table = scene_blur_table(result)
    (out / "scene_blur_table.md").write_text(table + "\n")
    print(table)
    print("cue sign kept (fraction of eyes), display × depth:")
    print(np.round(cue_agreement(result), 2))
    print(f"{eyes.n_eyes} eyes × {len(result['labels'])} displays × {result['depths_D'].size} "
          f"depths in {seconds:.0f} s")
    if not args.skip_figures:
        paths = save_scene_blur_figures(result, out)
        if args.displays is None:  # neither figure reads the population's rows
            paths.append(psf_figure(out))
            paths.append(scene_figure(out))
        print("figures:", *paths)
    rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(f"peak RSS {rss:.0f} MiB")


if __name__ == "__main__":
    main()
