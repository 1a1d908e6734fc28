#!/usr/bin/env bash
# End to end on a real Slurm (tools/slurm-local.sh: one node, this machine):
# a 4-frame shot as one job array, one task requeued (scontrol requeue) and
# one stopped with SIGTERM (scancel --batch --signal=TERM) mid-render, and a
# frame split 4 ways with one part requeued mid-render; every frame must
# complete and equal its uninterrupted render, the split frame the unsplit one.
# Exit 77 (CTest: skipped) when Slurm cannot run here, saying why.
#
#   tests/farm/test_farm_slurm.sh THEIA_BINARY SOURCE_DIR
set -uo pipefail
theia=$1
src=$2
SPP=${FARM_TEST_SPP:-2048}

skip() { echo "SKIPPED: $*"; exit 77; }
[ "$(id -u)" -eq 0 ] || skip "slurmd must run as root (it starts jobs as their user); run the farm label as root"
install_log=$("$src/tools/slurm-local.sh" install 2>&1) || skip "cannot install slurm-wlm and munge: $install_log"

export SLURM_LOCAL_DIR
SLURM_LOCAL_DIR=$(mktemp -d /tmp/theia-farm-test.XXXXXX)
export SLURM_LOCAL_PORT=$((20000 + RANDOM % 20000))
export SLURM_CONF=$SLURM_LOCAL_DIR/slurm.conf
cleanup() {
  "$src/tools/slurm-local.sh" stop >/dev/null 2>&1
  [ "${KEEP:-0}" = 1 ] || rm -rf "$SLURM_LOCAL_DIR"
}
start_log=$("$src/tools/slurm-local.sh" start 2>&1)
rc=$?
trap cleanup EXIT
[ $rc -eq 0 ] || skip "slurmd cannot run here: $start_log"
echo "$start_log"

work=$SLURM_LOCAL_DIR/work
mkdir -p "$work/shot" "$work/ref"
fail() {
  echo "FAILED: $*"
  for f in "$work"/*/logs/*.out "$SLURM_LOCAL_DIR"/log/slurmctld.log; do
    [ -f "$f" ] && { echo "--- $f"; tail -15 "$f"; }
  done
  exit 1
}

# The shot: a sphere growing from frame to frame, lit by a small emitter and the sky.
for f in 1 2 3 4; do
  cat >"$work/shot/frame.000$f.pbrt" <<PBRT
Film "rgb" "integer xresolution" [48] "integer yresolution" [32]
LookAt 0 1 -5  0 0 0  0 1 0
Camera "perspective" "float fov" [35]
WorldBegin
LightSource "infinite" "rgb L" [1 1 1]
AttributeBegin
  Translate 1.2 0.8 -0.5
  AreaLightSource "diffuse" "rgb L" [4 4 4]
  Shape "sphere" "float radius" [0.3]
AttributeEnd
Material "diffuse" "rgb reflectance" [0.7 0.5 0.3]
Shape "sphere" "float radius" [0.$((5 + f))]
Shape "trianglemesh" "point3 P" [-4 -1 -4  4 -1 -4  4 -1 4  -4 -1 4] "integer indices" [0 1 2 0 2 3]
PBRT
done

# The farm's jobs: the sequence on the default partition, the split frame on the preemptible one.
# Unguided (--no-guiding; the default --guiding-auto may guide at this spp): a split frame's parts
# would each learn their own field, unbiased but not the unsplit image (theia merge says so).
"$theia" farm submit --pattern "$work/shot/frame.%04d.pbrt" --frames 1-4 -d "$work/seq" --spp "$SPP" \
  --cpus-per-task 1 --signal-seconds 30 --render-options "--no-guiding" || fail "farm submit (sequence)"
"$theia" farm submit "$work/shot/frame.0001.pbrt" -d "$work/split" --split 4 --spp "$SPP" --cpus-per-task 1 \
  --partition preempt --render-options "--no-guiding" || fail "farm submit (split)"
seq_job=$(sed -n 's/.*"id": "\([0-9]*\)".*/\1/p' "$work/seq/farm.json" | head -1)
parts_job=$(sed -n 's/.*"id": "\([0-9]*\)".*/\1/p' "$work/split/farm.json" | head -1)
[ -n "$seq_job" ] && [ -n "$parts_job" ] || fail "no job ids in farm.json"

# Slurm holds a requeued job for about two minutes (its begin time); the test
# does not wait for that: any of our jobs pending on BeginTime is released.
release() {
  squeue -h -t PD -o "%i %r" | awk '$2 == "BeginTime" { print $1 }' | while read -r j; do
    scontrol update jobid="$j" StartTime=now >/dev/null 2>&1
  done
}
# Waits until a task has written a checkpoint (the render is under way), at most 120 s.
wait_checkpoint() {
  for _ in $(seq 1 1200); do
    compgen -G "$1/checkpoint-*.bin" >/dev/null && return 0
    sleep 0.1
  done
  return 1
}
interrupted_early() {  # the render must still be running when it is interrupted
  [ ! -e "$1" ] || fail "$1 was already written: the interruption did not land mid-render (raise FARM_TEST_SPP)"
}

wait_checkpoint "$work/seq/checkpoints/frame.0002" || fail "frame.0002 never checkpointed"
interrupted_early "$work/seq/frames/frame.0002.exr"
scontrol requeue "${seq_job}_1" || fail "scontrol requeue ${seq_job}_1"
echo "requeued ${seq_job}_1 (frame.0002) mid-render"
wait_checkpoint "$work/seq/checkpoints/frame.0003" || fail "frame.0003 never checkpointed"
interrupted_early "$work/seq/frames/frame.0003.exr"
scancel --batch --signal=TERM "${seq_job}_2" || fail "scancel --batch --signal=TERM ${seq_job}_2"
echo "sent SIGTERM to ${seq_job}_2 (frame.0003) mid-render"
wait_checkpoint "$work/split/checkpoints/frame.0001.part-2" || fail "part 2 never checkpointed"
interrupted_early "$work/split/parts/frame.0001.part-2.exr"
scontrol requeue "${parts_job}_2" || fail "scontrol requeue ${parts_job}_2"
echo "requeued ${parts_job}_2 (frame.0001 part 2) mid-render"

# The uninterrupted renders, while the farm finishes.
for f in 1 2 3 4; do
  "$theia" render "$work/shot/frame.000$f.pbrt" -o "$work/ref/frame.000$f.exr" --spp "$SPP" --threads 1 -q --no-guiding ||
    fail "reference render of frame $f"
done

for _ in $(seq 1 300); do
  release
  [ -z "$(squeue -h -o %i)" ] && break
  sleep 1
done
[ -z "$(squeue -h -o %i)" ] || fail "jobs still queued after 300 s: $(squeue -h)"

"$theia" farm status "$work/seq" | tee "$work/status.txt"
"$theia" farm status "$work/split"
"$theia" farm collect "$work/seq" || fail "farm collect: the sequence is incomplete"
"$theia" farm collect "$work/split" || fail "farm collect: the split frame is incomplete"
for f in frame.0002 frame.0003; do
  awk -v f=$f '$1 == f && $2 == "done" && $3 >= 1 { ok = 1 } END { exit !ok }' "$work/status.txt" ||
    fail "$f: status does not show it done after a requeue"
  grep -q '"resumed": true' "$work/seq/frames/$f.json" || fail "$f did not resume from its checkpoint"
done
grep -q '"resumed": true' "$work/split/parts/frame.0001.part-2.json" || fail "part 2 did not resume"

# Equal to the uninterrupted renders up to float summation order.
same() {  # same A B: relMSE below 1e-10 (a missing or repeated sample is ~1e-3)
  local e
  e=$("$theia" diff "$1" "$2" | awk '$1 == "relMSE" { print $2 }')
  awk -v e="$e" 'BEGIN { exit !(e != "" && e < 1e-10) }' || fail "$1 differs from $2: relMSE $e"
  echo "$(basename "$1") equals $(basename "$2") (relMSE $e)"
}
for f in 1 2 3 4; do same "$work/seq/frames/frame.000$f.exr" "$work/ref/frame.000$f.exr"; done
same "$work/split/frames/frame.0001.exr" "$work/ref/frame.0001.exr"
echo "farm: all frames complete and equal to their uninterrupted renders"
