#!/usr/bin/env bash
# Renders every glTF file under a folder of Khronos sample models (default ../shared/gltf-samples)
# through its own camera, or the default view, lit by --environment uniform, and prints per file
# the exit code and the warnings: the run behind docs/gltf-conformance.md.
#
#   scripts/gltf-samples.sh [BUILD_DIR] [--models DIR] [--out DIR] [--spp N] [--res WxH]
#
# Images go to --out (default BUILD_DIR/gltf-samples/), one EXR and PNG per file.
set -euo pipefail
cd "$(dirname "$0")/.."
build=build
if [[ $# -gt 0 && "$1" != --* ]]; then build=$1; shift; fi
models=../shared/gltf-samples
out=""
spp=16
res=160x90
while [[ $# -gt 0 ]]; do
  case "$1" in
    --models) models="$2"; shift 2 ;;
    --out) out="$2"; shift 2 ;;
    --spp) spp="$2"; shift 2 ;;
    --res) res="$2"; shift 2 ;;
    *) echo "gltf-samples.sh: unknown argument $1" >&2; exit 2 ;;
  esac
done
[[ -d "$models" ]] || { echo "gltf-samples.sh: no folder $models (--models DIR)" >&2; exit 2; }
out=${out:-$build/gltf-samples}
mkdir -p "$out"
out=$(cd "$out" && pwd)
rayfarm=$(cd "$build/cli" && pwd)/rayfarm
[[ -x "$rayfarm" ]] || { echo "gltf-samples.sh: build $rayfarm first" >&2; exit 2; }

failed=0
while IFS= read -r file; do
  name=$(echo "${file#"$models"/}" | tr '/.' '__')
  rc=0
  log=$(cd "$(dirname "$file")" && "$rayfarm" render "$(basename "$file")" --environment uniform \
          --spp "$spp" --res "$res" -o "$out/$name.exr" 2>&1) || rc=$?
  echo "== ${file#"$models"/}: exit $rc"
  grep -E "warning|error" <<<"$log" | sed 's/^.*\] //' | grep -v "^wrote " || true
  [[ $rc -eq 0 ]] || failed=$((failed + 1))
done < <(find "$models" \( -name '*.gltf' -o -name '*.glb' \) | sort)
echo "images in $out; $failed file(s) refused"
