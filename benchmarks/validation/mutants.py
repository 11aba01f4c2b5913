"""Put each of the seven round-4 mutants (deliberate bugs) into the package, one at a time,
run the tests, and record which tests catch it: a test suite that still passes with a bug in
it tests less than it claims.

Each mutant is one exact text replacement in one module (the run refuses a mutant whose
text is no longer there, so a moved line cannot silently make the mutant a no-op); the file
is restored after each run, also on Ctrl-C. The result is a table of mutants and the tests
that failed, as Markdown (stdout and ``--out``).

Run:  PYTHONPATH=. .venv/bin/python benchmarks/validation/mutants.py --out FILE
      [--only NAME ...] [-- PYTEST_ARGS ...]   (default pytest args: -q -n 2 -p no:cacheprovider)
"""

from __future__ import annotations

import argparse
import re
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]

MUTANTS = {
    "claim1-criterion": (
        "lfjax/vision/claims_accommodation.py",
        "claim 1's criterion accepts a mean error of exactly 0 D",
        "mean_error: Interval = Interval(lo=-0.25, hi=0.0, hi_open=True)",
        "mean_error: Interval = Interval(lo=-0.25, hi=0.0, hi_open=False)"),
    "claim7-strict": (
        "lfjax/vision/claims_resolution.py",
        "claim 7's fall of the cut-off need not be strict",
        "return all(b < a for a, b in zip(values, values[1:]))",
        "return all(b <= a for a, b in zip(values, values[1:]))"),
    "sa-sign": (
        "lfjax/kernel/scene.py",
        "the accommodation-dependent SA's sign flipped",
        "[jnp.asarray(slope * scale, float), jnp.asarray(radius, float)]",
        "[jnp.asarray(-slope * scale, float), jnp.asarray(radius, float)]"),
    "view-shift-sign": (
        "lfjax/kernel/pipeline.py",
        "the display's view shift sign flipped (D_CDP − D for D − D_CDP)",
        "shift_rad = (scene.depths_D - scene.cdp_D)",
        "shift_rad = (scene.cdp_D - scene.depths_D)"),
    "sce-form": (
        "lfjax/kernel/optics.py",
        "the Stiles–Crawford apodisation as exp(−ρr²) instead of 10^(−ρr²)",
        "-math.log(10.0) * sce_rho", "-sce_rho"),
    "lca-sign": (
        "lfjax/model/spectral.py",
        "the LCA's sign flipped",
        "return options.lca_A * (", "return -options.lca_A * ("),
    "ncsf-low-frequency": (
        "lfjax/kernel/metrics.py",
        "the Watson–Ahumada NCSF's low-frequency term's sign flipped",
        "- 0.8493 / jnp.cosh(f / 1.3625)", "+ 0.8493 / jnp.cosh(f / 1.3625)"),
}
"""name: (module, what the bug is, the correct text, the mutated text)."""


def run_mutant(name: str, pytest_args: list[str]) -> tuple[list[str], float]:
    """The tests that fail with mutant ``name`` in place, and the run's wall time (s)."""
    module, _, good, bad = MUTANTS[name]
    path = ROOT / module
    original = path.read_text()
    if good not in original:
        raise SystemExit(f"mutant {name}: {good!r} is not in {module} (moved? update MUTANTS)")
    t0 = time.perf_counter()
    try:
        path.write_text(original.replace(good, bad))
        proc = subprocess.run([sys.executable, "-m", "pytest", "-rf", *pytest_args], cwd=ROOT,
                              capture_output=True, text=True)
    finally:
        path.write_text(original)
    failed = sorted(set(re.findall(r"^FAILED (\S+)", proc.stdout, re.M)))
    return failed, time.perf_counter() - t0


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    extra = argv[argv.index("--") + 1:] if "--" in argv else []
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", required=True, help="Markdown file of the results")
    parser.add_argument("--only", nargs="*", choices=sorted(MUTANTS), default=None)
    args = parser.parse_args(argv[:argv.index("--")] if "--" in argv else argv)
    pytest_args = extra or ["-q", "-n", "2", "-p", "no:cacheprovider"]
    lines = [f"command: python benchmarks/validation/mutants.py {' '.join(argv)}", "",
             "| mutant | where | tests that fail |", "| --- | --- | --- |"]
    print("\n".join(lines), flush=True)
    for name in args.only or MUTANTS:
        failed, seconds = run_mutant(name, pytest_args)
        module, what = MUTANTS[name][:2]
        row = (f"| {what} | `{module}` | {len(failed)} ({seconds:.0f} s): "
               + (", ".join(f"`{t}`" for t in failed) or "**none: the mutant survives**") + " |")
        lines.append(row)
        print(row, flush=True)
        Path(args.out).write_text("\n".join(lines) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
