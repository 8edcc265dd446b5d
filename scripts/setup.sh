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
  python3 python3-dev python3-numpy python3-scipy python3-matplotlib python3-nbformat pybind11-dev
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

# Debian's /usr/bin/python3 finds the Python module (python/, built into build/python) from
# anywhere: an echoservo.pth in its /usr/local site folder (root only; docs/python.md).
python_path() {
  [ "$(id -u)" -eq 0 ] && [ -x /usr/bin/python3 ] || return 0
  local site
  site="$(/usr/bin/python3 -c 'import sys; v = sys.version_info; print(f"/usr/local/lib/python{v.major}.{v.minor}/dist-packages")')"
  mkdir -p "$site"
  echo "$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)/build/python" >"$site/echoservo.pth"
}

missing=()
for p in "${packages[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q 'install ok installed'; then
    missing+=("$p")
  fi
done

if [ "${#missing[@]}" -eq 0 ]; then
  echo "setup: all ${#packages[@]} packages already installed"
  python_path
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
python_path
