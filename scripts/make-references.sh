#!/usr/bin/env bash
# Remakes the Blender Cycles reference images under tests/data/references/ (see README.md there).
# Needs Blender 3.4 (Debian bookworm: apt-get install blender); tests and CI only read the
# committed files and never run Blender.
#
#   scripts/make-references.sh [--threads T]     # about 4 minutes on 2 idle cores
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
