#!/usr/bin/env bash
# The farm's overhead over `rayfarm render`, and how it scales from 1 to 2 workers.
#
#   bench/farm_overhead.sh [--scene FILE] [--size N] [--spp N] [--threads T] [--repeat R] [--build DIR]
#                          [--insecure] [--master-arg ARG]... [--overhead-only]
#
# Defaults: scenes/cornell-box/scene.json at 512x512, 256 spp, T = 2, binaries from ./build (or
# $RAYFARM_BIN). Runs, on this machine, the same job:
#   1. rayfarm render with T threads                       (the reference time and image)
#   2. a master and 1 worker with T threads                 -> the farm's overhead (ratio to 1)
#   3. a master and 1 worker with 1 thread, then 2 workers with 1 thread each -> 1 vs 2 workers
# Farm times are the master's (first unit handed out to final image written) and the client's
# (`rayfarm submit --wait` from start to exit). Every farm image is compared with the reference;
# they must be bit-identical. With --repeat R each figure is the fastest of R runs, which tames the
# noise of a shared machine. The farm uses CURVE keys made for the run (as deployed); --insecure
# runs it on plain sockets instead, to measure what encryption costs. --master-arg passes one
# argument to the master (repeat it: --master-arg --unit-seconds --master-arg 0). --overhead-only
# stops after step 2. Prints figures only; nothing here is a test.
set -euo pipefail

repo_root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
scene="$repo_root/scenes/cornell-box/scene.json"
size=512
spp=256
threads=2
repeat=1
build="${RAYFARM_BIN:-$repo_root/build}"
insecure=0
master_args=()
overhead_only=0

while [ $# -gt 0 ]; do
  case $1 in
    --scene) scene=$2; shift 2 ;;
    --size) size=$2; shift 2 ;;
    --spp) spp=$2; shift 2 ;;
    --threads) threads=$2; shift 2 ;;
    --repeat) repeat=$2; shift 2 ;;
    --build) build=$2; shift 2 ;;
    --insecure) insecure=1; shift ;;
    --master-arg) master_args+=("$2"); shift 2 ;;
    --overhead-only) overhead_only=1; shift ;;
    -h|--help) sed -n '2,20p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
    *) echo "farm_overhead: unknown option '$1'" >&2; exit 2 ;;
  esac
done

bin() {
  local c
  for c in "$build/$2/$1" "$build/$1"; do [ -x "$c" ] && { echo "$c"; return; }; done
  command -v "$1" || { echo "farm_overhead: cannot find $1 (build first, or --build DIR)" >&2; exit 1; }
}
rayfarm=$(bin rayfarm cli)
master_bin=$(bin rayfarm-master master)
worker_bin=$(bin rayfarm-worker worker)

work=$(mktemp -d "${TMPDIR:-/tmp}/rayfarm-overhead.XXXXXX")
# Run copies, so that a rebuild during the benchmark cannot mix two versions of the renderer.
mkdir "$work/bin"
cp "$rayfarm" "$master_bin" "$worker_bin" "$work/bin/"
rayfarm="$work/bin/rayfarm" master_bin="$work/bin/rayfarm-master" worker_bin="$work/bin/rayfarm-worker"
pids=()
cleanup() {
  local p
  for p in "${pids[@]}"; do kill -TERM "$p" 2>/dev/null || true; done
  sleep 0.5
  for p in "${pids[@]}"; do kill -KILL "$p" 2>/dev/null || true; done
  rm -rf "$work"
}
trap cleanup EXIT

# The scene with the requested film size, in a copy of its folder (its files travel along).
cp -r "$(dirname "$scene")" "$work/scene"
job_scene="$work/scene/$(basename "$scene")"
python3 - "$job_scene" "$size" <<'PY'
import json, sys
path, size = sys.argv[1], int(sys.argv[2])
scene = json.load(open(path))
scene["film"] = {"width": size, "height": size}
json.dump(scene, open(path, "w"), indent=2)
PY

# Keys for the master, the workers (one key for all) and the client, unless --insecure.
if [ "$insecure" = 1 ]; then
  master_auth=(--insecure); worker_auth=(--insecure); client_auth=(--insecure)
else
  for name in master worker client; do
    "$rayfarm" keygen -o "$work/keys" --name "$name" >/dev/null
  done
  mkdir -p "$work/keys/workers" "$work/keys/clients"
  cp "$work/keys/worker.key" "$work/keys/workers/"
  cp "$work/keys/client.key" "$work/keys/clients/"
  master_auth=(--key "$work/keys/master.key_secret" --worker-keys "$work/keys/workers"
               --client-keys "$work/keys/clients")
  worker_auth=(--key "$work/keys/worker.key_secret" --master-key "$work/keys/master.key")
  client_auth=(--key "$work/keys/client.key_secret" --master-key "$work/keys/master.key")
fi

free_port() { python3 -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])'; }
now() { date +%s.%N; }
calc() { python3 -c "print($1)"; }

echo "scene $(basename "$(dirname "$scene")")/$(basename "$scene") at ${size}x${size}, $spp spp; $(nproc) cores; $([ "$insecure" = 1 ] && echo "plain sockets (--insecure)" || echo "CURVE")"

min() { python3 -c "print(min($1, $2))"; }

local_s=1e9
for _ in $(seq "$repeat"); do
  start=$(now)
  "$rayfarm" --log-level warn render "$job_scene" -o "$work/local.exr" --spp "$spp" --threads "$threads" >/dev/null 2>&1
  local_s=$(min "$local_s" "$(calc "$(now) - $start")")
done
printf 'rayfarm render, %d threads:            %7.2f s\n' "$threads" "$local_s"

# run_farm WORKERS THREADS: sets master_s and client_s after checking the image.
run_farm() {
  local n=$1 t=$2 wport cport data i start_s job
  wport=$(free_port); cport=$(free_port)
  data=$(mktemp -d "$work/data-$n-$t.XXXX")
  "$master_bin" --worker-endpoint "tcp://127.0.0.1:$wport" --client-endpoint "tcp://127.0.0.1:$cport" \
    --data-dir "$data" --log-level warn "${master_auth[@]}" ${master_args[@]+"${master_args[@]}"} \
    >"$work/master-$n-$t.log" 2>&1 &
  pids+=($!)
  local farm_pids=($!)
  for i in $(seq 1 "$n"); do
    "$worker_bin" --master "tcp://127.0.0.1:$wport" --threads "$t" --cache-dir "$work/cache-$n-$t-$i" \
      --log-level warn "${worker_auth[@]}" >"$work/worker-$n-$t-$i.log" 2>&1 &
    pids+=($!); farm_pids+=($!)
  done
  # Every worker says hello before the clock starts.
  for _ in $(seq 100); do
    "$rayfarm" status --master "tcp://127.0.0.1:$cport" --timeout 1 "${client_auth[@]}" >/dev/null 2>&1 && break
    sleep 0.1
  done
  sleep 0.5
  start_s=$(now)
  job=$("$rayfarm" submit "$job_scene" --spp "$spp" --master "tcp://127.0.0.1:$cport" "${client_auth[@]}" --wait 2>/dev/null)
  job=${job%%$'\n'*}  # the first line is the job id; progress follows
  client_s=$(calc "$(now) - $start_s")
  master_s=$(python3 -c 'import json,sys; print(json.load(open(sys.argv[1]))["elapsed_seconds"])' "$data/jobs/$job/job.json")
  "$rayfarm" fetch "$job" -o "$work/farm-$n-$t.exr" --master "tcp://127.0.0.1:$cport" "${client_auth[@]}" >/dev/null
  if ! "$rayfarm" compare "$work/farm-$n-$t.exr" "$work/local.exr" >/dev/null 2>&1; then
    echo "farm_overhead: the farm's image ($n x $t threads) differs from rayfarm render's" >&2
    exit 1
  fi
  kill -TERM "${farm_pids[@]}" 2>/dev/null || true
  wait "${farm_pids[@]}" 2>/dev/null || true
}

# best_farm WORKERS THREADS: the fastest of --repeat runs, in master_s and client_s.
best_farm() {
  local best_m=1e9 best_c=1e9
  for _ in $(seq "$repeat"); do
    run_farm "$1" "$2"
    best_m=$(min "$best_m" "$master_s"); best_c=$(min "$best_c" "$client_s")
  done
  master_s=$best_m client_s=$best_c
}

best_farm 1 "$threads"; m1=$master_s; c1=$client_s
printf 'farm, 1 worker x %d threads:           %7.2f s (master), %7.2f s (client)  overhead %.3f (master), %.3f (client)\n' \
  "$threads" "$m1" "$c1" "$(calc "$m1 / $local_s")" "$(calc "$c1 / $local_s")"
if [ "$overhead_only" = 1 ]; then
  echo "the farm's image is bit-identical to rayfarm render's"
  exit 0
fi
best_farm 1 1; ma=$master_s; ca=$client_s
printf 'farm, 1 worker x 1 thread:             %7.2f s (master), %7.2f s (client)\n' "$ma" "$ca"
best_farm 2 1; mb=$master_s; cb=$client_s
printf 'farm, 2 workers x 1 thread:            %7.2f s (master), %7.2f s (client)  speed-up %.2f over 1 worker\n' \
  "$mb" "$cb" "$(calc "$ma / $mb")"
echo "every farm image is bit-identical to rayfarm render's"
