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
log "$file is valid ($(docker-compose version --short 2>/dev/null || echo docker-compose))"
