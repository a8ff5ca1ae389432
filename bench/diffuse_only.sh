#!/usr/bin/env bash
# Does a diffuse-only scene pay for the materials it does not use? Renders scenes/cornell-blocks
# (diffuse only) with the normal renderer and with a build that knows only diffuse materials
# (CMake option RAYFARM_DIFFUSE_ONLY: every material test is a compile-time constant), taking
# turns, and prints each median and their ratio. See docs/benchmarks.md.
#
#   bench/diffuse_only.sh [BUILD_DIR] [ROUNDS] [SPP] [THREADS]
set -euo pipefail
cd "$(dirname "$0")/.."
build=${1:-build}
rounds=${2:-5}
spp=${3:-32}
threads=${4:-2}
diffuse_build=${build}-diffuse-only

cmake -S . -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake -S . -B "$diffuse_build" -G Ninja -DCMAKE_BUILD_TYPE=Release -DRAYFARM_DIFFUSE_ONLY=ON \
  -DRAYFARM_BUILD_TESTS=OFF >/dev/null
ninja -C "$build" render_throughput >/dev/null
ninja -C "$diffuse_build" render_throughput >/dev/null

# A 256x256 copy of the scene, so that a run takes a second or more.
scene_dir=$(mktemp -d)
trap 'rm -rf "$scene_dir"' EXIT
python3 - "$scene_dir/scene.json" <<'PY'
import json, sys
scene = json.load(open("scenes/cornell-blocks/scene.json"))
scene["film"] = {"width": 256, "height": 256}
json.dump(scene, open(sys.argv[1], "w"))
PY

run() {  # prints the median spp/s of one process
  "$1/bench/render_throughput" "$scene_dir/scene.json" --spp "$spp" --threads "$threads" --runs 3 |
    awk '/^median:/ {print $2}'
}
normal=() diffuse=()
for ((i = 0; i < rounds; ++i)); do
  normal+=("$(run "$build")")
  diffuse+=("$(run "$diffuse_build")")
  echo "round $i: normal ${normal[-1]} spp/s, diffuse-only build ${diffuse[-1]} spp/s"
done
median() { printf '%s\n' "$@" | sort -g | awk '{v[NR] = $1} END {print v[int((NR + 1) / 2)]}'; }
m_normal=$(median "${normal[@]}")
m_diffuse=$(median "${diffuse[@]}")
echo "median over $rounds rounds: normal $m_normal spp/s, diffuse-only build $m_diffuse spp/s"
awk -v a="$m_normal" -v b="$m_diffuse" 'BEGIN {printf "normal / diffuse-only = %.3f\n", a / b}'
