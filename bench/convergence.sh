#!/usr/bin/env bash
# Convergence of the three integrators on the bundled Cornell box: relMSE against render time for
# naive, nee and mis, one plot with the three curves, and the table of times to relMSE 1e-2 and
# 1e-3 (docs/benchmarks.md, "Convergence of the integrators").
#
#   bench/convergence.sh [BUILD_DIR] [--scene S] [--size N] [--reference REF.exr] [--reference-spp N]
#                        [--budget CPU_S] [--stop-at RELMSE] [--threads T] [other options of the tool]
#   bench/convergence.sh build --budget 300 --size 128
#
# The reference is our own renderer (mis, 32768 spp, another seed), made on the first run and
# cached as BUILD_DIR/bench/convergence-data/reference-SCENE-SIZE-SPP.exr with its per-pixel variance; its
# own noise is subtracted from every measured relMSE. Times are CPU seconds of the render (both
# threads together), which a shared machine's load does not change; wall seconds are in the CSVs.
# The diffuse-only scenes/cornell-blocks:
#   bench/convergence.sh build --scene scenes/cornell-blocks/scene.json --reference-spp 16384
# Its Blender Cycles image works as a reference too (--reference
# tests/data/references/cornell-blocks-cycles.exr, variance found beside it), but its own relMSE,
# 7.5e-4, is most of what is measured at 1e-3.
set -euo pipefail
cd "$(dirname "$0")/.."
build=${1:-build}
shift || true
scene=scenes/cornell-box/scene.json
size=64
ref_spp=32768
reference=""
budget=150
stop_at=8e-4
threads=2
args=()
while [[ $# -gt 0 ]]; do
  case "$1" in
    --scene) scene="$2"; shift 2 ;;
    --size) size="$2"; shift 2 ;;
    --reference-spp) ref_spp="$2"; shift 2 ;;
    --reference) reference="$2"; shift 2 ;;
    --budget) budget="$2"; shift 2 ;;
    --stop-at) stop_at="$2"; shift 2 ;;
    --threads) threads="$2"; shift 2 ;;
    *) args+=("$1"); shift ;;
  esac
done
cmake --build "$build" --target convergence >/dev/null
out="$build/bench/convergence-data"
mkdir -p "$out"
name=$(basename "$(dirname "$scene")")
[[ -n "$reference" ]] || reference="$out/reference-$name-$size-$ref_spp.exr"
"$build/bench/convergence" "$scene" --size "$size" --reference "$reference" \
  --reference-spp "$ref_spp" --threads "$threads" --budget "$budget" --stop-at "$stop_at" \
  --out "$out/$name" --plot "$out/$name/convergence.png" ${args[@]+"${args[@]}"}
