#!/usr/bin/env bash
# Soak test of the farm's durability (not part of CI): many jobs, workers killed all the time, the
# master restarted mid-run, and every image checked bit for bit.
#
#   scripts/soak.sh [--jobs N] [--sequences K] [--workers W] [--size PX] [--spp N]
#                   [--kill-every S] [--timeout S] [--build DIR] [--keep]
#
# Defaults: 50 jobs submitted at once to a master with 4 workers (1 thread each) on loopback
# (--insecure), 64x64 images at 256 spp in 16x16 tiles and passes of 16 (256 units a job); every
# S = 3 seconds one worker is hit, in turn killed with SIGKILL and started again, or frozen with
# SIGSTOP for 2 s (long enough to be declared lost) and thawed; the master is killed with
# SIGKILL once a third of the units are merged and stopped with SIGTERM at two thirds, each time
# started again on the same data dir. The jobs use 5 distinct settings (two scenes, three seeds, one
# with a target error), so that 5 `rayfarm render`s give the reference of every job, and every
# job's final EXR is compared with its reference by `rayfarm compare` (exit 0 = bit-identical).
# Submitted at the same time, K = 2 sequences of scenes/animated-box (`submit --frames`, same size,
# spp and layout, own seeds; in turn 1-48:6, 4-48:6 with nee and a target error of 0.02 (reached at
# 64x64, unlike the jobs' 0.002, so its tiles stop adaptively), 2-47:5 with max depth 4) live
# through the same kills and restarts; every frame is fetched (`fetch SEQ --all`) and compared with
# `rayfarm render --frame N` of its settings (the thirds of the master's kill and stop count the
# frames, a frame being as many units as a job). Prints the figures: jobs, sequences and frames,
# units, kills, freezes, restarts, duplicates dropped, units requeued, stragglers, jobs resumed from
# checkpoints, lost (jobs or frames not done or not bit-identical; must be 0) and the wall time.
# Exit 0 when nothing is lost. Binaries from ./build (or $RAYFARM_BIN).
set -euo pipefail

repo_root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
jobs=50
sequences=2
workers=4
size=64
spp=256
kill_every=3
timeout=600
build="${RAYFARM_BIN:-$repo_root/build}"
keep=0

while [ $# -gt 0 ]; do
  case $1 in
    --jobs) jobs=$2; shift 2 ;;
    --sequences) sequences=$2; shift 2 ;;
    --workers) workers=$2; shift 2 ;;
    --size) size=$2; shift 2 ;;
    --spp) spp=$2; shift 2 ;;
    --kill-every) kill_every=$2; shift 2 ;;
    --timeout) timeout=$2; shift 2 ;;
    --build) build=$2; shift 2 ;;
    --keep) keep=1; shift ;;
    -h|--help) sed -n '2,24p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
    *) echo "soak: unknown option '$1'" >&2; exit 2 ;;
  esac
done

bin() {
  local c
  for c in "$build/$2/$1" "$build/$1"; do [ -x "$c" ] && { echo "$c"; return; }; done
  echo "soak: cannot find $1 under $build (build first, or --build DIR)" >&2
  exit 1
}
work=$(mktemp -d "${TMPDIR:-/tmp}/rayfarm-soak.XXXXXX")
mkdir "$work/bin" "$work/logs" "$work/out"
# Copies, so that a rebuild during the soak cannot mix two versions.
cp "$(bin rayfarm cli)" "$(bin rayfarm-master master)" "$(bin rayfarm-worker worker)" "$work/bin/"
rayfarm="$work/bin/rayfarm"

free_port() {
  python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1",0)); print(s.getsockname()[1])'
}
wport=$(free_port)
cport=$(free_port)
export RAYFARM_MASTER="tcp://127.0.0.1:$cport"

master_pid=""
declare -a worker_pids
declare -a ref_pids=()
cleanup() {
  local p
  for p in "${worker_pids[@]}" $master_pid; do kill -KILL "$p" 2>/dev/null || true; done
  for p in "${ref_pids[@]}"; do kill -TERM "$p" 2>/dev/null || true; done
  wait 2>/dev/null || true
  if [ "$keep" = 1 ]; then echo "soak: kept $work"; else rm -rf "$work"; fi
}
trap cleanup EXIT

start_master() {
  "$work/bin/rayfarm-master" --insecure --worker-endpoint "tcp://127.0.0.1:$wport" \
    --client-endpoint "tcp://127.0.0.1:$cport" --data-dir "$work/data" \
    --heartbeat-ms 250 --liveness 4 --checkpoint-interval-ms 1000 --max-queued-jobs 1000 \
    >>"$work/logs/master.log" 2>&1 &
  master_pid=$!
  local i
  for i in $(seq 100); do
    grep -q "master listening" "$work/logs/master.log" 2>/dev/null &&
      [ "$(grep -c 'master listening' "$work/logs/master.log")" -ge "$1" ] && return
    sleep 0.1
  done
  echo "soak: the master did not start" >&2
  exit 1
}
start_worker() {
  "$work/bin/rayfarm-worker" --insecure --master "tcp://127.0.0.1:$wport" --threads 1 \
    --cache-dir "$work/cache-$1" --name "w$1" --heartbeat-ms 250 --liveness 4 \
    --reconnect-max-ms 1000 >>"$work/logs/worker-$1.log" 2>&1 &
  worker_pids[$1]=$!
}

# Job settings: scene, size and the options; job k uses setting k % 5.
prepare_scene() {
  local name=$1
  mkdir -p "$work/scenes/$name"
  cp -r "$repo_root/scenes/$name/." "$work/scenes/$name/"
  python3 - "$work/scenes/$name/scene.json" "$size" <<'EOF'
import json, sys
path, size = sys.argv[1], int(sys.argv[2])
scene = json.load(open(path))
scene["film"] = {"width": size, "height": size}
json.dump(scene, open(path, "w"), indent=2)
EOF
}
prepare_scene cornell-box
prepare_scene embree-cornell
prepare_scene animated-box
settings=(
  "$work/scenes/cornell-box/scene.json|--spp $spp --seed 1"
  "$work/scenes/cornell-box/scene.json|--spp $spp --seed 2 --integrator nee"
  "$work/scenes/embree-cornell/scene.json|--spp $spp --seed 3"
  "$work/scenes/embree-cornell/scene.json|--spp $spp --seed 4 --max-depth 4"
  "$work/scenes/cornell-box/scene.json|--spp $spp --seed 5 --target-error 0.002 --min-passes 2"
)
layout="--tile 16 --pass-spp 16"
# Sequences: frames and options; sequence s uses setting (s - 1) % 3 and seed 10 + s.
seq_scene="$work/scenes/animated-box/scene.json"
seq_settings=(
  "1-48:6|--spp $spp"
  "4-48:6|--spp $spp --integrator nee --target-error 0.02 --min-passes 2"
  "2-47:5|--spp $spp --max-depth 4"
)
declare -a seq_frames seq_opts
frames_total=0
for s in $(seq 1 "$sequences"); do
  IFS='|' read -r range opts <<<"${seq_settings[$(( (s - 1) % 3 ))]}"
  seq_frames[s]=$range
  seq_opts[s]="$opts --seed $((10 + s))"
  # A-B:STEP -> the frame numbers.
  IFS='-:' read -r a b step <<<"$range"
  frames_total=$(( frames_total + ( b - a ) / step + 1 ))
done
frame_list() { local a b step; IFS='-:' read -r a b step <<<"${seq_frames[$1]}"; seq "$a" "$step" "$b"; }

start=$(date +%s.%N)
start_master 1
for w in $(seq 1 "$workers"); do start_worker "$w"; done

# Submit every job at once.
declare -a sub_pids
for k in $(seq 1 "$jobs"); do
  IFS='|' read -r scene opts <<<"${settings[$(( (k - 1) % 5 ))]}"
  # shellcheck disable=SC2086
  "$rayfarm" submit "$scene" $opts $layout --name "soak-$k" --timeout 60 --insecure \
    >"$work/out/submit-$k.out" 2>"$work/out/submit-$k.err" &
  sub_pids+=($!)
done
for s in $(seq 1 "$sequences"); do
  # shellcheck disable=SC2086
  "$rayfarm" submit "$seq_scene" --frames "${seq_frames[s]}" ${seq_opts[s]} $layout \
    --name "soak-seq-$s" --timeout 60 --insecure \
    >"$work/out/seq-submit-$s.out" 2>"$work/out/seq-submit-$s.err" &
  sub_pids+=($!)
done
for p in "${sub_pids[@]}"; do wait "$p" || { echo "soak: a submission failed" >&2; cat "$work/out"/*submit-*.err >&2; exit 1; }; done
submitted=$(cat "$work/out"/submit-*.out | grep -c '^j[0-9]')
echo "soak: $submitted jobs submitted"
if [ "$sequences" -gt 0 ]; then
  echo "soak: $(cat "$work/out"/seq-submit-*.out | grep -c '^j[0-9]') sequences submitted ($frames_total frames)"
fi

# References, while the farm works (they share the machine, which only slows things down).
for i in 0 1 2 3 4; do
  IFS='|' read -r scene opts <<<"${settings[$i]}"
  # shellcheck disable=SC2086
  "$rayfarm" render "$scene" -o "$work/out/ref-$i.exr" --threads 1 $opts $layout \
    >"$work/logs/ref-$i.log" 2>&1 &
  ref_pids+=($!)
done
# A sequence's references, one frame after the other (killed with the subshell on exit).
render_frames() {
  local s=$1 n child=""
  trap '[ -z "$child" ] || kill -KILL "$child" 2>/dev/null; exit 1' TERM
  for n in $(frame_list "$s"); do
    # shellcheck disable=SC2086
    "$rayfarm" render "$seq_scene" --frame "$n" -o "$work/out/ref-seq-$s.$(printf %04d "$n").exr" \
      --threads 1 ${seq_opts[s]} $layout >>"$work/logs/ref-seq-$s.log" 2>&1 &
    child=$!
    wait "$child" || echo "soak: reference of frame $n of sequence $s failed" >>"$work/logs/ref-seq-$s.log"
  done
}
for s in $(seq 1 "$sequences"); do
  render_frames "$s" &
  ref_pids+=($!)
done

units_total=$(( jobs * (size / 16) * (size / 16) * (spp / 16) ))
units_frames=$(( frames_total * (size / 16) * (size / 16) * (spp / 16) ))
kills=0
freezes=0
events=0
frozen=""
thaw_at=0
restarts=0
phase=0
next_kill=$(( $(date +%s) + kill_every ))
deadline=$(( $(date +%s) + timeout ))
while :; do
  sleep 0.5
  list=$("$rayfarm" list --timeout 5 --insecure 2>/dev/null || true)
  # A sequence is one line of the list, its frames done / total in the SPP column ("3/8 fr").
  read -r done_jobs done_seqs frames_done < <(awk '
    $1 ~ /^j[0-9]+$/ { seq = 0
      for (i = 2; i <= NF; i++) if ($i == "fr") { seq = 1; split($(i - 1), f, "/"); frames += f[1] }
      if (/ done /) { if (seq) seqs++; else stills++ } }
    END { print stills + 0, seqs + 0, frames + 0 }' <<<"$list")
  [ "$done_jobs" -ge "$jobs" ] && [ "$done_seqs" -ge "$sequences" ] && break
  if [ "$(date +%s)" -ge "$deadline" ]; then echo "soak: timeout" >&2; break; fi
  # Units merged so far, from the master's pass lines is too coarse: use the share of the done
  # jobs and frames (a frame is as many units as a job).
  merged_share=$(( (done_jobs + frames_done) * 3 / (jobs + frames_total) ))
  done_note=""
  [ "$sequences" -gt 0 ] && done_note=" and $frames_done of $frames_total frames"
  if [ "$phase" = 0 ] && [ "$merged_share" -ge 1 ]; then
    echo "soak: master killed (SIGKILL) with $done_jobs jobs$done_note done"
    kill -KILL "$master_pid"; wait "$master_pid" 2>/dev/null || true
    restarts=$((restarts + 1)); phase=1
    start_master $((restarts + 1))
  elif [ "$phase" = 1 ] && [ "$merged_share" -ge 2 ]; then
    echo "soak: master stopped (SIGTERM) with $done_jobs jobs$done_note done"
    kill -TERM "$master_pid"; wait "$master_pid" 2>/dev/null || true
    restarts=$((restarts + 1)); phase=2
    start_master $((restarts + 1))
  fi
  if [ -n "$frozen" ] && [ "$(date +%s)" -ge "$thaw_at" ]; then
    kill -CONT "${worker_pids[$frozen]}" 2>/dev/null || true
    frozen=""
  fi
  if [ "$(date +%s)" -ge "$next_kill" ]; then
    w=$(( RANDOM % workers + 1 ))
    events=$((events + 1))
    if [ $((events % 2)) = 1 ] || [ -n "$frozen" ]; then
      [ "$w" = "$frozen" ] && { kill -CONT "${worker_pids[$w]}" 2>/dev/null || true; frozen=""; }
      kill -KILL "${worker_pids[$w]}" 2>/dev/null || true
      wait "${worker_pids[$w]}" 2>/dev/null || true
      kills=$((kills + 1))
      start_worker "$w"
    else
      kill -STOP "${worker_pids[$w]}" 2>/dev/null || true
      frozen=$w
      thaw_at=$(( $(date +%s) + 2 ))
      freezes=$((freezes + 1))
    fi
    next_kill=$(( $(date +%s) + kill_every ))
  fi
done
[ -n "$frozen" ] && kill -CONT "${worker_pids[$frozen]}" 2>/dev/null || true
end=$(date +%s.%N)
wait_refs=0
for i in 0 1 2 3 4; do
  while [ ! -s "$work/out/ref-$i.exr" ] && [ $wait_refs -lt 600 ]; do sleep 0.5; wait_refs=$((wait_refs + 1)); done
done
for s in $(seq 1 "$sequences"); do
  for n in $(frame_list "$s"); do
    ref="$work/out/ref-seq-$s.$(printf %04d "$n").exr"
    while [ ! -s "$ref" ] && [ $wait_refs -lt 600 ]; do sleep 0.5; wait_refs=$((wait_refs + 1)); done
  done
done
sleep 1

# Every job: done, and bit-identical to its reference.
lost=0
identical=0
for k in $(seq 1 "$jobs"); do
  id=$(head -n1 "$work/out/submit-$k.out")
  i=$(( (k - 1) % 5 ))
  if ! "$rayfarm" fetch "$id" -o "$work/out/$id.exr" --timeout 30 --insecure >/dev/null 2>&1; then
    echo "soak: job $id ($k) cannot be fetched" >&2; lost=$((lost + 1)); continue
  fi
  state=$("$rayfarm" status "$id" --timeout 10 --insecure 2>/dev/null | head -n 3 || true)
  if ! grep -q "done" <<<"$state"; then
    echo "soak: job $id is not done: $state" >&2; lost=$((lost + 1)); continue
  fi
  if "$rayfarm" compare "$work/out/$id.exr" "$work/out/ref-$i.exr" >/dev/null 2>&1; then
    identical=$((identical + 1))
  else
    echo "soak: job $id differs from its reference" >&2; lost=$((lost + 1))
  fi
done

# Every frame of every sequence: done, and bit-identical to `rayfarm render --frame N`.
frames_identical=0
for s in $(seq 1 "$sequences"); do
  id=$(head -n1 "$work/out/seq-submit-$s.out")
  mkdir -p "$work/out/$id"
  "$rayfarm" status "$id" --json --timeout 10 --insecure >"$work/out/$id/status.json" 2>/dev/null || true
  if ! "$rayfarm" fetch "$id" --all -o "$work/out/$id/frame.####.exr" --timeout 30 --insecure \
      >"$work/out/$id/fetch.out" 2>&1; then
    echo "soak: sequence $id ($s): fetch --all failed: $(tail -n1 "$work/out/$id/fetch.out")" >&2
  fi
  # frames_done/frames_total and the frames not done, from the master.
  summary=$(python3 - "$work/out/$id/status.json" <<'EOF'
import json, sys
try:
    j = json.loads(open(sys.argv[1]).readline())
    rest = ["%d:%s" % (f["frame"], f["state"]) for f in j["frames"] if f["state"] != "done"]
    print(j["frames_done"], j["frames_total"], " ".join(rest))
except (OSError, ValueError, KeyError, TypeError):
    print("? ? (no status)")
EOF
)
  read -r fdone ftotal fnotdone <<<"$summary"
  expected=$(frame_list "$s" | wc -l)
  if [ "$ftotal" != "$expected" ]; then
    echo "soak: sequence $id ($s) has $ftotal frames, $expected submitted" >&2
  fi
  if [ "$fdone" != "$ftotal" ]; then
    echo "soak: sequence $id ($s): $fdone of $ftotal frames done; not done: $fnotdone" >&2
  fi
  for n in $(frame_list "$s"); do
    f=$(printf %04d "$n")
    out="$work/out/$id/frame.$f.exr"
    ref="$work/out/ref-seq-$s.$f.exr"
    if [ ! -s "$out" ]; then
      echo "soak: frame $n of $id ($id.$f) is not done or cannot be fetched" >&2; lost=$((lost + 1))
    elif [ ! -s "$ref" ]; then
      echo "soak: frame $n of $id has no reference (logs/ref-seq-$s.log)" >&2; lost=$((lost + 1))
    elif "$rayfarm" compare "$out" "$ref" >/dev/null 2>&1; then
      frames_identical=$((frames_identical + 1))
    else
      echo "soak: frame $n of $id ($id.$f) differs from rayfarm render --frame $n" >&2
      lost=$((lost + 1))
    fi
  done
done

log="$work/logs/master.log"
count() { grep -c -- "$1" "$log" || true; }
requeued=$({ grep -o 'requeued [0-9]* unit' "$log" || true; } | awk '{s += $2} END {print s + 0}')
printf 'soak figures (%s)\n' "$(date -u +%Y-%m-%dT%H:%MZ)"
printf '  jobs                  %d submitted, %d done and bit-identical to rayfarm render\n' "$jobs" "$identical"
if [ "$sequences" -gt 0 ]; then
  printf '  sequences             %d submitted, %d frames; %d frames done and bit-identical to rayfarm render --frame N\n' "$sequences" "$frames_total" "$frames_identical"
  printf '  units                 %d (%d in frames; the target-error jobs and frames need fewer)\n' "$((units_total + units_frames))" "$units_frames"
else
  printf '  units                 %d (the target-error jobs need fewer)\n' "$units_total"
fi
printf '  workers               %d x 1 thread; %d killed with SIGKILL and restarted, %d frozen 2 s with SIGSTOP\n' "$workers" "$kills" "$freezes"
printf '  master restarts       %d (one SIGKILL, one SIGTERM)\n' "$restarts"
printf '  jobs resumed          %d from a checkpoint, %d from the start (running, no checkpoint yet), %d queued again\n' "$(count 'resumed from checkpoint at')" "$(count 'restarted from the beginning')" "$(count 'queued again')"
printf '  checkpoints unusable  %d\n' "$(count 'cannot use checkpoint')"
printf '  duplicates dropped    %d\n' "$(count 'duplicate result')"
printf '  units requeued        %d\n' "$requeued"
printf '  stragglers            %d\n' "$(count 'is a straggler')"
printf '  lost                  %d\n' "$lost"
printf '  wall time             %.1f s\n' "$(awk -v a="$start" -v b="$end" 'BEGIN { print b - a }')"
[ "$lost" = 0 ]
