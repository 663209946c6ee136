#!/bin/sh
# media-time-error.sh: time to equal error, photon mapping against path tracing, in scenes with
# participating media: RMSE against a reference as a function of CPU time, for both methods.
#
#   scripts/media-time-error.sh [--quick | --reduced] cornell_fog|volumetric_caustic ...
#
# cornell_fog: the whole 64x64 image against the committed path-traced reference
#   data/reference-media/cornell_fog.pfm (its .info gives its samples; a reference of another
#   version of the scene file is refused). Path tracing at PT_SPPS and photon mapping (its
#   default plan) at PM_SPPS samples per pixel. The reference is a path tracer too: with
#   independent seeds RMSE^2(run) = E^2 + c / N_ref, where c is the path tracer's variance
#   constant (E^2 = c / N for a path-traced run of N samples). c is fitted by least squares from
#   the path-traced runs, c / N_ref is taken off every run ("corrected"), and the path tracer's
#   CPU time for photon mapping's error follows from c and its CPU seconds per sample (a
#   least-squares line through its runs).
# volumetric_caustic: the pixels of the light beam in the fog below the glass sphere (a
#   rectangle, BEAM_RECT, in a 64x64 image). Path tracing cannot be the reference there, so the
#   reference is a longer photon-mapping render made here (REF_PM_SPP samples, REF_PM_FLAGS:
#   3 times the volume-caustic photons), whose beam power is checked against a brute-force
#   integral by the test media_volumetric_caustic_energy; photon mapping's error against it
#   is therefore not independent of it, path tracing's is. Path tracing at PT_SPPS_VC and photon
#   mapping at PM_SPPS_VC, with PM_FLAGS_VC: 20,000 surface-caustic photons instead of 500,000
#   (the floor's caustic is outside the beam region; with the default, that pass alone emits
#   some 17 M photons through the lamp's tube). Reported: each run's RMSE and mean in the
#   beam, the path tracer's c = N RMSE^2 from its longest run and its CPU time extrapolated
#   from there to photon mapping's error, and the measured lower bound: the longest
#   path-traced run's CPU time over that of the cheapest photon-mapping run with at most the
#   same error.
#
# Every render runs on one thread; the time is its CPU time (user + system, /usr/bin/time), so
# the figures hold on a loaded machine. Writes docs/media/time_error_SCENE.csv (method, spp,
# seed, cpu_s, rmse, mean, rmse_corrected), docs/media/summary_SCENE.txt and
# docs/media/measurement_SCENE.txt (commit, date, machine, settings, reference); then
# scripts/gen-media-md.sh writes docs/MEDIA.md. The commit is the render binary's, found before
# anything is written (scripts/commit-stamp.sh): HEAD, "plus uncommitted changes in the
# sources" when git status lists any in photonmap/, render/ or the Makefile; refused (exit 2)
# when a source file is newer than the binary; PM_BENCH_COMMIT=TEXT stamps TEXT instead (a
# binary built from a clean export of a commit). --quick: fewer samples, into
# build/media-quick (not the published figures). --reduced: the published files, without the
# beam's longest path-traced run (4096 spp, about 150 of its 215 CPU-s): path tracing at
# 16..1024 spp there, everything else as at the defaults; measurement_SCENE.txt says so in its
# "protocol" line, which the document prints. --summarize: no renders; redo the analysis of
# the named scenes from their CSV files (and the document).
#
# Environment: PM_BUILD_DIR (where render is; default build/release).
set -eu
here=$(cd "$(dirname "$0")/.." && pwd)
bin="${PM_BUILD_DIR:-$here/build/release}/render"
out="$here/docs/media"
quick=0
reduced=0
summ=0
usage() { awk 'NR > 1 && /^#/ { sub(/^# ?/, ""); print; next } NR > 1 { exit }' "$0"; }
scenes=""
while [ $# -gt 0 ]; do
  case "$1" in
    -h|--help) usage; exit 0 ;;
    --quick) quick=1; shift ;;
    --reduced) reduced=1; shift ;;
    --summarize) summ=1; shift ;;
    cornell_fog|volumetric_caustic) scenes="$scenes $1"; shift ;;
    *) echo "media-time-error: unknown argument '$1' (see --help)" >&2; exit 2 ;;
  esac
done
[ -n "$scenes" ] || { echo "media-time-error: name a scene: cornell_fog or volumetric_caustic (see --help)" >&2; exit 2; }
[ $summ = 1 ] || [ -x "$bin" ] || { echo "media-time-error: $bin not found; run make first (or set PM_BUILD_DIR)" >&2; exit 2; }
# The binary's commit, before anything is written (scripts/commit-stamp.sh).
. "$here/scripts/commit-stamp.sh"
if [ $summ = 0 ]; then commit=$(commit_stamp "$here" "$bin") || exit 2; fi

RES=64
PT_SPPS="16 64 256 1024"
PM_SPPS="1 4 16"
PT_SPPS_VC="16 64 256 1024 4096"
PM_SPPS_VC="1 4"
PM_FLAGS_VC="--pm caustic_photons=20000"
REF_PM_SPP=4
REF_PM_FLAGS="--pm caustic_photons=20000 --pm volume_caustic_photons=300000"
BEAM_RECT="30 34 9 19"
if [ $quick = 1 ]; then
  PT_SPPS="4 16"; PM_SPPS="1"; PT_SPPS_VC="4 16"; PM_SPPS_VC="1"; REF_PM_SPP=1; REF_PM_FLAGS=""
  out="$here/build/media-quick"
fi
[ $quick = 0 ] || [ $reduced = 0 ] || { echo "media-time-error: --quick or --reduced, not both" >&2; exit 2; }
FULL_PT_SPPS=$PT_SPPS FULL_PT_SPPS_VC=$PT_SPPS_VC
[ $reduced = 1 ] && PT_SPPS_VC="16 64 256 1024"
mkdir -p "$out"
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

# Render; print the CPU seconds. Args: scene, output pfm, flags...
cpu_render() {
  scn=$1; pfm=$2; shift 2
  /usr/bin/time -f '%U %S' -o "$work/time" "$bin" "$here/data/scenes/$scn.json" --width $RES --height $RES \
      --threads 1 --quiet --hdr "$pfm" -o "$work/ignored.png" "$@" > "$work/log" 2>&1 ||
    { cat "$work/log" >&2; exit 1; }
  awk '{ printf "%.3f\n", $1 + $2 }' "$work/time"
}
# "rmse mean" of a pfm against a reference, optionally in a rectangle.
cmp2() {
  "$bin" --compare "$@" | awk '$1 == "rmse" { r = $2 } $1 == "mean_a" { m = $2 } END { printf "%s %s\n", r, m }'
}
stamp() { # scene, extra lines on stdin
  {
    echo "commit $commit"
    echo "date $date0"
    echo "machine $(nproc) cores, $(sed -n 's/^model name[^:]*: //p' /proc/cpuinfo | head -1), load $load0"
    echo "resolution $RES"
    cat
  } > "$out/measurement_$1.txt"
}

# The analysis of one scene's runs (a function of its CSV alone, so --summarize can redo it).
# cornell_fog: fit RMSE^2 = c (1/N + 1/N_ref) over the path-traced runs and correct every run
# by the reference's c / N_ref. The beam (fitb = 1): the path tracer's runs are not yet in
# the 1/N regime (its short runs miss the beam entirely: their error is the beam itself), so c
# is taken from its longest run alone (c = N RMSE^2, no bias: path tracing is unbiased and the
# reference's power is checked by the energy test); the extrapolation to photon mapping's
# error assumes RMSE falls as 1/sqrt(N) from there. Then the path tracer's CPU time for
# photon mapping's best error (a least-squares line of CPU time against N).
summarize() { # scene nref input.csv output.csv
  awk -F, -v nref="$2" -v fitb="$([ "$1" = cornell_fog ] && echo 0 || echo 1)" -v summary="$out/summary_$1.txt" '
    NR == 1 { print; next }
    { row[NR] = $1 "," $2 "," $3 "," $4 "," $5 "," $6 ","; m[NR] = $1; n[NR] = $2; t[NR] = $4; e[NR] = $5; last = NR
      if ($1 == "path") { k++; x[k] = 1 / $2 + (nref > 0 ? 1 / nref : 0); y[k] = $5 * $5; nn[k] = $2; tt[k] = $4 } }
    END {
      sx = sy = sxx = sxy = 0
      for (i = 1; i <= k; i++) { sx += x[i]; sy += y[i]; sxx += x[i] * x[i]; sxy += x[i] * y[i] }
      b2 = 0
      if (fitb) { for (i = 1; i <= k; i++) if (nn[i] > nmax) { nmax = nn[i]; c = nn[i] * y[i] } } else c = sxy / sxx
      vref = nref > 0 ? c / nref : 0
      # CPU seconds per sample: least squares through the origin-free line t = a + s N
      sn = st = snn = snt = 0
      for (i = 1; i <= k; i++) { sn += nn[i]; st += tt[i]; snn += nn[i] * nn[i]; snt += nn[i] * tt[i] }
      s = (k * snt - sn * st) / (k * snn - sn * sn); a = (st - s * sn) / k
      best = 0
      for (i = 2; i <= last; i++) {
        v = e[i] * e[i] - vref; corr[i] = v > 0 ? sqrt(v) : 0
        sub(/,$/, sprintf(",%.6g", corr[i]), row[i]); print row[i]
        if (m[i] == "pm" && (best == 0 || corr[i] < corr[best])) best = i
        if (m[i] == "path" && (lp == 0 || n[i] > n[lp])) lp = i }
      # the path tracer at photon mapping best error: N = c / (E^2 - b2)
      need = corr[best] * corr[best] - b2
      npt = need > 0 ? c / need : -1
      tpt = npt > 0 ? a + s * npt : -1
      # measured: the cheapest pm run at least as good as the longest path-traced run
      cheap = 0
      for (i = 2; i <= last; i++) if (m[i] == "pm" && corr[i] <= corr[lp] && (cheap == 0 || t[i] < t[cheap])) cheap = i
      printf "c %.6g\nb2 %.6g\nreference_spp %d\nreference_rmse %.6g\npt_cpu_per_spp %.6g\npt_cpu_fixed %.4g\n", c, b2, nref, sqrt(vref), s, a > summary
      printf "pm_best_spp %d\npm_best_cpu %.4g\npm_best_rmse %.6g\npt_spp_for_equal_error %.0f\npt_cpu_for_equal_error %.4g\nratio %.3f\n", n[best], t[best], corr[best], npt, tpt, (tpt > 0 ? tpt / t[best] : -1) >> summary
      printf "pt_longest_spp %d\npt_longest_cpu %.4g\npt_longest_rmse %.6g\n", n[lp], t[lp], corr[lp] >> summary
      if (cheap) printf "pm_cheapest_as_good_spp %d\npm_cheapest_as_good_cpu %.4g\nmeasured_ratio_at_least %.3f\n", n[cheap], t[cheap], t[lp] / t[cheap] >> summary
      else printf "pm_cheapest_as_good_spp 0\n" >> summary
    }' "$3" > "$4.tmp"
  mv "$4.tmp" "$4"
}

if [ $summ = 1 ]; then
  for scene in $scenes; do
    nref=$(awk '$1 == "reference_spp" { print $2 }' "$out/measurement_$scene.txt")
    summarize "$scene" "${nref:-0}" "$out/time_error_$scene.csv" "$out/time_error_$scene.csv"
  done
  sh "$here/scripts/gen-media-md.sh"
  exit 0
fi
for scene in $scenes; do
  # the date and load average at the start of the scene's runs (the document says "at the start")
  date0=$(date -u '+%Y-%m-%d %H:%M UTC')
  load0=$(cut -d' ' -f1 /proc/loadavg)
  csv="$out/time_error_$scene.csv"
  echo "method,spp,seed,cpu_s,rmse,mean,rmse_corrected" > "$work/te.csv"
  seed=200
  if [ "$scene" = cornell_fog ]; then
    ref="$here/data/reference-media/cornell_fog.pfm"
    info="$here/data/reference-media/cornell_fog.info"
    [ -f "$ref" ] && [ -f "$info" ] || { echo "media-time-error: no reference $ref" >&2; exit 2; }
    [ "$(awk '$1 == "scene_sha256" { print $2 }' "$info")" = "$(sha256sum "$here/data/scenes/cornell_fog.json" | cut -d' ' -f1)" ] ||
      { echo "media-time-error: data/scenes/cornell_fog.json changed since its reference was rendered" >&2; exit 2; }
    nref=$(awk '$1 == "spp" { print $2 }' "$info")
    rect=""
  else
    ref="$work/vc_ref.pfm"
    echo "media-time-error: volumetric_caustic: reference, photon mapping, $REF_PM_SPP spp" >&2
    # shellcheck disable=SC2086
    tref=$(cpu_render volumetric_caustic "$ref" --mode pm --spp $REF_PM_SPP --seed 999 $REF_PM_FLAGS)
    nref=0
    # shellcheck disable=SC2086
    rect="--rect $BEAM_RECT"
  fi
  if [ "$scene" = cornell_fog ]; then pts=$PT_SPPS; pms=$PM_SPPS; else pts=$PT_SPPS_VC; pms=$PM_SPPS_VC; fi
  for spp in $pts; do
    seed=$((seed + 1))
    echo "media-time-error: $scene: path tracing, $spp spp" >&2
    t=$(cpu_render "$scene" "$work/run.pfm" --mode path --spp "$spp" --seed $seed)
    # shellcheck disable=SC2086
    echo "path,$spp,$seed,$t,$(cmp2 "$work/run.pfm" "$ref" $rect | tr ' ' ',')," >> "$work/te.csv"
  done
  for spp in $pms; do
    seed=$((seed + 1))
    echo "media-time-error: $scene: photon mapping, $spp spp" >&2
    # shellcheck disable=SC2086
    t=$(cpu_render "$scene" "$work/run.pfm" --mode pm --spp "$spp" --seed $seed $([ "$scene" = cornell_fog ] || echo "$PM_FLAGS_VC"))
    # shellcheck disable=SC2086
    echo "pm,$spp,$seed,$t,$(cmp2 "$work/run.pfm" "$ref" $rect | tr ' ' ',')," >> "$work/te.csv"
  done
  summarize "$scene" "$nref" "$work/te.csv" "$csv"
  {
    echo "threads 1"
    if [ $quick = 1 ]; then echo "protocol quick (fewer samples, not for publication)"
    elif [ "$scene" = volumetric_caustic ] && [ $reduced = 1 ]; then
      left=""
      for n in $FULL_PT_SPPS_VC; do case " $PT_SPPS_VC " in *" $n "*) ;; *) left="$left $n" ;; esac; done
      echo "protocol reduced: path tracing at $PT_SPPS_VC spp (the full protocol also runs$left spp)"
    else echo "protocol full"; fi
    echo "reference_spp $nref"
    echo "pt_spps $pts"
    echo "pm_spps $pms"
    [ "$scene" = cornell_fog ] || echo "pm_flags $PM_FLAGS_VC"
    if [ "$scene" = cornell_fog ]; then
      echo "reference path tracing, $(awk '$1 == "spp" { print $2 }' "$info") spp, seed $(awk '$1 == "seed" { print $2 }' "$info"), $(awk '$1 == "cpu_seconds" { print $2 }' "$info") CPU-s (data/reference-media/cornell_fog.info)"
    else
      echo "reference photon mapping, $REF_PM_SPP spp, seed 999, $REF_PM_FLAGS, $tref CPU-s"
      echo "beam_rect $BEAM_RECT"
    fi
  } | stamp "$scene"
  echo "media-time-error: wrote $csv" >&2
done
[ $quick = 1 ] && exit 0
sh "$here/scripts/gen-media-md.sh"
