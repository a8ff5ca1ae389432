#!/usr/bin/env bash
# Time to a target error with and without adaptive passes, on a scene with very uneven noise:
# the Cornell box's glass sphere and its caustic beside flat diffuse walls. Each run stops when
# its estimated relMSE is below the target (per tile, or over whole passes with --no-adaptive);
# both are then measured against a reference rendered with another seed, so that neither can
# meet the target by underestimating its error. Adaptive tiles stop at error budgets that average
# to the target (common/schedule/pass_planner.h). Prints every run and the medians; see
# docs/benchmarks.md.
#
#   bench/adaptive.sh [BUILD_DIR] [TARGET] [ROUNDS] [SIZE] [THREADS]
set -euo pipefail
cd "$(dirname "$0")/.."
build=${1:-build}
target=${2:-5e-3}
rounds=${3:-3}
size=${4:-96}
threads=${5:-2}
rayfarm=$build/cli/rayfarm
ninja -C "$build" rayfarm >/dev/null

work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
python3 - "$work/scene.json" "$size" <<'PY'
import json, sys
scene = json.load(open("scenes/cornell-box/scene.json"))
scene["film"] = {"width": int(sys.argv[2]), "height": int(sys.argv[2])}
json.dump(scene, open(sys.argv[1], "w"))
PY
common=(--threads "$threads" --tile 16 --pass-spp 32)
echo "reference: $size x $size, 4096 spp, seed 1000"
"$rayfarm" render "$work/scene.json" -o "$work/reference.exr" --spp 4096 --seed 1000 "${common[@]}" \
  2>/dev/null >"$work/reference.txt"
grep -E '^(time|estimated)' "$work/reference.txt"
# The reference's own error is part of every measurement against it; it is taken off.
ref_error=$(awk '/^estimated/ {gsub(",", "", $3); print $3}' "$work/reference.txt")

run() {  # mode label, then flags; prints "label seconds spp_mean est measured"
  local label=$1
  shift
  "$rayfarm" render "$work/scene.json" -o "$work/$label.exr" --spp 16384 --seed 7 \
    --target-error "$target" --reference "$work/reference.exr" "${common[@]}" "$@" 2>/dev/null >"$work/$label.txt"
  local seconds spp est measured
  seconds=$(awk '/^time/ {print $2}' "$work/$label.txt")
  spp=$(sed -n 's/^stopped: [^;]*; \([0-9.]*\) spp mean.*/\1/p' "$work/$label.txt")
  est=$(awk '/^estimated/ {gsub(",", "", $3); print $3}' "$work/$label.txt")
  measured=$(awk '/^estimated/ {for (i = 1; i <= NF; ++i) if ($i == "relMSE" && i > 3) {gsub(",", "", $(i + 1)); print $(i + 1)}}' "$work/$label.txt")
  measured=$(awk -v m="$measured" -v r="$ref_error" 'BEGIN {printf "%.4g", m - r}')
  echo "$label $seconds $spp $est $measured"
}
printf '%-9s %9s %9s %11s %11s\n' mode seconds "spp mean" "est relMSE" "measured*"
echo "(* measured against the reference, less the reference's own estimated relMSE)"
adaptive=() whole=()
for ((i = 0; i < rounds; ++i)); do
  read -r l s p e m < <(run adaptive)
  printf '%-9s %9.2f %9s %11s %11s\n' "$l" "$s" "$p" "$e" "$m"
  adaptive+=("$s")
  read -r l s p e m < <(run whole --no-adaptive)
  printf '%-9s %9.2f %9s %11s %11s\n' "$l" "$s" "$p" "$e" "$m"
  whole+=("$s")
done
median() { printf '%s\n' "$@" | sort -g | awk '{v[NR] = $1} END {print v[int((NR + 1) / 2)]}'; }
a=$(median "${adaptive[@]}")
w=$(median "${whole[@]}")
echo "target relMSE $target: median time adaptive $a s, whole passes $w s"
awk -v a="$a" -v w="$w" 'BEGIN {printf "whole passes / adaptive = %.2f\n", w / a}'
