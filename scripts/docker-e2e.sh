#!/usr/bin/env bash
# End-to-end run of the compose cluster: build the images, start a master and N workers, submit the
# bundled Cornell box, fetch the EXR to the host, render the same scene locally in the same image and
# require `rayfarm compare` to call the two bit-identical. The cluster runs with the CURVE keys its
# `keys` service makes; the run also checks that a client key the master does not list is refused
# (exit 4) and logged, that the dashboard's API shows the job done and refuses an action without a
# token, and that the compose Prometheus scraped the master's /metrics. Prints timings; always tears the cluster down (docker-compose down -v, which
# also deletes the keys), also on failure.
#
# Needs a Docker engine. When none answers and this runs as root, it installs docker.io,
# docker-compose and debootstrap (apt) and starts `dockerd --storage-driver=vfs` for the duration of
# the run. Not part of the unit or e2e test suite: it takes minutes (the image build compiles rayfarm).
#
# Usage: scripts/docker-e2e.sh [--workers N] [--spp N] [--scene PATH-IN-IMAGE] [--from-git REV]
#                              [--no-build] [--keep]
#   --workers N     worker containers                    (default 2)
#   --spp N         samples per pixel                    (default 16)
#   --scene PATH    scene inside the image               (default the bundled Cornell box)
#   --from-git REV  build the image from a committed revision (git archive), not the working tree
#   --no-build      use the existing rayfarm image as it is
#   --keep          leave the cluster running (no teardown) to look around
# Environment: RAYFARM_BUILD_JOBS (compile jobs in the image build, default 2),
#   RAYFARM_WORKER_THREADS (threads per worker, default 1), E2E_TIMEOUT (seconds for the job, 900).
set -euo pipefail

REPO="$(cd "$(dirname "$0")/.." && pwd)"
WORKERS=2
SPP=16
SCENE=/usr/share/rayfarm/scenes/cornell-box/scene.json
BUILD=1
FROM_GIT=""
KEEP=0
TIMEOUT="${E2E_TIMEOUT:-900}"

log() { echo "docker-e2e: $*" >&2; }
die() { log "FAIL: $*"; exit 1; }

while [ $# -gt 0 ]; do
  case "$1" in
    --workers) WORKERS="$2"; shift 2 ;;
    --spp) SPP="$2"; shift 2 ;;
    --scene) SCENE="$2"; shift 2 ;;
    --from-git) FROM_GIT="$2"; shift 2 ;;
    --no-build) BUILD=0; shift ;;
    --keep) KEEP=1; shift ;;
    -h|--help) awk 'NR > 1 && /^#/ { sub(/^# ?/, ""); print; next } NR > 1 { exit }' "$0"; exit 0 ;;
    *) die "unknown argument '$1' (try --help)" ;;
  esac
done

now() { date +%s.%N; }
elapsed() { awk -v a="$1" -v b="$2" 'BEGIN { printf "%.1f", b - a }'; }

# ---- a Docker engine ---------------------------------------------------------------------------
STARTED_DOCKERD=""
ensure_engine() {
  if command -v docker >/dev/null && docker info >/dev/null 2>&1; then return; fi
  [ "$(id -u)" -eq 0 ] || die "no Docker engine answers, and starting one needs root"
  local missing=()
  command -v dockerd >/dev/null || missing+=(docker.io)
  command -v docker-compose >/dev/null || missing+=(docker-compose)
  command -v debootstrap >/dev/null || missing+=(debootstrap)
  if [ ${#missing[@]} -gt 0 ]; then
    log "installing ${missing[*]}"
    apt-get update -qq
    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
  fi
  log "starting dockerd --storage-driver=vfs (log: /tmp/rayfarm-dockerd.log)"
  nohup dockerd --storage-driver=vfs >/tmp/rayfarm-dockerd.log 2>&1 &
  STARTED_DOCKERD=$!
  for _ in $(seq 60); do
    docker info >/dev/null 2>&1 && return
    kill -0 "$STARTED_DOCKERD" 2>/dev/null || { tail -n 20 /tmp/rayfarm-dockerd.log >&2; die "dockerd exited"; }
    sleep 1
  done
  die "dockerd did not answer within 60 s (see /tmp/rayfarm-dockerd.log)"
}

# ---- the compose project -----------------------------------------------------------------------
# Its own project name and free host ports, so it never touches a cluster someone else runs here.
free_port() { python3 -c 'import socket; s = socket.socket(); s.bind(("", 0)); print(s.getsockname()[1])'; }

OUT="$REPO/out/docker-e2e"
export COMPOSE_PROJECT_NAME="rayfarm-e2e"
export RAYFARM_OUT="$OUT"
export RAYFARM_UID="$(id -u)" RAYFARM_GID="$(id -g)"
export RAYFARM_BUILD_JOBS="${RAYFARM_BUILD_JOBS:-2}"
export RAYFARM_WORKER_THREADS="${RAYFARM_WORKER_THREADS:-1}"
compose() { docker-compose -f "$REPO/deploy/docker-compose.yml" "$@"; }
cli() { compose run --rm -T cli "$@"; }

STATUS=1
teardown() {
  set +e
  if [ "$STATUS" -ne 0 ] && [ -n "${CLUSTER_UP:-}" ]; then
    log "logs of the failed run:"
    compose logs --no-color --tail=40 >&2
  fi
  if [ "$KEEP" -eq 1 ] && [ -n "${CLUSTER_UP:-}" ]; then
    log "--keep: cluster left running; stop it with: COMPOSE_PROJECT_NAME=$COMPOSE_PROJECT_NAME docker-compose -f deploy/docker-compose.yml down -v"
  elif [ -n "${CLUSTER_UP:-}" ]; then
    log "tearing down"
    compose down -v --remove-orphans >/dev/null 2>&1
  fi
  if [ -n "$STARTED_DOCKERD" ]; then
    log "stopping the dockerd this run started (pid $STARTED_DOCKERD)"
    kill "$STARTED_DOCKERD" 2>/dev/null && wait "$STARTED_DOCKERD" 2>/dev/null
  fi
  [ "$STATUS" -eq 0 ] && log "PASS" || log "FAIL"
}
trap teardown EXIT
trap 'exit 130' INT TERM

ensure_engine
command -v docker-compose >/dev/null || die "docker-compose is not installed"
export RAYFARM_WORKER_PORT="$(free_port)" RAYFARM_CLIENT_PORT="$(free_port)"
export RAYFARM_HTTP_PORT="$(free_port)" RAYFARM_PROMETHEUS_PORT="$(free_port)"
# GET (or POST, with a second argument) on the host, with $HTTP_TOKEN as a bearer token when set;
# prints "STATUS BODY".
http() {
  python3 - "$@" <<'PY'
import os, sys, urllib.request, urllib.error
req = urllib.request.Request(sys.argv[1], data=b"" if len(sys.argv) > 2 else None)
if os.environ.get("HTTP_TOKEN"):
    req.add_header("Authorization", "Bearer " + os.environ["HTTP_TOKEN"])
try:
    with urllib.request.urlopen(req, timeout=10) as r:
        print(r.status, r.read().decode())
except urllib.error.HTTPError as e:
    print(e.code, e.read().decode())
except OSError as e:
    print(0, e)
PY
}
mkdir -p "$OUT"
rm -f "$OUT"/farm.exr "$OUT"/local.exr "$OUT"/local.png

# ---- images ------------------------------------------------------------------------------------
t0=$(now)
"$REPO/scripts/docker-base-image.sh"
t_base=$(now)
if [ "$BUILD" -eq 1 ] && [ -n "$FROM_GIT" ]; then
  rev="$(git -C "$REPO" rev-parse --short "$FROM_GIT^{commit}")" || die "no git revision '$FROM_GIT'"
  log "building the rayfarm image from git $rev (-j$RAYFARM_BUILD_JOBS)"
  CONTEXT="$(mktemp -d /var/tmp/rayfarm-context.XXXXXX)"
  git -C "$REPO" archive "$rev" | tar -x -C "$CONTEXT"
  cp "$REPO/.dockerignore" "$CONTEXT/" 2>/dev/null || true
  docker build -f "$CONTEXT/deploy/Dockerfile" -t "${RAYFARM_IMAGE:-rayfarm:latest}" \
    --build-arg BASE="${RAYFARM_BASE_IMAGE:-rayfarm/debian:bookworm}" \
    --build-arg JOBS="$RAYFARM_BUILD_JOBS" "$CONTEXT" \
    || { rm -rf "$CONTEXT"; die "image build failed"; }
  rm -rf "$CONTEXT"
elif [ "$BUILD" -eq 1 ]; then
  log "building the rayfarm image from the working tree (-j$RAYFARM_BUILD_JOBS)"
  compose build master
fi
if [ "$BUILD" -eq 1 ]; then
  log "building the Prometheus image (Debian's prometheus)"
  compose build prometheus
fi
t_build=$(now)

# ---- the cluster -------------------------------------------------------------------------------
log "starting a master and $WORKERS workers (host ports $RAYFARM_WORKER_PORT, $RAYFARM_CLIENT_PORT)"
CLUSTER_UP=1
compose up -d --scale worker="$WORKERS" master worker prometheus
for _ in $(seq 60); do
  health="$(docker inspect -f '{{.State.Health.Status}}' "$(compose ps -q master)" 2>/dev/null || true)"
  [ "$health" = healthy ] && break
  sleep 1
done
[ "$health" = healthy ] || die "the master is not healthy after 60 s (state: ${health:-none})"
running="$(compose ps -q worker | wc -l)"
[ "$running" -eq "$WORKERS" ] || die "$running of $WORKERS workers running"
t_up=$(now)

# ---- keys: the keys service made them; a key not on the allow-list is refused -----------------
log "checking that the master refuses a client key it does not list"
set +e
cli bash -c 'rayfarm keygen -o /tmp/stranger --name stranger >/dev/null &&
  RAYFARM_KEY=/tmp/stranger/stranger.key_secret rayfarm list --timeout 10' 2>&1 | tail -n 1 >&2
refused_code=${PIPESTATUS[0]}
set -e
[ "$refused_code" = 4 ] || die "a client with an unknown key got exit $refused_code, expected 4 (refused)"
compose logs --no-color master 2>/dev/null | grep -q "refused a client connection from" \
  || die "the master did not log the refused client"

# ---- submit, wait, fetch -----------------------------------------------------------------------
log "submitting $SCENE at $SPP spp"
submit_out="$(cli rayfarm submit "$SCENE" --spp "$SPP")" || die "submit failed (its error is above)"
JOB="$(printf '%s\n' "$submit_out" | tail -n 1 | tr -d '[:space:]')"
[ -n "$JOB" ] || die "submit printed no job id"
log "job $JOB"
t_submit=$(now)
timeout "$TIMEOUT" docker-compose -f "$REPO/deploy/docker-compose.yml" run --rm -T cli \
  rayfarm watch "$JOB" || die "job $JOB did not finish within ${TIMEOUT} s"
t_done=$(now)
cli rayfarm status "$JOB" >&2 || true
cli rayfarm fetch "$JOB" -o /out/farm.exr || die "fetch failed"
[ -s "$OUT/farm.exr" ] || die "fetch wrote no $OUT/farm.exr"
t_fetch=$(now)

# ---- the dashboard and the metrics -------------------------------------------------------------
log "checking the dashboard (port $RAYFARM_HTTP_PORT) and Prometheus (port $RAYFARM_PROMETHEUS_PORT)"
dash="http://127.0.0.1:$RAYFARM_HTTP_PORT"
# The master listens beyond loopback inside its container: reading needs a token too.
read -r code body <<<"$(http "$dash/api/jobs/$JOB")"
[ "$code" = 401 ] || die "reading a job without a token got HTTP $code, expected 401: $body"
token="$(cli rayfarm token | tail -n 1 | tr -d '[:space:]')"
read -r code body <<<"$(HTTP_TOKEN="$token" http "$dash/api/jobs/$JOB")"
[ "$code" = 200 ] && echo "$body" | grep -q '"state":"JOB_DONE"' \
  || die "the dashboard's API does not show $JOB done with the cli key's token: $code $body"
read -r code body <<<"$(HTTP_TOKEN="${token}0" http "$dash/api/jobs/$JOB/cancel" post)"
[ "$code" = 401 ] || die "a cancel with a forged token got HTTP $code, expected 401: $body"
http "$dash/metrics" | grep -q '^rayfarm_units_merged_total [1-9]' \
  || die "the master's /metrics counts no merged unit"
scraped=no
for _ in $(seq 60); do
  if http "http://127.0.0.1:$RAYFARM_PROMETHEUS_PORT/api/v1/query?query=rayfarm_units_merged_total" \
      | grep -q '"value":\['; then scraped=yes; break; fi
  sleep 2
done
[ "$scraped" = yes ] || die "Prometheus has no rayfarm_units_merged_total after 120 s"
t_metrics=$(now)

# ---- the same render on one machine, and the comparison ----------------------------------------
log "rendering the same scene locally in the image"
render_out="$(cli rayfarm render "$SCENE" --spp "$SPP" -o /out/local.exr 2>&1)" \
  || { echo "$render_out" >&2; die "local render failed"; }
echo "$render_out" >&2
t_local=$(now)
if cli rayfarm compare /out/farm.exr /out/local.exr; then
  identical=yes
else
  identical=no
fi

log "master log for the job:"
master_log="$(compose logs --no-color master 2>/dev/null | grep -F "job $JOB " || true)"
echo "$master_log" | tail -n 15 >&2
# The processes' own clocks, without the cost of starting a container for each CLI call.
farm_s="$(echo "$master_log" | sed -n 's/.* done[^:]*: .* in \([0-9.]*\) s .*/\1/p' | tail -n 1)"
local_s="$(echo "$render_out" | sed -n 's/^time \([0-9.]*\) s.*/\1/p' | tail -n 1)"

cat <<EOF
docker-e2e summary
  workers              $WORKERS x $RAYFARM_WORKER_THREADS thread(s)
  scene, spp           $SCENE, $SPP
  base image           $(elapsed "$t0" "$t_base") s
  rayfarm image build  $(elapsed "$t_base" "$t_build") s
  cluster up           $(elapsed "$t_build" "$t_up") s  (CURVE keys made by the keys service)
  submit               $(elapsed "$t_up" "$t_submit") s
  watch until done     $(elapsed "$t_submit" "$t_done") s
  status + fetch       $(elapsed "$t_done" "$t_fetch") s
  dashboard, metrics   $(elapsed "$t_fetch" "$t_metrics") s  (until Prometheus had scraped the master)
  local render         $(elapsed "$t_metrics" "$t_local") s
  (each CLI call above includes starting a container)
  job on the farm      ${farm_s:-?} s  (master's log: accepted → done)
  rayfarm render       ${local_s:-?} s  (one process, all cores of this host)
  EXR on the host      $OUT/farm.exr
  bit-identical        $identical
EOF
[ "$identical" = yes ] || die "the farm's EXR differs from rayfarm render"
STATUS=0
