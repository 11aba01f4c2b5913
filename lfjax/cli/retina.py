"""``lfjax retina``: the retinal image of a scene with depth through a light-field display or in
natural viewing (:func:`lfjax.vision.scene_images.retinal_scene`)."""

from __future__ import annotations

import argparse
import json
import sys

import numpy as np

from lfjax.base.errors import ParameterError
from lfjax._version import stamp
from lfjax.base.files import check_output_folder, staged_output
from lfjax.cli import common, flags
from lfjax.display.panel import PRESETS
from lfjax.display.spectra import DISPLAY_NAMES
from lfjax.model.eyes import average_eye, sample_eyes
from lfjax.model.layouts import grid_layout
from lfjax.vision.scene_files import read_depth_map_scene, read_layers_file, save_retina_figure
from lfjax.vision.scene_images import (LayeredScene, check_scene_memory, demo_scene,
                                       retinal_scene)
from lfjax.vision.viewing import Viewing

COMMAND = "retina"
DISPLAY_CHOICES = ("natural", "2x2", "3x3", "4x4") + tuple(PRESETS)
DEMO_SIZE, N_LAYERS, CDP_D = 256, 8, 2.0  # --size, --n-layers and --cdp where they apply
DEMO_DEPTHS = 3  # the --demo scene's distinct depths (demo_scene)


def add_parser(sub) -> None:
    rp = sub.add_parser(
        COMMAND,
        help="retinal image of a scene with depth, through a light-field display or natural "
             "viewing; retina.png, retina.npy, retina.json",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description=(
            "The retinal image of a scene with depth (lfjax.vision.scene_images). The scene is\n"
            "an image with a depth map (--image, --depth: the image an .npy of (3, H, W) or\n"
            "(H, W, 3) luminance per R, G, B primary or (H, W) grey, or an opaque .png (sRGB\n"
            "decoded to linear luminance); the depth map an .npy of (H, W) dioptres), layers at depths (--layers-file: an .npz with layers (n, 3, H, W)\n"
            "premultiplied colour, alpha (n, H, W) coverage and depths_D (n,) nearest first),\n"
            "or --demo (a synthetic scene at 4, 2 and 0.5 D). Each layer is blurred by its own\n"
            "polychromatic PSF per primary - the display's rendering of its depth, or a real\n"
            "surface there (--display natural) - and the layers are composited front to back\n"
            "with occlusion (each layer's coverage blurred with its own PSF attenuates what lies\n"
            "behind; partial occlusion at edges and the views' own perspectives are left out:\n"
            "see docs/guides/scene-blur.md). The eye is the Thibos et al. (2002) average eye or\n"
            "virtual eye N (--eye N, seed 0), accommodated at --accommodation D or by default at\n"
            "its predicted accommodation (continuous VSOTF peak) for the depth at the image\n"
            "centre (or --fixation D).\n\n"
            "Outputs in DIR: retina.png (scene and retinal image side by side), retina.npy\n"
            "(3, H, W) and retina.json (accommodation, layer depths, settings), all or none."
        ),
    )
    src = rp.add_mutually_exclusive_group(required=True)
    src.add_argument("--image", metavar="IMG",
                     help="image, .npy or .png (with --depth); luminance, real and >= 0")
    src.add_argument("--layers-file", metavar="LAYERS.npz",
                     help=".npz with layers, alpha and depths_D (nearest first)")
    src.add_argument("--demo", action="store_true", help="the synthetic three-depth scene")
    rp.add_argument("--depth", metavar="DEPTH.npy",
                    help="depth map of --image, D, .npy of the image's shape")
    rp.add_argument("--size", metavar="N", type=flags.positive_int, default=None,
                    help=f"pixels across the --demo scene (default {DEMO_SIZE})")
    rp.add_argument("--n-layers", metavar="N", type=flags.positive_int, default=None,
                    help=f"layers cut from a depth map (--image or --demo; default {N_LAYERS})")
    rp.add_argument("--pixel-arcmin", metavar="A", type=flags.finite_float, default=1.0,
                    help="visual angle of one scene pixel, arcmin (default 1)")
    rp.add_argument("--display", choices=DISPLAY_CHOICES, default="3x3",
                    help="natural viewing, the paper's n x n views (CDP --cdp) or a panel preset "
                         "(its own CDP, lenslet diffraction and pixels) (default 3x3)")
    rp.add_argument("--cdp", metavar="D", type=flags.finite_float, default=None,
                    help=f"CDP of the n x n layouts, D (default {CDP_D:g}); a panel preset has its "
                         "own, natural viewing none")
    rp.add_argument("--primaries", choices=DISPLAY_NAMES, default="oled",
                    help="the display's primaries (default oled)")
    rp.add_argument("--eye", metavar="N", default="average",
                    help="'average' (default) or the index of a Thibos virtual eye (seed 0)")
    rp.add_argument("--accommodation", metavar="D", type=flags.finite_float, default=None,
                    help="accommodation, D (default: the eye's predicted one)")
    rp.add_argument("--fixation", metavar="D", type=flags.finite_float, default=None,
                    help="fixated depth for the predicted accommodation, D (default: the depth "
                         "at the image centre)")
    rp.add_argument("--no-occlusion", action="store_true",
                    help="add the layers instead of compositing them with occlusion")
    flags.add_out(rp, "lfjax-retina", "output folder (default lfjax-retina)")
    flags.add_force(rp, "write into a non-empty --out (files of the same names are replaced)")


def _eye(text: str):
    if text == "average":
        return average_eye(3.0)
    try:
        index = int(text)
    except ValueError:
        index = -1
    if index < 0:
        raise ParameterError("eye", "{eye} must be 'average' or an eye index >= 0, got {got!r}",
                             got=text)
    return sample_eyes(0, index + 1, 3.0)[index:index + 1]


def check_combinations(args) -> None:
    """Each flag given applies to the scene and display asked for (none is ignored), or a
    ``ParameterError`` naming it; fills in the defaults of those that apply."""
    source = "--demo" if args.demo else "--layers-file" if args.layers_file else "--image"
    if args.depth is not None and source != "--image":
        raise ParameterError("depth_map_D", "{depth_map_D} is the depth map of {image}; "
                             "{source} brings its own depths", source=source)
    if args.size is not None and source != "--demo":
        raise ParameterError("size", "{size} sets the --demo scene's pixels; {source} has its "
                             "own", source=source)
    if args.n_layers is not None and source == "--layers-file":
        raise ParameterError("n_layers", "{n_layers} cuts a depth map into layers; "
                             "--layers-file gives the layers")
    if args.cdp is not None and (args.display == "natural" or args.display in PRESETS):
        raise ParameterError("cdp_D", "{cdp_D} sets the CDP of the n x n layouts (--display "
                             "2x2, 3x3, 4x4); {which}", which="natural viewing has none"
                             if args.display == "natural" else
                             f"the panel preset {args.display!r} has its own")
    args.size = DEMO_SIZE if args.size is None else args.size
    args.n_layers = N_LAYERS if args.n_layers is None else args.n_layers
    args.cdp = CDP_D if args.cdp is None else args.cdp


def _scene(args) -> LayeredScene:
    if args.demo:
        # from the size alone, before the demo's arrays are made
        check_scene_memory((args.size, args.size), min(args.n_layers, DEMO_DEPTHS),
                           parameter="size")
        return LayeredScene.from_depth_map(*demo_scene(args.size), args.pixel_arcmin,
                                           args.n_layers)
    if args.layers_file:
        return read_layers_file(args.layers_file, args.pixel_arcmin)
    return read_depth_map_scene(args.image, args.depth, args.pixel_arcmin, args.n_layers)


def _display(name: str):
    if name == "natural":
        return "natural"
    if name in PRESETS:
        return PRESETS[name]()
    return grid_layout(int(name[0]))


def output_bytes(shape) -> int:
    """Room ``lfjax retina`` asks of its output folder's disk before any work, bytes, for a
    scene of ``shape`` (H, W) pixels: retina.npy (3 × H × W, 8 bytes allowed per value),
    retina.png (880 × 462 pixels whatever the scene: under 2 MB) and retina.json, with
    4 MiB of margin."""
    height, width = (int(n) for n in shape)
    return 3 * height * width * 8 + 4 * 2**20


def run(args) -> int:
    prog = f"{common.PROG} {COMMAND}"
    def work():
        check_combinations(args)
        check_output_folder(args.out, args.force, parameter="out_dir")
        eye = _eye(args.eye)
        scene = _scene(args)
        # room for the outputs, known with the scene's size: before the retinal image
        out = check_output_folder(args.out, args.force, parameter="out_dir",
                                  need_bytes=output_bytes(scene.layers.shape[-2:]))
        display = _display(args.display)
        result = retinal_scene(eye, scene, viewing=Viewing(cdp_D=args.cdp), display=display,
                               primaries=args.primaries, accommodation_D=args.accommodation,
                               fixation_D=args.fixation, occlusion=not args.no_occlusion,
                               progress=lambda line: print(f"{prog}: {line}", file=sys.stderr,
                                                           flush=True))
        return out, scene, result

    done, status = common.guarded(prog, COMMAND, work)
    if status is not None:
        return status
    out, scene, result = done
    retina = np.asarray(result["retina"])
    summary = dict(accommodation_D=result["accommodation_D"], fixation_D=result["fixation_D"],
                   layer_depths_D=[float(d) for d in result["depths_D"]],
                   freq_step_cpd=result["freq_step_cpd"], display=args.display,
                   primaries=args.primaries, eye=args.eye, pixel_arcmin=args.pixel_arcmin,
                   occlusion=not args.no_occlusion, command=common.command_line(args.argv),
                   provenance=stamp())
    def write() -> None:
        with staged_output(out, args.force) as tmp:
            np.save(tmp / "retina.npy", retina)
            (tmp / "retina.json").write_text(json.dumps(summary, indent=1) + "\n")
            save_retina_figure(tmp / "retina.png", scene, retina,
                               f"{args.display}, eye {args.eye} at {result['accommodation_D']:.2f} D "
                               f"(fixating {result['fixation_D']:.2f} D), {args.primaries} primaries")

    _, status = common.guarded(prog, COMMAND, write, refused=())
    if status is not None:
        return status
    print(f"{prog}: eye {args.eye} at {result['accommodation_D']:.3f} D (fixating "
          f"{result['fixation_D']:.2f} D), {len(result['depths_D'])} layers; wrote retina.png, "
          f"retina.npy, retina.json to {out}")
    return 0
