#!/usr/bin/env bash
# Peak memory (and wall time) of lfjax subcommands at their defaults, each under
# /usr/bin/time -v, as a new user runs them (issue #36 item 5: every subcommand's defaults
# within 4 GB of peak memory).
#   bash benchmarks/speed/defaults_memory.sh [OUT] [COMMAND...]   (OUT default /tmp/lfjax-defaults-memory)
# COMMANDs: optimise retina sweep-report (default: all three; reproduce, sweep and design
# are measured by targets_36.py and design_defaults.sh). Run from the repository root.
set -u
OUT=${1:-/tmp/lfjax-defaults-memory}
shift || true
WHICH=${*:-optimise retina sweep-report}
mkdir -p "$OUT"
PY=${PYTHON:-python}
run() {  # name, then the lfjax arguments
  local name=$1; shift
  echo "== $name: lfjax $*  (commit $(git rev-parse --short HEAD 2>/dev/null), $(date -u +%FT%TZ), load $(cut -d' ' -f1-3 /proc/loadavg))"
  /usr/bin/time -v -o "$OUT/$name.time" "$PY" -u -m lfjax.cli "$@" 2>&1 | tail -n 4 | sed 's/^/   /'
  grep -E "Elapsed|Maximum resident|Exit status" "$OUT/$name.time" | sed 's/^\s*/   /'
}
for c in $WHICH; do
  case $c in
    optimise) run optimise optimise --out "$OUT/optimise" --force --no-progress ;;
    retina) run retina retina --demo --out "$OUT/retina" --force ;;
    sweep-report)
      # a small store first (its config: the template with 20 eyes), then the report at its defaults
      "$PY" -m lfjax.cli sweep --template "$OUT/small.toml" >/dev/null 2>&1 || true
      sed -i 's/^n_eyes = .*/n_eyes = 20/' "$OUT/small.toml"
      "$PY" -m lfjax.cli sweep "$OUT/small.toml" --out "$OUT/small.zarr" --no-progress >/dev/null 2>&1
      run sweep-report sweep-report "$OUT/small.zarr" --out "$OUT/report" --no-progress ;;
  esac
done
