"""Sweep inputs bounded before anything is created: impossible values and sizes refused
with the numbers, no store left behind a failed start, the plan (--dry-run) and the
commented template (--template)."""

from __future__ import annotations

import tomllib

import numpy as np
import pytest

from lfjax.sweep import (
    SweepConfig,
    SweepConfigError,
    SweepTooLargeError,
    config_from_dict,
    estimate,
    load_config,
    run_sweep,
)
from lfjax.sweep.config_files import config_template
from lfjax.sweep.guard import check_fits
from lfjax.vision.prepare import States
from lfjax.vision.viewing import Viewing

ONE_EYE = {
    "population": {"n_eyes": 1, "seed": 3},
    "display": {"layouts": ["2x2"], "depth_offsets_D": [0.0]},
    "accommodation": {"step_D": 0.5, "window_D": 1.0},
    "spectrum": {"wavelengths_nm": [400.0, 700.0, 100.0]},
    "run": {"chunk_size": 1},
}


def one_eye(**sections) -> dict:
    data = {k: dict(v) for k, v in ONE_EYE.items()}
    for section, body in sections.items():
        data.setdefault(section, {}).update(body)
    return data


def toml_text(data: dict) -> str:
    from lfjax.sweep.config_keys import toml_value

    lines = []
    for section, body in data.items():
        lines.append(f"[{section}]")
        lines += [f"{k} = {toml_value(v)}" for k, v in body.items()]
    return "\n".join(lines) + "\n"


# ----------------------------------------------------------------------------- config values


@pytest.mark.parametrize("changes, message", [
    ({"population": {"pupil_diameters_mm": [0.01]}}, "must be >= 2 mm"),
    ({"spectrum": {"wavelengths_nm": [400.0, 700.0, 0.001]}}, "step must be >= 1 nm"),
    ({"accommodation": {"step_D": 1e-5}}, "at most 10000"),
    ({"accommodation": {"step_D": 1e-320}}, "at most 10000"),
])
def test_grids_and_pupils_outside_the_model_are_refused_with_the_range(changes, message):
    with pytest.raises(SweepConfigError) as err:
        config_from_dict(one_eye(**changes))
    assert message in str(err.value)


def test_every_key_is_declared_once_and_its_declared_range_is_enforced():
    """Each SweepConfig field (but options and base_dir) is one declared key: its type is
    the field's, its unit its name's suffix, its default the field's; every declared range
    or choice is refused just outside it, naming the key, and shows in the template and the
    docstring."""
    import dataclasses

    from lfjax.sweep.config import KEYS
    from lfjax.sweep.config_keys import OneOf, Range

    fields = [f.name for f in dataclasses.fields(SweepConfig)
              if f.name not in ("options", "base_dir")]
    assert [k.field for k in KEYS] == fields
    assert len({k.where for k in KEYS}) == len(KEYS)
    default = SweepConfig()
    template = " ".join(config_template().replace("#", " ").split())  # comments unwrapped
    doc = SweepConfig.__doc__
    for key in KEYS:
        assert getattr(default, key.field) == key.default, key.where
        assert key.unit == ("" if "_" not in key.name else
                            {"D": "D", "mm": "mm", "nm": "nm", "cpd": "cpd",
                             "arcmin": "arcmin", "um": "um"}.get(key.name.rsplit("_", 1)[1], "")), key.where
        assert f"[{key.section}] {key.name}``" in doc, key.where
        for check in key.checks:
            if isinstance(check, Range):
                outside = (check.lo - (0 if check.lo_open else 1) if check.lo is not None
                           else check.hi + (0 if check.hi_open else 1))
                bad = float(outside) if key.kind in ("float", "floats") else int(outside)
            elif isinstance(check, OneOf):
                bad = 5.5 if key.kind in ("float", "floats") else "nope"
            else:
                continue
            assert check.rule(key.unit) in template, (key.where, check.rule(key.unit))
            value = [bad] if key.kind in ("floats", "strings") else bad
            with pytest.raises(SweepConfigError) as err:
                config_from_dict(one_eye(**{key.section: {key.name: value}}))
            assert any(p.startswith(f"{key.where} must ") for p in err.value.problems), (
                key.where, err.value.problems)


def test_empty_config_file_and_a_folder_are_refused(tmp_path):
    empty = tmp_path / "empty.toml"
    empty.write_text("# nothing set yet\n")
    with pytest.raises(SweepConfigError, match="sets nothing.*--template"):
        load_config(empty)
    with pytest.raises(SweepConfigError, match="is a folder, not a TOML config file"):
        load_config(tmp_path)


def test_eyes_inputs_are_checked():
    import lfjax
    from lfjax.model.eyes import Eyes
    from lfjax.model.layouts import paper_layouts
    from lfjax.vision.focus import through_focus

    for seed in (-1, 2**32):
        with pytest.raises(ValueError, match=r"seed \(key\) must be in \[0, 2\*\*32\)"):
            lfjax.sample_eyes(seed, 2)
    with pytest.raises(ValueError, match="n_eyes must be <= 67108864"):
        lfjax.sample_eyes(0, 2**32)
    with pytest.raises(ValueError, match="at least one eye"):
        Eyes(np.zeros((0, 15)), 3.0)
    with pytest.raises(TypeError, match="eyes must be an lfjax.Eyes, got list"):
        through_focus(
            [[0.0] * 15],
            paper_layouts(3.0)["2x2"],
            States.around([2.0]),
            Viewing(pupil_diameter_mm=3.0, cdp_D=2.0),
        )


# ----------------------------------------------------------------------------- sizes


def test_estimate_counts_the_store_and_check_fits_names_the_numbers(tmp_path):
    config = config_from_dict(one_eye(population={"n_eyes": 999}))
    est = estimate(config)
    assert est.n_eyes == 1000 and est.n_accommodation == config.accommodation_D.size
    # vsotf and strehl (float32) alone: eyes x 1 pupil x 1 layout x 1 depth x states
    assert est.store_bytes > 2 * 4 * 1000 * config.accommodation_D.size
    check_fits(est, store=tmp_path / "s.zarr", host_bytes=1e12, disk_bytes=1e12)
    with pytest.raises(SweepTooLargeError) as err:
        check_fits(est, store=tmp_path / "s.zarr", host_bytes=1e3, disk_bytes=1e3)
    text = str(err.value)
    assert "host memory" in text and "1000 eyes" in text and "available" in text
    assert "disk: the store may need up to" in text and "nothing was created" in text


def test_the_time_estimate_counts_the_states_continuous_peaks_add():
    """A ``local`` peak evaluates three states per (eye, depth) beyond the grid, each as
    costly as a grid state: the estimate grows by exactly that share (it once counted the
    grid alone and under-estimated the default sweep by half)."""
    from lfjax.sweep import build_tasks, population

    data = one_eye(display={"depth_offsets_D": [-0.5, 0.0, 0.5]})
    times, refined = {}, {}
    for method in ("vertex", "parabola", "local"):
        config = config_from_dict(one_eye(**{**data, "metrics": {"peak_method": method}}))
        eyes, _ = population(config)
        est = estimate(config, build_tasks(config, eyes))
        times[method] = est.seconds
        (task,) = est.tasks
        refined[method] = task.n_refined
        assert task.n_depths == 3
    assert refined == {"vertex": 0, "parabola": 3, "local": 9}
    (task,) = estimate(config, build_tasks(config, eyes)).tasks
    grid_share = times["vertex"]
    # every state costs the same transforms, so time is linear in the states evaluated
    per_state = (times["local"] - times["parabola"]) / 6
    assert times["parabola"] - grid_share == pytest.approx(3 * per_state, rel=1e-6)
    assert grid_share / per_state > task.n_states  # the grid's states plus its rendering


def test_a_frequency_step_that_cannot_fit_is_refused_before_any_store(tmp_path, capsys):
    from lfjax.cli import main

    toml = tmp_path / "fine.toml"
    toml.write_text(toml_text(one_eye(sampling={"freq_step_cpd": 1e-4})))
    store = tmp_path / "fine.zarr"
    assert main(["sweep", str(toml), "--out", str(store), "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert "device memory" in err and "FFT" in err and "available" in err, err
    assert not store.exists() and list(tmp_path.iterdir()) == [toml]


def test_a_failed_start_leaves_no_store(tmp_path, monkeypatch):
    from lfjax.sweep import compute

    def out_of_memory(self, task, zernike_um):
        raise MemoryError("the first chunk ran out of memory")

    monkeypatch.setattr(compute.ChunkEvaluator, "evaluate", out_of_memory)
    store = tmp_path / "failed.zarr"
    with pytest.raises(MemoryError) as err:
        run_sweep(config_from_dict(one_eye()), store, progress=False)
    assert not store.exists() and list(tmp_path.iterdir()) == []
    assert "was removed: no chunk had finished" in " ".join(err.value.__notes__)


# ----------------------------------------------------------------------------- plan, template


def test_dry_run_prints_the_plan_and_writes_nothing(tmp_path, capsys):
    from lfjax.cli import main

    toml = tmp_path / "plan.toml"
    toml.write_text(toml_text(one_eye()))
    assert main(["sweep", str(toml), "--out", str(tmp_path / "plan.zarr"), "--dry-run"]) == 0
    out = capsys.readouterr().out
    for line in ("eyes        2 in 2 chunks of 1", "layouts     2x2", "depths      1: 2 D",
                 "wavelengths 4", "sampling    3 mm 2x2: df", "time        ~",
                 "host memory ~", "device mem  ~", "store       ≤"):
        assert line in out, (line, out)
    assert list(tmp_path.iterdir()) == [toml]


def test_dry_run_lists_the_display_keys_set_with_their_units(tmp_path, capsys):
    """The plan names the lenticular strips, cross-talk and lenslet keys a config sets (with
    units and defaults), and says nothing of them for the ideal display."""
    from lfjax.cli import main
    from lfjax.sweep.guard import display_effects

    toml = tmp_path / "strips.toml"
    toml.write_text(toml_text(one_eye(display={
        "layouts": ["1x2"], "strip_width_ratio": 1.25, "strip_y_defocus_D": -0.83,
        "leakage_weight": 0.1}, sampling={"freq_step_cpd": 1.0})))
    assert main(["sweep", str(toml), "--out", str(tmp_path / "plan.zarr"), "--dry-run"]) == 0
    out = capsys.readouterr().out
    assert ("display     strip_width_ratio = 1.25 unitless (default 1); strip_y_defocus_D = "
            "-0.83 D (default 0); leakage_weight = 0.1 unitless (default 0)\n") in out, out
    assert display_effects(config_from_dict(one_eye())) == ()
    aberrated = config_from_dict(one_eye(display={"lenslet_spherical_um": 0.5,
                                                  "lenslet_distance_mm": 300.0}))
    assert display_effects(aberrated) == ("lenslet_distance_mm = 300 mm (default not set)",
                                          "lenslet_spherical_um = 0.5 µm (default 0)")
    assert "display  " not in estimate(config_from_dict(one_eye())).summary()


def test_lenslet_aberrations_with_strips_are_refused_by_the_config():
    """A 1xN layout with a lenslet_*_um key crashed inside the pipeline (no strip shape in
    the spherical lenslets' aberration model): the config refuses it, naming the key."""
    with pytest.raises(SweepConfigError, match=r"display.lenslet_coma_um .* must be 0 with 1xN"):
        config_from_dict(one_eye(display={"layouts": ["1x2", "2x2"], "lenslet_coma_um": 0.1}))


def test_template_writes_every_key_with_its_default(tmp_path, capsys):
    from lfjax.cli import main
    from lfjax.sweep.config import SCHEMA

    text = config_template()
    assert config_from_dict(tomllib.loads(text)).as_dict() == SweepConfig().as_dict()
    for section, keys in SCHEMA.items():
        for key in keys:
            assert f"\n{key} = " in text or f"\n# {key} = " in text, key
    target = tmp_path / "new.toml"
    assert main(["sweep", str(target), "--template"]) == 0
    assert target.read_text() == text
    assert main(["sweep", str(target), "--template"]) == 2  # never overwrites
    assert "already exists" in capsys.readouterr().err


def test_a_killed_reproduce_leaves_no_hidden_folder_after_the_next_run(tmp_path, capsys,
                                                                        monkeypatch):
    """A SIGKILLed ``lfjax reproduce`` cannot clean its temporary folder; the next run in
    the same place removes it (its process is gone) and says so."""
    import socket
    import subprocess
    import sys

    from lfjax import cli
    from lfjax.reproduce import run as rep  # where reproduce looks its parts up

    gone = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"],
                          capture_output=True, text=True, check=True)
    orphan = tmp_path / f".lfjax-staging-res-{socket.gethostname()}-{int(gone.stdout)}-x1y2"
    orphan.mkdir()
    (orphan / "results.nc").write_text("half written")

    def boom(*args, **kwargs):
        raise RuntimeError("simulated failure")

    monkeypatch.setattr(rep, "compute_examples", boom)
    monkeypatch.setattr(rep, "run_study", lambda config, options=None, stage=None: None)
    monkeypatch.setattr(cli.cache, "enable_compilation_cache", lambda folder=None: None)
    code = cli.main(["reproduce", "--quick", "--no-progress", "--out", str(tmp_path / "res")])
    assert code == 1
    assert "removed 1 folder(s) left by an interrupted run" in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []


# ----------------------------------------------------------------------------- memory


def test_radial_mtf_bins_in_memory_of_the_plane_not_its_cube():
    """The ring average of an L x (L/2+1) OTF keeps O(L²) host data (a dense binning matrix
    is O(L³): 5.8 GiB at L = 1458) and equals the dense matrix's average."""
    import jax.numpy as jnp

    from lfjax.kernel import metrics

    index, weights, _ = metrics.radial_bins(1458)
    assert index.nbytes + weights.nbytes < 64 * 2**20
    n = 33
    fy = np.fft.fftfreq(n, 1.0 / n)
    fx = np.fft.rfftfreq(n, 1.0 / n)
    ring = np.rint(np.hypot(fx[None, :], fy[:, None])).ravel().astype(int)
    mult = np.broadcast_to(np.r_[1.0, np.full(n // 2, 2.0)], (n, n // 2 + 1)).ravel()
    dense = np.zeros((n // 2 + 1, ring.size))
    keep = ring <= n // 2
    dense[ring[keep], np.flatnonzero(keep)] = mult[keep]
    dense /= dense.sum(axis=1, keepdims=True)
    otf = np.random.default_rng(1).normal(size=(2, n, n // 2 + 1)) + 0.5j
    got, freq = metrics.radial_mtf(jnp.asarray(otf), n, 0.5)
    np.testing.assert_allclose(np.asarray(got), np.abs(otf).reshape(2, -1) @ dense.T,
                               rtol=1e-5)
    np.testing.assert_allclose(np.asarray(freq), 0.5 * np.arange(n // 2 + 1))


def test_host_guards_hold_a_block_of_eyes_not_the_population(monkeypatch):
    """The field guard's ray angles and the planner's order RMS evaluate eyes in blocks:
    the same answers, with memory of one block (the whole population at once took ~90 KB
    per eye: 9 GB for 100,000 eyes)."""
    import tracemalloc

    from lfjax.planner import plan as planner
    from lfjax.base import sampling

    z = np.asarray(__import__("lfjax").sample_eyes(0, 5000, 6.0).zernike_um)
    tracemalloc.start()
    slope = sampling.eye_slope_rad(z, 6.0, 3.0)
    rms = planner._order_rms_um(z, 6.0, 3.0)
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    assert peak < 200 * 2**20, peak / 2**20  # one block: ~90 MiB; all 5,000 eyes: ~450 MiB
    monkeypatch.setattr(sampling, "EYE_BLOCK", 7)
    monkeypatch.setattr(planner, "EYE_BLOCK", 7)
    assert sampling.eye_slope_rad(z[:20], 6.0, 3.0) == pytest.approx(
        max(sampling.eye_slope_rad(z[i:i + 1], 6.0, 3.0) for i in range(20)), rel=1e-12)
    small = planner._order_rms_um(z[:20], 6.0, 3.0)
    for order, value in small.items():
        assert value == pytest.approx(max(planner._order_rms_um(z[i:i + 1], 6.0, 3.0)[order]
                                          for i in range(20)), rel=1e-12)
    assert slope > 0 and set(rms) == set(small)


def test_transform_units_count_a_strips_narrow_window():
    """The estimates' unit (lfjax.kernel.pipeline.transform_units): a square band costs
    wavelengths·n²·log2 n, a strip's narrow band (n_fft_x columns) n_fft_x/n of it; the sweep
    guard and the design plan time transforms with it."""
    import math

    from lfjax.kernel.pipeline import transform_units

    square = transform_units(((0, 3, 256),))
    assert square == pytest.approx(3 * 256 * 256 * 8)
    narrow = transform_units(((0, 3, 256, 64),))
    assert narrow == pytest.approx(square * 64 / 256)
    both = transform_units(((0, 3, 256), (3, 5, 200, 80)))
    assert both == pytest.approx(square + 2 * 200 * 80 * math.log2(200))


def test_the_plan_says_its_time_model_is_the_cpus():
    """The time model is calibrated on 2 CPU cores: on an accelerator the plan says it is
    not modelled (the CPU figure was 3.8 h where one H200 took 110 s, RESULTS §34) and
    suggests a larger chunk when run.chunk_size is small."""
    from lfjax.sweep.guard import ACCELERATOR_CHUNK

    config = config_from_dict(one_eye())
    cpu = estimate(config, platform="cpu").summary()
    assert "(calibrated on 2 CPU cores)" in cpu and "not modelled" not in cpu
    assert "note        run.chunk_size" not in cpu
    gpu = estimate(config, platform="gpu").summary()
    assert "time        not modelled on gpu" in gpu and "calibrated on 2 CPU" not in gpu
    assert "note        run.chunk_size 1: one call per chunk" in gpu
    big = config_from_dict(one_eye(run={"chunk_size": ACCELERATOR_CHUNK}))
    assert "note        run.chunk_size" not in estimate(big, platform="gpu").summary()
    assert estimate(config).platform == "cpu"  # this suite runs on the CPU backend
