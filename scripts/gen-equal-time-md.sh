#!/bin/sh
# gen-equal-time-md.sh: the "equal time at defaults" section of docs/RESULTS.md, from what
# scripts/make-equal-time.sh measured (runs.csv, calib.csv, plan_*.txt, measurement.txt).
#
#   scripts/gen-equal-time-md.sh [DIR]      DIR: default docs/results/equal_time
#
# Prints markdown on standard output (scripts/gen-results-md.sh includes it). Every figure is
# read or computed from DIR's files; the stamp is measurement.txt's.
#
# Computed here, per scene:
#   c       the path tracer's variance constant, least squares of MSE = c (1/spp + 1/N_ref)
#           over the path-traced runs (N_ref: the reference's spp);
#   corrected RMSE = sqrt(MSE - c / N_ref) (the reference's own noise taken out; a run below
#           that noise is shown as "< ref"). A run whose corrected MSE is under that noise (a
#           small difference of two close figures; "< ref" included) has a lower bound for a
#           ratio, ">= R": its uncorrected MSE is taken as its error, which can only overstate
#           it, so path tracing's time for it can only be understated (the rule of
#           gen-hard-scenes-md.sh, LOWER BOUNDS);
#   path's time model: CPU = a + b spp, least squares over the path-traced runs (calibration
#           runs included);
#   for each pm run: path's spp for its corrected error, c / E^2, the CPU time the model gives
#           for it, and the ratio of that time to the pm run's own CPU time (> 1: pm is faster);
#   slope: least-squares slope of log(corrected RMSE) against log(CPU time), per mode (an
#           unbiased estimator at fixed cost per sample falls as time^-0.5).
#
#   scripts/gen-equal-time-md.sh --readme [DIR]
# rewrites README.md's block between "<!-- make run comparison" and "<!-- end of make run
# comparison -->" with the photon-mapping rows of cornell_spheres (the scene make run shows):
# the figures of the section's table, nothing else.
#
#   scripts/gen-equal-time-md.sh --survey [DIR]     DIR: default docs/results/survey
# the survey's section: the targets' table alone (a measurement.txt with follow_up_of RES: the
# section of the survey's misses measured again larger, scripts/make-survey.sh).
#
#   scripts/gen-equal-time-md.sh --survey-readme [DIR [DIR2]]
# rewrites README.md's block between "<!-- survey summary" and "<!-- end of survey summary -->"
# with the survey's verdicts in words, counted from the targets' tables of DIR (default
# docs/results/survey) and of its follow-up DIR2 (default docs/results/survey96): which scenes
# meet their target, which only by lower bounds, which cannot be compared or measured, which
# miss and by how much. Every figure and name is the tables'; nothing else is said.
# --survey-readme-block prints the block instead (tests/test_docs.c compares README.md's with it).
#
#   scripts/gen-equal-time-md.sh --misses [DIR]
# the scenes of the survey in DIR whose verdict is "no" or "not measured", one per line (what
# make-survey.sh measures again larger).
set -eu
here=$(cd "$(dirname "$0")/.." && pwd)
case "${1:-}" in -h|--help) awk 'NR > 1 && /^#/ { sub(/^# ?/, ""); print; next } NR > 1 { exit }' "$0"; exit 0 ;; esac
. "$here/scripts/measured-table.sh"
if [ "${1:-}" = --readme ]; then
  shift
  readme_doc "$0" "$@"
  awk -v stamp="$stampline" '
    /^### / { in_s = ($2 == "cornell_spheres") }
    /^Path tracing here/ { next }
    in_s && /^\| pm \|/ {
      split($0, f, "|"); for (i in f) gsub(/^ +| +$/, "", f[i])
      n++; line[n] = sprintf("- %s CPU-s (budget %s, %s spp): corrected RMSE %s (the reference'"'"'s noise %s of its MSE); path tracing needs %s CPU-s for that error (ratio %s).", f[5], f[3], f[4], f[9], f[8], f[10] == "" ? "-" : f[10], f[11] == "" ? "-" : f[11])
    }
    END {
      printf "Measured on cornell_spheres at 96x96, 2 threads, photon mapping at its defaults against path tracing\n"
      printf "(docs/RESULTS.md, \"Equal time at the defaults\", stamp %s):\n\n", stamp
      for (i = 1; i <= n; i++) print line[i]
    }' "$tmpd" > "$tmpr"
  readme_put "<!-- make run comparison" "<!-- end of make run comparison -->"
  echo "gen-equal-time-md: README.md's make run comparison rewritten" >&2
  exit 0
fi
if [ "${1:-}" = --survey-readme ] || [ "${1:-}" = --survey-readme-block ]; then
  mode=$1
  shift
  d1="${1:-$here/docs/results/survey}" d2="${2:-$here/docs/results/survey96}"
  readme_doc "$0" --survey "$d1"
  words() { # the targets' table on stdin, in words; $1: the size, $2: the follow-up's (or empty)
    awk -F'|' -v size="$1" -v again="$2" -v stamp="$3" '
      BEGIN { sq = "\047" }
      function join(a, n,    i, t) { t = ""; for (i = 1; i <= n; i++) t = t (i == 1 ? "" : (i == n ? " and " : ", ")) a[i]; return t }
      function lb(v) { return match(v, />= [0-9.]+x/) ? substr(v, RSTART, RLENGTH) : "?" }
      function range(lo, hi) { return (hi == "-" || hi == lo) ? lo : lo "-" hi }
      /^\| [a-z0-9_]+ \|/ && $3 ~ /x/ {
        for (i = 2; i <= 7; i++) gsub(/^ +| +$/, "", $i)
        n++; sc = $2; tg = $3; lo = $4; hi = $5; v = $7
        if (v == "yes") { ny++; yes[ny] = sc " " range(lo, hi) }
        else if (v ~ /^yes, every run by a lower bound/) { nb++; bnd[nb] = sc " " lb(v) }
        else if (v ~ /^yes, /) { ns++; some[ns] = sc " " range(lo, hi) " and " lb(v) " by a lower bound" }
        else if (v ~ /^not comparable/) { nc++; nocmp[nc] = sc }
        else if (v ~ /^not measured/) { nm++; nmeas[nm] = sc " (" (lo ~ /^[0-9]/ ? range(lo, hi) " where its runs are above the reference" sq "s noise, but its lower bound, " : "its lower bound, ") lb(v) ", is under its " tg " target)" }
        else { nn++; miss[nn] = sc " (" range(lo, hi) ", target " tg ")" }
      }
      END {
        if (again == "") {
          printf "In the %sx%s survey (docs/RESULTS.md, \"Every shipped scene, small\", stamp %s), %d of the %d scenes meet their ", size, size, stamp, ny + nb + ns, n
          printf "target: %d at every run (%s)", ny, join(yes, ny)
          if (nb) printf "; %d only by lower bounds, their photon-mapping runs%s corrected error being under the reference%ss own noise (%s)", nb, sq, sq, join(bnd, nb)
          if (ns) printf "; %d with some runs by a lower bound (%s)", ns, join(some, ns)
          printf ".\n"
        } else {
          printf "Measured again at %sx%s (docs/RESULTS.md, \"The small survey%ss misses, at %sx%s\", stamp %s):", size, size, sq, size, size, stamp
          if (ny + nb + ns) printf " %s meet%s the target (%s%s%s%s%s).", (ny + nb + ns == 1 ? "one" : ny + nb + ns), (ny + nb + ns == 1 ? "s" : ""), join(yes, ny), (ny && nb ? "; " : ""), (nb ? "by lower bounds: " join(bnd, nb) : ""), ((ny || nb) && ns ? "; " : ""), join(some, ns)
          printf "\n"
        }
        if (nc) printf "%d cannot be compared, as path tracing cannot render their light (%s).\n", nc, join(nocmp, nc)
        if (nm) printf "%d %s not measured: %s.\n", nm, nm == 1 ? "is" : "are", join(nmeas, nm)
        if (nn) printf "%d miss%s it: %s.\n", nn, nn == 1 ? "es" : "", join(miss, nn)
      }'
  }
  # readme_doc left DIR's table in $tmpd and its stamp in $stampline; DIR2's is made once here
  r1=$(measured_key "$d1" resolution)
  {
    words "$r1" "" "$stampline" < "$tmpd" | fold -s -w 100 | sed 's/ *$//'
    if [ -f "$d2/measurement.txt" ]; then
      echo
      sh "$0" --survey "$d2" | words "$(measured_key "$d2" resolution)" "$r1" "$(measured_key "$d2" commit | cut -d' ' -f1)" |
        fold -s -w 100 | sed 's/ *$//'
    fi
  } > "$tmpr"
  if [ "$mode" = --survey-readme-block ]; then cat "$tmpr"; exit 0; fi
  readme_put "<!-- survey summary" "<!-- end of survey summary -->"
  echo "gen-equal-time-md: README.md's survey summary rewritten" >&2
  exit 0
fi
if [ "${1:-}" = --misses ]; then
  # the scenes whose verdict in the survey's targets' table is "no" or "not measured", one per line
  shift
  sh "$0" --survey "$@" | awk -F'|' '/^\| [a-z0-9_]+ \|/ && ($7 ~ /^ no *$/ || $7 ~ /^ not measured/) { gsub(/ /, "", $2); print $2 }'
  exit 0
fi
survey=0
if [ "${1:-}" = --survey ]; then survey=1; shift; fi
dir="${1:-$here/docs/results/$([ $survey = 1 ] && echo survey || echo equal_time)}"
for f in runs.csv calib.csv measurement.txt; do
  [ -f "$dir/$f" ] || { echo "gen-equal-time-md: $dir/$f missing: run scripts/make-equal-time.sh" >&2; exit 2; }
done
m() { awk -v k="$1" '$1 == k { sub(/^[^ ]+ /, ""); print; exit }' "$dir/measurement.txt"; }
scenes=$(awk -F, 'NR > 1 && !seen[$1]++ { printf "%s ", $1 }' "$dir/runs.csv")
ratios=$(mktemp)
cons=$(mktemp)
trap 'rm -f "$ratios" "$cons"' EXIT

if [ $survey = 1 ] && [ -n "$(m follow_up_of)" ]; then
  echo "## The small survey's misses, at $(m resolution)x$(m resolution)"
  echo
  echo "Generated by \`scripts/gen-equal-time-md.sh --survey\` from \`docs/results/survey$(m resolution)/\`, which"
  echo "\`scripts/make-survey.sh\` measured after the section above: the scenes that did not meet their target"
  echo "there, at $(m follow_up_of)x$(m follow_up_of), or that it could not measure (no run above its reference's noise), again with the protocol of \"Equal time at the defaults\" ($(m resolution)x$(m resolution) pixels, budgets"
  echo "of $(m budgets) CPU-seconds), each against its own $(m resolution)x$(m resolution) path-traced reference. $(awk -v a="$(m resolution)" -v b="$(m follow_up_of)" 'BEGIN { printf "%g", a * a / (b * b) }') times the pixels"
  echo "weigh photon mapping's fixed costs less; the targets are still for larger images and longer budgets."
elif [ $survey = 1 ]; then
  echo "## Every shipped scene, small"
  echo
  echo "Generated by \`scripts/gen-equal-time-md.sh --survey\` from \`docs/results/survey/\`, which"
  echo "\`scripts/make-survey.sh\` measured with the protocol of the section above, \"Equal time at the defaults\","
  echo "on every scene in data/scenes/, each against its own $(m resolution)x$(m resolution) path-traced reference. At this size and"
  echo "these budgets photon mapping's fixed costs (the plan's pilots, the photon passes, precomputed"
  echo "irradiance) weigh far more than in a render at a scene's own size: a ratio below 1 says photon"
  echo "mapping is not ahead at this size, not that it loses at the scene's own."
else
echo "## Equal time at the defaults"
echo
echo "Generated by \`scripts/gen-equal-time-md.sh\` from \`docs/results/equal_time/\`, which"
echo "\`scripts/make-equal-time.sh\` measured. Photon mapping runs at its defaults (\`render SCENE --mode pm\`"
echo "with no flag but the size, spp, seed and threads: the plan chooses the rest and prints it),"
echo "path tracing with \`--mode path\`. A scaled-down protocol (the full one is 10, 30, 100 and 300 s at"
echo "the scenes' own size): $(m resolution)x$(m resolution) pixels, $(m threads) threads, budgets of"
echo "$(m budgets) CPU-seconds (user + sys of the whole process: the photon pass and the plan's pilots"
echo "count). The renderer's --time budget is wall-clock time, which a shared machine's load distorts, so each"
echo "budget is met in CPU time by choosing spp from timing runs (path two, pm three: its photons grow with spp$(m refine | awk '$1 != "" { printf "; a run that spends under %d%% of its budget runs once more with more spp (those the timing slope adds for the rest of the budget, at most spp x budget / CPU time)", $1 * 100 }')$(m rerun_over | awk '$1 != "" { printf ", one over %d%% runs once more at spp x budget / CPU time", $1 * 100 }')$(m refine | awk '$1 != "" { printf ", and that run is kept" }')); the runs are compared by the CPU"
echo "time they really took."
fi
echo
measured_table "$dir" "$scenes"
echo
# the survey prints only the targets' table (the scenes' sections still write the ratios)
{
echo "The reference is a path tracer too: its noise (c / N_ref) is taken out of every run's mean"
echo "squared error, with c fitted from the path-traced runs (corrected RMSE). Path tracing's CPU time for"
echo "a photon-mapping run's error comes from the fits (path's error and time against spp); the ratio is"
echo "that time over the photon-mapping run's own: above 1, photon mapping reached the error sooner."
echo "Where the reference's noise is most of a run's mean squared error (the share column), the corrected"
echo "RMSE is a small difference of two larger figures, and c comes from a few path-traced runs: read"
echo "those ratios as rough. A run whose corrected mean squared error is under the reference's noise (a"
echo "share above 50%; \"< ref\": its whole mean squared error is) has its ratio written \">= R\": it takes"
echo "its uncorrected RMSE as its error, which can only overstate the error, so R is a lower bound (under"
echo "the same fits of path tracing's error and time)."
if [ -n "$(m before)" ]; then
  echo "Rows \"pm, before\" are the same runs with the renderer of $(m before) (its defaults then)."
fi
if [ -n "$(m prog_spp)" ] && grep -q ',pm_passes,' "$dir/runs.csv"; then
  echo "Rows \"pm, progressive\" render \`--passes N --pass-spp $(m prog_spp)\` (N in the budget column):"
  echo "every pass traces fresh photon maps and the estimates' radius caps shrink (Knaus and Zwicker 2011,"
  echo "alpha = the setting ppm_alpha). Their theoretical rate: variance O(N^-alpha) and bias O(N^(alpha-1))"
  echo "give a corrected RMSE falling as N^-(1-alpha) at best, slope -1/3 at alpha = 2/3, once the shrinking"
  echo "caps bind (the pass lines below give pass 0's radii)."
fi
echo
for s in $scenes; do
  echo "### $s"
  echo
  if [ -f "$dir/plan_$s.txt" ]; then
    echo "The plan, as the renderer printed it:"
    echo
    echo '```'
    cat "$dir/plan_$s.txt"
    echo '```'
    echo
  fi
  if [ -f "$dir/passes_$s.txt" ]; then
    echo "Progressive runs, pass 0 as printed$(m prog_seeds | awk 'NF > 1 { printf " (seed %s, the last chain)", $NF }'): \`$(cat "$dir/passes_$s.txt")\`"
    echo
  fi
  awk -F, -v s="$s" -v calib="$dir/calib.csv" -v rf="$ratios" -v cf="$cons" -v before="$(m before)" '
    function ln(x) { return log(x) }
    BEGIN {
      while ((getline line < calib) > 0) {
        split(line, f, ",")
        if (f[1] == s && f[2] == "path") { ct[++nc] = f[4]; cs[nc] = f[3] }
      }
    }
    NR > 1 && $1 == s {
      n++; mode[n] = $2; bud[n] = $3; spp[n] = $4; cpu[n] = $5; wall[n] = $6; rmse[n] = $7; nref = $8
      sd[n] = NF >= 9 ? $9 : ""; if ($2 == "pm_passes" && !(sd[n] in pseeds)) { pseeds[sd[n]] = 1; npseeds++ }
      if ($2 == "path") { ct[++nc] = $5; cs[nc] = $4 }
    }
    END {
      # c: least squares of mse = c x, x = 1/spp + 1/nref, over the path runs
      sxy = 0; sxx = 0
      for (i = 1; i <= n; i++) if (mode[i] == "path") { x = 1 / spp[i] + 1 / nref; sxy += x * rmse[i] ^ 2; sxx += x * x }
      c = sxx > 0 ? sxy / sxx : 0
      # path time: cpu = a + b spp, least squares
      sx = sy = sxx2 = sxy2 = 0
      for (i = 1; i <= nc; i++) { sx += cs[i]; sy += ct[i]; sxx2 += cs[i] * cs[i]; sxy2 += cs[i] * ct[i] }
      b = (nc * sxy2 - sx * sy) / (nc * sxx2 - sx * sx); a = (sy - b * sx) / nc
      # a path tracer has next to no fixed cost: a negative intercept (the load made a long run
      # slower per sample) would give negative times; then the line goes through 0
      if (a < 0) { a = 0; b = sxy2 / sxx2 }
      printf "Path tracing here: variance constant c = %.4g (from the path-traced runs), CPU-s = %.3g + %.4g x spp (from %d runs, timing runs included).\n\n", c, a, b, nc
      print "| mode | budget (CPU-s) | spp | CPU-s | wall s | RMSE | reference noise, share of the MSE | corrected RMSE | path CPU-s for that error | ratio |"
      print "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|"
      best = ""; worst = 1e300
      split("pm pm_before path pm_passes", modes, " ")
      label["pm"] = "pm"; label["pm_before"] = "pm, before (" before ")"; label["path"] = "path"
      label["pm_passes"] = "pm, progressive"
      for (m = 1; m <= 4; m++) {
        want = modes[m]
        for (i = 1; i <= n; i++) if (mode[i] == want) {
          e2 = rmse[i] ^ 2 - c / nref
          if (e2 > 0) { cr = sprintf("%.4g", sqrt(e2)) } else { cr = "< ref" }
          pt = ""; r = ""; exact = e2 > c / nref
          if (want != "path" && !exact && rmse[i] > 0) {
            # a lower bound: the corrected MSE is under the noise of the reference, and the
            # uncorrected MSE overstates the error (see the header)
            t = a + b * (c / rmse[i] ^ 2); pt = sprintf(">= %.3g", t); r = sprintf(">= %.2fx", t / cpu[i])
            if (want == "pm") printf "%s LB %.6g\n", s, t / cpu[i] >> rf
          } else if (want == "pm" && !exact) printf "%s NA\n", s >> rf
          if (want != "path" && exact) {
            t = a + b * (c / e2); pt = sprintf("%.3g", t); r = sprintf("%.2fx", t / cpu[i])
            if (want == "pm") {
              if (t / cpu[i] < worst) worst = t / cpu[i]
              printf "%s %.6g\n", s, t / cpu[i] >> rf
            }
          }
          if (want == "pm_passes") printf "%s %s %.6g %s %s\n", s, bud[i], cpu[i], (e2 > 0 ? sprintf("%.6g", sqrt(e2)) : "NA"), (sd[i] == "" ? "-" : sd[i]) >> cf
          bd = want == "pm_passes" ? bud[i] " passes" (npseeds > 1 ? ", seed " sd[i] : "") : bud[i]
          printf "| %s | %s | %d | %.2f | %.2f | %.4g | %.0f%% | %s | %s | %s |\n", label[want], bd, spp[i], cpu[i], wall[i], rmse[i], 100 * (c / nref) / rmse[i] ^ 2, cr, pt, r
        }
      }
      # slopes of log corrected rmse against log cpu
      for (m = 1; m <= 4; m++) {
        want = modes[m]; k = 0; mx = my = 0
        for (i = 1; i <= n; i++) if (mode[i] == want && rmse[i] ^ 2 - c / nref > 0) {
          k++; X[k] = ln(cpu[i]); Y[k] = 0.5 * ln(rmse[i] ^ 2 - c / nref); mx += X[k]; my += Y[k]
        }
        if (k >= 2) {
          mx /= k; my /= k; num = den = 0
          for (j = 1; j <= k; j++) { num += (X[j] - mx) * (Y[j] - my); den += (X[j] - mx) ^ 2 }
          sl[m] = sprintf("%.2f (%d runs)", num / den, k)
        } else sl[m] = "n/a"
      }
      printf "\nError against CPU time, log-log slope of the corrected RMSE: photon mapping at fixed maps %s", sl[1]
      if (sl[2] != "n/a") printf ", before %s", sl[2]
      printf ", path tracing %s", sl[3]
      if (sl[4] != "n/a") printf ", progressive photon mapping %s", sl[4]
      printf ".\n"
      if (worst < 1e300) printf "\nLowest ratio of the photon-mapping runs: %.2fx.\n", worst
    }' "$dir/runs.csv"
  echo
done
} | if [ $survey = 1 ]; then cat > /dev/null; else cat; fi
echo "### Against the targets"
echo
echo "| scene | target | lowest ratio measured | highest ratio measured | runs below the reference's noise | met at every budget measured |"
echo "|---|---:|---:|---:|---:|---|"
for s in $scenes; do
  case $s in cornell_spheres) tgt=5 ;; water_caustic|volumetric_caustic) tgt=20 ;; *) tgt=1 ;; esac
  if [ "$(m "ref_misses_$s")" = yes ]; then
    printf "| %s | %sx | - | - | - | not comparable: the scene sends light from point or directional lights through specular surfaces onto diffuse ones, which path tracing cannot render (render warns), so its path-traced reference misses that light |\n" "$s" "$tgt"
    continue
  fi
  awk -v s="$s" -v t="$tgt" '
    $1 == s && $2 == "NA" { na++; next }
    $1 == s && $2 == "LB" { na++; nl++; if (nl == 1 || $3 < lb) lb = $3; if ($3 < t) lbmiss++; next }
    $1 == s { n++; if (n == 1 || $2 < lo) lo = $2; if (n == 1 || $2 > hi) hi = $2; if ($2 < t) miss++ }
    END { lbs = nl ? sprintf(", %d by a lower bound (>= %.2fx)", nl, lb) : ""
          if (miss) printf "| %s | %sx | %.2fx | %.2fx | %d | no |\n", s, t, lo, hi, na
          else if (n && !lbmiss && na == nl) printf "| %s | %sx | %.2fx | %.2fx | %d | yes%s |\n", s, t, lo, hi, na, lbs
          else if (!n && nl && !lbmiss && na == nl) printf "| %s | %sx | >= %.2fx | - | %d | yes, every run by a lower bound (>= %.2fx): its corrected error is below the reference'"'"'s noise |\n", s, t, lb, na, lb
          else printf "| %s | %sx | %s | %s | %d | not measured: %d photon-mapping run%s a corrected error below the reference'"'"'s own noise%s (a longer reference is needed) |\n", s, t, n ? sprintf("%.2fx", lo) : "-", n ? sprintf("%.2fx", hi) : "-", na, na, na == 1 ? " had" : "s had", lbmiss ? sprintf(", and its lower bound (>= %.2fx) is under the target", lb) : "" }' "$ratios"
done
echo
echo "The targets are for 2 threads at the scenes' own size and budgets of 10 s and more; this"
echo "table applies them to the scaled-down protocol above."
if [ -s "$cons" ]; then
  echo
  echo "### Consistency (progressive photon mapping)"
  echo
  echo "The target: the corrected RMSE keeps falling from 10 s to 1000 s by at least 1.8x for each 10x of"
  echo "time, with no floor, and region means within 1% of the reference at the longest time. Here, scaled"
  echo "down: the progressive runs above, each step from one run to the next longer one as its fall per 10x of"
  echo "CPU time, (RMSE before / RMSE after)^(1 / log10(CPU after / CPU before)); the regions are the"
  echo 'image and a 3 x 3 grid of blocks of the longest run (`regions_prog.csv`). Each seed runs the whole chain'
  echo "(the runs of one seed share their first passes, as a progressive render does); where there are several"
  echo "seeds, the last row of a scene gives the median of each step over the seeds, the lowest of those"
  echo "medians (and the median of each seed's lowest step), the blocks of every seed together and the worst."
  echo
  echo "| scene | seed | passes | CPU-s | falls per 10x of time, step by step | over the whole range | lowest step (a floor shows here) | image mean | blocks within 1% | largest block difference |"
  echo "|---|---|---|---|---|---:|---:|---:|---:|---:|"
  for s in $scenes; do
    awk -v s="$s" -v reg="$dir/regions_prog.csv" '
      function med(a, k,    i, j, t, b) {   # median of a[1..k]
        for (i = 1; i <= k; i++) b[i] = a[i]
        for (i = 2; i <= k; i++) for (j = i; j > 1 && b[j - 1] > b[j]; j--) { t = b[j]; b[j] = b[j - 1]; b[j - 1] = t }
        return k % 2 ? b[(k + 1) / 2] : (b[k / 2] + b[k / 2 + 1]) / 2
      }
      $1 == s && $4 != "NA" {
        if (!($5 in ns)) { seeds[++nseeds] = $5 }
        k = ++ns[$5]; p[$5, k] = $2; t[$5, k] = $3; e[$5, k] = $4
      }
      END {
        while ((getline line < reg) > 0) {
          split(line, f, ","); if (f[1] != s) continue
          rs = (7 in f) && f[7] != "" ? f[7] : "-"
          d = f[6] + 0; a = d < 0 ? -d : d
          if (f[3] == "image") img[rs] = d
          else { nb[rs]++; if (a <= 0.01) ok[rs]++; if (!(rs in worst) || a > worst[rs]) { worst[rs] = a; wd[rs] = d; wn[rs] = f[3] } }
        }
        rows = 0
        for (q = 1; q <= nseeds; q++) {
          sd = seeds[q]; n = ns[sd]
          if (n < 2) continue
          rows++; steps = ""; low = 1e300
          for (i = 2; i <= n; i++) {
            fall = (e[sd, i - 1] / e[sd, i]) ^ (1 / (log(t[sd, i] / t[sd, i - 1]) / log(10)))
            st[i, rows] = fall
            steps = steps (i > 2 ? ", " : "") sprintf("%.2fx", fall); if (fall < low) low = fall
          }
          all = (e[sd, 1] / e[sd, n]) ^ (1 / (log(t[sd, n] / t[sd, 1]) / log(10)))
          lows[rows] = low; alls[rows] = all; nn = n
          tb += nb[sd]; tok += ok[sd]
          if (sd in worst && (wsd == "" || worst[sd] > wmax)) { wmax = worst[sd]; wsd = sd }
          printf "| %s | %s | %s to %s | %.3g to %.3g | %s | %.2fx | %.2fx | %s | %d of %d | %s |\n", s, sd, p[sd, 1], p[sd, n], t[sd, 1], t[sd, n], steps, all, low,
            (sd in img) ? sprintf("%+.2f%%", 100 * img[sd]) : "-", ok[sd], nb[sd], (sd in worst) ? sprintf("%+.2f%% (%s)", 100 * wd[sd], wn[sd]) : "-"
        }
        if (rows < 2) exit
        steps = ""; low = 1e300
        for (i = 2; i <= nn; i++) {
          for (r = 1; r <= rows; r++) col[r] = st[i, r]
          m = med(col, rows); steps = steps (i > 2 ? ", " : "") sprintf("%.2fx", m); if (m < low) low = m
        }
        printf "| %s | median of %d | | | %s | %.2fx | %.2fx (each seed'"'"'s lowest: %.2fx) | - | %d of %d | %s |\n", s, rows, steps, med(alls, rows), low, med(lows, rows), tok, tb,
          wsd == "" ? "-" : sprintf("worst %+.2f%% (%s) (seed %s)", 100 * wd[wsd], wn[wsd], wsd)
      }' "$cons"
  done
fi
