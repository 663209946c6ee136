#!/bin/sh
# measure-gather-ceiling.sh: how far photon mapping can go on the hard scenes (docs/HARD_SCENES.md)
# if its photon maps cost nothing: the camera side's error alone, against path tracing's at the
# same time. Writes docs/hard_scenes/ceiling/ (CSV and a stamp); scripts/gen-hard-scenes-md.sh
# turns it into the section "The final gather's ceiling".
#
#   scripts/measure-gather-ceiling.sh [--quick]
#
# WHY. Photon mapping at the defaults spends its time on two things: tracing photon maps, and
# the camera samples, whose final gather reads those maps (gather rays to precomputed
# irradiance, the first hit's direct light, emission). Ports, guided photons, importance
# emission and more photons all work on the maps: they lower the maps' noise or their cost. None
# of them lowers the variance of the camera samples themselves. So this measures that variance
# with the maps made free: traced once (GC_PHOTONS global photons, and as many volume photons in
# a scene with a medium), saved, and loaded by every run (`--load-photons`), whose
# "rendering" time (the camera samples alone; the loading, the precomputed irradiance and the
# pilots are not counted) and image are kept. The runs share one map, so the map's own error is
# the same in each and leaves the differences between seeds: half the mean squared difference
# of two seeds' images (`render --compare`, over every pair of seeds) is the variance of one run,
# the camera side's alone. Path tracing runs beside it, at `--time GC_BUDGET` (default 10 s),
# the same seeds.
#
# The ceiling (computed by scripts/gen-gather-ceiling-md.sh, per map and gather setting; its
# header has the details): path tracing's error, less the reference's noise, times its rendering
# time (the median over the seeds) over the oracle's variance times its rendering time (their
# means): how many times less time than path tracing the camera side alone needs for the same
# squared error. Everything is in the oracle's favour: its maps cost no time, they carry no
# noise of their own into its variance, and their bias is not counted. Photon mapping at the
# defaults pays for its maps and their noise on top, so its ratio in the budget table should
# not exceed the ceiling; where it does, the ceiling's premise (that the camera samples cost
# and vary as they do here) fails, and the section says so.
#
# The maps' share of the time: photon mapping at the defaults (`--mode pm --time GC_BUDGET`, the
# same seeds) spends part of its passes tracing maps and the rest on the camera samples; its
# statistics' "Rendering" over "Passes: all passes" is the camera's share, which scales the
# ceiling to what the camera samples get at the defaults (gen-gather-ceiling-md.sh).
#
# Maps of two sizes (GC_PHOTONS, default "2000000 50000"): about what photon mapping traced in
# all over a 10 s run of door_ajar (38 passes of about 53,000), and about one pass's map. A coarser map's
# estimates are smoother, so the gathers that read it may vary less; the ceiling takes the best
# of both. Settings: the gathers' rays per camera sample, gather_rays/secondary_rays 1/1 and 4/2
# (the ends of the three the sample pilot chooses from), each forced (`--pm`); per map and
# setting one calibration run at 256 spp, then GC_SEEDS seeds (default 4) at the square spp that
# takes about GC_SECONDS (default 5) of rendering.
#
# Output (GC_OUT, default docs/hard_scenes/ceiling): runs.csv (scene, kind, photons, setting,
# seed, seed_b, spp, render_s, mse, ref_spp, passes_s; kind "oracle": a loaded-map run against
# the reference, "pair": two oracle runs against each other (seed and seed_b), "path": path
# tracing at the budget against the reference, "pm": photon mapping at the defaults at the
# budget, its render_s the camera samples' seconds and passes_s its passes' (maps and camera);
# the budget runs' spp count their adaptive samples too), measurement.txt (commit stamp, date, machine, load, threads,
# photons, budget). GC_SCENES (default the five hard scenes), GC_THREADS (default 2).
# --quick: door_ajar only (or GC_SCENES), 2 seeds, 1/1 only, 200000 photons, 1 s budgets, into
# build/gather-ceiling-quick (or GC_OUT).
#
# Environment: PM_BUILD_DIR (default build/release).
set -eu
here=$(cd "$(dirname "$0")/.." && pwd)
bin="${PM_BUILD_DIR:-$here/build/release}/render"
refdir="$here/data/reference-hard"
scenes="${GC_SCENES:-pinhole_room door_ajar sun_window lamp_shade sun_window_fog}"
out="${GC_OUT:-$here/docs/hard_scenes/ceiling}"
threads="${GC_THREADS:-2}"
seeds="${GC_SEEDS:-4}"
photons="${GC_PHOTONS:-2000000 50000}"
budget="${GC_BUDGET:-10}"
target="${GC_SECONDS:-5}"
settings="1/1 4/2"
case "${1:-}" in
  -h|--help) awk 'NR > 1 && /^#/ { sub(/^# ?/, ""); print; next } NR > 1 { exit }' "$0"; exit 0 ;;
  --quick) scenes="${GC_SCENES:-door_ajar}"; seeds=2; settings=1/1; photons=200000; budget=1; target=1
           out="${GC_OUT:-$here/build/gather-ceiling-quick}" ;;
  "") ;;
  *) echo "measure-gather-ceiling: unknown option '$1' (see --help)" >&2; exit 2 ;;
esac
for v in "GC_SEEDS:$seeds" $(for p in $photons; do echo "GC_PHOTONS:$p"; done) "GC_BUDGET:$budget" "GC_SECONDS:$target" "GC_THREADS:$threads"; do
  case ${v#*:} in ''|*[!0-9]*|0*) echo "measure-gather-ceiling: ${v%%:*} must be a whole number from 1 ('${v#*:}')" >&2; exit 2 ;; esac
done
[ "$seeds" -ge 2 ] || { echo "measure-gather-ceiling: GC_SEEDS must be at least 2 (a variance needs two runs)" >&2; exit 2; }
[ -x "$bin" ] || { echo "measure-gather-ceiling: $bin not found; run make first" >&2; exit 2; }
. "$here/scripts/commit-stamp.sh"
stamp=$(commit_stamp "$here" "$bin") || exit 2
. "$here/scripts/reference-check.sh"
for name in $scenes; do
  ref_require measure-gather-ceiling "$refdir" "$name" "$here/data/scenes/$name.json"
done

work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
mkdir -p "$out.partial"
csv="$out.partial/runs.csv"
echo "scene,kind,photons,setting,seed,seed_b,spp,render_s,mse,ref_spp,passes_s" > "$csv"

# go NAME LOG ARGS...: render NAME at its reference's size into $work/img.pfm, log in LOG;
# sets secs (the rendering time the summary line prints).
go() {
  g_name=$1 g_log=$2
  shift 2
  "$bin" "$here/data/scenes/$g_name.json" --width "$(ref_info "$refdir" "$g_name" width)" \
      --height "$(ref_info "$refdir" "$g_name" height)" --threads "$threads" \
      --hdr "$work/img.pfm" -o "$work/img.png" "$@" > "$g_log" 2>&1 || {
    echo "measure-gather-ceiling: $g_name $* failed:" >&2; tail -5 "$g_log" >&2; exit 1; }
  secs=$(sed -n 's/^Summary: wall time [0-9.]* s (rendering \([0-9.]*\) s).*/\1/p' "$g_log")
  [ -n "$secs" ] || { echo "measure-gather-ceiling: $g_name $*: no summary line" >&2; exit 1; }
}
mse_of() { # A.pfm B.pfm
  "$bin" --compare "$1" "$2" | awk '$1 == "rmse" { printf "%.6g", $2 * $2 }'
}
# stat NAME LOG: the figure of the statistics line NAME (its words, then the figure) in LOG
stat() {
  awk -v k="$1" '{ l = $0; sub(/^ +/, "", l) } index(l, k) == 1 && substr(l, length(k) + 1) ~ /^ +[0-9.]+( s)?$/ {
    n = split(l, f, " "); v = f[n] == "s" ? f[n - 1] : f[n]; print v; exit }' "$2"
}

for name in $scenes; do
  ref="$refdir/$name.pfm"
  refspp=$(ref_info "$refdir" "$name" spp)
  for np in $photons; do
    maps="--pm global_photons=$np --pm volume_photons=$np"
    # shellcheck disable=SC2086
    go "$name" "$work/maps.log" --mode pm --spp 16 --seed 1 $maps --save-photons "$work/maps"
    echo "measure-gather-ceiling: $name: maps of $np photons traced" >&2
    for set in $settings; do
      pm="$maps --pm gather_rays=${set%/*} --pm secondary_rays=${set#*/} --load-photons $work/maps"
      # shellcheck disable=SC2086
      go "$name" "$work/log" --mode pm --spp 256 --seed 1 $pm
      # the square spp whose rendering takes about $target s at the calibration's pace
      spp=$(awk -v t="$secs" -v g="$target" 'BEGIN { if (t < 0.01) t = 0.01
        n = int(16 * sqrt(g / t) + 0.999); if (n < 16) n = 16; print n * n }')
      s=1
      while [ "$s" -le "$seeds" ]; do
        # shellcheck disable=SC2086
        go "$name" "$work/log" --mode pm --spp "$spp" --seed "$s" $pm
        cp "$work/img.pfm" "$work/oracle_$s.pfm"
        m=$(mse_of "$work/img.pfm" "$ref")
        echo "$name,oracle,$np,$set,$s,,$spp,$secs,$m,$refspp," >> "$csv"
        echo "measure-gather-ceiling: $name oracle $np photons $set seed $s: $spp spp, rendering $secs s, MSE $m" >&2
        s=$((s + 1))
      done
      a=1
      while [ "$a" -lt "$seeds" ]; do
        b=$((a + 1))
        while [ "$b" -le "$seeds" ]; do
          echo "$name,pair,$np,$set,$a,$b,$spp,,$(mse_of "$work/oracle_$a.pfm" "$work/oracle_$b.pfm"),$refspp," >> "$csv"
          b=$((b + 1))
        done
        a=$((a + 1))
      done
    done
    rm -rf "$work/maps"
  done
  px=$(( $(ref_info "$refdir" "$name" width) * $(ref_info "$refdir" "$name" height) ))
  s=1
  while [ "$s" -le "$seeds" ]; do
    for mode in pm path; do
      go "$name" "$work/log" --mode $mode --time "$budget" --seed "$s"
      m=$(mse_of "$work/img.pfm" "$ref")
      # samples a pixel (the passes' and the adaptive ones), from the statistics' count
      spp=$(awk -v px="$px" '$1 == "Samples" { printf "%.6g", $2 / px; exit }' "$work/log")
      [ -n "$spp" ] || { echo "measure-gather-ceiling: $name $mode: no sample count in its statistics" >&2; exit 1; }
      if [ $mode = pm ]; then
        secs=$(stat Rendering "$work/log")
        all=$(stat "Passes: all passes" "$work/log")
        [ -n "$secs" ] && [ -n "$all" ] || { echo "measure-gather-ceiling: $name pm: no pass times in its statistics" >&2; exit 1; }
      else
        all=
      fi
      echo "$name,$mode,,,$s,,$spp,$secs,$m,$refspp,$all" >> "$csv"
      echo "measure-gather-ceiling: $name $mode --time $budget seed $s: rendering $secs s${all:+ of the passes' $all s}, MSE $m" >&2
    done
    s=$((s + 1))
  done
done
{
  measured_lines "$stamp" "$threads"
  echo "photons $photons"
  echo "budget $budget"
  echo "seeds $seeds"
} > "$out.partial/measurement.txt"
rm -rf "$out"
mv "$out.partial" "$out"
echo "measure-gather-ceiling: wrote $out" >&2
