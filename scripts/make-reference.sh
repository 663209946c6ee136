#!/bin/sh
# make-reference.sh: render the long path-traced references that photon mapping is judged
# against (docs/RESULTS.md), into data/reference/ (gitignored: the PFMs are regenerated, not
# stored).
#
#   scripts/make-reference.sh [SCENE_NAME ...]      default: cornell_spheres cornell_diffuse
#
# Environment: PM_BUILD_DIR (where `render` is; default build/release), REF_RES (image side,
# default 128: scripts/make-results.sh renders at the references' size, and its sample counts
# are sized for 128x128), REF_SPP_<name> (samples per pixel; defaults below: cornell_spheres
# 32768, rounded up to 33124 by the 182x182 strata, the others 8192), REF_THREADS (default 2),
# REF_NICE (the niceness it runs at, default 10), REF_OUT (the directory, default
# data/reference; make-equal-time.sh's 96x96 references go to data/reference/et96).
#
# For each scene it writes data/reference/NAME.pfm (linear), NAME.png (a look at it) and
# NAME.info, a "key value" file with the scene file's SHA-256, the resolution, spp, seed and
# CPU time. scripts/make-results.sh refuses a reference whose scene hash no longer matches
# the scene file, so an edited scene cannot be judged against a stale reference.
#
# The reference uses seed 1000; the path-tracing runs of the time-to-equal-error experiment
# use other seeds, so their noise is independent of the reference's. The reference's own
# noise (it is a path tracer too) is estimated there from the same runs, not assumed zero.
# It runs under nice. At 128x128 on 2 cores, cornell_spheres (33,124 spp) took 382 s (569
# CPU-s) and cornell_diffuse (8,281 spp) 90 s (124 CPU-s), at 58ea9b4.
set -eu
here=$(cd "$(dirname "$0")/.." && pwd)
bin="${PM_BUILD_DIR:-$here/build/release}/render"
[ -x "$bin" ] || { echo "make-reference: $bin not found; run make first (or set PM_BUILD_DIR)" >&2; exit 2; }
res="${REF_RES:-128}"
threads="${REF_THREADS:-2}"
nice="${REF_NICE:-10}"
out="${REF_OUT:-$here/data/reference}"
mkdir -p "$out"
[ $# -gt 0 ] || set -- cornell_spheres cornell_diffuse
for name in "$@"; do
  scene="$here/data/scenes/$name.json"
  [ -f "$scene" ] || { echo "make-reference: no scene $scene" >&2; exit 2; }
  case "$name" in
    cornell_spheres) def_spp=32768 ;;
    *) def_spp=8192 ;;
  esac
  eval "spp=\${REF_SPP_$name:-$def_spp}"
  echo "make-reference: $name at ${res}x${res}, $spp spp (started $(date -u +%H:%M:%S) UTC)"
  t0=$(date +%s)
  /usr/bin/time -f '%U %S' -o "$out/$name.time" nice -n "$nice" "$bin" "$scene" --mode path \
      --width "$res" --height "$res" --spp "$spp" --seed 1000 --threads "$threads" --quiet \
      --hdr "$out/$name.pfm.tmp.pfm" -o "$out/$name.png" > "$out/$name.log"
  mv "$out/$name.pfm.tmp.pfm" "$out/$name.pfm"
  t1=$(date +%s)
  cpu=$(awk '{print $1 + $2}' "$out/$name.time")
  {
    echo "scene_sha256 $(sha256sum "$scene" | cut -d' ' -f1)"
    echo "width $res"
    echo "height $res"
    echo "spp $(sed -n 's/^Rendering [0-9]*x[0-9]*, \([0-9]*\) spp.*/\1/p' "$out/$name.log")"
    echo "seed 1000"
    echo "cpu_seconds $cpu"
    echo "wall_seconds $((t1 - t0))"
    echo "commit $(git -C "$here" rev-parse --short HEAD 2>/dev/null || echo unknown)"
  } > "$out/$name.info"
  echo "make-reference: $name done in $((t1 - t0)) s wall, $cpu s CPU"
done
