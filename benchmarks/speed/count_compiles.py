"""Count the programs XLA compiles in one `lfjax reproduce` run, and time the run.

Every program JAX hands to the backend passes through one timed event
(``/jax/core/compile/backend_compile_duration``), whether it is compiled or read back from
the persistent compilation cache (``/jax/compilation_cache/cache_hits`` counts those).
So, in a fresh process:

* programs compiled = backend compile events − cache hits;
* with an empty cache folder (cold), every event is a compilation.

The run is ``lfjax reproduce --quick`` through :func:`lfjax.cli.main` (the command line in
this process); ``--alternatives`` runs the same quick study with the modelling alternatives
switched on (``StudyConfig.quick(alternatives=True)``; the command line's ``--quick`` leaves
them out), and ``--full`` the default study (``lfjax reproduce``, alternatives included). The cache folder is ``--cache`` (pass a new empty folder for a cold run, the same
folder again for a warm one).

Run:  PYTHONPATH=. .venv/bin/python benchmarks/speed/count_compiles.py --cache DIR --out DIR
      [--alternatives | --full] [--accuracy claims|vsotf] [--programs FILE]
"""

from __future__ import annotations

import argparse
import collections
import json
import os
import sys
import time
from pathlib import Path


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cache", required=True, help="persistent compilation cache folder")
    parser.add_argument("--out", required=True, help="output folder of the reproduction")
    parser.add_argument("--alternatives", action="store_true",
                        help="quick study with the modelling alternatives")
    parser.add_argument("--full", action="store_true",
                        help="the default (full) study, alternatives included")
    parser.add_argument("--accuracy", choices=("claims", "vsotf"), default=None,
                        help="passed to lfjax reproduce (default: its own)")
    parser.add_argument("--programs", default=None,
                        help="JSON file of every compiled program's name and count (to find "
                             "which program a change adds or removes)")
    args = parser.parse_args(argv)
    os.environ["LFJAX_CACHE_DIR"] = str(Path(args.cache).resolve())

    import jax

    counts = collections.Counter()
    seconds = collections.Counter()

    def on_event(event, **kwargs):
        counts[event] += 1

    largest = []

    def on_duration(event, duration, **kwargs):
        counts[event] += 1
        seconds[event] += duration
        if event == "/jax/core/compile/backend_compile_duration":
            largest.append((round(duration, 1), str(kwargs.get("fun_name"))))

    jax.monitoring.register_event_listener(on_event)
    jax.monitoring.register_event_duration_secs_listener(on_duration)

    t0 = time.perf_counter()
    if args.alternatives:
        from lfjax.cli import enable_compilation_cache
        from lfjax.reproduce import StudyConfig, reproduce

        enable_compilation_cache()
        reproduce(args.out, StudyConfig.quick(alternatives=True), force=True, progress=False)
        rc = 0
    else:
        from lfjax.cli import main as cli_main

        quick = [] if args.full else ["--quick"]
        accuracy = [] if args.accuracy is None else ["--accuracy", args.accuracy]
        rc = cli_main(["reproduce", *quick, *accuracy, "--out", args.out, "--force",
                       "--no-progress"])
    wall = time.perf_counter() - t0
    events = counts["/jax/core/compile/backend_compile_duration"]
    hits = counts["/jax/compilation_cache/cache_hits"]
    result = {
        "wall_s": round(wall, 1),
        "backend_compile_events": events,
        "cache_hits": hits,
        "programs_compiled": events - hits,
        "backend_compile_s": round(seconds["/jax/core/compile/backend_compile_duration"], 1),
        "tracing_and_lowering_s": round(
            seconds["/jax/core/compile/jaxpr_trace_duration"]
            + seconds["/jax/core/compile/jaxpr_to_mlir_module_duration"], 1),
        "largest_backend_compiles_s": sorted(largest, reverse=True)[:6],
        "load_average": [round(x, 2) for x in os.getloadavg()],
        "run": "full" if args.full else "quick + alternatives" if args.alternatives else "quick",
        "accuracy": args.accuracy or "default",
    }
    print(json.dumps(result))
    if args.programs:
        names = collections.Counter(name for _, name in largest)
        Path(args.programs).write_text(json.dumps(dict(sorted(names.items())), indent=1) + "\n")
    return rc


if __name__ == "__main__":
    sys.exit(main())
