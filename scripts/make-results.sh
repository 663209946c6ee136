#!/bin/sh
# make-results.sh: judge photon mapping at its defaults against long path-traced references and
# write docs/RESULTS.md (tables, images side by side, difference images, the time-to-error plot).
#
#   scripts/make-results.sh [--quick]
#
# Needs RES_REF_DIR/{cornell_spheres,cornell_diffuse}.pfm and .info (default data/reference:
# scripts/make-reference.sh, 128x128 path tracing; it refuses a reference whose scene file
# changed since) and gnuplot for the plot (scripts/install-deps.sh --bench). The image size is
# the references' (their .info). --quick runs fewer and shorter renders into
# build/results-quick (its RESULTS.md too), to try the script out; its figures are not the
# published ones.
#
# Photon mapping runs at its defaults: `render SCENE --mode pm` with no flag but the size, the
# spp, the seed and the threads (the plan chooses the rest and prints it; the photon counts
# are fitted to the render: README.md, "Photons fitted to the render"). One hand-set
# configuration (HAND_FLAGS below, the one the document published before the defaults were
# measured) is run beside it as extra, labelled rows (RES_HAND_SPPS; empty: none).
#
# What it measures (all in linear HDR, against the reference):
#  1. Correctness. Each scene is rendered with photon mapping (RES_PM_SPP samples per pixel).
#     The means of the whole image, of each wall, the floor and the ceiling (pixels that see
#     that object alone: a `render --mode objects` mask) and of the caustic under the glass
#     sphere (floor pixels in a rectangle) are compared with the reference's, with tolerances
#     of 3% (image), 5% (walls, floor, ceiling) and 10% (caustic).
#  2. Time to equal error on cornell_spheres. Path tracing at RES_PT_SPPS and photon mapping at
#     RES_PM_SPPS samples per pixel, each timed (CPU time of the whole process, user + sys, and
#     wall clock, RES_THREADS threads) and compared with the reference (RMSE). The reference is
#     itself a path tracer with N_ref samples: with independent seeds, RMSE^2(run) = E^2 +
#     c / N_ref, where E is the run's true error and c the path tracer's variance constant
#     (E^2 = c / N for a path-traced run of N samples). c is fitted by least squares from the
#     path-traced runs, the reference's share c / N_ref is subtracted from every run (the
#     corrected RMSE), and path tracing's CPU time as a line in N (least squares) gives its time
#     for each photon-mapping run's error; gen-results-md.sh computes the ratios.
#
#     A scene whose path-traced reference cannot show some light (specular objects that a
#     point or directional light sees: `render --mode path` warns and names them, with the
#     objects their caustics fall on) is refused before anything is measured; the two scenes
#     here have area lights only.
#  3. measurement.txt: the binary's commit (scripts/commit-stamp.sh: HEAD, "plus uncommitted
#     changes in the sources" when there are some; refused when a source file is newer than
#     the binary; PM_BENCH_COMMIT=TEXT names it instead), the date at the end of the run, the
#     machine and its load, the settings and each reference's .info, so that
#     scripts/gen-results-md.sh stamps the document with the measurement, not with the checkout
#     or the time it is regenerated at.
#
# Files are written into OUT.partial as the runs end (kept if the script stops) and replace
# OUT's at the end; the media (media/) and equal-time (equal_time/) folders are left alone.
#
# Environment: PM_BUILD_DIR (default build/release), RES_THREADS (default 2), RES_REF_DIR
# (default data/reference), RES_OUT (default docs/results), RES_PM_SPP (default 576),
# RES_PT_SPPS (default "64 256 1024 4096 16384"), RES_PM_SPPS (default "16 64 256 576 2304"),
# RES_HAND_SPPS (default "64 576"). At 128x128 on 2 shared cores the whole run took 510 s (at
# c8bc61f; the path-traced run of 16384 spp and photon mapping at 2304 spp are most of it).
set -eu
here=$(cd "$(dirname "$0")/.." && pwd)
bin="${PM_BUILD_DIR:-$here/build/release}/render"
threads="${RES_THREADS:-2}"
refdir="${RES_REF_DIR:-$here/data/reference}"
out="${RES_OUT:-$here/docs/results}"
quick=0
case "${1:-}" in
  -h|--help) awk 'NR > 1 && /^#/ { sub(/^# ?/, ""); print; next } NR > 1 { exit }' "$0"; exit 0 ;;
  --quick) quick=1 ;;
  "") ;;
  *) echo "make-results: unknown option '$1' (see --help)" >&2; exit 2 ;;
esac
[ -x "$bin" ] || { echo "make-results: $bin not found; run make first" >&2; exit 2; }
command -v gnuplot >/dev/null 2>&1 || { echo "make-results: gnuplot missing (scripts/install-deps.sh --bench)" >&2; exit 2; }
. "$here/scripts/commit-stamp.sh"
stamp=$(commit_stamp "$here" "$bin") || exit 2

# The hand-set configuration (extra rows only): one gather ray per camera sample, two at the
# next level, a million caustic photons and shadow rays instead of shadow photons.
HAND_FLAGS="--pm gather_rays=1 --pm secondary_rays=2 --pm caustic_photons=1000000 --pm shadow=false"
PM_SPP=${RES_PM_SPP:-576}
PT_SPPS=${RES_PT_SPPS:-64 256 1024 4096 16384}
PM_SPPS=${RES_PM_SPPS:-16 64 256 576 2304}
HAND_SPPS=${RES_HAND_SPPS-64 576}
if [ $quick = 1 ]; then
  PM_SPP=16
  PT_SPPS="16 64"
  PM_SPPS="4 16"
  HAND_SPPS="4"
  out="$here/build/results-quick"
fi
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
rm -rf "$out.partial"
mkdir -p "$out.partial"
part="$out.partial"

# ---- the references -------------------------------------------------------------------------
info() { awk -v k="$2" '$1 == k { print $2 }' "$refdir/$1.info"; }
for name in cornell_spheres cornell_diffuse; do
  scene="$here/data/scenes/$name.json"
  [ -f "$refdir/$name.pfm" ] && [ -f "$refdir/$name.info" ] || {
    echo "make-results: no reference for $name in $refdir: run scripts/make-reference.sh first (REF_OUT=$refdir)" >&2; exit 2; }
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
[ "$(info cornell_diffuse width)" = "$res" ] || {
  echo "make-results: the references in $refdir differ in size ($res, $(info cornell_diffuse width))" >&2; exit 2; }
nref=$(info cornell_spheres spp)
[ "$res" = 128 ] || [ $quick = 1 ] || echo "make-results: note: the references are ${res}x$res; the sample counts" \
  "here are sized for 128x128 (about 10 minutes on 2 idle cores), so this run takes about" \
  "$(awk -v r="$res" 'BEGIN { printf "%.2g", r * r / 16384 }') times as long" >&2

# Run a render; print "wall_s cpu_s". Args: scene name, output stem, render flags...
timed() {
  name=$1; stem=$2; shift 2
  /usr/bin/time -f '%e %U %S' -o "$work/time" "$bin" "$here/data/scenes/$name.json" \
      --width "$res" --height "$res" --threads "$threads" --quiet --hdr "$stem.pfm" \
      -o "$work/ignored.png" "$@" > "$stem.log" 2> "$stem.err" || {
    echo "make-results: render $name $* failed:" >&2; cat "$stem.err" >&2; exit 1; }
  awk '{ printf "%.3f %.3f\n", $1, $2 + $3 }' "$work/time"
}
# "key value" lines of render --compare, as one value. Args: key, compare args...
cmpval() { key=$1; shift; "$bin" --compare "$@" | awk -v k="$key" '$1 == k { print $2 }'; }

# ---- 1. correctness ----------------------------------------------------------------------------
corr="$part/regions.csv"
echo "scene,config,region,pixels,pm_mean,ref_mean,rel_diff,tolerance,pass" > "$corr"
configs=defaults
[ -z "$HAND_SPPS" ] || configs="defaults hand"
for name in cornell_spheres cornell_diffuse; do
  for config in $configs; do
    ref="$refdir/$name.pfm"
    stem="$work/${name}_$config"
    flags=
    [ "$config" = hand ] && flags=$HAND_FLAGS
    echo "make-results: $name: photon mapping ($config), $PM_SPP spp" >&2
    [ -f "$work/$name.ids.pfm" ] || "$bin" "$here/data/scenes/$name.json" --mode objects \
        --width "$res" --height "$res" --spp 1024 --quiet --hdr "$work/$name.ids.pfm" \
        -o "$work/ignored.png" > /dev/null
    # shellcheck disable=SC2086
    t=$(timed "$name" "$stem" --mode pm --spp "$PM_SPP" --seed 7 $flags)
    echo "$t" > "$part/${name}_$config.time"
    [ "$config" = defaults ] && grep -E '^  [a-z ]+: ' "$stem.log" > "$part/${name}_plan.txt"
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
      awk -v s=$name -v c="$config" -v r="$region" -v tol="$tol" '
        { v[$1] = $2 }
        END { d = v["rel_mean"]; a = d < 0 ? -d : d
              printf "%s,%s,%s,%d,%.6g,%.6g,%.5f,%.2f,%s\n", s, c, r, v["pixels"], v["mean_a"], v["mean_b"], d, tol, a <= tol ? "yes" : "no" }' \
        "$work/cmp" >> "$corr"
    done
    [ "$config" = defaults ] || continue
    # Images at the reference's auto exposure, and the difference.
    exp=$("$bin" --tonemap "$ref" "$part/${name}_ref.png" | sed -n 's/.*exposure \([0-9.e+-]*\).*/\1/p')
    "$bin" --tonemap "$stem.pfm" "$part/${name}_pm.png" --exposure "$exp" > /dev/null
    "$bin" --compare "$stem.pfm" "$ref" --diff "$part/${name}_diff.png" --diff-scale 0.25 > "$work/cmp"
  done
done

# ---- 2. time to equal error ----------------------------------------------------------------------
ref="$refdir/cornell_spheres.pfm"
te="$part/time_error.csv"
echo "method,spp,seed,wall_s,cpu_s,rmse_vs_ref,rmse_corrected" > "$work/te.csv"
seed=100
for run in $(for s in $PT_SPPS; do echo "path:$s"; done; for s in $PM_SPPS; do echo "pm:$s"; done
             for s in $HAND_SPPS; do echo "pm_hand:$s"; done); do
  method=${run%%:*}; spp=${run#*:}
  seed=$((seed + 1))
  echo "make-results: time to error: $method, $spp spp" >&2
  # shellcheck disable=SC2086 # HAND_FLAGS is a list of flags
  case $method in
    path) set -- --mode path ;;
    pm) set -- --mode pm ;;
    pm_hand) set -- --mode pm $HAND_FLAGS ;;
  esac
  t=$(timed cornell_spheres "$work/run" "$@" --spp "$spp" --seed $seed)
  used=$(sed -n 's/^Rendering [0-9]*x[0-9]*, \([0-9]*\) spp.*/\1/p' "$work/run.log")
  echo "$method,${used:-$spp},$seed,$(echo "$t" | tr ' ' ','),$(cmpval rmse "$work/run.pfm" "$ref")," >> "$work/te.csv"
done
# Fit c (RMSE^2 = c (1/N + 1/N_ref) for the path tracer), subtract the reference's c/N_ref;
# path tracing's CPU time: least squares cpu = a + b N (through 0 if a comes out negative).
awk -F, -v nref="$nref" -v summary="$part/time_error_summary.txt" '
  NR == 1 { print; next }
  { row[NR] = $0; e[NR] = $6; last = NR
    if ($1 == "path") { x = 1 / $2 + 1 / nref; sxy += $6 * $6 * x; sxx += x * x
                        tn += $2; tc += $5; tnn += $2 * $2; tnc += $2 * $5; np++ } }
  END {
    c = sxy / sxx; vref = c / nref
    b = (np * tnc - tn * tc) / (np * tnn - tn * tn); a = (tc - b * tn) / np
    if (a < 0) { a = 0; b = tnc / tnn }
    for (i = 2; i <= last; i++) {
      v = e[i] * e[i] - vref
      sub(/,$/, v > 0 ? sprintf(",%.6g", sqrt(v)) : ",0", row[i]); print row[i] }
    printf "c %.6g\nreference_spp %d\nreference_rmse %.6g\npt_cpu_per_spp %.6g\npt_cpu_fixed %.6g\n", c, nref, sqrt(vref), b, a > summary
  }' "$work/te.csv" > "$te"

# The plot: corrected RMSE against CPU time, each method, and the path tracer's fitted curve.
sv() { awk -v k="$1" '$1 == k { print $2 }' "$part/time_error_summary.txt"; }
c=$(sv c); b=$(sv pt_cpu_per_spp); a=$(sv pt_cpu_fixed)
hand_plot=
[ -z "$HAND_SPPS" ] || hand_plot=", \"$te\" using (strcol(1) eq \"pm_hand\" ? \$5 : 1/0):(\$7 > 0 ? \$7 : 1/0) with linespoints pt 9 title \"photon mapping, hand-set flags\""
gnuplot <<EOF
set terminal pngcairo size 720,480 font ",10"
set output "$part/time_error.png"
set datafile separator ","
set logscale xy
set xlabel "CPU time of the process (s), --threads $threads"
set ylabel "RMSE against the reference (reference noise removed)"
set grid
set key bottom left
set title "cornell\\\\_spheres, ${res}x${res}: error against time"
pt(t) = t > $a ? sqrt($c / ((t - ($a)) / $b)) : 1/0
plot "$te" using (strcol(1) eq "path" ? \$5 : 1/0):(\$7 > 0 ? \$7 : 1/0) with linespoints pt 7 title "path tracing", \
     "$te" using (strcol(1) eq "pm" ? \$5 : 1/0):(\$7 > 0 ? \$7 : 1/0) with linespoints pt 5 title "photon mapping, defaults"$hand_plot, \
     pt(x) with lines dt 2 title "path tracing, fitted c / N"
EOF
# ---- 3. what was measured, on what -------------------------------------------------------------
{
  echo "commit $stamp"
  echo "date $(date -u '+%Y-%m-%d %H:%M UTC')"
  echo "machine $(nproc) cores, $(sed -n 's/^model name[^:]*: //p' /proc/cpuinfo | head -1)"
  echo "load $(cut -d' ' -f1-3 /proc/loadavg) (1, 5, 15 min, at the end)"
  echo "threads $threads"
  echo "pm_spp $PM_SPP"
  echo "pt_spps $PT_SPPS"
  echo "pm_spps $PM_SPPS"
  [ -z "$HAND_SPPS" ] || { echo "hand_flags $HAND_FLAGS"; echo "hand_spps $HAND_SPPS"; }
  for name in cornell_spheres cornell_diffuse; do
    for k in width height spp seed cpu_seconds commit; do echo "ref_${name}_$k $(info $name $k)"; done
  done
} > "$part/measurement.txt"
# Replace the files of the last run (not media/ or equal_time/, which have their own scripts).
mkdir -p "$out"
for f in "$out"/*; do [ -f "$f" ] && rm -f "$f"; done
cp "$part"/* "$out/"
rm -rf "$part"
echo "make-results: wrote $out" >&2
if [ $quick = 1 ]; then
  sh "$here/scripts/gen-results-md.sh" --out "$out/RESULTS.md" "$out"
else
  sh "$here/scripts/gen-results-md.sh"
fi
