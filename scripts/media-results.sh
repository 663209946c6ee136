#!/bin/sh
# media-results.sh: photon mapping against the path-traced references of the media scenes
# (cornell_fog, glass_of_smoke), for the media section of docs/RESULTS.md.
#
#   scripts/media-results.sh [--no-doc]
#
# Needs the committed references data/reference-media/NAME.pfm and NAME.info (64x64 path
# tracing, made by scripts/make-reference.sh with REF_RES=64; the .info holds the samples, the
# CPU time and the scene file's SHA-256, and a reference of another version of the scene is
# refused). Each scene is rendered with photon mapping, its default plan, PM_SPP samples per
# pixel, on one thread (CPU time measured), and the means of the image and of the pixels that
# see each listed object (a --mode objects mask; the fog or smoke in front of the object is
# part of the pixel) are compared with the reference's: tolerances 3% (image) and 5% (objects).
# Writes docs/results/media/: regions.csv, NAME_pm.time (CPU seconds), NAME_plan.txt (the plan
# as printed), the images (NAME_ref.png, NAME_pm.png at the reference's exposure, NAME_diff.png)
# and measurement.txt (commit, date, machine, settings, each reference's info); then runs
# scripts/gen-results-md.sh (unless --no-doc). The commit is the render binary's, found before
# anything is written (scripts/commit-stamp.sh): HEAD, "plus uncommitted changes in the sources"
# when git status lists any in photonmap/, render/ or the Makefile; refused (exit 2) when a
# source file is newer than the binary; PM_BENCH_COMMIT=TEXT stamps TEXT instead (a binary
# built from a clean export of a commit).
#
# Environment: PM_BUILD_DIR (where render is; default build/release).
set -eu
here=$(cd "$(dirname "$0")/.." && pwd)
bin="${PM_BUILD_DIR:-$here/build/release}/render"
out="$here/docs/results/media"
refdir="$here/data/reference-media"
doc=1
case "${1:-}" in
  -h|--help) awk 'NR > 1 && /^#/ { sub(/^# ?/, ""); print; next } NR > 1 { exit }' "$0"; exit 0 ;;
  --no-doc) doc=0 ;;
  "") ;;
  *) echo "media-results: unknown argument '$1' (see --help)" >&2; exit 2 ;;
esac
[ -x "$bin" ] || { echo "media-results: $bin not found; run make first (or set PM_BUILD_DIR)" >&2; exit 2; }
# The binary's commit, before anything is written (scripts/commit-stamp.sh).
. "$here/scripts/commit-stamp.sh"
stamp=$(commit_stamp "$here" "$bin") || exit 2
PM_SPP=4
RES=64
SCENES="cornell_fog glass_of_smoke"
info() { awk -v k="$2" '$1 == k { print $2 }' "$refdir/$1.info"; }
for name in $SCENES; do
  [ -f "$refdir/$name.pfm" ] && [ -f "$refdir/$name.info" ] || { echo "media-results: no reference $refdir/$name.pfm" >&2; exit 2; }
  [ "$(info "$name" scene_sha256)" = "$(sha256sum "$here/data/scenes/$name.json" | cut -d' ' -f1)" ] ||
    { echo "media-results: data/scenes/$name.json changed since its reference was rendered" >&2; exit 2; }
  [ "$(info "$name" width)" = $RES ] || { echo "media-results: $name's reference is not ${RES}x$RES" >&2; exit 2; }
done
mkdir -p "$out"
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
echo "scene,region,pixels,pm_mean,ref_mean,rel_diff,tolerance,pass" > "$work/regions.csv"
for name in $SCENES; do
  scene="$here/data/scenes/$name.json"
  ref="$refdir/$name.pfm"
  echo "media-results: $name: photon mapping, $PM_SPP spp" >&2
  "$bin" "$scene" --mode objects --width $RES --height $RES --spp 64 --quiet --hdr "$work/ids.pfm" -o "$work/ids.png" > /dev/null
  /usr/bin/time -f '%U %S' -o "$work/time" "$bin" "$scene" --mode pm --spp $PM_SPP --seed 7 --width $RES --height $RES \
      --threads 1 --hdr "$work/pm.pfm" -o "$work/pm.png" > "$work/log" 2>&1 || { cat "$work/log" >&2; exit 1; }
  awk '{ printf "%.2f\n", $1 + $2 }' "$work/time" > "$out/${name}_pm.time"
  grep -E '^  [a-z ]+: (on|off) \(' "$work/log" > "$out/${name}_plan.txt"
  case $name in
    cornell_fog) regions="floor:1 ceiling:2 back_wall:3 left_wall:4 right_wall:5" ;;
    glass_of_smoke) regions="smoke_sphere:7 floor:1 back_wall:3 left_wall:4 right_wall:5" ;;
  esac
  for r in image $regions; do
    region=${r%%:*}
    if [ "$region" = image ]; then args="" tol=0.03; else args="--mask $work/ids.pfm --id ${r#*:}" tol=0.05; fi
    # shellcheck disable=SC2086
    "$bin" --compare "$work/pm.pfm" "$ref" $args | awk -v s=$name -v r=$region -v tol=$tol '
      { v[$1] = $2 }
      END { d = v["rel_mean"]; a = d < 0 ? -d : d
            printf "%s,%s,%d,%.6g,%.6g,%.5f,%.2f,%s\n", s, r, v["pixels"], v["mean_a"], v["mean_b"], d, tol, a <= tol ? "yes" : "no" }' >> "$work/regions.csv"
  done
  exp=$("$bin" --tonemap "$ref" "$out/${name}_ref.png" | sed -n 's/.*exposure \([0-9.e+-]*\).*/\1/p')
  "$bin" --tonemap "$work/pm.pfm" "$out/${name}_pm.png" --exposure "$exp" > /dev/null
  "$bin" --compare "$work/pm.pfm" "$ref" --diff "$out/${name}_diff.png" --diff-scale 0.25 > /dev/null
done
mv "$work/regions.csv" "$out/regions.csv"
{
  echo "commit $stamp"
  echo "date $(date -u '+%Y-%m-%d %H:%M UTC')"
  echo "machine $(nproc) cores, $(sed -n 's/^model name[^:]*: //p' /proc/cpuinfo | head -1)"
  echo "resolution $RES"
  echo "pm_spp $PM_SPP"
  for name in $SCENES; do
    for k in spp seed cpu_seconds commit; do echo "ref_${name}_$k $(info "$name" $k)"; done
  done
} > "$out/measurement.txt"
echo "media-results: wrote $out" >&2
[ $doc = 1 ] && sh "$here/scripts/gen-results-md.sh"
exit 0
