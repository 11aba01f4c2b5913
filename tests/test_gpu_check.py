"""``benchmarks/speed/gpu_check.sh``, the one-command GPU check (issue #36 item 7), tried on
the CPU: the commands it runs at full size are ones ``lfjax`` accepts and mean what the
issue asks (10,000 eyes x the paper's four layouts x 9 depths, every other setting at its
default); a ``--tiny`` run under a short time limit stops its steps at the limit and still
leaves a complete record (every step's wall time and exit status, the commit, the device,
the summary); the verdicts mark a target met only for a finished full-size run on a GPU.

The tiny run uses the session's compilation cache (``--reuse-cache``; tests/conftest.py
sets ``LFJAX_CACHE_DIR``) and a 40 s limit, so it costs the suite at most about 45 s
whatever the machine: on two busy cores its steps are mostly cut short by the limit, which
is the path a GPU run that misses a target takes.
"""

from __future__ import annotations

import dataclasses
import importlib.util
import json
import os
import shlex
import shutil
import subprocess
import sys
import time
from pathlib import Path

import pytest

from lfjax.cli import build_parser
from lfjax.model.layouts import PAPER_LAYOUTS
from lfjax.sweep.config import config_from_dict
from lfjax.sweep.config_files import load_config

ROOT = Path(__file__).resolve().parents[1]
SCRIPT = ROOT / "benchmarks" / "speed" / "gpu_check.sh"
STEPS = ("reproduce_cold", "reproduce_warm", "sweep", "optimise")
LIMIT_S = 40

pytestmark = pytest.mark.skipif(shutil.which("bash") is None or shutil.which("timeout") is None,
                                reason="needs bash and coreutils' timeout")


def _env() -> dict:
    env = dict(os.environ)
    env["PYTHON"] = sys.executable
    # the lfjax under test, whether or not it is installed
    env["PYTHONPATH"] = os.pathsep.join(p for p in (str(ROOT), env.get("PYTHONPATH")) if p)
    return env


def _script(*args, timeout: float = 60) -> subprocess.CompletedProcess:
    return subprocess.run(["bash", str(SCRIPT), *args], capture_output=True, text=True,
                          env=_env(), timeout=timeout)


def _helper():
    spec = importlib.util.spec_from_file_location("gpu_check", SCRIPT.with_suffix(".py"))
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _printed(tiny: bool, tmp_path: Path):
    """The four commands (argument lists after ``lfjax``) and the sweep's config, as the
    script would run them, with $WORK in ``tmp_path``."""
    proc = _script("--print-commands", *(["--tiny"] if tiny else []))
    assert proc.returncode == 0, proc.stderr
    head, toml = proc.stdout.split("--- sweep.toml\n")
    commands = {}
    for line in head.strip().splitlines():
        name, command = line.split(": ", 1)
        argv = shlex.split(command.replace("$WORK", str(tmp_path)))
        assert argv[0] == "lfjax"
        commands[name] = argv[1:]
    assert tuple(commands) == STEPS
    (tmp_path / "sweep.toml").write_text(toml)
    return commands, load_config(tmp_path / "sweep.toml")


@pytest.mark.parametrize("tiny", [False, True], ids=["full", "tiny"])
def test_commands_are_accepted_by_lfjax(tmp_path, tiny):
    """Every command parses with lfjax's own parser, and its sweep config loads: a wrong flag
    or key would otherwise be found only on the GPU, in its one run."""
    commands, config = _printed(tiny, tmp_path)
    parser = build_parser()
    parsed = {name: parser.parse_args(argv) for name, argv in commands.items()}
    assert parsed["reproduce_cold"].quick is tiny and parsed["reproduce_warm"].quick is tiny
    assert commands["reproduce_cold"][:-1] == commands["reproduce_warm"][:-1]  # same run twice
    assert parsed["sweep"].config == str(tmp_path / "sweep.toml")
    if tiny:
        assert config.n_eyes == 1 and len(config.layouts) == 1 and len(config.depths_D) == 2
        assert parsed["optimise"].steps == 1 and parsed["optimise"].test_eyes == 0


def test_full_size_is_the_issue_s_question(tmp_path):
    """At full size: reproduce and optimise at their defaults (only --out given), the sweep 10,000 eyes x the paper's four layouts x 9 depths with every other key
    at its default but the chunk size, 256 (the script records it)."""
    commands, config = _printed(False, tmp_path)
    parser = build_parser()
    for name in ("reproduce_cold", "optimise"):
        argv = commands[name]
        given = parser.parse_args(argv)
        default = parser.parse_args([argv[0], "--out", given.out])
        assert vars(given) == vars(default), name
    assert config.n_eyes == 10_000
    assert tuple(config.layouts) == tuple(PAPER_LAYOUTS) and len(config.depths_D) == 9
    assert config.chunk_size == 256
    default = config_from_dict({}, base_dir=config.base_dir)
    assert config == dataclasses.replace(default, n_eyes=10_000, chunk_size=256)


@pytest.mark.parametrize("args, words", [
    (["--limit", "10"], "--limit"),
    (["--limit", "8 min"], "--limit"),
    (["--chunk", "0"], "--chunk"),
    (["--frobnicate"], "--frobnicate"),
])
def test_usage_errors_write_nothing(tmp_path, args, words):
    out = tmp_path / "never"
    proc = _script(*args, "--out", str(out))
    lines = proc.stderr.strip().splitlines()
    assert proc.returncode == 2
    assert len(lines) == 1 and "error" in lines[0] and words in lines[0]
    assert not out.exists()


def test_verdicts():
    """met only for a finished full-size run on a GPU within the goal; a run stopped by the
    limit misses the goal only if it had at least the goal's time."""
    v = _helper().verdict
    ok = {"wall_s": 20.0, "rc": 0, "budget_s": 100, "timed_out": False}
    assert v(ok, 30.0, on_gpu=True, tiny=False)[0] == "met"
    assert v(dict(ok, wall_s=31.0), 30.0, on_gpu=True, tiny=False)[0] == "missed"
    assert v(dict(ok, rc=1), 30.0, on_gpu=True, tiny=False)[0] == "missed"
    stopped = dict(ok, wall_s=100.5, rc=124, timed_out=True)
    assert v(stopped, 30.0, on_gpu=True, tiny=False)[0] == "missed"
    assert v(dict(stopped, budget_s=10), 30.0, on_gpu=True, tiny=False)[0] == "not run"
    assert v(ok, 30.0, on_gpu=False, tiny=False) == ("not run", "20.0 s (ok); no GPU "
                                                     "(backend ?)")
    assert v(ok, 30.0, on_gpu=True, tiny=True)[0] == "not run"
    assert v({}, 30.0, on_gpu=True, tiny=False)[0] == "not run"
    assert v({"skipped": "no time left"}, 30.0, on_gpu=True, tiny=False)[0] == "not run"


@pytest.fixture(scope="module")
def tiny_record(tmp_path_factory):
    out = tmp_path_factory.mktemp("gpu_check") / "record"
    t0 = time.perf_counter()
    proc = _script("--tiny", "--reuse-cache", "--limit", str(LIMIT_S), "--out", str(out),
                   timeout=LIMIT_S + 60)
    return proc, out, time.perf_counter() - t0


def test_tiny_run_keeps_its_time_limit(tiny_record):
    proc, out, seconds = tiny_record
    summary = json.loads((out / "summary.json").read_text())
    # 0: every step finished; 1: one was stopped by the limit (or failed: checked below)
    assert proc.returncode == (0 if all(s.get("rc") == 0 for s in summary["steps"].values())
                               else 1), proc.stdout[-3000:]
    # the limit, a few seconds for bash and the record, nothing like the steps' own needs
    assert seconds <= LIMIT_S + 10, seconds


def test_tiny_run_records_every_step(tiny_record):
    proc, out, _ = tiny_record
    summary = json.loads((out / "summary.json").read_text())
    has_time = shutil.which("time") is not None or Path("/usr/bin/time").exists()
    for name in STEPS:
        step = summary["steps"][name]
        assert step["name"] == name and step["command"].startswith("lfjax ")
        assert "skipped" not in step, step  # every step had some of the limit
        assert isinstance(step["rc"], int) and step["wall_s"] >= 0, step
        # ran to the end, or was stopped by the limit: no lfjax command refused or failed
        assert step["rc"] == 0 or step["timed_out"], (name, step, proc.stdout[-3000:])
        if step["timed_out"]:
            assert step["budget_s"] - 0.5 <= step["wall_s"] <= step["budget_s"] + 3 + 3, step
        else:
            assert step["wall_s"] <= step["budget_s"] + 0.5, step
        if step["rc"] == 0 or has_time:
            assert step["host_maxrss_kB"] > 10_000, step  # a Python with jax: tens of MiB
        assert (out / "steps" / f"{name}.log").exists()
    sweep = summary["steps"]["sweep"]
    assert sweep["chunk_size"] == 2 and sweep["n_eyes"] == 1


def test_tiny_run_records_commit_device_and_summary(tiny_record):
    proc, out, _ = tiny_record
    run = json.loads((out / "run.json").read_text())
    git = subprocess.run(["git", "-C", str(ROOT), "rev-parse", "HEAD"], capture_output=True,
                         text=True)
    assert run["commit"] == (git.stdout.strip() if git.returncode == 0 else "unknown")
    assert run["tiny"] is True and run["limit_s"] == LIMIT_S
    assert run["cold_cache"].startswith("reused")
    device = json.loads((out / "device.json").read_text())
    assert device["backend"] and device["devices"]
    text = (out / "summary.md").read_text()
    for name in STEPS:
        assert f"| {name} |" in text
    summary = json.loads((out / "summary.json").read_text())
    assert [t["step"] for t in summary["targets"]] == ["reproduce_cold", "reproduce_warm",
                                                       "sweep"]
    # a tiny run measures no target
    assert all(t["verdict"] == "not run" for t in summary["targets"])
    log = (out / "log.txt").read_text()
    assert all(f"] {name}: lfjax " in log for name in STEPS)
    assert "== record in" in log  # the log is complete when the script returns
    assert log.strip() == proc.stdout.strip()
