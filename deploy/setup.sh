#!/usr/bin/env bash
# Installs every Debian 12 package that Tessera needs to build, test and run.
# Idempotent: packages already present are skipped, so re-running is cheap.
set -euo pipefail

PACKAGES=(
  build-essential cmake pkg-config git
  libembree-dev
  libopenimageio-dev openimageio-tools libopencv-core-dev
  libgrpc++-dev libgrpc-dev protobuf-compiler protobuf-compiler-grpc libprotobuf-dev
  libspdlog-dev libfmt-dev
  libtbb-dev
  nlohmann-json3-dev
  libsqlite3-dev libsqlitecpp-dev
  libgtest-dev libgmock-dev googletest
  libbenchmark-dev
  libcli11-dev
  libtinyobjloader-dev
  libxxhash-dev libzstd-dev libssl-dev
  libnanoflann-dev
  python3-yaml ffmpeg
  python3-grpcio python3-protobuf
  clang libclang-rt-dev ninja-build
  libcpp-httplib-dev prometheus-cpp-dev
  chromium chromium-driver python3-selenium
)

missing=()
for p in "${PACKAGES[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done

if [ ${#missing[@]} -eq 0 ]; then
  echo "setup: all ${#PACKAGES[@]} packages present"
  exit 0
fi

echo "setup: installing ${missing[*]}"
SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
echo "setup: done"
