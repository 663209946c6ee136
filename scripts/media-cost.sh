#!/bin/sh
# media-cost.sh: does a scene without media render any slower with the media code? CPU time of
# two render binaries, side by side, on scenes that have no medium.
#
#   scripts/media-cost.sh BEFORE_RENDER BEFORE_LABEL AFTER_RENDER AFTER_LABEL [REPS]
#
# Each case (cornell_box path-traced, cornell_box and cornell_spheres photon-mapped; 32x32
# pixels, one thread) runs REPS times (default 5) per binary, the two binaries alternating run
# by run so that the machine's load falls on both alike; the time is the render's CPU time
# (user + system). Writes docs/media/cost.csv (case, binary, run, cpu_s) and
# docs/media/cost_measurement.txt (the two labels, date, machine, load average before and
# after); scripts/gen-media-md.sh reports the medians and their ratio. The RMSE between the
# two binaries' path-traced images is recorded too (0: they did the same work). COST_NOTE (in the
# environment) is kept as a note on how the binaries were built; COST_SAME_SOURCES=yes says the
# two were built from the same sources (an A/A run, which shows the measurement's own spread).
set -eu
here=$(cd "$(dirname "$0")/.." && pwd)
case "${1:-}" in -h|--help) awk 'NR > 1 && /^#/ { sub(/^# ?/, ""); print; next } NR > 1 { exit }' "$0"; exit 0 ;; esac
[ $# -ge 4 ] || { echo "media-cost: give BEFORE_RENDER BEFORE_LABEL AFTER_RENDER AFTER_LABEL [REPS] (see --help)" >&2; exit 2; }
b0=$1; l0=$2; b1=$3; l1=$4; reps=${5:-5}
for b in "$b0" "$b1"; do [ -x "$b" ] || { echo "media-cost: $b is not an executable" >&2; exit 2; }; done
out="$here/docs/media"
mkdir -p "$out"
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
load0=$(cut -d' ' -f1 /proc/loadavg)
echo "case,binary,run,cpu_s" > "$work/cost.csv"
run() { # binary label case scene flags...
  bin=$1; lab=$2; cs=$3; scn=$4; shift 4
  /usr/bin/time -f '%U %S' -o "$work/time" "$bin" "$here/data/scenes/$scn.json" --width 32 --height 32 --threads 1 \
      --quiet --seed 3 --hdr "$work/$lab.$cs.pfm" -o "$work/ignored.png" "$@" > "$work/log" 2>&1 || { cat "$work/log" >&2; exit 1; }
  awk -v c="$cs" -v l="$lab" -v r="$rep" '{ printf "%s,%s,%d,%.3f\n", c, l, r, $1 + $2 }' "$work/time" >> "$work/cost.csv"
}
rep=1
while [ $rep -le "$reps" ]; do
  for pair in "$b0 $l0" "$b1 $l1"; do
    set -- $pair
    run "$1" "$2" cornell_box_path cornell_box --mode path --spp 1024
    run "$1" "$2" cornell_box_pm cornell_box --mode pm --spp 4
    run "$1" "$2" cornell_spheres_pm cornell_spheres --mode pm --spp 4
  done
  echo "media-cost: round $rep of $reps done" >&2
  rep=$((rep + 1))
done
same=$("$b1" --compare "$work/$l0.cornell_box_path.pfm" "$work/$l1.cornell_box_path.pfm" | awk '$1 == "rmse" { print $2 }')
mv "$work/cost.csv" "$out/cost.csv"
{
  echo "before $l0"
  echo "after $l1"
  echo "date $(date -u '+%Y-%m-%d %H:%M UTC')"
  echo "machine $(nproc) cores, $(sed -n 's/^model name[^:]*: //p' /proc/cpuinfo | head -1)"
  echo "load $load0 before, $(cut -d' ' -f1 /proc/loadavg) after"
  echo "path_rmse_between_binaries $same"
  echo "resolution 32"
  echo "threads 1"
  echo "runs $reps"
  [ -z "${COST_SAME_SOURCES:-}" ] || echo "same_sources $COST_SAME_SOURCES"
  [ -z "${COST_NOTE:-}" ] || echo "note $COST_NOTE"
} > "$out/cost_measurement.txt"
echo "media-cost: wrote $out/cost.csv" >&2
