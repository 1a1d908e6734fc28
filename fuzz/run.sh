#!/bin/sh
# Runs the libFuzzer targets of a THEIA_FUZZ build for SECONDS each, from a
# scratch copy of the seed corpus (new inputs land in BUILD/corpus-TARGET,
# crashes in BUILD/crashes-TARGET).
#   fuzz/run.sh BUILD_DIR/fuzz SECONDS [scene|ply|image ...]
# FUZZ_TIMEOUT (seconds per input, default 10): libFuzzer's timeout is wall
# clock, so a run under `nice` on a busy machine needs more (a starved input
# is not a hang: replay it alone to see its CPU time).
set -eu
bin=$1
seconds=$2
shift 2
here=$(cd "$(dirname "$0")" && pwd)
targets=${*:-scene ply image}
status=0
for t in $targets; do
  corpus=$bin/corpus-$t
  crashes=$bin/crashes-$t
  mkdir -p "$corpus" "$crashes"
  cp -n "$here"/corpus/$t/* "$corpus"/ 2>/dev/null || true
  # 2 GB RSS and 10 s per input: an allocation the header checks missed, or a hang, is a finding.
  timeout=${FUZZ_TIMEOUT:-10}
  # The fast unwinder (frame pointers) for the stacks ASan keeps at every allocation:
  # the slow one through OpenImageIO was half the image target's time.
  ASAN_OPTIONS=fast_unwind_on_malloc=1 "$bin"/fuzz_$t "$corpus" -dict="$here"/pbrt.dict -max_total_time="$seconds" -rss_limit_mb=2048 -timeout="$timeout" \
    -artifact_prefix="$crashes"/ -print_final_stats=1 2>"$bin"/fuzz-$t.log || status=1
  grep -E "stat::number_of_executed_units|SUMMARY|ERROR" "$bin"/fuzz-$t.log | sed "s/^/$t: /"
done
exit $status
