#!/usr/bin/env bash
# gpu_check.sh: lfjax on one GPU, measured by one command (issue #36 item 7).
#
# Install (a fresh machine with one NVIDIA GPU; nothing else is needed):
#
#   pip install -e '.[cuda]'        # lfjax with jax[cuda12] (pyproject.toml's `cuda` extra;
#                                   # `.[cuda13]` for CUDA 13, driver 580 or newer)
#
# A machine with no package index (as benchmarks/results/34-gpu-check-h200.md's was): put the
# checkout and wheels of the packages its image lacks on PYTHONPATH instead; the steps run
# lfjax.cli.main in-process, so no console script is needed.
#
# Run, from anywhere:
#
#   bash benchmarks/speed/gpu_check.sh [--out DIR] [--limit SECONDS] [--chunk N] [--keep]
#   bash benchmarks/speed/gpu_check.sh --tiny --out /tmp/gc      # CPU-sized smoke run
#
# Steps, in this order, each under `timeout` with what is left of the total limit
# (default 480 s = 8 min; each step at most its share, below, of the time left once the
# device is listed; time one step leaves unused goes to the later ones; a step that runs out
# is stopped, recorded as timed out, and the script goes on to the next):
#
#   1 reproduce_cold   `lfjax reproduce` at its defaults, compilation cache (JAX's and the
#                      planner's, LFJAX_CACHE_DIR) in a new empty temporary folder  (30 %)
#   2 reproduce_warm   the same again, same caches                                   (12 %)
#   3 sweep            `lfjax sweep` of 10,000 eyes (+ the average eye) x the paper's four
#                      layouts x 9 depths, every other key at its default; run.chunk_size
#                      256 on a GPU (--chunk; the default 8 elsewhere), recorded      (38 %)
#   4 optimise         `lfjax optimise` at its defaults                 (20 % and what is left)
#
# The sweep and the fit use the caches the reproduce steps filled (their own programs are
# compiled in their step: a first sweep, a first fit).
#
# --tiny runs the same steps at their smallest sizes (reproduce --quick; a sweep of 1 eye +
# the average eye x 1 layout x 2 depths; a 1-step fit on 1 eye), meant for the CPU and the
# test suite (tests/test_gpu_check.py). --reuse-cache lets the cold step use the caller's
# caches (LFJAX_CACHE_DIR, JAX_COMPILATION_CACHE_DIR) instead of empty ones: the test suite
# uses it to share compiled programs; the record says so and its "cold" figure is not cold.
# --print-commands prints the four commands and the sweep's config, and runs nothing.
#
# Record, in one folder (default benchmarks/speed/gpu_check/<date>-<short commit>/):
#   log.txt          everything printed (also on the terminal, unbuffered), lfjax's progress
#                    bars included (one update per 5 s: TQDM_MININTERVAL)
#   run.json         command, date, commit (and whether the tree was modified), limit,
#                    caches, the JAX_/XLA_/LFJAX_/CUDA_ environment, total time
#   device.json      jax's backend, devices (memory limits), versions; nvidia-smi.txt
#   sweep.toml       the sweep's config
#   steps/NAME.json  per step: command, wall time, exit status, time budget, timed out,
#                    host peak RSS (/usr/bin/time -v, else the process's getrusage), device
#                    peak (jax memory_stats peak_bytes_in_use where the backend reports it;
#                    nvidia-smi's memory.used sampled every 250 ms as well, which includes
#                    jax's preallocation); steps/NAME.log its output
#   summary.md       the table of steps and each target (reproduce cold <= 30 s, warm <= 5 s,
#                    the 10,000-eye sweep <= 2 min) with the measured figure, marked met,
#                    missed or not run; summary.json the same as data
# The steps' own outputs go to a temporary folder, removed at the end unless --keep (the
# reproduce REPORT.md files and the fitted layout.json are copied into the record).
#
# PYTHON names the interpreter (default: python, else python3); LFJAX_COMMIT the commit
# where the tree is a copy without its git folder. Exit status 0 when every
# step ran and exited 0, 1 otherwise (one timed out, failed or had no time left), 2 on a
# usage error (nothing is written then).
set -u
{  # the whole script is read before it runs: editing the file meanwhile cannot derail a run

HERE=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
REPO=$(cd "$HERE/../.." && pwd)
HELPER="$HERE/gpu_check.py"

usage() { sed -n '2,/^set -u/p' "${BASH_SOURCE[0]}" | sed '$d; s/^# \{0,1\}//'; }
refuse() { echo "gpu_check.sh: error: $*" >&2; exit 2; }

ARGS="$*"
TINY=0 OUT="" LIMIT=480 CHUNK="" REUSE=0 KEEP=0 PRINT=0
while [ $# -gt 0 ]; do
    case $1 in
        --tiny) TINY=1 ;;
        --out) [ $# -ge 2 ] || refuse "--out needs a folder"; OUT=$2; shift ;;
        --limit) [ $# -ge 2 ] || refuse "--limit needs seconds"; LIMIT=$2; shift ;;
        --chunk) [ $# -ge 2 ] || refuse "--chunk needs a number"; CHUNK=$2; shift ;;
        --reuse-cache) REUSE=1 ;;
        --keep) KEEP=1 ;;
        --print-commands) PRINT=1 ;;
        -h|--help) usage; exit 0 ;;
        *) refuse "unknown argument '$1' (see --help)" ;;
    esac
    shift
done
[[ $LIMIT =~ ^[0-9]+$ ]] && [ "$LIMIT" -ge 30 ] \
    || refuse "--limit must be whole seconds >= 30, got '$LIMIT'"
[ -z "$CHUNK" ] || { [[ $CHUNK =~ ^[0-9]+$ ]] && [ "$CHUNK" -ge 1 ]; } \
    || refuse "--chunk must be a whole number >= 1, got '$CHUNK'"

PY=${PYTHON:-$(command -v python || command -v python3)}
[ -n "$PY" ] || refuse "no python found (set PYTHON)"
# lfjax's own progress bars go into the log too (where a stopped step had got to), one
# update every 5 s at most
export PYTHONUNBUFFERED=1 TQDM_MININTERVAL=${TQDM_MININTERVAL:-5}

# ---------------------------------------------------------------- the commands
# commands TOML CHUNK: sets REPRODUCE, OPTIMISE and N_EYES, writes the sweep's config to TOML
commands() {
    local toml=$1 chunk=$2
    if [ "$TINY" = 1 ]; then
        REPRODUCE=(reproduce --quick)
        N_EYES=1
        cat >"$toml" <<TOML
# gpu_check.sh --tiny: 1 eye + the average eye x 1 layout x 2 depths, coarse grids
[population]
n_eyes = $N_EYES
[display]
layouts = ["2x2"]
depth_offsets_D = [0.0, 1.0]
[accommodation]
step_D = 0.5
window_D = 1.0
[spectrum]
wavelengths_nm = [400.0, 700.0, 100.0]
[run]
chunk_size = $chunk
TOML
        OPTIMISE=(optimise --train-eyes 1 --test-eyes 0 --wavelengths 550 --freq-step 2
                  --depths 1 3 --n-depths 2 --max-diameter 2 --steps 1 --report-accuracy fit)
    else
        REPRODUCE=(reproduce)
        N_EYES=10000
        cat >"$toml" <<TOML
# gpu_check.sh: 10,000 eyes (+ the average eye) x the paper's four layouts x 9 depths;
# every key but these two at its default (lfjax sweep --template lists them)
[population]
n_eyes = $N_EYES
[run]
chunk_size = $chunk
TOML
        OPTIMISE=(optimise)
    fi
}

if [ "$PRINT" = 1 ]; then  # what would run (the test suite parses it); nothing runs
    toml=$(mktemp)
    commands "$toml" "${CHUNK:-$([ "$TINY" = 1 ] && echo 2 || echo 256)}"
    echo "reproduce_cold: lfjax ${REPRODUCE[*]} --out \$WORK/reproduce_cold"
    echo "reproduce_warm: lfjax ${REPRODUCE[*]} --out \$WORK/reproduce_warm"
    echo "sweep: lfjax sweep \$WORK/sweep.toml --out \$WORK/sweep.zarr"
    echo "optimise: lfjax ${OPTIMISE[*]} --out \$WORK/optimise"
    echo "--- sweep.toml"
    cat "$toml"
    rm -f "$toml"
    exit 0
fi

# ---------------------------------------------------------------- the record
START=$(date +%s)
DEADLINE=$((START + LIMIT))
# GRACE: timeout's wait between SIGTERM and SIGKILL, so a step may overrun its budget by
# that much; RESERVE keeps it and the summary's few seconds back from every step
if [ "$LIMIT" -ge 240 ]; then GRACE=15; else GRACE=3; fi
RESERVE=$((GRACE + 5))
MIN_STEP=2   # a step with less time than this is not started (recorded as not run)
# STEP_OVERHEAD: what a step costs beyond its budget besides the kill's grace (the step's
# record, written by a Python process, and the shell's bookkeeping): on busy cores it took
# the last step's MIN_STEP away, and the step was not run
STEP_OVERHEAD=2
STEPS_LEFT=4

# LFJAX_COMMIT names the commit where the tree is a copy without git (a device machine's)
COMMIT=$(git -C "$REPO" rev-parse HEAD 2>/dev/null || echo "${LFJAX_COMMIT:-unknown}")
DIRTY=false
[ -n "$(git -C "$REPO" status --porcelain --untracked-files=no 2>/dev/null)" ] && DIRTY=true
STAMP=$(date +%Y-%m-%d-%H%M%S)
[ -n "$OUT" ] || OUT="$REPO/benchmarks/speed/gpu_check/$STAMP-${COMMIT:0:7}"
mkdir -p "$OUT/steps" || refuse "cannot create --out $OUT"
OUT=$(cd "$OUT" && pwd)
[ -z "$(ls -A "$OUT/steps")" ] || refuse "--out $OUT already holds a record; name a new folder"
WORK=$(mktemp -d "${TMPDIR:-/tmp}/lfjax-gpu-check.XXXXXX")
SMI_PID=""

exec </dev/null > >(tee -a "$OUT/log.txt") 2>&1
TEE_PID=$!

cleanup() {
    [ -n "$SMI_PID" ] && kill "$SMI_PID" 2>/dev/null
    [ "$KEEP" = 1 ] || rm -rf "$WORK"
}
trap cleanup EXIT

clock() { echo "$(( $(date +%s) - START )) s"; }
left() { echo $(( DEADLINE - $(date +%s) - RESERVE )); }
meta() { "$PY" "$HELPER" meta "$OUT" "$@"; }

echo "== gpu_check.sh $ARGS"
echo "== commit $COMMIT$([ "$DIRTY" = true ] && echo ' (modified tree)'), record in $OUT"
echo "== limit $LIMIT s in total; $([ "$TINY" = 1 ] && echo '--tiny sizes' || echo 'full sizes')"
meta --env --field command "gpu_check.sh $ARGS" --field date "$(date -u +%Y-%m-%dT%H:%M:%SZ)" \
     --field commit "$COMMIT" --field modified "$DIRTY" --field limit_s "$LIMIT" \
     --field tiny "$([ "$TINY" = 1 ] && echo true || echo false)" --field python "$PY"

# ---------------------------------------------------------------- the device
if command -v nvidia-smi >/dev/null 2>&1; then
    timeout 30 nvidia-smi >"$OUT/nvidia-smi.txt" 2>&1
    cat "$OUT/nvidia-smi.txt"
else
    echo "nvidia-smi: not found" | tee "$OUT/nvidia-smi.txt"
fi
echo "== [$(clock)] jax.devices()"
budget=$(left)
[ "$budget" -gt 120 ] && budget=120
timeout -k "$GRACE" "$budget" "$PY" -u "$HELPER" device "$OUT" \
    || echo "== jax could not list its devices (exit $?): see above"
BACKEND=$("$PY" -c 'import json,sys; print(json.load(open(sys.argv[1])).get("backend","?"))' \
          "$OUT/device.json" 2>/dev/null || echo "?")
if [ -z "$CHUNK" ]; then
    if [ "$TINY" = 1 ]; then CHUNK=2; elif [ "$BACKEND" = gpu ]; then CHUNK=256; else CHUNK=8; fi
fi
commands "$WORK/sweep.toml" "$CHUNK"
cp "$WORK/sweep.toml" "$OUT/sweep.toml"

# ---------------------------------------------------------------- the caches
if [ "$REUSE" = 1 ]; then
    CACHE=${LFJAX_CACHE_DIR:-${XDG_CACHE_HOME:-$HOME/.cache}/lfjax/jax}
    COLD="reused: $CACHE (--reuse-cache; the cold figure is not cold)"
else
    CACHE="$WORK/cache"
    COLD="empty: a new temporary folder"
fi
mkdir -p "$CACHE"
export LFJAX_CACHE_DIR="$CACHE" JAX_COMPILATION_CACHE_DIR="$CACHE"
meta --field cold_cache "$COLD" --field backend "$BACKEND" --field sweep_chunk_size "$CHUNK"

# ---------------------------------------------------------------- one step
FAILED=0
run_step() {  # NAME CAP [KEY JSON]... -- LFJAX-ARGS...
    local name=$1 cap=$2 fields=() budget rc t0 t1 wall
    shift 2
    while [ "$1" != "--" ]; do fields+=(--field "$1" "$2"); shift 2; done
    shift
    local cmd="lfjax $*"
    cmd=${cmd//"$WORK"/\$WORK}
    # keep MIN_STEP (and a kill's grace and a step's overhead) for each later step, so every
    # step gets its turn
    STEPS_LEFT=$((STEPS_LEFT - 1))
    budget=$(( $(left) - STEPS_LEFT * (MIN_STEP + GRACE + STEP_OVERHEAD) ))
    [ "$cap" -lt "$budget" ] && budget=$cap
    echo
    echo "== [$(clock)] $name: $cmd"
    if [ "$budget" -lt "$MIN_STEP" ]; then
        echo "== [$(clock)] $name: not run, no time left of the $LIMIT s limit"
        FAILED=1
        "$PY" "$HELPER" step "$OUT" "$name" --skipped "no time left of the $LIMIT s limit" \
            --field command "$cmd" --field budget_s "$budget" "${fields[@]}"
        return
    fi
    echo "== time limit $budget s"
    local timev=()
    [ -x /usr/bin/time ] && timev=(/usr/bin/time -v -o "$OUT/steps/$name.time.txt")
    if command -v nvidia-smi >/dev/null 2>&1; then
        nvidia-smi --query-gpu=memory.used --format=csv,noheader,nounits -lms 250 \
            >"$OUT/steps/$name.smi.txt" 2>/dev/null &
        SMI_PID=$!
    fi
    t0=$(date +%s.%N)
    # /usr/bin/time outside timeout: it survives the time limit and still writes its figures
    "${timev[@]}" timeout -k "$GRACE" "$budget" \
        "$PY" -u "$HELPER" exec --stats "$OUT/steps/$name.stats.json" -- "$@" 2>&1 \
        | tee "$OUT/steps/$name.log"
    rc=${PIPESTATUS[0]}
    t1=$(date +%s.%N)
    if [ -n "$SMI_PID" ]; then
        kill "$SMI_PID" 2>/dev/null
        wait "$SMI_PID" 2>/dev/null
        SMI_PID=""
    fi
    wall=$(awk -v a="$t0" -v b="$t1" 'BEGIN { printf "%.3f", b - a }')
    [ "$rc" = 0 ] || FAILED=1
    "$PY" "$HELPER" step "$OUT" "$name" --field command "$cmd" --field wall_s "$wall" \
        --field rc "$rc" --field budget_s "$budget" "${fields[@]}"
    case $rc in
        0) echo "== [$(clock)] $name: done in $wall s" ;;
        124|137) echo "== [$(clock)] $name: timed out after $wall s (limit $budget s)" ;;
        *) echo "== [$(clock)] $name: failed, exit $rc after $wall s" ;;
    esac
}

# ---------------------------------------------------------------- the steps
# each step's share of the time left after the device: 30, 12, 38 and 20 %; time a step
# leaves unused goes to the later ones (the fit takes whatever is left)
AVAIL=$(left)
run_step reproduce_cold $((AVAIL * 30 / 100)) -- "${REPRODUCE[@]}" --out "$WORK/reproduce_cold"
run_step reproduce_warm $((AVAIL * 12 / 100)) -- "${REPRODUCE[@]}" --out "$WORK/reproduce_warm"
run_step sweep $((AVAIL * 38 / 100)) store "\"$WORK/sweep.zarr\"" n_eyes "$N_EYES" \
    chunk_size "$CHUNK" -- sweep "$WORK/sweep.toml" --out "$WORK/sweep.zarr"
run_step optimise "$LIMIT" -- "${OPTIMISE[@]}" --out "$WORK/optimise"

for name in reproduce_cold reproduce_warm; do
    [ -f "$WORK/$name/REPORT.md" ] && cp "$WORK/$name/REPORT.md" "$OUT/$name.REPORT.md"
done
[ -f "$WORK/optimise/layout.json" ] && cp "$WORK/optimise/layout.json" "$OUT/optimise.layout.json"

# ---------------------------------------------------------------- the summary
echo
echo "== [$(clock)] summary"
meta --field total_s "$(( $(date +%s) - START ))"
"$PY" "$HELPER" summary "$OUT" || FAILED=1
echo "== record in $OUT"
[ "$KEEP" = 1 ] && echo "== the steps' outputs are kept in $WORK"
# let tee write the last lines before the script returns
exec >&- 2>&-
wait "$TEE_PID" 2>/dev/null
exit "$FAILED"
}
