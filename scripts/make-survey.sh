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
# about SV_REF_CPU CPU-s (default 60): a 64-spp path run times the scene first, and the
# reference's spp is what SV_REF_CPU buys, at least 1024. --refs-only: make the missing
# references and stop.
#
# What it shows: the small size and budgets weigh photon mapping's fixed costs (the plan's
# pilots, the photon passes, precomputed irradiance) far more than a render at a scene's own
# size does; read a ratio below 1 here as "not ahead at this size", not as the scene's verdict.
# It takes about 15 minutes on 2 idle cores once the references exist (about 15 more to make them:
# at 60 CPU-s a reference's noise is about an eighth of path tracing's error at the 8 CPU-s
# budget, so a photon-mapping run up to about 7 times ahead there keeps a corrected error above
# it and a ratio that is not only a lower bound, gen-equal-time-md.sh).
#
# The misses, larger: the scenes that did not meet their target at this size, or that it could
# not measure (no run above the reference's noise; the verdict column of the targets' table,
# `gen-equal-time-md.sh --misses`), are measured again at
# SV_FOLLOW_RES x SV_FOLLOW_RES pixels (default 96; empty: not at all) with the equal-time
# section's budgets "4 12 40" (SV_FOLLOW_BUDGETS), against references of about
# SV_FOLLOW_REF_CPU CPU-s (default 240) in data/reference/et96/ (made when missing, about 2 min
# of wall time each on 2 cores), into docs/results/survey96/ (SV_FOLLOW_OUT); its
# measurement.txt says which survey the scenes came from (follow_up_of), and
# gen-equal-time-md.sh --survey prints it as the section after this one. About 1.5 minutes a
# scene once the references exist.
#
# Environment: PM_BUILD_DIR (default build/release), SV_RES, SV_BUDGETS, SV_REF_CPU,
# SV_REF_DIR, SV_OUT, SV_FOLLOW_RES, SV_FOLLOW_BUDGETS, SV_FOLLOW_REF_CPU, SV_FOLLOW_OUT.
set -eu
here=$(cd "$(dirname "$0")/.." && pwd)
bin="${PM_BUILD_DIR:-$here/build/release}/render"
res="${SV_RES:-32}"
refdir="${SV_REF_DIR:-$here/data/reference/s$res}"
refcpu="${SV_REF_CPU:-60}"
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
out="${SV_OUT:-$here/docs/results/survey}"
ET_RES="$res" ET_SCENES="$*" ET_BUDGETS="${SV_BUDGETS:-2 8}" ET_PROG_SCENES= ET_REF_DIR="$refdir" \
  ET_OUT="$out" sh "$here/scripts/make-equal-time.sh"
# README.md's survey summary, from the tables just measured (only for the default outputs: a
# survey written elsewhere, a test's, leaves the README alone)
summary() { [ -n "${SV_OUT:-}" ] || sh "$here/scripts/gen-equal-time-md.sh" --survey-readme; }
follow="${SV_FOLLOW_RES-96}"
if [ -z "$follow" ]; then summary; exit 0; fi
misses=$(sh "$here/scripts/gen-equal-time-md.sh" --misses "$out")
if [ -z "$misses" ]; then
  echo "make-survey: every scene met its target at ${res}x$res; no follow-up at ${follow}x$follow" >&2
  summary
  exit 0
fi
echo "make-survey: missed at ${res}x$res, measured again at ${follow}x$follow:" $misses >&2
fout="${SV_FOLLOW_OUT:-$here/docs/results/survey$follow}"
rm -rf "$fout"
# shellcheck disable=SC2086
SV_RES="$follow" SV_BUDGETS="${SV_FOLLOW_BUDGETS:-4 12 40}" SV_REF_CPU="${SV_FOLLOW_REF_CPU:-240}" \
  SV_REF_DIR="${SV_FOLLOW_REF_DIR:-$here/data/reference/et$follow}" SV_OUT="$fout" SV_FOLLOW_RES= \
  sh "$0" $misses
echo "follow_up_of $res" >> "$fout/measurement.txt"
summary
