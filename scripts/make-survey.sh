#!/bin/sh
# make-survey.sh: every shipped scene (data/scenes/*.json), photon mapping at its defaults
# against path tracing at equal CPU time, small: scripts/make-equal-time.sh's protocol at
# SV_RES x SV_RES pixels (default 32) and budgets SV_BUDGETS CPU-s (default "2 8"), no
# progressive runs, into docs/results/survey/ (SV_OUT). scripts/gen-results-md.sh prints it
# as docs/RESULTS.md's last section, "Every shipped scene, small" (gen-equal-time-md.sh --survey).
#
#   scripts/make-survey.sh [--refs-only] [SCENE ...]      default: every shipped scene
#
# The references: SV_RES x SV_RES path-traced images in data/reference/sSV_RES/ (SV_REF_DIR),
# made by scripts/make-reference.sh where one is missing or its scene file changed, each at
# about SV_REF_CPU CPU-s (default 20): a 64-spp path run times the scene first, and the
# reference's spp is what SV_REF_CPU buys, at least 1024. --refs-only: make the missing
# references and stop.
#
# What it shows: the small size and budgets weigh photon mapping's fixed costs (the plan's
# pilots, the photon passes, precomputed irradiance) far more than a render at a scene's own
# size does; read a ratio below 1 here as "not ahead at this size", not as the scene's verdict.
# It takes about 15 minutes on 2 idle cores once the references exist (about 5 more to make them).
#
# Environment: PM_BUILD_DIR (default build/release), SV_RES, SV_BUDGETS, SV_REF_CPU,
# SV_REF_DIR, SV_OUT.
set -eu
here=$(cd "$(dirname "$0")/.." && pwd)
bin="${PM_BUILD_DIR:-$here/build/release}/render"
res="${SV_RES:-32}"
refdir="${SV_REF_DIR:-$here/data/reference/s$res}"
refcpu="${SV_REF_CPU:-20}"
refs_only=0
case "${1:-}" in
  -h|--help) awk 'NR > 1 && /^#/ { sub(/^# ?/, ""); print; next } NR > 1 { exit }' "$0"; exit 0 ;;
  --refs-only) refs_only=1; shift ;;
  -*) echo "make-survey: unknown option '$1' (see --help)" >&2; exit 2 ;;
esac
[ -x "$bin" ] || { echo "make-survey: $bin not found; run make first" >&2; exit 2; }
if [ $# -eq 0 ]; then
  set -- $(for f in "$here"/data/scenes/*.json; do basename "$f" .json; done)
fi
. "$here/scripts/reference-check.sh"
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
for name in "$@"; do
  scene="$here/data/scenes/$name.json"
  [ -f "$scene" ] || { echo "make-survey: no scene $scene" >&2; exit 2; }
  [ "$(ref_state "$refdir" "$name" "$scene")" = ok ] && continue
  /usr/bin/time -f '%U %S' -o "$work/time" "$bin" "$scene" --mode path --width "$res" --height "$res" \
      --spp 64 --seed 999 --threads 2 --quiet --hdr "$work/t.pfm" -o "$work/t.png" > /dev/null
  spp=$(awk -v c="$refcpu" '{ t = $1 + $2; n = t > 0 ? int(c / t * 64) : 1024; print n < 1024 ? 1024 : n }' "$work/time")
  echo "make-survey: $name: 64 spp took $(awk '{ print $1 + $2 }' "$work/time") CPU-s; reference at $spp spp" >&2
  env "REF_SPP_$name=$spp" REF_RES="$res" REF_OUT="$refdir" sh "$here/scripts/make-reference.sh" "$name" >&2
done
[ $refs_only = 1 ] && exit 0
ET_RES="$res" ET_SCENES="$*" ET_BUDGETS="${SV_BUDGETS:-2 8}" ET_PROG_SCENES= ET_REF_DIR="$refdir" \
  ET_OUT="${SV_OUT:-$here/docs/results/survey}" sh "$here/scripts/make-equal-time.sh"
