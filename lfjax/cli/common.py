"""What every subcommand of ``lfjax`` shares: the flags declared once, the argument types,
the parameter↔flag table, the error and exit conventions, and the compilation cache.

Conventions: a usage error (a flag argparse refuses, or a value a library check refuses
before any work) prints one line and exits with status 2; a failure during the run prints
one line and exits with status 1 (``LFJAX_DEBUG=1`` lets the exception through); Ctrl-C
exits with status 130. A library check raises :class:`~lfjax.base.errors.ParameterError`
naming its parameter; :func:`refuse` names the flag instead, through :data:`FLAGS`.
"""

from __future__ import annotations

import argparse
import math
import os
import signal
import sys
import threading
from collections.abc import Callable
from pathlib import Path
from typing import TypeVar

import jax

from lfjax.base.errors import ParameterError
from lfjax.base.files import emergency_cleanup
from lfjax.base.programs import enable_program_cache
from lfjax.planner.cache import enable_plan_cache

PROG = "lfjax"

T = TypeVar("T")

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
        "out_dir": "--out", "force": "--force",
    },
}
"""The one parameter↔flag table: for each subcommand, the library parameter a check names
(:attr:`~lfjax.base.errors.ParameterError.parameters`) → the flag (or positional) that
sets it. tests/cli/test_cli.py checks that it covers every parameter the subcommand's library
calls can name and that every flag in it exists."""


# ----------------------------------------------------------------------------- errors


def message(err: BaseException, command: str | None = None, fold: bool = False) -> str:
    """``err``'s message; a :class:`ParameterError` names the flags of ``command``
    (:data:`FLAGS`). ``fold``: whitespace folded into one line (a list of problems, such as
    a sweep config's, keeps its lines otherwise)."""
    text = err.naming(FLAGS.get(command, {})) if isinstance(err, ParameterError) else str(err)
    return " ".join(text.split()) if fold else text


def refuse(prog: str, err: BaseException | str, command: str | None = None,
           fold: bool = False) -> int:
    """A value refused before any work (a usage error): said on stderr; exit status 2."""
    text = err if isinstance(err, str) else message(err, command, fold)
    print(f"{prog}: error: {text}", file=sys.stderr)
    return 2


def interrupted(prog: str, note: str = "") -> int:
    """Ctrl-C: one line on stderr; exit status 130."""
    print(f"{prog}: interrupted{note}", file=sys.stderr)
    return 130


INTERRUPT_GRACE_S = 1.5
"""Seconds a Ctrl-C'd run has to stop through its own clean-up (each ``except
KeyboardInterrupt`` and ``finally``: staging folders removed, locks released) before
:func:`exit_promptly_on_interrupt` ends it: a main thread inside a long XLA computation sees
the KeyboardInterrupt only when that computation returns."""

_STOPPED = threading.Event()  # the run has done its clean-up and is exiting


def exit_promptly_on_interrupt(prog: str, grace_s: float = INTERRUPT_GRACE_S) -> bool:
    """Make Ctrl-C (SIGINT) and SIGTERM end this process within ``grace_s`` seconds.

    Python runs its SIGINT handler (raising KeyboardInterrupt) only between bytecodes of the
    main thread, so a Ctrl-C during a compiled computation waited for it to finish. The C
    signal handler writes the signal to a wake-up pipe at once, though: a watcher thread
    reads it and, unless the main thread has finished its own clean-up within ``grace_s``
    (:func:`exit_now`), removes this process's unfinished outputs (the staging folders of
    :func:`lfjax.base.files.staged_output`) and releases its store locks
    (:func:`lfjax.base.files.emergency_cleanup`), says so, and exits with status 130. Only in
    the main thread of the real command (not when :func:`lfjax.cli.main` is called with
    ``argv``, as tests do); returns whether it was installed."""
    if threading.current_thread() is not threading.main_thread():
        return False
    if callable(signal.getsignal(signal.SIGINT)):
        # Python's own handler again (lfjax's start-up one exits at once, cleaning nothing)
        signal.signal(signal.SIGINT, signal.default_int_handler)
    read_end, write_end = os.pipe()
    os.set_blocking(write_end, False)
    try:
        signal.set_wakeup_fd(write_end, warn_on_full_buffer=False)
    except ValueError:
        return False
    stop_signals = {int(signal.SIGINT), int(signal.SIGTERM)}

    def watch() -> None:
        while True:
            try:
                received = os.read(read_end, 64)
            except OSError:
                return
            if not received:
                return
            if stop_signals.intersection(received) and not _STOPPED.wait(grace_s):
                emergency_cleanup()  # staging folders removed, store locks released
                print(f"{prog}: interrupted (stopped after {grace_s:g} s without waiting for "
                      f"the computation; unfinished outputs removed)", file=sys.stderr,
                      flush=True)
                os._exit(130)

    threading.Thread(target=watch, name="lfjax-interrupt-watch", daemon=True).start()
    previous_hook = sys.unraisablehook

    def unraisable(info) -> None:
        # a KeyboardInterrupt raised inside a garbage-collection callback (XLA's) is lost to
        # the main thread: the watcher ends the run, without a traceback on the way
        if info.exc_type is not None and issubclass(info.exc_type, KeyboardInterrupt):
            return
        previous_hook(info)

    sys.unraisablehook = unraisable
    return True


def exit_now(status: int) -> None:
    """End the real command with ``status`` once its clean-up is done, without the
    interpreter's shutdown: after a Ctrl-C, XLA's worker threads may still be running a
    computation, and tearing the runtime down under them crashed the process (a
    segmentation fault, exit -11, instead of 130). Output streams are flushed first."""
    _STOPPED.set()
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):
            pass
    os._exit(status)


def unexpected_error(prog: str, err: Exception, suffix: str = "") -> int:
    """An error no check foresaw: one line on stderr, no traceback (``LFJAX_DEBUG=1``
    re-raises it); exit status 1."""
    text = " ".join(str(err).split()) or type(err).__name__
    print(f"{prog}: error: {type(err).__name__}: {text}{suffix}", file=sys.stderr)
    if os.environ.get("LFJAX_DEBUG"):
        raise err
    return 1


def guarded(prog: str, command: str | None, work: Callable[[], T], *,
            note: str | Callable[[], str] = "", refused: tuple[type[Exception], ...] = (ValueError,),
            fold: bool = False,
            failed: Callable[[Exception], str | None] | None = None) -> tuple[T | None, int | None]:
    """Run a subcommand's work under the command line's conventions: ``(work(), None)``, or
    ``(None, status)`` after saying what stopped it in one line on stderr.

    Ctrl-C → :func:`interrupted` (130); an exception of a ``refused`` type → :func:`refuse`
    (2: a value found wrong once the work had begun, such as an output folder taken meanwhile);
    an exception ``failed`` gives a line for (a failure the command foresees, such as a full
    disk) → that line after ``prog: error:`` (1); any other exception →
    :func:`unexpected_error` (1, no traceback), its notes (``add_note``) in parentheses.
    ``note`` (or a function giving it, read when the work stops) says what was kept, e.g.
    "; nothing written"; it follows the interrupted and unexpected-error lines."""
    def said() -> str:
        return note() if callable(note) else note
    try:
        return work(), None
    except KeyboardInterrupt:
        return None, interrupted(prog, said())
    except refused as err:
        return None, refuse(prog, err, command, fold=fold)
    except Exception as err:  # one line, no traceback
        line = failed(err) if failed is not None else None
        if line is not None:
            print(f"{prog}: error: {line}", file=sys.stderr)
            return None, 1
        notes = " ".join(getattr(err, "__notes__", []))
        return None, unexpected_error(prog, err, said() + (f" ({notes})" if notes else ""))


class OneLineParser(argparse.ArgumentParser):
    """ArgumentParser whose errors are a single line (no usage block)."""

    def error(self, message: str):  # noqa: D401 - argparse API
        self.exit(2, f"{self.prog}: error: {message} (see --help)\n")


# ----------------------------------------------------------------------------- argument types


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
    parser.add_argument("--depths", metavar=("LOW", "HIGH"), nargs=2, type=finite_float,
                        default=default, required=default is None, help=help)
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


def command_line(argv: list[str]) -> str:
    """The command as run, for a result's provenance."""
    return " ".join([PROG, *argv])


# ----------------------------------------------------------------------------- compilation cache


def compilation_cache_dir() -> Path:
    """Folder of the persistent JAX compilation cache used by the command line.

    ``$LFJAX_CACHE_DIR`` if set, else ``$XDG_CACHE_HOME/lfjax/jax`` (default
    ``~/.cache/lfjax/jax``).
    """
    explicit = os.environ.get("LFJAX_CACHE_DIR")
    if explicit:
        return Path(explicit).expanduser()
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "lfjax" / "jax"


PLAN_FOLDER = "lfjax-plans"
"""Sub-folder of the compilation cache where the planner's plans are kept
(:mod:`lfjax.planner.cache`)."""


PROGRAM_FOLDER = "lfjax-programs"
"""Sub-folder of the compilation cache where exported programs are kept
(:mod:`lfjax.base.programs`)."""


def enable_compilation_cache(folder: Path | None = None) -> Path | None:
    """Turn on JAX's persistent compilation cache in ``folder`` (returns it, or None when
    the folder cannot be created), and keep the planner's plans in its ``lfjax-plans``
    sub-folder and the exported programs in ``lfjax-programs``. A second run then skips
    most compilation and tracing, and all planning."""
    folder = compilation_cache_dir() if folder is None else Path(folder)
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError:
        return None
    if not os.access(folder, os.W_OK):
        return None
    jax.config.update("jax_compilation_cache_dir", str(folder))
    jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.0)
    jax.config.update("jax_persistent_cache_min_entry_size_bytes", 0)
    # the planner's sampling plans beside the programs: a warm run re-plans nothing
    enable_plan_cache(folder / PLAN_FOLDER)
    # and the largest programs exported: a warm run does not trace them again
    enable_program_cache(folder / PROGRAM_FOLDER)
    return folder
