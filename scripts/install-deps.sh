#!/bin/sh
# install-deps.sh: install the Debian packages photonmap needs to build, test, bench and run CI.
#
#   scripts/install-deps.sh [--bench | --ci | --mpi | --all]
#
# With no option: what `make test` and `make run` need (compiler, pkg-config, the four
# libraries, GNU time for the scripts' timings). --bench adds gnuplot (plots) and valgrind
# (the cache profile of `make bench`); --ci adds clang with its OpenMP runtime and its
# sanitizer runtimes (the clang and ThreadSanitizer builds of .ci/run); --mpi adds OpenMPI
# (mpicc, mpirun: `make MPI=1`, render-mpi); --all is everything.
#
# Only `make deps`, `run`, `test`, `check`, `bench`, `bench-quick` and `results` call this (when
# pkg-config cannot find a dependency), and `make MPI=1` with --mpi when mpicc is missing, so
# that on a fresh Debian 12 machine, as root,
# `make run` and `make test` alone are enough. It installs with --no-install-recommends, so
# every package a step needs is named here, never left to a recommendation.
set -eu

# Needed to build and test: compiler, pkg-config, the libraries (nanoflann is header-only,
# raced in bench/ beside FLANN; OpenEXR: its C API, OpenEXRCore, for --hdr x.exr), GNU time
# (/usr/bin/time).
BASE="build-essential pkg-config libflann-dev libnanoflann-dev libcjson-dev libpng-dev libopenexr-dev time"
# Needed by `make bench` and the plot scripts.
BENCH="gnuplot-nox valgrind"
# Needed by .ci/run: clang, its OpenMP runtime (libomp, with the Archer tool TSan uses) and
# its sanitizer runtimes (only recommended by clang, so named here).
CI="clang libomp-dev libclang-rt-14-dev"
# Needed by `make MPI=1` (render-mpi) and its tests: OpenMPI's compiler wrapper and mpirun.
MPI="libopenmpi-dev openmpi-bin"

want="$BASE"
case "${1:-}" in
  "") ;;
  --bench) want="$BASE $BENCH" ;;
  --ci) want="$BASE $CI" ;;
  --mpi) want="$BASE $MPI" ;;
  --all) want="$BASE $BENCH $CI $MPI" ;;
  -h|--help) sed -n '2,16p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
  *) echo "install-deps: unknown option '$1' (usage: scripts/install-deps.sh [--bench | --ci | --mpi | --all])" >&2
     exit 2 ;;
esac

missing=""
for p in $want; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing="$missing $p"
done
if [ -z "$missing" ]; then
  exit 0
fi

if [ "$(id -u)" != 0 ]; then
  SUDO=sudo
else
  SUDO=
fi
echo "install-deps: installing:$missing" >&2
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
# shellcheck disable=SC2086
$SUDO apt-get install -y -qq --no-install-recommends $missing >/dev/null
echo "install-deps: done" >&2
