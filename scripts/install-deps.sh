#!/bin/sh
# install-deps.sh: install the Debian packages photonmap needs to build, test and bench.
#
# The Makefile calls this when pkg-config cannot find a dependency, so that on a fresh
# Debian 12 machine (as root) `make test` alone is enough. Run it by hand with --all to
# also get the benchmark and profiling tools (gnuplot, hyperfine, valgrind, perf).
set -eu

# Needed to build and test: compiler, pkg-config, and the three libraries.
BASE="build-essential pkg-config libflann-dev libcjson-dev libpng-dev"
# Needed by `make bench` and the plot scripts.
BENCH="gnuplot-nox hyperfine valgrind"

want="$BASE"
case "${1:-}" in
  --all|--bench) want="$BASE $BENCH" ;;
  -h|--help) echo "usage: scripts/install-deps.sh [--all]"; exit 0 ;;
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
