"""Session set-up for the lfjax test suite.

* float64 everywhere (``jax_enable_x64``): the physics checks and the finite-difference
  gradient checks need it. lfjax follows ``jnp.result_type(float)``, so it computes in
  float64 here; the float32 accuracy statement (kernel/test_optics.py) runs inside
  ``jax.enable_x64(False)``.
* XLA's CPU backend optimisation level 0 and, on jaxlib 0.6 or newer, its older
  (non-MLIR) fusion emitters (``--xla_cpu_use_fusion_emitters=false``): this suite is
  dominated by compiling many programs (each distinct shape or static option recompiles);
  level 0 compiles them 2-3x faster, and the older emitters take about a third off the CPU
  time of the heaviest files again (tests/vision/test_peaks.py: 294 → 192 s); neither
  changes a result beyond round-off. Each is added unless ``XLA_FLAGS`` already names it;
  the notebooks' kernels and the command-line subprocesses inherit them.
* Shapes in the types are checked (``LFJAX_SHAPE_CHECKS=1``, before lfjax is imported): the
  public numerical entry points check their jaxtyping annotations with beartype at every
  call (``lfjax.base.types.shape_checked``).
* Expensive results shared by several test files are session fixtures here (each costs
  one XLA compile); cheap module-level inputs live in ``helpers.py``.
* Python's cyclic garbage collector runs less often (first generation every 20,000
  allocations, not 700) once everything is imported (``gc.freeze``): tracing a program
  through JAX's transformations allocates millions of short-lived objects, tracing is most
  of what each compile costs here, and the default thresholds spend about a tenth of it
  collecting. No result depends on when garbage is collected.
* The heaviest test files are handed to the pytest-xdist workers first
  (``HEAVY_FIRST``, with ``--no-loadscope-reorder`` in pyproject's addopts; the others
  follow, most tests first, as xdist itself orders them): whole files run on one worker
  (``--dist loadfile``), so a heavy file started last would leave the other worker idle
  for its whole length.
* One compilation cache per test session, shared by every process the session starts (the
  pytest-xdist workers, the notebooks' kernels, the command-line subprocesses), and empty
  at its start: a program one of them compiled is read back by the others, and nothing is
  read from the user's own cache (``~/.cache/lfjax``), so a run's time and results do not
  depend on what ran before it. ``LFJAX_TEST_CACHE_DIR`` names another folder to keep it.
"""

from __future__ import annotations

import os

def _jaxlib_at_least(major: int, minor: int) -> bool:
    """Whether the installed jaxlib is at least ``major.minor`` (read from its metadata,
    before jax is imported). XLA aborts the process on a flag it does not know, and
    ``xla_cpu_use_fusion_emitters`` is newer than the oldest jaxlib lfjax accepts."""
    import re
    from importlib.metadata import PackageNotFoundError, version

    try:
        found = re.match(r"(\d+)\.(\d+)", version("jaxlib"))
    except PackageNotFoundError:
        return False
    return bool(found) and (int(found[1]), int(found[2])) >= (major, minor)


_FLAGS = [("xla_backend_optimization_level", "0")]
if _jaxlib_at_least(0, 6):
    _FLAGS.append(("xla_cpu_use_fusion_emitters", "false"))
for _flag, _value in _FLAGS:
    if _flag not in os.environ.get("XLA_FLAGS", ""):
        os.environ["XLA_FLAGS"] = (
            os.environ.get("XLA_FLAGS", "") + f" --{_flag}={_value}"
        ).strip()

os.environ.setdefault("LFJAX_SHAPE_CHECKS", "1")


def _session_cache() -> tuple[str, bool]:
    """The session's compilation cache folder, and whether this process made it (the xdist
    controller, or a plain pytest run; every process it starts inherits the folder)."""
    folder = os.environ.get("LFJAX_TEST_CACHE_DIR")
    if folder:
        return folder, False
    import tempfile

    folder = tempfile.mkdtemp(prefix="lfjax-test-cache-")
    os.environ["LFJAX_TEST_CACHE_DIR"] = folder
    return folder, True


_CACHE, _MADE_CACHE = _session_cache()
os.environ["JAX_COMPILATION_CACHE_DIR"] = _CACHE  # this process and the workers
os.environ["LFJAX_CACHE_DIR"] = _CACHE  # the command line's subprocesses and the notebooks
os.environ.setdefault("JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS", "0.5")

import jax  # noqa: E402

jax.config.update("jax_enable_x64", True)

import numpy as np  # noqa: E402
import pytest  # noqa: E402

import lfjax  # noqa: E402
from lfjax.vision.focus import through_focus  # noqa: E402

import helpers as H  # noqa: E402
from lfjax.vision.prepare import States
from lfjax.vision.viewing import Viewing

import gc  # noqa: E402

gc.freeze()
gc.set_threshold(20_000, 50, 100)

@pytest.fixture(scope="session")
def dl_convergence():
    """OTFs at 550 nm (no SCE/SA/LCA) of the eyes of ``helpers.marechal_eyes`` (row 0
    aberration-free, then single Zernike modes) through 3, 1.5 and 0.75 mm pupils, all on
    ONE grid (Sampling(1 cpd, n_fft=200, edge 0.25 samples)) so one compile serves all;
    pupil samples across N_p = d / (λ df) = 95.2, 47.6, 23.8.

    Returns {pupil_mm: (row-0 full-plane OTF (L, L), N_p, max axis error of row 0 vs the
    analytic MTF)} and "stacks": {pupil_mm: half-plane OTFs (n_eyes, 1, 1, L, L//2+1)}.
    """
    sampling = lfjax.Sampling(1.0, n_fft=200, edge_width_samples=0.25)
    out = {"stacks": {}}
    for d in (3.0, 1.5, 0.75):
        stack = lfjax.polychromatic_otf(
            H.marechal_eyes(),
            [2.0],
            lfjax.Viewing(pupil_diameter_mm=d, cdp_D=2.0),
            spectrum=H.spectrum_550_plain(),
            sampling=sampling,
            options=H.PLAIN,
        )
        otf = np.asarray(stack.full_plane())[0, 0, 0]
        out["stacks"][d] = np.asarray(stack.otf)
        out[d] = (otf, H.pupil_samples(d, 550.0, 1.0), H.dl_axis_error(otf, 1.0, d, 550.0))
    return out


@pytest.fixture(scope="session")
def natural_tf():
    """Natural-view through focus at 550 nm (LCA = 0 there), accommodation SA off, SCE on.

    Eyes: [aberration-free, myopic +1 D (c(2,0) = +0.3248 µm), hyperopic −1 D]; depths
    [0, 2] D (CDP 2 D); offsets −1.2 … +1.2 D in 0.2 D steps relative to each depth (the
    hyperopic limit masks the negative states of depth 0).
    """
    options = lfjax.ModelOptions(accommodation_sa="off")
    spectrum = lfjax.make_spectrum([550.0], options)
    offsets = np.round(np.arange(-6, 7) * 0.2, 9)
    return through_focus(
        H.defocus_eyes(),
        None,
        States.around([0.0, 2.0], offsets),
        Viewing(pupil_diameter_mm=3.0, cdp_D=2.0),
        spectrum=spectrum,
        sampling=lfjax.Sampling(1.5),
        options=options,
    )


def _physics_tf(n):
    """Aberration-free eye, n×n viewpoints in a 3 mm pupil, CDP 2 D, rendered 0, 2, 4 D,
    absolute accommodation 0 … 4.2 D (0.2 D) within ±2.2 D of each depth, 550 nm, paper
    options (SCE amplitude, accommodation SA scaled, paper VSOTF reference)."""
    options = lfjax.ModelOptions()
    grid = np.round(np.arange(0, 22) * 0.2, 9)
    return through_focus(
        lfjax.model.eyes.aberration_free_eye(),
        lfjax.grid_layout(n, 3.0),
        States.grid(grid, depths_D=[0.0, 2.0, 4.0], window_D=2.2),
        Viewing(pupil_diameter_mm=3.0, cdp_D=2.0),
        spectrum=lfjax.make_spectrum([550.0], options),
        sampling=lfjax.Sampling(1.25),
        options=options,
    )


@pytest.fixture(scope="session")
def tf_2x2():
    return _physics_tf(2)


@pytest.fixture(scope="session")
def tf_4x4():
    return _physics_tf(4)


HEAVY_FIRST = (
    "vision/test_peaks.py",
    "layout_opt/test_layout_opt.py",
    "sweep/test_sweep.py",
    "design/test_design_fit.py",
    "model/test_options.py",
    "cli/test_cli.py",
    "display/test_lenslets.py",
    "sweep/test_sweep_report.py",
    "planner/test_plan.py",
    "reproduce/test_alternatives.py",
    "test_docs.py",
    "kernel/test_streamed_views.py",
    "test_gpu_check.py",
)
"""Test files (relative to tests/) by CPU time, most first, from a whole run's
``--durations`` (each over about 35 s on two cores)."""


def pytest_collection_modifyitems(config, items):
    """Heaviest files first (``HEAVY_FIRST``), then the others by their number of tests,
    most first; a file's own tests keep their order (the sort is stable)."""
    from collections import Counter
    from pathlib import Path

    tests = Path(__file__).resolve().parent

    def name(item):
        path = Path(str(item.path))
        return path.relative_to(tests).as_posix() if path.is_relative_to(tests) else str(path)

    counts = Counter(name(item) for item in items)
    rank = {file: i for i, file in enumerate(HEAVY_FIRST)}
    items.sort(key=lambda item: (rank.get(name(item), len(rank)), -counts[name(item)]))


def pytest_sessionfinish(session, exitstatus):
    if _MADE_CACHE:
        import shutil

        shutil.rmtree(_CACHE, ignore_errors=True)
