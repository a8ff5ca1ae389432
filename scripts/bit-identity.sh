#!/usr/bin/env bash
# Checks that the working tree renders every bundled scene bit-identical to an earlier commit.
#
#   scripts/bit-identity.sh [--build DIR] [--spp N] [--keep] COMMIT
#
# Builds `rayfarm` of COMMIT beside the working tree (in .bit-identity/<sha>/, kept for the next
# run) and `rayfarm` of the working tree (in DIR, default build), then renders every
# scenes/*/scene.json present in both trees with both binaries, in these settings:
#   - the scene's own integrator at --spp N (default 16);
#   - each of naive, nee and mis at N/2 spp;
#   - mis with --clamp 4 (the clamped path);
#   - adaptive: --target-error 0.05 with --spp 8N in 16-pixel tiles (the pass planner's stopping);
#   - the independent sampler at N/2 spp, also with update roulette and nee;
# and compares each pair with `rayfarm compare` (exit 0 = bit-identical). Each binary renders the
# scene of its own tree. Prints one line per render and a summary; exit 0 when every pair is
# bit-identical, 1 when any differs or fails to render, 2 on a usage or build error.
#
# A committed golden image would not do: Embree picks its kernels for the CPU at run time, so the
# same commit may render other bits on another CPU generation. Both builds here run on this CPU.
set -euo pipefail

repo_root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
build="$repo_root/build"
spp=16
keep=0
base=""

while [ $# -gt 0 ]; do
  case $1 in
    --build) build=$2; shift 2 ;;
    --spp) spp=$2; shift 2 ;;
    --keep) keep=1; shift ;;
    -h|--help) sed -n '2,18p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
    -*) echo "bit-identity: unknown option '$1'" >&2; exit 2 ;;
    *) [ -z "$base" ] || { echo "bit-identity: one COMMIT only" >&2; exit 2; }; base=$1; shift ;;
  esac
done
[ -n "$base" ] || { echo "bit-identity: which commit? (scripts/bit-identity.sh COMMIT)" >&2; exit 2; }
case $spp in '' | *[!0-9]* | 0 | 1) echo "bit-identity: --spp wants a whole number >= 2" >&2; exit 2 ;; esac

cd "$repo_root"
sha=$(git rev-parse --verify --quiet "$base^{commit}") ||
  { echo "bit-identity: '$base' is not a commit of this repository" >&2; exit 2; }
launcher=()
if command -v ccache > /dev/null; then
  launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache -DCMAKE_C_COMPILER_LAUNCHER=ccache)
fi

configure_and_build() {  # source dir, build dir
  local log="$2/bit-identity.log"
  mkdir -p "$2"
  if [ ! -f "$2/build.ninja" ]; then
    cmake -S "$1" -B "$2" -G Ninja -DCMAKE_BUILD_TYPE=Release "${launcher[@]}" > "$log" 2>&1 ||
      { echo "bit-identity: configuring $1 failed (see $log)" >&2; exit 2; }
  fi
  cmake --build "$2" --target rayfarm --parallel "$(nproc)" >> "$log" 2>&1 ||
    { echo "bit-identity: building $1 failed (see $log)" >&2; exit 2; }
}

# The earlier commit, exported as a plain tree (no worktree bookkeeping), built once and kept.
old_root="$repo_root/.bit-identity/$sha"
if [ ! -d "$old_root/src" ]; then
  rm -rf "$old_root.partial"
  mkdir -p "$old_root.partial"
  git archive --format=tar "$sha" | tar -x -C "$old_root.partial"
  mkdir -p "$old_root"
  mv "$old_root.partial" "$old_root/src"
fi
echo "building $(git log -1 --format='%h %s' "$sha" | cut -c1-72)"
configure_and_build "$old_root/src" "$old_root/build"
echo "building the working tree in $build"
configure_and_build "$repo_root" "$build"

find_cli() {
  local c
  for c in "$1/cli/rayfarm" "$1/rayfarm"; do [ -x "$c" ] && { echo "$c"; return; }; done
  echo "bit-identity: no rayfarm binary under $1" >&2
  exit 2
}
old_cli=$(find_cli "$old_root/build")
new_cli=$(find_cli "$build")

work=$(mktemp -d "${TMPDIR:-/tmp}/rayfarm-bit-identity.XXXXXX")
cleanup() { if [ "$keep" = 1 ]; then echo "renders kept in $work"; else rm -rf "$work"; fi; }
trap cleanup EXIT

half=$((spp / 2))
settings=(
  "scene:--spp $spp"
  "naive:--spp $half --integrator naive"
  "nee:--spp $half --integrator nee"
  "mis:--spp $half --integrator mis"
  "clamp:--spp $half --integrator mis --clamp 4"
  "adaptive:--spp $((spp * 8)) --target-error 0.05 --tile 16"
)
# The independent sampler reads one stream in the order the path asks for numbers: a change to
# that order shows only here. (Commits before the sampler option skip these.)
if "$old_cli" render --help 2>/dev/null | grep -q -- '--sampler'; then
  settings+=(
    "independent:--spp $half --sampler independent"
    "independent-update:--spp $half --sampler independent --roulette update --integrator nee"
  )
fi

pairs=0
identical=0
failed=0
for scene in scenes/*/scene.json; do
  name=$(basename "$(dirname "$scene")")
  if [ ! -f "$old_root/src/$scene" ]; then
    echo "  $name: not in $base, skipped"
    continue
  fi
  for setting in "${settings[@]}"; do
    label=${setting%%:*}
    read -r -a flags <<< "${setting#*:}"
    out_old="$work/$name-$label-old.exr"
    out_new="$work/$name-$label-new.exr"
    pairs=$((pairs + 1))
    if ! "$old_cli" render "$old_root/src/$scene" "${flags[@]}" -o "$out_old" > "$out_old.log" 2>&1; then
      echo "  FAIL  $name $label: $base could not render it (see $out_old.log)"
      failed=$((failed + 1)); keep=1; continue
    fi
    if ! "$new_cli" render "$repo_root/$scene" "${flags[@]}" -o "$out_new" > "$out_new.log" 2>&1; then
      echo "  FAIL  $name $label: the working tree could not render it (see $out_new.log)"
      failed=$((failed + 1)); keep=1; continue
    fi
    status=0
    summary=$("$new_cli" compare "$out_new" "$out_old" 2>&1) || status=$?
    if [ "$status" = 0 ]; then
      identical=$((identical + 1))
      echo "  same  $name $label (${setting#*:})"
    else
      failed=$((failed + 1)); keep=1
      echo "  DIFF  $name $label (${setting#*:}): $(echo "$summary" | tr '\n' ' ')"
    fi
  done
done

echo "bit-identity against $(git rev-parse --short "$sha"): $identical of $pairs renders bit-identical, $failed differ or failed"
[ "$failed" = 0 ] && [ "$pairs" -gt 0 ]
