#!/usr/bin/env bash
# rayfarm against Embree's tutorial path tracer (Debian package embree-tools) on the same scene:
# the Cornell box of Embree's docs lit by its point light, 512x512, the same path length and
# threads. Runs both alternately ROUNDS times and prints each figure, the medians and the ratio.
#
# Usage: bench/embree_comparison.sh [BUILD_DIR] [THREADS] [ROUNDS] [FRAMES]
set -euo pipefail
cd "$(dirname "$0")/.."
build=${1:-build}
threads=${2:-2}
rounds=${3:-5}
frames=${4:-8}
models=/usr/share/doc/embree3/models
command -v pathtracer >/dev/null || { echo "install embree-tools for Embree's pathtracer" >&2; exit 2; }
[ -x "$build/bench/render_throughput" ] || { echo "build $build/bench/render_throughput first" >&2; exit 2; }

ours=() theirs=()
for r in $(seq "$rounds"); do
  t=$(cd "$models" && pathtracer -c cornell_box.ecs --size 512 512 --threads "$threads" \
        --max-path-length 8 --benchmark 2 "$frames" 2>&1 | awk '/BENCHMARK_RENDER_AVG /{print $2}')
  o=$("$build/bench/render_throughput" scenes/embree-cornell/scene.json --spp "$frames" --runs 1 \
        --threads "$threads" | awk '/^median:/{print $2}')
  echo "round $r: embree pathtracer $t spp/s, rayfarm $o spp/s"
  theirs+=("$t") ours+=("$o")
done
median() { printf '%s\n' "$@" | sort -g | awk '{a[NR]=$1} END {print a[int((NR+1)/2)]}'; }
mt=$(median "${theirs[@]}") mo=$(median "${ours[@]}")
echo "median: embree pathtracer $mt spp/s, rayfarm $mo spp/s, ratio $(awk -v a="$mo" -v b="$mt" 'BEGIN{printf "%.2f", a/b}')"
