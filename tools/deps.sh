#!/usr/bin/env bash
# Checks the Debian packages sphnl needs and installs the missing ones with
# apt-get. Without root (or without apt-get) it prints the exact command and
# exits non-zero.
set -euo pipefail
PACKAGES=(g++ make cmake git libbenchmark-dev libbenchmark-tools libgtest-dev libeigen3-dev nlohmann-json3-dev
          python3 python3-numpy python3-pandas python3-matplotlib python3-scipy valgrind
          pybind11-dev python3-pybind11 python3-dev libopenmpi-dev openmpi-bin libnanoflann-dev)
missing=()
for p in "${PACKAGES[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done
if [ ${#missing[@]} -eq 0 ]; then
  exit 0
fi
cmd="apt-get update && DEBIAN_FRONTEND=noninteractive apt-get install -y ${missing[*]}"
if ! command -v apt-get >/dev/null 2>&1; then
  echo "sphnl: missing packages: ${missing[*]}; this is not a Debian system, install their equivalents by hand." >&2
  exit 1
fi
if [ "$(id -u)" -ne 0 ]; then
  echo "sphnl: missing packages: ${missing[*]}" >&2
  echo "sphnl: run as root:  $cmd" >&2
  exit 1
fi
echo "sphnl: installing missing packages: ${missing[*]}"
echo "+ $cmd"
apt-get update -qq
DEBIAN_FRONTEND=noninteractive apt-get install -y -qq "${missing[@]}"
