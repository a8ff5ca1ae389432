#!/usr/bin/env bash
# What a pixel filter costs: the Cornell box rendered with each filter (film.filter) at the same
# samples, rounds alternating between the filters, and the median of rayfarm's own "time" line
# (its passes, without reading the scene or building the BVH) per filter, with its ratio to the
# box of the pixel's own area (docs/benchmarks.md, "Pixel filters").
#
#   bench/pixel_filter.sh [BUILD_DIR] [--res WxH] [--spp N] [--rounds R] [--threads T]
#   nice bench/pixel_filter.sh build
set -euo pipefail
cd "$(dirname "$0")/.."
build=build
if [[ $# -gt 0 && "$1" != --* ]]; then build=$1; shift; fi
res=256x256
spp=64
rounds=5
threads=2
while [[ $# -gt 0 ]]; do
  case "$1" in
    --res) res="$2"; shift 2 ;;
    --spp) spp="$2"; shift 2 ;;
    --rounds) rounds="$2"; shift 2 ;;
    --threads) threads="$2"; shift 2 ;;
    *) echo "pixel_filter.sh: unknown argument $1" >&2; exit 2 ;;
  esac
done

cmake --build "$build" --target rayfarm >/dev/null
rayfarm="$build/cli/rayfarm"
dir="$build/bench/pixel-filter"
mkdir -p "$dir"
filters="box gaussian mitchell lanczos blackman-harris"
# The scene's folder copied, and in it one copy of the scene per filter.
rm -rf "$dir/scene"
cp -r scenes/cornell-box "$dir/scene"
for f in $filters; do
  python3 - "$f" "$dir/scene" >"$dir/scene/$f.json" <<'EOF'
import json, sys
scene = json.load(open(sys.argv[2] + "/scene.json"))
if sys.argv[1] != "box":
    scene["film"]["filter"] = sys.argv[1]
json.dump(scene, sys.stdout, indent=1)
EOF
done

declare -A times
for ((r = 0; r < rounds; ++r)); do
  for f in $filters; do
    t=$("$rayfarm" render "$dir/scene/$f.json" --res "$res" --spp "$spp" \
          --threads "$threads" -o "$dir/$f.exr" 2>&1 | awk '$1 == "time" {print $2}')
    times[$f]+="$t "
  done
done

median() { tr ' ' '\n' | grep . | sort -g | awk '{v[NR] = $1} END {print v[int((NR + 1) / 2)]}'; }
box=$(echo "${times[box]}" | median)
echo "Cornell box, $res, $spp spp, $threads threads, $rounds rounds (median of rayfarm's time line):"
printf '%-16s %10s %8s   %s\n' filter "median s" "x box" "all runs"
for f in $filters; do
  m=$(echo "${times[$f]}" | median)
  printf '%-16s %10s %8.3f   %s\n' "$f" "$m" "$(echo "$m / $box" | bc -l)" "${times[$f]}"
done
