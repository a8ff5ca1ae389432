#!/usr/bin/env bash
# Validates deploy/docker-compose.yml with Debian's docker-compose (`config -q`): the YAML, the
# schema of the file's format version, and variable interpolation with the defaults. Needs no Docker
# engine, so it runs in CI. Installs the docker-compose package when it is missing (root or sudo).
#
# Usage: scripts/check-compose.sh [COMPOSE_FILE]
# Exit status: 0 valid, 1 invalid, 2 docker-compose unavailable.
set -euo pipefail

file="$(realpath -m "${1:-$(dirname "$0")/../deploy/docker-compose.yml}")"

log() { echo "check-compose: $*" >&2; }

[ -f "$file" ] || { log "error: $file does not exist"; exit 1; }

if ! command -v docker-compose >/dev/null; then
  SUDO=""
  if [ "$(id -u)" -ne 0 ]; then
    command -v sudo >/dev/null || { log "error: docker-compose is missing and cannot be installed without root"; exit 2; }
    SUDO="sudo"
  fi
  log "installing docker-compose (Debian package)"
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends docker-compose >/dev/null \
    || { log "error: could not install docker-compose"; exit 2; }
fi

# Validation only: point at a socket that does not exist, so a running engine changes nothing and a
# missing one is not an error. Warnings (such as an unset variable) are shown and count as failures.
if ! out="$(DOCKER_HOST=unix:///nonexistent docker-compose -f "$file" config -q 2>&1)"; then
  log "error: $file is invalid:"
  echo "$out" | sed 's/^/  /' >&2
  exit 1
fi
if [ -n "$out" ]; then
  log "error: $file validates with warnings:"
  echo "$out" | sed 's/^/  /' >&2
  exit 1
fi
# What YAML validation cannot see, on the file as compose resolves it with the defaults:
config="$(DOCKER_HOST=unix:///nonexistent docker-compose -f "$file" config 2>/dev/null)"
fail() { log "error: $file: $*"; exit 1; }
# The master's ports are published on loopback unless RAYFARM_BIND opens them. docker-compose 1.29
# prints them as "- IP:HOST:CONTAINER/tcp", Compose v2 as "host_ip: IP" under "published: HOST".
master="$(echo "$config" | awk '/^  master:/{m=1; next} /^  [a-z]/{m=0} m')"
ports="$(echo "$master" | awk '/^    ports:/{p=1; next} /^    [a-z]/{p=0} p')"
[ -n "$ports" ] || fail "the master publishes no ports"
short="$(echo "$ports" | sed -nE 's/^ *- *["'"'"']?([^"'"'"']*)["'"'"']?$/\1/p' || true)"
if [ -n "$short" ]; then
  echo "$short" | grep -vqE '^127\.0\.0\.1:' && fail "ports published beyond loopback by default: $(echo $short)"
else
  hosts="$(echo "$ports" | sed -nE 's/^ *host_ip: *["'"'"']?([^"'"'"']*)["'"'"']?$/\1/p' | sort -u || true)"
  [ "$hosts" = "127.0.0.1" ] || fail "ports published on '${hosts:-every interface}' by default; publish on 127.0.0.1 (RAYFARM_BIND)"
fi
# A stopped worker returns its unit: compose waits for it longer than it waits for its unit (plus
# 2 s for its goodbye), or SIGKILL comes first and the master requeues the unit after a silence.
worker="$(echo "$config" | awk '/^  worker:/{w=1; next} /^  [a-z]/{w=0} w')"
grace_ms="$(echo "$worker" | grep -A1 -- '- --stop-grace-ms' | tail -1 | tr -dc '0-9' || true)"
grace_ms="${grace_ms:-8000}"  # the worker's default
period="$(echo "$worker" | sed -nE 's/^ *stop_grace_period: *//p' | tr -d "'\"" || true)"
period="${period:-10s}"  # compose's default
case "$period" in
  *m*s) period_s=$(( ${period%%m*} * 60 + $(echo "${period#*m}" | tr -dc '0-9') )) ;;
  *m) period_s=$(( ${period%m} * 60 )) ;;
  *s) period_s="${period%s}" ;;
  *) period_s="$period" ;;
esac
if [ $(( grace_ms + 2000 )) -gt $(( period_s * 1000 )) ]; then
  fail "the worker's stop_grace_period ($period) is shorter than its --stop-grace-ms ($grace_ms ms) + 2 s: docker stop would kill it before it returns its unit"
fi
log "$file is valid ($(docker-compose version --short 2>/dev/null || echo docker-compose)); ports on 127.0.0.1 by default; worker stop grace ${grace_ms} ms within ${period}"
