#!/usr/bin/env bash
# Does a diffuse-only scene pay for the materials it does not use? Renders scenes/cornell-blocks
# (diffuse only) with the normal renderer and with one whose BSDF knows only diffuse materials
# (render_throughput --diffuse-only: the path tracer over a one-alternative Bsdf variant, every
# material dispatch a direct call), taking turns, and prints each median and their ratio. See
# docs/benchmarks.md.
#
#   bench/diffuse_only.sh [BUILD_DIR] [ROUNDS] [SPP] [THREADS]
set -euo pipefail
cd "$(dirname "$0")/.."
build=${1:-build}
rounds=${2:-5}
spp=${3:-32}
threads=${4:-2}

cmake -S . -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=Release >/dev/null
ninja -C "$build" render_throughput >/dev/null

# A 256x256 copy of the scene, so that a run takes a second or more.
scene_dir=$(mktemp -d)
trap 'rm -rf "$scene_dir"' EXIT
python3 - "$scene_dir/scene.json" <<'PY'
import json, sys
scene = json.load(open("scenes/cornell-blocks/scene.json"))
scene["film"] = {"width": 256, "height": 256}
json.dump(scene, open(sys.argv[1], "w"))
PY

run() {  # prints the median spp/s of one process; extra arguments go to render_throughput
  "$build/bench/render_throughput" "$scene_dir/scene.json" --spp "$spp" --threads "$threads" \
    --runs 3 "$@" | awk '/^median:/ {print $2}'
}
normal=() diffuse=()
for ((i = 0; i < rounds; ++i)); do
  normal+=("$(run)")
  diffuse+=("$(run --diffuse-only)")
  echo "round $i: normal ${normal[-1]} spp/s, diffuse-only ${diffuse[-1]} spp/s"
done
median() { printf '%s\n' "$@" | sort -g | awk '{v[NR] = $1} END {print v[int((NR + 1) / 2)]}'; }
m_normal=$(median "${normal[@]}")
m_diffuse=$(median "${diffuse[@]}")
echo "median over $rounds rounds: normal $m_normal spp/s, diffuse-only $m_diffuse spp/s"
awk -v a="$m_normal" -v b="$m_diffuse" 'BEGIN {printf "normal / diffuse-only = %.3f\n", a / b}'
