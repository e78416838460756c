#!/usr/bin/env bash
# Installs the Debian packages the build and tests need. Idempotent: when every
# package is already present it installs nothing and does not touch apt.
set -euo pipefail

PACKAGES=(
  build-essential cmake ninja-build pkg-config
  libeigen3-dev libtbb-dev
  libgdal-dev gdal-bin python3-gdal libproj-dev proj-data
  libgeographiclib-dev
  libopencv-dev libceres-dev
  libopenvdb-dev libboost-iostreams-dev
  libcli11-dev nlohmann-json3-dev libspdlog-dev libfmt-dev
  libgtest-dev libgmock-dev libbenchmark-dev
  libssl-dev python3 python3-jsonschema
  clang libclang-rt-14-dev
  slurm-wlm munge
  chromium
)

missing=()
for pkg in "${PACKAGES[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$pkg" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$pkg")
  fi
done

# The web tools (glTF validator, SPZ decoder, CesiumJS, headless browser
# driver) come from npm, pinned by web/package-lock.json; installed again only
# when the lock file changed.
install_web() {
  if ! command -v npm >/dev/null 2>&1; then
    echo "setup: npm is missing; installing Debian's nodejs and npm"
    $SUDO apt-get install -y -qq --no-install-recommends nodejs npm >/dev/null
  fi
  # npm ci rewrites node_modules/.package-lock.json: it is newer than the
  # lock file unless the lock changed (or nothing was installed yet).
  if ! [ web/node_modules/.package-lock.json -nt web/package-lock.json ]; then
    echo "setup: installing the web tools (npm ci in web/)"
    (cd web && npm ci --no-audit --no-fund --loglevel=error)
  fi
}

cd "$(dirname "$0")/.."
SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi

if [ ${#missing[@]} -eq 0 ]; then
  echo "setup: all ${#PACKAGES[@]} packages present"
  install_web
  exit 0
fi

echo "setup: installing ${#missing[@]} missing packages: ${missing[*]}"
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
install_web
echo "setup: done"
