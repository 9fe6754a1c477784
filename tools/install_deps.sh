#!/usr/bin/env bash
# Installs epiloc's build and run dependencies from Debian packages. Idempotent: packages already
# present are not reinstalled, and nothing is done when everything is there.
set -euo pipefail

packages=(
  build-essential cmake pkg-config ninja-build
  libopencv-dev libeigen3-dev libflann-dev
  libsqlite3-dev sqlite3 libgeographiclib-dev
  libgtest-dev libgmock-dev
  libcli11-dev libspdlog-dev libfmt-dev nlohmann-json3-dev
  libxxhash-dev gnuplot-nox time python3
  libceres-dev
)

missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done

if ((${#missing[@]} == 0)); then
  echo "install_deps: all ${#packages[@]} packages present"
  exit 0
fi

echo "install_deps: installing ${missing[*]}"
sudo=""
if [[ $(id -u) -ne 0 ]]; then sudo="sudo"; fi
export DEBIAN_FRONTEND=noninteractive
$sudo apt-get update -qq
$sudo apt-get install -y -qq --no-install-recommends "${missing[@]}"
