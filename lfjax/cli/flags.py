"""The flags of ``lfjax``'s subcommands, declared once: the parameter↔flag table
(:data:`FLAGS`) through which a library check's
:class:`~lfjax.base.errors.ParameterError` names the flag, the argument types, and the
flags several subcommands share.
"""

from __future__ import annotations

import argparse
import math

FLAGS: dict[str, dict[str, str]] = {
    "reproduce": {
        "out": "--out", "force": "--force", "n_eyes": "--eyes", "seed": "--seed",
        "accuracy": "--accuracy", "population_store": "--population",
        "display_effects_eyes": "--display-eyes",
    },
    "optimise": {
        # lfjax.layout_opt.OptimisationSettings, field by field
        "n_views": "--views", "lattice": "--lattice", "parametrisation": "--parametrisation",
        "objective": "--objective", "accommodation_tolerance_D": "--accommodation-tolerance",
        "depth_range_D": "--depths", "n_depths": "--n-depths", "cdp_D": "--cdp",
        "pupil_diameter_mm": "--pupil", "max_diameter_mm": "--max-diameter",
        "min_diameter_mm": "--min-diameter", "containment": "--containment",
        "non_overlap": "--non-overlap", "train_eyes": "--train-eyes", "test_eyes": "--test-eyes",
        "seed": "--seed", "wavelengths_nm": "--wavelengths",
        "display_distance_mm": "--display-distance", "pixel_width_arcmin": "--pixel-arcmin",
        "spectrum": "--spectrum", "freq_step_cpd": "--freq-step", "method": "--solver",
        "steps": "--steps", "report_accuracy": "--report-accuracy", "front": "--front",
        # the library calls those fields reach: lattice_sites, display_optics_at, display_primaries
        "kind": "--lattice", "distance_mm": "--display-distance", "name": "--spectrum",
        # lfjax.layout_opt.optimise_and_save
        "out_dir": "--out", "force": "--force",
    },
    "sweep": {
        "store": "--out", "resume": "--resume", "max_chunks": "--max-chunks",
        "config": "CONFIG.toml",
        # lfjax.sweep.distributed.start_distributed
        "coordinator_address": "--coordinator", "num_processes": "--num-processes",
        "process_id": "--process-id", "timeout_s": "--distributed-timeout",
    },
    "sweep-report": {
        "store_path": "STORE", "out_dir": "--out", "draws": "--draws", "seed": "--seed",
    },
    "design": {
        # lfjax.design.design_cdp_D and design_panel
        "depth_range_D": "--depths", "cdp_D": "--cdp", "preset": "--panel",
        "distance_mm": "--distance", "pixel_pitch_mm": "--pixel-pitch",
        "pixel_count": "--pixel-count", "diffraction": "--diffraction",
        # lfjax.design.DesignConstraints (its min_gap_fraction is not a flag)
        "min_eye_box_mm": "--min-eye-box", "min_fill": "--min-fill",
        "min_f_number": "--f-number", "max_f_number": "--f-number",
        "lens_form": "--lens-form", "refractive_index": "--refractive-index",
        "distance_range_mm": "--distance-range", "lenticular": "--lenticular",
        # lfjax.design.check_design (fit_design's checks) and Sampling
        "n_depths": "--n-depths", "views_per_side": "--views", "wavelengths_nm": "--wavelengths",
        "steps": "--steps", "report_accuracy": "--report-accuracy", "freq_step_cpd": "--freq-step",
        "report_counts": "--report-counts",
        # lfjax.layout_opt.EyeDraw
        "seed": "--seed", "train_eyes": "--train-eyes", "test_eyes": "--test-eyes",
        # lfjax.base.files.check_output_folder
        "out_dir": "--out", "force": "--force",
    },
    "retina": {
        # lfjax.vision.scene_images.retinal_scene and LayeredScene, lfjax.vision.viewing.Viewing
        # and the scene's files (lfjax.vision.scene_files)
        "image": "--image", "depth_map_D": "--depth", "layers_file": "--layers-file",
        "layers": "--layers-file", "alpha": "--layers-file", "depths_D": "--layers-file",
        "n_layers": "--n-layers", "pixel_arcmin": "--pixel-arcmin", "display": "--display",
        "primaries": "--primaries", "eye": "--eye", "accommodation_D": "--accommodation",
        "fixation_D": "--fixation", "cdp_D": "--cdp", "occlusion": "--no-occlusion",
        "size": "--size", "out_dir": "--out", "force": "--force",
    },
}
"""The one parameter↔flag table: for each subcommand, the library parameter a check names
(:attr:`~lfjax.base.errors.ParameterError.parameters`) → the flag (or positional) that
sets it. tests/cli/test_cli.py checks that it covers every parameter the subcommand's library
calls can name and that every flag in it exists."""


def whole_number(text: str, lowest: int, below: int | None = None, allowed: str = "") -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number, got {text!r}") from None
    if value < lowest or (below is not None and value >= below):
        raise argparse.ArgumentTypeError(f"must be {allowed or f'>= {lowest}'}, got {value}")
    return value


def positive_int(text: str) -> int:
    """Whole number >= 1."""
    return whole_number(text, 1)


def count(text: str) -> int:
    """Whole number >= 0."""
    return whole_number(text, 0)


def seed(text: str) -> int:
    return whole_number(text, 0, 2**32, "in 0 … 4294967295")


def finite_float(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"must be finite, got {text!r}")
    return value


# ----------------------------------------------------------------------------- shared flags


def add_out(parser, default: str | None, help: str, metavar: str = "DIR") -> None:
    parser.add_argument("--out", metavar=metavar, default=default, help=help)


def add_force(parser, help: str) -> None:
    parser.add_argument("--force", action="store_true", help=help)


def add_no_progress(parser, help: str = "do not show the progress bar (on stderr)") -> None:
    parser.add_argument("--no-progress", action="store_true", help=help)


def add_seed(parser, help: str) -> None:
    parser.add_argument("--seed", metavar="S", type=seed, default=0, help=help)


def add_eyes(parser, train_default: int, test_default: int, test_help: str) -> None:
    """--train-eyes, --test-eyes and --seed of a fit scored on held-out eyes."""
    parser.add_argument("--train-eyes", metavar="N", type=positive_int, default=train_default,
                        help=f"training eyes, >= 1 (default {train_default})")
    parser.add_argument("--test-eyes", metavar="N", type=count, default=test_default,
                        help=test_help)
    add_seed(parser, "training eyes from seed S, held-out eyes from S+1 (default 0)")


def add_depths(parser, default, n_default: int, help: str) -> None:
    """--depths LOW HIGH and --n-depths K of a rendered depth range."""
    required = default is None
    parser.add_argument("--depths", metavar=("LOW", "HIGH"), nargs=2, type=finite_float,
                        default=default, required=required,
                        help=f"required: {help}" if required else help)
    parser.add_argument("--n-depths", metavar="K", type=positive_int, default=n_default,
                        help=f"rendered depths evenly spanning the range, >= 2 (default {n_default})")


def add_fit_setting(parser, steps_default: int, steps_help: str, wavelengths_help: str,
                    report_help: str, freq_step_help: str, report_choices=("full", "fit"),
                    report_default: str = "full") -> None:
    """--wavelengths, --steps, --report-accuracy and --freq-step of a fit and its report."""
    parser.add_argument("--wavelengths", metavar="NM", nargs="+", type=finite_float,
                        default=[550.0], help=wavelengths_help)
    parser.add_argument("--steps", metavar="N", type=count, default=steps_default, help=steps_help)
    parser.add_argument("--report-accuracy", choices=tuple(report_choices), default=report_default,
                        help=report_help)
    parser.add_argument("--freq-step", metavar="CPD", type=finite_float, default=None,
                        help=freq_step_help)


__all__ = ["FLAGS", "whole_number", "positive_int", "count", "seed", "finite_float", "add_out",
           "add_force", "add_no_progress", "add_seed", "add_eyes", "add_depths",
           "add_fit_setting"]
