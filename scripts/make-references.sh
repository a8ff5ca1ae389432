#!/usr/bin/env bash
# Remakes the Blender Cycles reference images under tests/data/references/ and
# tests/data/gltf-references/ (see the README.md in each).
# Needs Blender 3.4 (Debian bookworm: apt-get install blender); tests and CI only read the
# committed files and never run Blender.
#
#   scripts/make-references.sh [--threads T]     # about 7 minutes on 2 idle cores
set -euo pipefail
cd "$(dirname "$0")/.."
threads=0
if [[ "${1:-}" == "--threads" ]]; then threads="$2"; fi
command -v blender >/dev/null || { echo "blender not found (apt-get install blender)" >&2; exit 1; }

# cornell-blocks: 64x64, 16384 spp as 8 independent renders of 2048 (seeds 1..8), so that the
# reference's own variance is known (cornell-blocks-cycles-variance.exr). Emitters are found by
# BSDF sampling only: Blender 3.4.1's mesh-light sampling is biased low near the light's plane
# (tests/data/references/README.md).
blender -b --factory-startup --python scripts/blender_reference.py -- \
  scenes/cornell-blocks/scene.json tests/data/references/cornell-blocks-cycles.exr \
  --spp 16384 --seeds 8 --seed 1 --threads "$threads" --no-light-sampling \
  --source-name scenes/cornell-blocks/scene.json \
  2>&1 | grep -v '^Fra:'

# glTF: a small scene built in Blender, exported with Blender's glTF exporter to
# tests/data/gltf-references/showcase.gltf (+ .bin, floor-texture.png) with our JSON scene
# showcase-scene.json beside it, and Cycles' render of the same Blender scene: 64x48, 16384 spp as
# 8 renders of 2048 (seeds 1..8). See tests/data/gltf-references/README.md.
blender -b --factory-startup --python scripts/blender_gltf_reference.py -- \
  tests/data/gltf-references --spp 16384 --seeds 8 --seed 1 --threads "$threads" \
  2>&1 | grep -v '^Fra:' | grep -v '| INFO:'

# glTF lights: Blender's point, spot and sun lamps and a normal-mapped floor, exported with and
# without tangents (lights.gltf, lights-notangents.gltf), and Cycles' render of the scene, direct
# light only: 64x48, 16384 spp as 8 renders of 2048. See tests/data/gltf-references/README.md.
blender -b --factory-startup --python scripts/blender_gltf_reference.py -- \
  tests/data/gltf-references --scene lights --spp 16384 --seeds 8 --seed 1 --threads "$threads" \
  2>&1 | grep -v '^Fra:' | grep -v '| INFO:'
