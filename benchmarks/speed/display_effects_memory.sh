#!/usr/bin/env bash
# Peak resident memory of `lfjax reproduce --quick --display-effects --display-eyes 1` on the CPU,
# for the lfjax source tree in SRC (default: this checkout), with its log under OUTDIR.
#
#   bash benchmarks/speed/display_effects_memory.sh [SRC] [OUTDIR] [CPUS]
#
# PYTHON (default python3) is the interpreter. SRC may be an older tree, e.g. `git archive c687eb3^ lfjax | tar -x -C /tmp/before` (the commit
# before the radial MTF's dense binning matrix was replaced by a gather). CPUS pins the run
# (taskset list, e.g. 0-7). Besides /usr/bin/time's maximum RSS, a sampler writes the peak seen so
# far every 2 s to OUTDIR/rss.txt, so a run stopped by a time limit still reports its peak to then.
set -u
SRC=${1:-$(pwd)}
OUTDIR=${2:-/tmp/lfjax-memory}
CPUS=${3:-}
mkdir -p "$OUTDIR"
export PYTHONPATH="$SRC${PYTHONPATH:+:$PYTHONPATH}" JAX_PLATFORMS=cpu PYTHONUNBUFFERED=1
pin=()
[ -n "$CPUS" ] && pin=(taskset -c "$CPUS")
start=$(date +%s)
"${pin[@]}" /usr/bin/time -v -o "$OUTDIR/time.txt" "${PYTHON:-python3}" -m lfjax.cli reproduce --quick \
    --display-effects --display-eyes 1 --no-progress --force --out "$OUTDIR/report" \
    >"$OUTDIR/log" 2>&1 &
pid=$!
peak=0
while kill -0 "$pid" 2>/dev/null; do
    kb=$(ps -o rss= --ppid "$pid" 2>/dev/null | sort -n | tail -1)
    [ -n "${kb// /}" ] && [ "$kb" -gt "$peak" ] && peak=$kb
    echo "elapsed $(( $(date +%s) - start )) s, peak RSS so far ${peak} kB" >"$OUTDIR/rss.txt"
    sleep 2
done
wait "$pid"; rc=$?
echo "exit $rc after $(( $(date +%s) - start )) s, peak RSS sampled ${peak} kB" >"$OUTDIR/rss.txt"
grep -E "Maximum resident|Elapsed|Exit status" "$OUTDIR/time.txt" >>"$OUTDIR/rss.txt" 2>/dev/null
cat "$OUTDIR/rss.txt"
