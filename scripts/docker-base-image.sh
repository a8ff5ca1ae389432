#!/usr/bin/env bash
# Builds the Debian bookworm base image that deploy/Dockerfile starts from, without pulling anything
# from a container registry: debootstrap a minimal root file system from the Debian mirror this
# machine's apt already uses, then `docker import` it.
#
# Usage: scripts/docker-base-image.sh [--force]
#   --force              rebuild even when the image already exists
# Environment:
#   RAYFARM_BASE_IMAGE   image name            (default rayfarm/debian:bookworm)
#   DEBIAN_MIRROR        Debian mirror URL     (default: read from /etc/apt/sources.list{,.d})
#   DEBIAN_SECURITY      security mirror URL   (default: read from the same place, may be empty)
#
# Idempotent: exits at once when the image exists. Needs root (debootstrap) and a Docker engine.
set -euo pipefail

readonly SUITE=bookworm
IMAGE="${RAYFARM_BASE_IMAGE:-rayfarm/debian:bookworm}"
FORCE=0

log() { echo "docker-base-image: $*" >&2; }
die() { log "error: $*"; exit 1; }

for arg in "$@"; do
  case "$arg" in
    --force) FORCE=1 ;;
    -h|--help) awk 'NR > 1 && /^#/ { sub(/^# ?/, ""); print; next } NR > 1 { exit }' "$0"; exit 0 ;;
    *) die "unknown argument '$arg' (try --help)" ;;
  esac
done

# Prints the first URI of an apt source (one-line or deb822 format) whose suites include $1.
find_mirror() {
  local suite="$1" f
  local -a files=()
  [ -f /etc/apt/sources.list ] && files+=(/etc/apt/sources.list)
  for f in /etc/apt/sources.list.d/*.list /etc/apt/sources.list.d/*.sources; do
    [ -f "$f" ] && files+=("$f")
  done
  for f in "${files[@]+"${files[@]}"}"; do
    case "$f" in
      *.sources)
        # deb822: blank-line separated stanzas with Types:, URIs:, Suites: fields.
        awk -v want="$suite" '
          function flush() {
            if (types ~ /(^| )deb( |$)/ && (" " suites " ") ~ (" " want " ") && uris != "") {
              split(uris, u, " "); print u[1]; found = 1; exit
            }
            types = ""; uris = ""; suites = ""
          }
          /^[ \t]*#/ { next }
          /^[ \t]*$/ { flush(); next }
          tolower($1) == "types:"  { $1 = ""; types = $0 }
          tolower($1) == "uris:"   { $1 = ""; uris = $0 }
          tolower($1) == "suites:" { $1 = ""; suites = $0 }
          END { if (!found) flush() }
        ' "$f"
        ;;
      *)
        # One-line format: deb [options] URI SUITE COMPONENTS...
        awk -v want="$suite" '
          $1 == "deb" {
            i = 2
            if ($i ~ /^\[/) { while (i <= NF && $i !~ /\]$/) i++; i++ }
            if ($(i + 1) == want) { print $i; exit }
          }
        ' "$f"
        ;;
    esac
  done | sed 's:/*[[:space:]]*$::' | head -n 1
}

command -v docker >/dev/null || die "docker is not installed (apt-get install docker.io)"
docker info >/dev/null 2>&1 || die "no Docker engine answers on ${DOCKER_HOST:-/var/run/docker.sock}"

if [ "$FORCE" -eq 0 ] && docker image inspect "$IMAGE" >/dev/null 2>&1; then
  log "$IMAGE already exists, nothing to do (use --force to rebuild)"
  exit 0
fi

[ "$(id -u)" -eq 0 ] || die "debootstrap needs root"
command -v debootstrap >/dev/null || die "debootstrap is not installed (apt-get install debootstrap)"

MIRROR="${DEBIAN_MIRROR:-$(find_mirror "$SUITE")}"
MIRROR="${MIRROR:-http://deb.debian.org/debian}"
SECURITY="${DEBIAN_SECURITY-$(find_mirror "$SUITE-security")}"
log "mirror $MIRROR${SECURITY:+, security $SECURITY}"

ROOTFS="$(mktemp -d /var/tmp/rayfarm-rootfs.XXXXXX)"
chmod 0755 "$ROOTFS"  # becomes the image's "/": mktemp's 0700 would lock out non-root users
cleanup() { rm -rf --one-file-system "$ROOTFS"; }
trap cleanup EXIT

start=$(date +%s)
log "debootstrap --variant=minbase $SUITE into $ROOTFS (takes a few minutes)"
debootstrap --variant=minbase "$SUITE" "$ROOTFS" "$MIRROR" >"$ROOTFS.log" 2>&1 || {
  tail -n 30 "$ROOTFS.log" >&2; rm -f "$ROOTFS.log"; die "debootstrap failed"
}
rm -f "$ROOTFS.log"

# The image's apt sees the same mirrors as this machine, plus the settings this network needs
# (a snapshot mirror with expired Release dates, a proxy) and the usual container habits.
{
  echo "deb $MIRROR $SUITE main"
  echo "deb $MIRROR $SUITE-updates main"
  [ -n "$SECURITY" ] && echo "deb $SECURITY $SUITE-security main"
} >"$ROOTFS/etc/apt/sources.list"
{
  echo 'APT::Install-Recommends "false";'
  echo 'APT::Install-Suggests "false";'
  apt-config dump 2>/dev/null | grep -E '^Acquire::(Check-Valid-Until|Check-Date|https?::Proxy) ' || true
} >"$ROOTFS/etc/apt/apt.conf.d/90rayfarm"
# Keep layers small: no package cache, no documentation.
cat >"$ROOTFS/etc/apt/apt.conf.d/91rayfarm-clean" <<'EOF'
DPkg::Post-Invoke { "rm -f /var/cache/apt/archives/*.deb /var/cache/apt/*.bin || true"; };
EOF
cat >"$ROOTFS/etc/dpkg/dpkg.cfg.d/90rayfarm-nodoc" <<'EOF'
path-exclude /usr/share/doc/*
path-include /usr/share/doc/*/copyright
path-exclude /usr/share/man/*
path-exclude /usr/share/info/*
path-exclude /usr/share/locale/*
EOF
# Drop package lists and caches but keep apt's own directories (and their owners) in place.
find "$ROOTFS/var/lib/apt/lists" "$ROOTFS/var/cache/apt" -type f -delete
rm -rf "$ROOTFS"/usr/share/doc/*/changelog*

log "importing as $IMAGE"
tar --numeric-owner -C "$ROOTFS" -c . | docker import \
  --change 'ENV LANG=C.UTF-8' \
  --change 'ENV PATH=/usr/local/sbin:/usr/local/bin:/usr/sbin:/usr/bin:/sbin:/bin' \
  --change 'CMD ["/bin/bash"]' \
  --message "Debian $SUITE minbase from $MIRROR" \
  - "$IMAGE" >/dev/null

log "built $IMAGE in $(( $(date +%s) - start ))s ($(docker image inspect -f '{{.Size}}' "$IMAGE" | awk '{printf "%.0f MB", $1/1e6}'))"
