"""Shared helpers for the lfjax benchmarks: machine header, timing, sampling that passes the guard.

Timings on a shared 2-core machine are noisy: every benchmark reports ratios measured side by
side in one process (interleaved repeats, minimum of several), never absolute times alone.
"""

from __future__ import annotations

import datetime
import os
import platform
import re
import shlex
import subprocess
import sys
import time

import numpy as np

BENCH_DATE = datetime.date.today().isoformat()
"""Date stamped on the results: the day the benchmark runs (UTC clock of the machine)."""


def machine_info() -> dict:
    model = platform.processor() or "unknown"
    try:
        out = subprocess.run(["lscpu"], capture_output=True, text=True, check=True).stdout
        for line in out.splitlines():
            if line.strip().lower().startswith("model name"):
                model = line.split(":", 1)[1].strip()
                break
    except (OSError, subprocess.CalledProcessError):
        pass
    try:
        load = os.getloadavg()
    except OSError:
        load = (float("nan"),) * 3
    import jax

    return {
        "cpu": model,
        "cores": os.cpu_count(),
        "python": platform.python_version(),
        "jax": jax.__version__,
        "backend": jax.default_backend(),
        "x64": bool(jax.config.jax_enable_x64),
        "load_avg_1m": round(load[0], 2),
    }


def header(title: str) -> dict:
    """Print the command, machine, versions and dates; return the machine dict."""
    info = machine_info()
    cmd = " ".join(shlex.quote(a) for a in [os.path.relpath(sys.executable)] + sys.argv)
    print(f"# {title}")
    print(f"command : {cmd}")
    print(f"machine : {info['cpu']}, {info['cores']} cores, load avg (1 min) {info['load_avg_1m']}")
    print(
        f"software: python {info['python']}, jax {info['jax']} ({info['backend']}, "
        f"x64={info['x64']}), numpy {np.__version__}"
    )
    print(f"date    : {datetime.datetime.now().isoformat(timespec='seconds')}")
    print(f"lfjax   : {git_state()}")
    print()
    return info


def git_state() -> str:
    """Commit of the checkout and a short hash of uncommitted changes under lfjax/ (if any)."""
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    try:
        rev = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=root, capture_output=True,
                             text=True, check=True).stdout.strip()
        diff = subprocess.run(["git", "diff", "HEAD", "--", "lfjax"], cwd=root, capture_output=True,
                              text=True, check=True).stdout
    except (OSError, subprocess.CalledProcessError):
        return "unknown (not a git checkout)"
    if not diff:
        return f"commit {rev} (lfjax/ clean)"
    import hashlib

    return f"commit {rev} + uncommitted lfjax/ changes (diff sha1 {hashlib.sha1(diff.encode()).hexdigest()[:10]})"


def block(x):
    """block_until_ready on every array leaf of a pytree."""
    import jax

    for leaf in jax.tree_util.tree_leaves(x):
        if hasattr(leaf, "block_until_ready"):
            leaf.block_until_ready()
    return x


class CompileTimer:
    """Sums jax's own compile-stage durations (trace, lowering, XLA backend compile) while active.

    Uses ``jax.monitoring`` events ``/jax/core/compile/*_duration``; so a first call's compile
    time is measured directly, without a second (steady) call.
    """

    _active: list = []
    _registered = False

    def __enter__(self):
        import jax

        if not CompileTimer._registered:
            def listener(name, duration, **_):
                if name.startswith("/jax/core/compile/"):
                    for t in CompileTimer._active:
                        t.seconds += duration
            jax.monitoring.register_event_duration_secs_listener(listener)
            CompileTimer._registered = True
        self.seconds = 0.0
        CompileTimer._active.append(self)
        return self

    def __exit__(self, *exc):
        CompileTimer._active.remove(self)
        return False


def timed_first(fn, *args, **kwargs) -> tuple[float, float, object]:
    """(wall seconds, compile seconds inside it, output) of one call."""
    with CompileTimer() as ct:
        t, out = timed(fn, *args, **kwargs)
    return t, ct.seconds, out


def timed(fn, *args, **kwargs) -> tuple[float, object]:
    t0 = time.perf_counter()
    out = block(fn(*args, **kwargs))
    return time.perf_counter() - t0, out


def interleaved_min(fns: dict, repeats: int) -> dict:
    """Run each zero-argument callable ``repeats`` times, interleaved (A B A B …); min seconds.

    Interleaving exposes every candidate to the same background load, so their ratio is
    meaningful on a shared machine even when absolute times drift.
    """
    best = {k: float("inf") for k in fns}
    for _ in range(repeats):
        for k, fn in fns.items():
            t, _ = timed(fn)
            best[k] = min(best[k], t)
    return best


_DF_RE = re.compile(r"use freq_step_cpd <= ([0-9.eE+-]+)")


def passing_freq_step(try_fn, start: float = 1.0, digits: int = 2) -> float:
    """Largest frequency step (rounded down to ``digits`` decimals) accepted by the guard.

    ``try_fn(df)`` must run the lfjax aliasing guard (e.g. a call that raises ValueError
    "... use freq_step_cpd <= X"). Follows the guard's own suggestion, so the step is the one
    lfjax itself accepts (``lfjax.planner.plan.plan_sampling`` is printed beside it for reference).
    """
    df = start
    for _ in range(8):
        try:
            try_fn(df)
            return df
        except ValueError as err:
            m = _DF_RE.search(str(err))
            if not m:
                raise
            suggested = float(m.group(1))
            df = np.floor(suggested * 10**digits) / 10**digits
    raise RuntimeError("no passing freq_step_cpd found")


def fmt_s(seconds: float) -> str:
    if seconds < 1e-3:
        return f"{seconds * 1e6:.1f} µs"
    if seconds < 1.0:
        return f"{seconds * 1e3:.1f} ms"
    return f"{seconds:.2f} s"


def markdown_table(rows: list[dict], columns: list[str]) -> str:
    lines = ["| " + " | ".join(columns) + " |", "| " + " | ".join("---" for _ in columns) + " |"]
    for r in rows:
        lines.append("| " + " | ".join(str(r.get(c, "")) for c in columns) + " |")
    return "\n".join(lines)
