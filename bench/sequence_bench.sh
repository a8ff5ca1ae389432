#!/usr/bin/env bash
# What a long frame sequence costs the master before any worker renders it: accepting, querying,
# listing and cancelling one, its memory and its data dir.
#
#   bench/sequence_bench.sh [--frames N] [--size S] [--repeat R] [--build DIR]
#
# Defaults: 1000 frames of scenes/animated-box (its animation stretched to N frames) at 256x256,
# R = 3, binaries from ./build. Starts a master on loopback without keys or workers, and for each
# round submits the sequence, asks its status and the job list, and cancels it, timing each
# command from the client (the master does the work on its reactor thread, except the scene's
# check on submission). Prints each round's figures, then the medians, the master's resident
# memory after the last submission, and what a film per frame would have held (96 bytes a pixel).
# Prints figures only; nothing here is a test.
set -euo pipefail

repo_root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
frames=1000 size=256 repeat=3 build="$repo_root/build"
while [[ $# -gt 0 ]]; do
  case "$1" in
    --frames) frames=$2; shift 2 ;;
    --size) size=$2; shift 2 ;;
    --repeat) repeat=$2; shift 2 ;;
    --build) build=$2; shift 2 ;;
    *) echo "sequence_bench: unknown option $1" >&2; exit 2 ;;
  esac
done
work=$(mktemp -d)
master_pid=
cleanup() {
  [[ -n "$master_pid" ]] && kill "$master_pid" 2>/dev/null && wait "$master_pid" 2>/dev/null
  rm -rf "$work"
}
trap cleanup EXIT
python3 - "$work" "$frames" "$size" "$repo_root" <<'PY'
import json, sys
work, frames, size, root = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), sys.argv[4]
scene = json.load(open(root + '/scenes/animated-box/scene.json'))
scene['animation']['frames'] = [1, frames]
scene['film'] = {'width': size, 'height': size}
json.dump(scene, open(work + '/scene.json', 'w'))
PY
port=$(python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')
"$build/master/rayfarm-master" --insecure --worker-endpoint "tcp://127.0.0.1:$((port + 1))" \
  --client-endpoint "tcp://127.0.0.1:$port" --data-dir "$work/data" \
  --max-queued-jobs "$frames" > "$work/master.log" 2>&1 &
master_pid=$!
rf() { "$build/cli/rayfarm" "$@" --insecure --master "tcp://127.0.0.1:$port" --timeout 120; }
seconds() { local t0 t1; t0=$(date +%s%N); "$@" > /dev/null 2>&1; t1=$(date +%s%N); echo "scale=3; ($t1 - $t0) / 1000000000" | bc; }
for _ in $(seq 50); do rf list > /dev/null 2>&1 && break; sleep 0.1; done
median() { sort -n | awk '{v[NR] = $1} END {print v[int((NR + 1) / 2)]}'; }
: > "$work/rounds"
for round in $(seq "$repeat"); do
  t0=$(date +%s%N)
  seq_id=$(rf submit "$work/scene.json" --frames "1-$frames" 2> /dev/null)
  t1=$(date +%s%N)
  submit=$(echo "scale=3; ($t1 - $t0) / 1000000000" | bc)
  rss=$(ps -o rss= -p "$master_pid" | tr -d ' ')
  status=$(seconds rf status "$seq_id" --json)
  list=$(seconds rf list)
  cancel=$(seconds rf cancel "$seq_id")
  data=$(du -sk "$work/data/jobs" | cut -f1)
  rf rm "$seq_id" > /dev/null 2>&1
  echo "$submit $status $list $cancel $rss $data" >> "$work/rounds"
  echo "round $round: submit ${submit} s, status ${status} s, list ${list} s, cancel ${cancel} s; master RSS ${rss} KiB, data dir ${data} KiB"
done
echo "sequence of $frames frames at ${size}x${size}, medians of $repeat rounds:"
for i in 1 2 3 4; do
  name=$(echo "submit status list cancel" | cut -d' ' -f$i)
  echo "  $name: $(cut -d' ' -f$i "$work/rounds" | median) s"
done
echo "  master RSS after submitting: $(cut -d' ' -f5 "$work/rounds" | median) KiB"
echo "  data dir with the sequence: $(cut -d' ' -f6 "$work/rounds" | median) KiB"
echo "  films if allocated at once: $(( frames * size * size * 96 / 1024 / 1024 )) MiB"
