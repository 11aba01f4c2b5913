"""Python side of ``gpu_check.sh`` (read that script's header first).

Five subcommands, each run by the shell script in its own process:

* ``device OUT``: what the machine is: jax's backend and devices (with each device's memory
  limit where the backend reports it), the versions, where ``lfjax`` is imported from;
  written to ``OUT/device.json``.
* ``exec --stats FILE -- ARGS…``: runs ``lfjax ARGS…`` in this process (the console script
  ``lfjax`` is :func:`lfjax.cli.main`, so this is the same command), then writes its exit
  status, its own wall time, the process's peak resident memory and each device's
  ``memory_stats()["peak_bytes_in_use"]`` to ``FILE``. Device memory can only be read from
  inside the process that used it, hence this wrapper. SIGTERM (``timeout``'s signal) is
  turned into Ctrl-C, so a step stopped by the time limit still writes its figures.
* ``meta OUT --field KEY VALUE …``: merges the run's facts (command, commit, date, limit,
  caches, environment) into ``OUT/run.json``.
* ``step OUT NAME --field KEY VALUE …``: after each step, gathers what the shell measured
  (command, wall time, exit status, time budget) with the step's files (``/usr/bin/time -v``,
  ``exec``'s figures, nvidia-smi's samples) into ``OUT/steps/NAME.json``.
* ``summary OUT``: reads the record the script wrote (``OUT/steps/*.json``, ``device.json``,
  ``run.json``) and writes ``OUT/summary.md`` (the table of steps, and each target of issue
  #36 item 7 with the measured figure, marked met, missed or not run) and ``OUT/summary.json``.
  It imports neither jax nor lfjax, so it runs even when they are broken.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import resource
import signal
import sys
import threading
import time
from pathlib import Path

STEPS = ("reproduce_cold", "reproduce_warm", "sweep", "optimise")
"""The steps, in the order the script runs them."""

TITLES = {
    "reproduce_cold": "`lfjax reproduce`, cold (empty compilation and plan caches)",
    "reproduce_warm": "`lfjax reproduce`, warm (the same caches again)",
    "sweep": "`lfjax sweep`: eyes x the paper's four layouts x 9 depths",
    "optimise": "`lfjax optimise` (the layout fit)",
}

TARGETS = (
    ("reproduce_cold", "`lfjax reproduce` cold", 30.0),
    ("reproduce_warm", "`lfjax reproduce` warm", 5.0),
    ("sweep", "sweep of 10,000 eyes x 4 layouts x 9 depths", 120.0),
)
"""Issue #36 item 7: (step, what, goal in seconds of wall time on one GPU)."""


# ----------------------------------------------------------------------------- device


def _device_memory(device) -> dict | None:
    """``device.memory_stats()`` (bytes), or None where the backend reports none (the CPU)."""
    try:
        stats = device.memory_stats()
    except Exception:  # noqa: BLE001 - backends without memory statistics raise or return None
        return None
    return {k: int(v) for k, v in stats.items() if isinstance(v, (int, float))} if stats else None


def cmd_device(out: Path) -> int:
    import importlib.metadata
    import importlib.util

    import jax
    import jaxlib

    # where lfjax would be imported from, without importing it (seconds, for matplotlib and
    # colour): the steps import it themselves
    spec = importlib.util.find_spec("lfjax")
    try:  # lfjax._version's own source of the version
        lfjax_version = importlib.metadata.version("lfjax")
    except importlib.metadata.PackageNotFoundError:
        lfjax_version = "not installed"
        if spec is not None:  # a checkout on PYTHONPATH: its pyproject.toml's version
            version_file = Path(spec.origin).parent / "_version.py"
            module = importlib.util.spec_from_file_location("_lfjax_version", version_file)
            try:
                loaded = importlib.util.module_from_spec(module)
                module.loader.exec_module(loaded)
                lfjax_version = f"{loaded._source_version()} (not installed)"
            except Exception:  # noqa: BLE001 - a record, not a step: keep "not installed"
                pass

    devices = [{"id": d.id, "platform": d.platform, "kind": getattr(d, "device_kind", ""),
                "repr": str(d), "memory_stats": _device_memory(d)} for d in jax.devices()]
    info = {
        "backend": jax.default_backend(),
        "devices": devices,
        "jax": jax.__version__, "jaxlib": jaxlib.__version__,
        "lfjax": lfjax_version, "lfjax_file": spec.origin if spec else None,
        "python": platform.python_version(), "host": platform.node(),
        "machine": platform.machine(), "cpus": os.cpu_count(),
        "x64": bool(jax.config.jax_enable_x64),
    }
    (out / "device.json").write_text(json.dumps(info, indent=2) + "\n")
    print(f"jax {info['jax']} (jaxlib {info['jaxlib']}), backend {info['backend']}, "
          f"lfjax {info['lfjax']} from {info['lfjax_file']}")
    for d in devices:
        limit = (d["memory_stats"] or {}).get("bytes_limit")
        print(f"  device {d['id']}: {d['repr']} ({d['kind']})"
              + (f", memory limit {limit / 2**30:.1f} GiB" if limit else ""))
    return 0


# ----------------------------------------------------------------------------- exec


def _terminated(signum, frame):
    raise KeyboardInterrupt  # the CLI's own Ctrl-C handling ends the run and says so


def _write_stats(stats_file: Path, **fields) -> None:
    fields["ru_maxrss_kB"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss  # Linux: KiB
    tmp = stats_file.with_suffix(".tmp")
    tmp.write_text(json.dumps(fields, indent=2) + "\n")
    tmp.replace(stats_file)  # whole or not at all, whenever the process is killed


_SAMPLING = threading.Lock()
_FINISHED = threading.Event()


def _sample_rss(stats_file: Path, t0: float, period_s: float = 1.0) -> None:
    """Keep the peak resident memory so far in ``stats_file`` while the command runs: a step
    killed after its grace (SIGKILL) leaves /usr/bin/time nothing to report, but this."""
    while not _FINISHED.wait(period_s):
        with _SAMPLING:  # never after the final figures
            if not _FINISHED.is_set():
                _write_stats(stats_file, rc=None, running=True,
                             in_process_s=round(time.perf_counter() - t0, 3))


def _backend_started() -> bool:
    """Whether jax has started a backend (reading memory statistics would start one, which
    takes seconds on a GPU that a stopped step does not have)."""
    try:
        from jax._src import xla_bridge  # private: only this yes/no is read from it

        return bool(xla_bridge._backends)
    except Exception:  # noqa: BLE001 - another jax: ask the devices anyway
        return hasattr(sys.modules["jax"], "local_devices")


def cmd_exec(stats_file: Path, argv: list[str]) -> int:
    signal.signal(signal.SIGTERM, _terminated)
    t0 = time.perf_counter()
    threading.Thread(target=_sample_rss, args=(stats_file, t0), daemon=True).start()
    rc, error = 1, None
    try:
        from lfjax.cli import main

        rc = main(argv)
    except KeyboardInterrupt:
        rc, error = 130, "interrupted (time limit)"
    except BaseException as err:  # noqa: BLE001 - recorded, then the status says it failed
        rc, error = 1, f"{type(err).__name__}: {err}"
    finally:
        seconds = time.perf_counter() - t0
        peaks, backend = [], None
        # jax's figures only if it got as far as importing jax (a step stopped while
        # importing must not start now: the grace before SIGKILL is short)
        if "jax" in sys.modules and _backend_started():
            try:
                jax = sys.modules["jax"]
                backend = jax.default_backend()
                for d in jax.local_devices():
                    stats = _device_memory(d)
                    if stats and "peak_bytes_in_use" in stats:
                        peaks.append(stats["peak_bytes_in_use"])
            except Exception as err:  # noqa: BLE001 - the figures are optional, the status not
                error = error or f"memory_stats: {type(err).__name__}: {err}"
        with _SAMPLING:
            _FINISHED.set()
            _write_stats(stats_file, rc=int(rc if rc is not None else 0),
                         in_process_s=round(seconds, 3),
                         device_peak_bytes=max(peaks) if peaks else None, backend=backend,
                         error=error)
    return int(rc or 0)


# ----------------------------------------------------------------------------- step


def _time_v(path: Path) -> dict:
    """``/usr/bin/time -v``'s maximum resident set size (KiB) and exit status, if written."""
    found = {}
    try:
        for line in path.read_text().splitlines():
            key, _, value = line.strip().rpartition(": ")
            if key == "Maximum resident set size (kbytes)":
                found["host_maxrss_kB"] = int(value)
            elif key == "Exit status":
                found["time_exit_status"] = int(value)
    except (OSError, ValueError):
        pass
    return found


def _smi_peak(path: Path) -> int | None:
    """Largest memory.used (MiB) nvidia-smi sampled while the step ran (all GPUs summed per
    sample is not needed: the check runs on one GPU, so the largest value is taken)."""
    try:
        values = [int(v) for line in path.read_text().splitlines()
                  for v in line.replace(",", " ").split() if v.isdigit()]
    except OSError:
        return None
    return max(values) if values else None


def cmd_step(out: Path, name: str, fields: dict, skipped: str | None) -> int:
    """Assemble ``OUT/steps/NAME.json`` from what the shell measured and the step's files."""
    folder = out / "steps"
    folder.mkdir(parents=True, exist_ok=True)
    step = {"name": name, "title": TITLES.get(name, name)}
    step.update(fields)
    if skipped:
        step["skipped"] = skipped
    else:
        stats = _load(folder / f"{name}.stats.json")
        timing = _time_v(folder / f"{name}.time.txt")
        step.update({k: stats.get(k) for k in ("device_peak_bytes", "backend", "error",
                                               "in_process_s")})
        # both are lower bounds of the peak: /usr/bin/time -v loses the Python process's
        # figure when timeout is killed before it reaps it (SIGKILL after the grace), the
        # process's own getrusage (sampled every second) misses at most its last second
        figures = {"/usr/bin/time -v": timing.get("host_maxrss_kB"),
                   "getrusage": stats.get("ru_maxrss_kB")}
        figures = {k: v for k, v in figures.items() if v}
        source = max(figures, key=figures.get) if figures else None
        step["host_maxrss_kB"] = figures.get(source)
        step["host_maxrss_source"] = source
        step["smi_peak_MiB"] = _smi_peak(folder / f"{name}.smi.txt")
        step["timed_out"] = step.get("rc") in (124, 137)
    (folder / f"{name}.json").write_text(json.dumps(step, indent=2) + "\n")
    return 0


def cmd_meta(out: Path, fields: dict, env: bool) -> int:
    """Merge ``fields`` (and with ``env`` the variables that steer jax and lfjax) into
    ``OUT/run.json``."""
    run = _load(out / "run.json")
    run.update(fields)
    if env:
        run["environment"] = {k: v for k, v in sorted(os.environ.items())
                              if k.startswith(("JAX_", "XLA_", "LFJAX_", "CUDA_", "PYTHON"))}
    (out / "run.json").write_text(json.dumps(run, indent=2) + "\n")
    return 0


# ----------------------------------------------------------------------------- summary


def _load(path: Path) -> dict:
    try:
        return json.loads(path.read_text())
    except (OSError, ValueError):
        return {}


def _mib(n_bytes) -> str:
    return "n/a" if n_bytes is None else f"{n_bytes / 2**20:,.0f} MiB"


def _status(step: dict) -> str:
    if not step:
        return "not run"
    if step.get("skipped"):
        return f"not run ({step['skipped']})"
    if step.get("timed_out"):
        return f"timed out after {step['budget_s']:.0f} s"
    return "ok" if step.get("rc") == 0 else f"failed (exit {step.get('rc')})"


def _sweep_progress(store: str | None) -> str:
    """Eyes in the store's finished chunks (a sweep stopped by the limit keeps them)."""
    if not store or not Path(store).exists():
        return ""
    try:
        import numpy as np
        import zarr

        group = zarr.open_group(store, mode="r")
        done = np.asarray(group["chunk_complete"][:], bool)
        size, n_eye = int(group.attrs["chunk_size"]), int(group["eye"].shape[0])
        eyes = sum(min((i + 1) * size, n_eye) - i * size for i in np.flatnonzero(done))
        return f"{eyes} of {n_eye} eyes in {int(done.sum())} of {done.size} chunks finished"
    except Exception as err:  # noqa: BLE001 - a note, not a figure the summary needs
        return f"store unreadable ({type(err).__name__})"


def verdict(step: dict, goal_s: float, on_gpu: bool, tiny: bool) -> tuple[str, str]:
    """(met | missed | not run, the measured figure in words) of one target."""
    status = _status(step)
    if not step or step.get("skipped"):
        return "not run", status
    wall = step.get("wall_s")
    measured = f"{wall:.1f} s ({status})" if wall is not None else status
    if tiny:
        return "not run", f"{measured}; --tiny: not the target's size"
    if not on_gpu:
        return "not run", f"{measured}; no GPU (backend {step.get('backend') or '?'})"
    if step.get("timed_out"):
        if step["budget_s"] >= goal_s:
            return "missed", measured
        return "not run", f"{measured}; the time left was under the goal"
    if step.get("rc") != 0:
        return "missed", measured
    return ("met" if wall <= goal_s else "missed"), measured


def cmd_summary(out: Path) -> int:
    run = _load(out / "run.json")
    device = _load(out / "device.json")
    steps = {name: _load(out / "steps" / f"{name}.json") for name in STEPS}
    tiny = bool(run.get("tiny"))
    backend = device.get("backend")
    on_gpu = backend in ("gpu", "cuda", "rocm")
    devices = ", ".join(f"{d.get('repr')} ({d.get('kind')})" for d in device.get("devices", []))
    sweep = steps.get("sweep", {})
    sweep_note = _sweep_progress(sweep.get("store"))
    if sweep_note:
        sweep["progress"] = sweep_note

    lines = [
        "# gpu_check record",
        "",
        f"- command: `{run.get('command', '?')}`",
        f"- date: {run.get('date', '?')}; commit: {run.get('commit', '?')}",
        f"- device: {devices or 'unknown (see log.txt)'}; backend {backend or '?'}",
        f"- jax {device.get('jax', '?')}, lfjax {device.get('lfjax', '?')}",
        f"- size: {'--tiny (CPU-sized smoke run: no target applies)' if tiny else 'full'}; "
        f"time limit {run.get('limit_s', '?')} s in total, used "
        f"{run.get('total_s', float('nan')):.0f} s",
        f"- caches of the cold step: {run.get('cold_cache', '?')}",
        "",
        "## Steps",
        "",
        "| step | command | wall (s) | status | host peak RSS | device peak |",
        "| --- | --- | --- | --- | --- | --- |",
    ]
    for name in STEPS:
        s = steps[name]
        wall = f"{s['wall_s']:.1f}" if s.get("wall_s") is not None else "—"
        rss = s.get("host_maxrss_kB")
        device_peak = _mib(s.get("device_peak_bytes"))
        if s.get("device_peak_bytes") is None and s.get("smi_peak_MiB") is not None:
            device_peak = f"{s['smi_peak_MiB']:,} MiB (nvidia-smi, whole GPU)"
        elif s.get("device_peak_bytes") is None and s:
            device_peak = "not reported by the backend"
        lines.append(
            f"| {name} | `{s.get('command', '—')}` | {wall} | {_status(s)} | "
            f"{_mib(rss * 1024) if rss else 'n/a'} | {device_peak} |")
    if sweep.get("chunk_size"):
        lines += ["", f"The sweep's config: {sweep.get('n_eyes')} eyes (plus the average "
                      f"eye) in chunks of {sweep['chunk_size']} (run.chunk_size)"
                      + (f"; {sweep_note}" if sweep_note else "") + "."]
    lines += ["", "## Targets (issue #36 item 7, on one GPU)", "",
              "| target | goal | measured | verdict |", "| --- | --- | --- | --- |"]
    targets = []
    cold = steps["reproduce_cold"]
    for name, what, goal in TARGETS:
        mark, measured = verdict(steps[name], goal, on_gpu, tiny)
        if name == "reproduce_warm" and steps[name] and (not cold or cold.get("rc") != 0):
            measured += "; after a cold run that did not finish, so its caches were incomplete"
        targets.append({"step": name, "target": what, "goal_s": goal, "verdict": mark,
                        "measured": measured})
        lines.append(f"| {what} | ≤ {goal:g} s | {measured} | **{mark}** |")
    lines.append("")
    text = "\n".join(lines)
    (out / "summary.md").write_text(text)
    (out / "summary.json").write_text(json.dumps(
        {"run": run, "device": device, "steps": steps, "targets": targets}, indent=2) + "\n")
    print(text)
    return 0


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    sub = parser.add_subparsers(dest="cmd", required=True)
    sub.add_parser("device").add_argument("out", type=Path)
    ex = sub.add_parser("exec")
    ex.add_argument("--stats", type=Path, required=True)
    ex.add_argument("args", nargs=argparse.REMAINDER)
    sub.add_parser("summary").add_argument("out", type=Path)
    meta = sub.add_parser("meta")
    meta.add_argument("out", type=Path)
    meta.add_argument("--env", action="store_true",
                      help="also record the JAX_*, XLA_*, LFJAX_*, CUDA_* and PYTHON* variables")
    meta.add_argument("--field", nargs=2, action="append", default=[], metavar=("KEY", "JSON"))
    st = sub.add_parser("step")
    st.add_argument("out", type=Path)
    st.add_argument("name", choices=STEPS)
    st.add_argument("--skipped", default=None, help="why the step did not run")
    st.add_argument("--field", nargs=2, action="append", default=[], metavar=("KEY", "JSON"),
                    help="a field of the step's record, its value as JSON (or a plain string)")
    args = parser.parse_args(argv)
    fields = {}
    for key, value in getattr(args, "field", []):
        try:
            fields[key] = json.loads(value)
        except ValueError:
            fields[key] = value
    if args.cmd == "step":
        return cmd_step(args.out, args.name, fields, args.skipped)
    if args.cmd == "meta":
        return cmd_meta(args.out, fields, args.env)
    if args.cmd == "device":
        return cmd_device(args.out)
    if args.cmd == "exec":
        rest = args.args[1:] if args.args[:1] == ["--"] else args.args
        return cmd_exec(args.stats, rest)
    return cmd_summary(args.out)


if __name__ == "__main__":
    sys.exit(main())
