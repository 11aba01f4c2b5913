#!/usr/bin/env bash
# `lfjax design` at its defaults (every flag but --depths), and the fit's memory against its
# training eyes, each under /usr/bin/time -v: prints the command, its plan and progress, the
# wall time and the peak resident memory (RESULTS §21).
#   bash benchmarks/speed/design_defaults.sh [OUT]        (OUT default /tmp/lfjax-design-bench)
# Run from the repository root with the environment that has lfjax installed.
set -u
OUT=${1:-/tmp/lfjax-design-bench}
mkdir -p "$OUT"
PY=${PYTHON:-python}
run() {  # name, then the lfjax arguments
  local name=$1; shift
  echo "== $name: lfjax $*  (commit $(git rev-parse --short HEAD 2>/dev/null), $(date -u +%FT%TZ), load $(cut -d' ' -f1-3 /proc/loadavg))"
  /usr/bin/time -v -o "$OUT/$name.time" "$PY" -u -m lfjax.cli "$@" --out "$OUT/$name" --force 2>&1 | sed 's/^/   /'
  grep -E "Elapsed|Maximum resident" "$OUT/$name.time" | sed 's/^\s*/   /'
}
# the fit's memory: the phone preset's 3x3 with 1 and 3 training eyes (RESULTS §15: 4.09 and
# 8.27 GB before the gradient ran over eye chunks)
run phone-3x3-train1 design --panel phone --depths 1 3 --n-depths 3 --views 3 --train-eyes 1 \
    --test-eyes 1 --steps 1 --report-accuracy fit
run phone-3x3-train3 design --panel phone --depths 1 3 --n-depths 3 --views 3 --train-eyes 3 \
    --test-eyes 1 --steps 1 --report-accuracy fit
# the defaults
run near-eye-defaults design --panel near-eye --depths 1 2
run phone-defaults design --panel phone --depths 1 3
