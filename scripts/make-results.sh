#!/bin/sh
# make-results.sh: judge photon mapping against the long path-traced references and write
# docs/RESULTS.md (tables, images side by side, difference images, the time-to-error plot).
#
#   scripts/make-results.sh [--quick]
#
# Needs data/reference/{cornell_spheres,cornell_diffuse}.pfm from scripts/make-reference.sh
# (it refuses a reference whose scene file changed since) and gnuplot for the plot
# (scripts/install-deps.sh --bench). --quick runs fewer and shorter renders, to try the
# script out; its figures are not the published ones.
#
# What it measures (all in linear HDR, against the reference):
#  1. Correctness. Each scene is rendered with photon mapping (PM_FLAGS, PM_SPP samples per
#     pixel). The means of the whole image, of each wall, the floor and the ceiling (pixels
#     that see that object alone: a `render --mode objects` mask) and of the caustic under the
#     glass sphere (floor pixels in a rectangle) are compared with the reference's, with
#     tolerances of 3% (image), 5% (walls, floor, ceiling) and 10% (caustic).
#  2. Time to equal error on cornell_spheres. Path tracing at PT_SPPS and photon mapping at
#     PM_SPPS samples per pixel, each timed (wall clock, 2 threads) and compared with the
#     reference (RMSE). The reference is itself a path tracer with N_ref samples: with
#     independent seeds, RMSE^2(run) = E^2 + c / N_ref, where E is the run's true error and c
#     the path tracer's variance constant (E^2 = c / N for a path-traced run of N samples).
#     c is fitted by least squares from the path-traced runs, the reference's share c / N_ref
#     is subtracted from every run, and the path tracer's time for the error photon mapping
#     reaches in 60 s follows from c and its measured time per sample.
#
#     A scene whose path-traced reference cannot show some light (specular objects that a
#     point or directional light sees: `render --mode path` warns and names them, with the
#     objects their caustics fall on) is refused before anything is measured; the two scenes
#     here have area lights only.
#  3. measurement.txt: the commit (with -dirty for uncommitted changes), the date at the end of
#     the run, the machine, the settings and each reference's .info, so that
#     scripts/gen-results-md.sh stamps the document with the measurement, not with the checkout
#     or the time it is regenerated at.
#
# Environment: PM_BUILD_DIR (default build/release), RES_THREADS (default 2).
set -eu
here=$(cd "$(dirname "$0")/.." && pwd)
bin="${PM_BUILD_DIR:-$here/build/release}/render"
threads="${RES_THREADS:-2}"
refdir="$here/data/reference"
out="$here/docs/results"
quick=0
[ "${1:-}" = "--quick" ] && quick=1
case "${1:-}" in -h|--help) awk 'NR > 1 && /^#/ { sub(/^# ?/, ""); print; next } NR > 1 { exit }' "$0"; exit 0 ;; esac
[ -x "$bin" ] || { echo "make-results: $bin not found; run make first" >&2; exit 2; }
command -v gnuplot >/dev/null 2>&1 || { echo "make-results: gnuplot missing (scripts/install-deps.sh --bench)" >&2; exit 2; }

# Photon-mapping settings for every run here (documented in docs/RESULTS.md): one gather ray
# per camera sample and many samples, a million caustic photons, and shadow rays instead of
# shadow photons (with 14 primitives a shadow ray costs less than a 16-photon lookup). The
# default plan, shadow photons included, is checked for correctness too (DEFAULT_FLAGS).
PM_FLAGS="--pm gather_rays=1 --pm secondary_rays=2 --pm caustic_photons=1000000 --pm shadow=false"
DEFAULT_FLAGS="--pm gather_rays=1 --pm secondary_rays=2 --pm caustic_photons=1000000"
PM_SPP=576
PT_SPPS="256 1024 4096 16384"
PM_SPPS="64 256 576 1024"
if [ $quick = 1 ]; then
  PM_SPP=16
  PT_SPPS="16 64"
  PM_SPPS="4 16"
  out="$here/build/results-quick"
fi
mkdir -p "$out"
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

# ---- the references -------------------------------------------------------------------------
info() { awk -v k="$2" '$1 == k { print $2 }' "$refdir/$1.info"; }
for name in cornell_spheres cornell_diffuse; do
  scene="$here/data/scenes/$name.json"
  [ -f "$refdir/$name.pfm" ] && [ -f "$refdir/$name.info" ] || {
    echo "make-results: no reference for $name: run scripts/make-reference.sh first" >&2; exit 2; }
  if [ "$(info $name scene_sha256)" != "$(sha256sum "$scene" | cut -d' ' -f1)" ]; then
    echo "make-results: $scene changed since its reference was rendered; run scripts/make-reference.sh $name" >&2
    exit 2
  fi
  # A path-traced reference lacks the caustics of point and directional lights (light they
  # send through specular surfaces onto diffuse ones; render/scene/delta_lit.h). `render --mode
  # path` names the specular objects such a light sees and the objects those caustics fall
  # on; the regions below would include them, so such a scene is refused, not compared.
  "$bin" "$scene" --mode path --width 8 --height 8 --spp 1 --quiet -o "$work/check.png" \
      > /dev/null 2> "$work/check.err" || { cat "$work/check.err" >&2; exit 2; }
  if grep -q "path tracing cannot render" "$work/check.err"; then
    cat "$work/check.err" >&2
    echo "make-results: $name: its path-traced reference lacks light that photon mapping renders" \
         "(above); leave those objects out of its regions (render --compare --mask IDS.pfm --id N," \
         "N the other objects) before comparing it" >&2
    exit 2
  fi
done
res=$(info cornell_spheres width)
nref=$(info cornell_spheres spp)

# Run a render; print "wall_s cpu_s". Args: scene name, output stem, render flags...
timed() {
  name=$1; stem=$2; shift 2
  /usr/bin/time -f '%e %U %S' -o "$work/time" "$bin" "$here/data/scenes/$name.json" \
      --width "$res" --height "$res" --threads "$threads" --quiet --hdr "$stem.pfm" \
      -o "$work/ignored.png" "$@" > "$stem.log"
  awk '{ printf "%.3f %.3f\n", $1, $2 + $3 }' "$work/time"
}
# "key value" lines of render --compare, as one value. Args: key, compare args...
cmpval() { key=$1; shift; "$bin" --compare "$@" | awk -v k="$key" '$1 == k { print $2 }'; }

# ---- 1. correctness ----------------------------------------------------------------------------
corr="$out/regions.csv"
echo "scene,config,region,pixels,pm_mean,ref_mean,rel_diff,tolerance,pass" > "$corr"
for run in cornell_spheres:pm cornell_diffuse:pm cornell_spheres:default cornell_diffuse:default; do
  name=${run%%:*}; config=${run#*:}
  ref="$refdir/$name.pfm"
  flags=$PM_FLAGS stem="$work/${name}_pm"
  [ "$config" = default ] && flags=$DEFAULT_FLAGS stem="$work/${name}_default"
  echo "make-results: $name: photon mapping ($config settings), $PM_SPP spp" >&2
  [ -f "$work/$name.ids.pfm" ] || "$bin" "$here/data/scenes/$name.json" --mode objects \
      --width "$res" --height "$res" --spp 1024 --quiet --hdr "$work/$name.ids.pfm" \
      -o "$work/ignored.png" > /dev/null
  # shellcheck disable=SC2086
  t=$(timed "$name" "$stem" --mode pm --spp "$PM_SPP" --seed 7 $flags)
  echo "$t" > "$out/${name}_$config.time"
  [ "$config" = default ] && grep -E '^  [a-z ]+: (on|off) \(' "$stem.log" > "$out/${name}_plan.txt"
  # Caustic rectangle under the glass sphere, in pixels of a 256-pixel image, scaled.
  cx=$((152 * res / 256)); cy=$((222 * res / 256)); cw=$((42 * res / 256)); ch=$((16 * res / 256))
  for region in image floor ceiling back_wall right_wall left_wall caustic; do
    case $region in
      image) args="" tol=0.03 ;;
      floor) args="--id 1" tol=0.05 ;;
      ceiling) args="--id 2" tol=0.05 ;;
      back_wall) args="--id 3" tol=0.05 ;;
      right_wall) args="--id 4" tol=0.05 ;;
      left_wall) args="--id 5" tol=0.05 ;;
      caustic) [ $name = cornell_spheres ] || continue
               args="--id 1 --rect $cx $cy $cw $ch" tol=0.10 ;;
    esac
    [ -n "$args" ] && args="--mask $work/$name.ids.pfm $args"
    # shellcheck disable=SC2086
    "$bin" --compare "$stem.pfm" "$ref" $args > "$work/cmp"
    awk -v s=$name -v c=$config -v r=$region -v tol=$tol '
      { v[$1] = $2 }
      END { d = v["rel_mean"]; a = d < 0 ? -d : d
            printf "%s,%s,%s,%d,%.6g,%.6g,%.5f,%.2f,%s\n", s, c, r, v["pixels"], v["mean_a"], v["mean_b"], d, tol, a <= tol ? "yes" : "no" }' \
      "$work/cmp" >> "$corr"
  done
  [ "$config" = default ] && continue
  # Images at the reference's auto exposure, and the difference.
  exp=$("$bin" --tonemap "$ref" "$out/${name}_ref.png" | sed -n 's/.*exposure \([0-9.e+-]*\).*/\1/p')
  "$bin" --tonemap "$stem.pfm" "$out/${name}_pm.png" --exposure "$exp" > /dev/null
  "$bin" --compare "$stem.pfm" "$ref" --diff "$out/${name}_diff.png" --diff-scale 0.25 > "$work/cmp"
done

# ---- 2. time to equal error ----------------------------------------------------------------------
ref="$refdir/cornell_spheres.pfm"
te="$out/time_error.csv"
echo "method,spp,seed,wall_s,cpu_s,rmse_vs_ref,rmse_corrected" > "$te.tmp"
seed=100
for spp in $PT_SPPS; do
  seed=$((seed + 1))
  echo "make-results: time to error: path tracing, $spp spp" >&2
  t=$(timed cornell_spheres "$work/pt" --mode path --spp "$spp" --seed $seed)
  echo "path,$spp,$seed,$(echo "$t" | tr ' ' ','),$(cmpval rmse "$work/pt.pfm" "$ref")," >> "$te.tmp"
done
for spp in $PM_SPPS; do
  seed=$((seed + 1))
  echo "make-results: time to error: photon mapping, $spp spp" >&2
  # shellcheck disable=SC2086
  t=$(timed cornell_spheres "$work/pm" --mode pm --spp "$spp" --seed $seed $PM_FLAGS)
  echo "pm,$spp,$seed,$(echo "$t" | tr ' ' ','),$(cmpval rmse "$work/pm.pfm" "$ref")," >> "$te.tmp"
done
# Fit c (RMSE^2 = c (1/N + 1/N_ref) for the path tracer), subtract the reference's c/N_ref.
awk -F, -v nref="$nref" -v summary="$out/time_error_summary.txt" '
  NR == 1 { print; next }
  { row[NR] = $0; m[NR] = $1; n[NR] = $2; w[NR] = $4; cpu[NR] = $5; e[NR] = $6; last = NR
    if ($1 == "path") { x = 1 / $2 + 1 / nref; sxy += $6 * $6 * x; sxx += x * x
                        tn += $2; tw += $4; tnn += $2 * $2; tnw += $2 * $4; np++ } }
  END {
    c = sxy / sxx; vref = c / nref
    # Path-traced time per sample: least squares t = a + b N.
    b = (np * tnw - tn * tw) / (np * tnn - tn * tn); a = (tw - b * tn) / np
    for (i = 2; i <= last; i++) {
      v = e[i] * e[i] - vref; corr[i] = v > 0 ? sqrt(v) : 0
      sub(/,$/, sprintf(",%.6g", corr[i]), row[i]); print row[i] }
    # Photon mapping at 60 s: interpolate log error against log time between the runs around it.
    target = 60; best = -1
    for (i = 2; i <= last; i++) if (m[i] == "pm") {
      if (w[i] <= target && (lo == "" || w[i] > w[lo])) lo = i
      if (w[i] >= target && (hi == "" || w[i] < w[hi])) hi = i }
    if (lo == "" || hi == "" || lo == hi) { i = lo == "" ? hi : lo; epm = corr[i]; tpm = w[i] }
    else { f = (log(target) - log(w[lo])) / (log(w[hi]) - log(w[lo]))
           epm = exp(log(corr[lo]) + f * (log(corr[hi]) - log(corr[lo]))); tpm = target }
    npt = c / (epm * epm); tpt = a + b * npt
    printf "c %.6g\nreference_spp %d\nreference_rmse %.6g\npt_seconds_per_spp %.6g\npt_seconds_fixed %.4g\n", c, nref, sqrt(vref), b, a > summary
    printf "pm_seconds %.4g\npm_rmse %.6g\npt_spp_for_equal_error %.0f\npt_seconds_for_equal_error %.4g\nratio %.3f\n", tpm, epm, npt, tpt, tpt / tpm >> summary
  }' "$te.tmp" > "$te"
rm -f "$te.tmp"

# The plot: corrected RMSE against wall time, both methods, and the path tracer's fitted curve.
c=$(awk '$1 == "c" { print $2 }' "$out/time_error_summary.txt")
b=$(awk '$1 == "pt_seconds_per_spp" { print $2 }' "$out/time_error_summary.txt")
a=$(awk '$1 == "pt_seconds_fixed" { print $2 }' "$out/time_error_summary.txt")
gnuplot <<EOF
set terminal pngcairo size 720,480 font ",10"
set output "$out/time_error.png"
set datafile separator ","
set logscale xy
set xlabel "wall time on $threads threads (s)"
set ylabel "RMSE against the reference (reference noise removed)"
set grid
set key top right
set title "cornell\\\\_spheres, ${res}x${res}: error against time"
pt(t) = t > $a ? sqrt($c / ((t - ($a)) / $b)) : 1/0
set arrow from 60, graph 0 to 60, graph 1 nohead dt 3 lc rgb "gray50"
set label "60 s" at 60, graph 0.95 offset 0.5, 0 textcolor rgb "gray40"
plot "$te" using (strcol(1) eq "path" ? \$4 : 1/0):7 with linespoints pt 7 title "path tracing", \
     "$te" using (strcol(1) eq "pm" ? \$4 : 1/0):7 with linespoints pt 5 title "photon mapping", \
     pt(x) with lines dt 2 title "path tracing, fitted c / N"
EOF
# ---- 3. what was measured, on what -------------------------------------------------------------
{
  echo "commit $(git -C "$here" describe --always --dirty --abbrev=7 2>/dev/null || echo unknown)"
  echo "date $(date -u '+%Y-%m-%d %H:%M UTC')"
  echo "machine $(nproc) cores, $(sed -n 's/^model name[^:]*: //p' /proc/cpuinfo | head -1)"
  echo "threads $threads"
  echo "pm_spp $PM_SPP"
  echo "pm_flags $PM_FLAGS"
  echo "default_flags $DEFAULT_FLAGS"
  for name in cornell_spheres cornell_diffuse; do
    for k in width height spp seed cpu_seconds; do echo "ref_${name}_$k $(info $name $k)"; done
  done
} > "$out/measurement.txt"
echo "make-results: wrote $out" >&2
[ $quick = 1 ] && exit 0
sh "$here/scripts/gen-results-md.sh"
