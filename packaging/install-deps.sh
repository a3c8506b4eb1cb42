#!/usr/bin/env bash
# Installs everything Saker needs to build, test and run on Debian 12 (bookworm).
# Idempotent: packages already present are skipped by apt, and a machine that
# already has all of them does not even refresh the package lists.
# Usage (as root): packaging/install-deps.sh [--sanitizers]
set -euo pipefail

packages=(
  # Build tools
  cmake ninja-build g++ ccache pkg-config lld
  # GUI and engine libraries
  qt6-base-dev qt6-svg-dev libopencv-dev libeigen3-dev libceres-dev libgeographiclib-dev
  libavformat-dev libavcodec-dev libswscale-dev libavutil-dev ffmpeg
  libgdal-dev nlohmann-json3-dev libsqlite3-dev libtbb-dev libcli11-dev
  # Tests, benchmarks and headless GUI runs; clang and its runtimes for the fuzzers that
  # tests/run-all.sh runs (gcc's ASan, UBSan and TSan runtimes come with g++)
  libgtest-dev libgmock-dev xvfb xauth clang libclang-rt-14-dev
)
if [[ "${1:-}" == "--sanitizers" ]]; then
  packages+=(clang libclang-rt-14-dev)
fi

missing=()
for p in "${packages[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done

if ((${#missing[@]} == 0)); then
  echo "install-deps: all ${#packages[@]} packages already installed"
  exit 0
fi

if [[ $(id -u) -ne 0 ]]; then
  echo "install-deps: missing packages: ${missing[*]}" >&2
  echo "install-deps: run as root (or with sudo) to install them" >&2
  exit 1
fi

echo "install-deps: installing ${#missing[@]} packages: ${missing[*]}"
apt-get update
DEBIAN_FRONTEND=noninteractive apt-get install -y "${missing[@]}"
