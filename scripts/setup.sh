#!/usr/bin/env bash
# Installs the Debian 12 packages echoservo's build and tests need. Run as root (sudo is
# used only when not root). Skips apt entirely when every package is already installed.
set -euo pipefail

packages=(
  g++ cmake ninja-build
  clang-14 libclang-rt-14-dev llvm-14 clang-format-14 lld
  libgtest-dev libgmock-dev libbenchmark-dev
  libeigen3-dev libceres-dev nlohmann-json3-dev libcli11-dev libmuparser-dev
  chromium
  libvtk9-dev
  libembree-dev
  libopenigtlink-dev
  libopencv-dev
  libtbb-dev
  libfastrtps-dev libfastcdr-dev fastddsgen fastdds-tools
  libssl-dev
  python3
  zlib1g-dev
  xvfb
  xauth
  iproute2
  rt-tests
  stress-ng linux-perf
  libnlopt-dev
  slurm-wlm
  munge
)

missing=()
for p in "${packages[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q 'install ok installed'; then
    missing+=("$p")
  fi
done

if [ "${#missing[@]}" -eq 0 ]; then
  echo "setup: all ${#packages[@]} packages already installed"
  exit 0
fi

if [ "$(id -u)" -eq 0 ]; then
  as_root=()
elif command -v sudo >/dev/null 2>&1; then
  as_root=(sudo)
else
  echo "setup: missing packages (${missing[*]}); run as root or install sudo" >&2
  exit 1
fi

echo "setup: installing ${missing[*]}"
"${as_root[@]}" env DEBIAN_FRONTEND=noninteractive apt-get update
"${as_root[@]}" env DEBIAN_FRONTEND=noninteractive \
  apt-get install -y --no-install-recommends "${packages[@]}"
