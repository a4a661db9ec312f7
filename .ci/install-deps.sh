#!/usr/bin/env bash
# Installs the Debian packages rvegen needs to build and test (idempotent; quick when present).
# The list follows the verified platform notes: ParaView 5.11 ships its own VTK, so libvtk9-dev
# must NOT be installed (its python3-vtk9 conflicts with python3-paraview).
set -euo pipefail
PKGS=(
  build-essential cmake g++ libgtest-dev libgmock-dev googletest libbenchmark-dev
  paraview paraview-dev python3-paraview qtbase5-dev qttools5-dev libqt5svg5-dev
  qtxmlpatterns5-dev-tools libqt5x11extras5-dev libqt5opengl5-dev libutfcpp-dev libdouble-conversion-dev zlib1g-dev
  libtiff-dev libtheora-dev libpng-dev libnetcdf-dev libxml2-dev liblzma-dev liblz4-dev libjpeg-dev
  libglew-dev libgl2ps-dev libgdal-dev libfreetype-dev libavcodec-dev libavformat-dev libswscale-dev
  libexpat1-dev libboost-dev python3-mpi4py libx11-dev libgl-dev mpi-default-dev
  libhdf5-openmpi-dev libeigen3-dev libtbb-dev libopenvdb-dev libboost-iostreams-dev
  libboost-system-dev libfftw3-dev libfftw3-mpi-dev libgmsh-dev libocct-foundation-dev libocct-modeling-data-dev
  libocct-modeling-algorithms-dev nlohmann-json3-dev xvfb xauth python3-numpy python3-matplotlib python3-h5py clang-format
  clang-14 libclang-rt-14-dev calculix-ccx python3-meshio gmsh
)
missing=()
for p in "${PKGS[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -eq 0 ]; then
  echo "install-deps: all ${#PKGS[@]} packages present"
  exit 0
fi
SUDO=""
[ "$(id -u)" -eq 0 ] || SUDO="sudo"
echo "install-deps: installing ${#missing[@]} packages: ${missing[*]}"
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
