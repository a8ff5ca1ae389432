#!/usr/bin/env bash
# The main job, end to end: install the dependencies, build rayfarm, start a local cluster (a master
# and 2 workers as local processes, with CURVE keys made on the first run), submit the bundled
# Cornell box, follow its progress, and leave the EXR and a PNG preview in out/. The cluster is
# stopped at the end, also on failure or Ctrl-C.
#
# Usage: scripts/demo.sh [--workers N] [--spp N] [--scene PATH]
set -euo pipefail
cd "$(dirname "$0")/.."

workers=2
spp=256
scene=scenes/cornell-box/scene.json
while [ $# -gt 0 ]; do
  case "$1" in
    --workers) workers=$2; shift 2 ;;
    --spp) spp=$2; shift 2 ;;
    --scene) scene=$2; shift 2 ;;
    *) echo "demo: unknown option $1 (--workers N, --spp N, --scene PATH)" >&2; exit 2 ;;
  esac
done

bash scripts/install-deps.sh
cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=Release
cmake --build build --parallel "$(nproc)" --target rayfarm rayfarm-master rayfarm-worker

cluster=.cluster/demo
trap 'deploy/local-cluster stop --dir "$cluster" >/dev/null 2>&1 || true' EXIT
threads=$(( $(nproc) / workers )); [ "$threads" -ge 1 ] || threads=1
deploy/local-cluster start --workers "$workers" --threads "$threads" --dir "$cluster"
# The cluster's endpoint and the CLI's keys (CURVE on every socket): RAYFARM_MASTER, RAYFARM_KEY,
# RAYFARM_MASTER_KEY.
# shellcheck source=/dev/null
source "$cluster/env"
master=$RAYFARM_MASTER

name=$(basename "$(dirname "$scene")")
mkdir -p out
job=$(build/cli/rayfarm submit "$scene" --master "$master" --spp "$spp" --name "$name")
echo "demo: submitted job $job ($name, $spp spp) to $master"
build/cli/rayfarm watch "$job" --master "$master"
build/cli/rayfarm fetch "$job" --master "$master" -o "out/$name.exr"
echo "demo: the image is out/$name.exr, its preview out/$name.png; logs are in $cluster/"
