#!/usr/bin/env bash
# Installs exactly what rayfarm needs to build, test and run, from Debian packages. Idempotent.
set -euo pipefail

packages=(
  cmake ninja-build g++ pkg-config git
  libembree-dev libopenexr-dev libspdlog-dev libfmt-dev libcli11-dev nlohmann-json3-dev
  libtbb-dev libpng-dev libjpeg62-turbo-dev libtinygltf-dev libpugixml-dev
  libzmq3-dev cppzmq-dev libprotobuf-dev protobuf-compiler libssl-dev libcpp-httplib-dev
  libgtest-dev libgmock-dev libbenchmark-dev
  python3
)
# ffmpeg makes a finished sequence's MP4 movie: optional for a master, needed by the tests;
# RAYFARM_DEPS=build (an image's build stage) leaves it out.
# The dashboard's end-to-end test drives a real browser: headless Chromium through Selenium.
[ "${RAYFARM_DEPS:-all}" = build ] || packages+=(ffmpeg chromium chromium-driver python3-selenium)

missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -eq 0 ]; then
  echo "install-deps: all ${#packages[@]} packages present"
  exit 0
fi

SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
echo "install-deps: installing ${missing[*]}"
$SUDO apt-get update -qq
DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
