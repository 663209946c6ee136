#!/bin/sh
# gen-hard-scenes-md.sh: docs/HARD_SCENES.md, from what scripts/make-hard-scenes.sh measured
# (runs.csv, plan_*.txt, measurement.txt; and ceiling/, when there, the last section's, by
# scripts/gen-gather-ceiling-md.sh).
#
#   scripts/gen-hard-scenes-md.sh [DIR]      DIR: default docs/hard_scenes
#
# Prints markdown on standard output. Every figure is read or computed from DIR's files; the
# stamp is measurement.txt's.
#
#   scripts/gen-hard-scenes-md.sh --readme [DIR]
# rewrites README.md's block between "<!-- hard scenes" and "<!-- end of hard scenes -->" with
# the document's "Against the target" table, its "10x met" line, its verdict on pinhole_room's
# region means and the ceilings' sentence: the figures of the document, nothing else (the seeds it names
# are read from DIR's CSV, as the document's are).
#   scripts/gen-hard-scenes-md.sh --readme-block [DIR]
# prints that block instead (tests/test_docs_hard.c compares it with README.md's).
#
# Computed here, per scene (N_ref: the reference's spp):
#   c       path tracing's variance constant: the mean over its runs of MSE / (1/spp + 1/N_ref)
#           (an unbiased estimator against a reference that is one too: MSE = c/spp + c/N_ref);
#   k       path tracing's CPU-s per spp: the mean over its runs of CPU-s / spp;
#   the reference's noise c / N_ref, taken out of every run's MSE (corrected MSE; a run below
#           it is shown as "< ref");
#   for each photon-mapping run: path tracing's corrected MSE at the same CPU time, c k / CPU,
#           and the CPU time path tracing needs for the run's corrected MSE, k c / MSE; their
#           ratio to the run's own (the same figure both ways: above 1, photon mapping is
#           ahead; the target is 10).
#   per sample count, the same from the mean of the seeds' corrected MSE and CPU time, and the
#           worst run's ratio.
# From budget.csv (runs at a time budget, when the file is there; any number of seeds), per
# scene: each run's corrected MSE; each seed's ratio, path tracing's corrected MSE times its
# CPU-s over photon mapping's, the same seed (path tracing's error falls as 1 / time, so this
# is the time-to-equal-error ratio at photon mapping's CPU time; the two ran the same wall
# time, and the MSE ratio alone is shown beside it); the worst seed's ratio (the lowest), the
# median (of an even count, the mean of the middle two) and the best; and the ratio of the
# means, the same from the seeds' mean corrected MSE and mean CPU-s. A seed with a run below the
# reference's noise or without CPU time, or without a run of either mode, has no ratio (two
# runs of one mode and seed are an error). LOWER BOUNDS: a photon-mapping run whose corrected
# MSE is under the reference's noise (a difference of two close figures) counts with its whole
# MSE instead, which includes that noise and so can only overstate its error: its seed's ratio
# is a lower bound ("at least"), and so is every figure it can lower (the worst when it is that
# seed's, the median when a bound lies at or below it, the best and the ratio of the means when
# there is one). A bound of 10x or more meets the target; one under 10x leaves it not judged,
# unless a seed's exact ratio is under 10x too (then it is not met).
# At a sample count the same LOWER BOUNDS hold, run by run (below).
# "10x met" judges the worst: a sample count or the budget meets the target only when every
# seed's ratio is 10 or more (at a sample count, every photon-mapping run's), whatever the mean
# says; when a seed has no ratio and the others meet it, it is "not judged".
set -eu
here=$(cd "$(dirname "$0")/.." && pwd)
case "${1:-}" in -h|--help) awk 'NR > 1 && /^#/ { sub(/^# ?/, ""); print; next } NR > 1 { exit }' "$0"; exit 0 ;; esac
. "$here/scripts/measured-table.sh"
# seeds_in CSV: the seeds of CSV (column 5) as "seed 1", "seeds 1 and 2", "seeds 1 to 6" or
# "seeds 1, 3 and 4".
seeds_in() {
  awk -F, 'NR > 1 && !seen[$5]++ { v[++n] = $5 + 0 }
    END {
      for (i = 2; i <= n; i++) for (j = i; j > 1 && v[j] < v[j - 1]; j--) { t = v[j]; v[j] = v[j - 1]; v[j - 1] = t }
      if (n < 2) { print n ? "seed " v[1] : "no seed"; exit }
      run = 1; for (i = 2; i <= n; i++) if (v[i] != v[i - 1] + 1) run = 0
      if (run && n > 2) { print "seeds " v[1] " to " v[n]; exit }
      l = "seeds " v[1]; for (i = 2; i < n; i++) l = l ", " v[i]; print l " and " v[n]
    }' "$1"
}
if [ "${1:-}" = --readme ] || [ "${1:-}" = --readme-block ]; then
  mode=$1
  shift
  readme_doc "$0" "$@"
  rdir="${1:-$here/docs/hard_scenes}"
  nthreads=$(grep -m1 -o '[0-9]* threads, seed' "$tmpd" | awk '{ print $1 }')
  bseeds=
  [ -f "$rdir/budget.csv" ] && bseeds=$(seeds_in "$rdir/budget.csv")
  awk -v stamp="$stampline" -v nthreads="${nthreads:-?}" -v fseeds="$(seeds_in "$rdir/runs.csv")" -v bseeds="$bseeds" '
    /^## / { sec = substr($0, 4) }
    sec == "Against the target" && /^\|/ { tab[++n] = $0 }
    sec == "Against the target" && /^"10x met" judges/ { verdict = $0 }
    sec ~ /region means/ && /^At [0-9]/ { regions = $0 }
    sec == "The final gather'"'"'s ceiling" && /^Measured sources/ { cst = $0; sub(/^Measured sources \(stamp /, "", cst); sub(/\).*/, "", cst) }
    sec == "The final gather'"'"'s ceiling" && /^(Ceilings |Under 10x |At the edge )/ { ceil = $0 }
    END {
      printf "Measured by `scripts/make-hard-scenes.sh` (docs/HARD_SCENES.md, stamp %s): time to equal\n", stamp
      printf "error against path tracing at the defaults, %s threads. At a sample count: the mean of %s\n", nthreads, fseeds
      printf "(read a factor 1.5 as noise) and the worst run%s.\n\n", bseeds == "" ? "" : "; at the time budget, " bseeds ": the worst seed,\nthe median, the best and the ratio of the means"
      for (i = 1; i <= n; i++) print tab[i]
      if (verdict != "") printf "\n%s\n", verdict
      if (regions != "") printf "\npinhole_room'"'"'s region means against the reference (the 2%% target). %s\n", regions
      if (ceil != "") printf "\nThe final gather'"'"'s ceiling (docs/HARD_SCENES.md, stamp %s): photon mapping'"'"'s camera samples alone, with its maps loaded instead of traced, against path tracing at the budget. %s\n", cst, ceil
    }' "$tmpd" > "$tmpr"
  grep -q '^|---' "$tmpr" || { echo "gen-hard-scenes-md: no table in the document" >&2; exit 2; }
  if [ "$mode" = --readme-block ]; then cat "$tmpr"; exit 0; fi
  grep -q '^<!-- hard scenes' "$here/README.md" || { echo "gen-hard-scenes-md: README.md has no hard scenes block" >&2; exit 2; }
  readme_put "<!-- hard scenes" "<!-- end of hard scenes -->"
  echo "gen-hard-scenes-md: README.md's hard scenes block rewritten" >&2
  exit 0
fi
dir="${1:-$here/docs/hard_scenes}"
for f in runs.csv measurement.txt; do
  [ -f "$dir/$f" ] || { echo "gen-hard-scenes-md: $dir/$f missing: run scripts/make-hard-scenes.sh" >&2; exit 2; }
done
m() { awk -v k="$1" '$1 == k { sub(/^[^ ]+ /, ""); print; exit }' "$dir/measurement.txt"; }
scenes=$(awk -F, 'NR > 1 && !seen[$1]++ { printf "%s ", $1 }' "$dir/runs.csv")
summary=$(mktemp)
bsummary=$(mktemp)
notes=$(mktemp)
trap 'rm -f "$summary" "$bsummary" "$notes"' EXIT
budget_csv="$dir/budget.csv"
[ -f "$budget_csv" ] || budget_csv=
fseeds=$(seeds_in "$dir/runs.csv")
nfseeds=$(awk -F, 'NR > 1 && !seen[$5]++ { n++ } END { print n + 0 }' "$dir/runs.csv")

echo "# Hard scenes: light through small openings"
echo
echo "Generated by \`scripts/gen-hard-scenes-md.sh\` from \`docs/hard_scenes/\`, which"
echo "\`scripts/make-hard-scenes.sh\` measured. The scenes of light through small openings (data/scenes/: pinhole_room, door_ajar,"
echo "sun_window, lamp_shade, sun_window_fog), each against its long path-traced reference"
echo "(data/reference-hard/NAME.pfm; NAME.info says how it was made). Photon mapping runs at its defaults"
echo "(\`render SCENE --mode pm\` with no flag but the size, spp, seed and threads: the plan finds the"
echo "openings and chooses the rest), path tracing with \`--mode path\`, each at the reference's size,"
echo "$(m threads) threads, $fseeds. Error: the mean squared error of RGB over the pixels against the"
echo "reference (\`render --compare\`, rmse squared), less the reference's own noise. Time: CPU seconds of the"
echo "whole process (user + sys: the plan's probe and pilots and the photon passes count)."
if [ -n "$budget_csv" ]; then
  echo "Each scene also runs at a time budget, \`render --time T\` in both modes at the defaults (the"
  echo "passes' samples too), $(seeds_in "$budget_csv"): what a user who gives a budget gets, measured directly."
fi
echo
measured_table "$dir" "$scenes"
echo
echo "Equal time: path tracing is unbiased, so its squared error at a photon-mapping run's CPU time is"
echo "c k / CPU (c its variance constant, fitted from its own runs against the reference, k its CPU-s per"
echo "sample), and the time it needs for that run's error is k c / MSE. The ratio of either to the"
echo "photon-mapping run's is the same figure: the time-to-equal-error ratio, above 1 when photon mapping"
echo "is ahead; the target is 10x. Photon mapping's error at a fixed sample count includes the"
echo "frozen noise of its maps (a seed's maps are the same for every pixel), so its ratio moves with the"
echo "sample count; two counts are measured. With $nfseeds seeds a row's figures are rough: read a factor of"
echo "about 1.5 either way as noise."
echo
for s in $scenes; do
  echo "## $s"
  echo
  if [ -s "$dir/plan_$s.txt" ]; then
    echo "The plan's lines for ports and the gather guide, as printed (seed 1):"
    echo
    echo '```'
    cat "$dir/plan_$s.txt"
    echo '```'
    echo
  fi
  awk -F, -v s="$s" -v sf="$summary" '
    NR > 1 && $1 == s {
      n++; mode[n] = $2; w[n] = $3; spp[n] = $4; seed[n] = $5; cpu[n] = $6; wall[n] = $7; mse[n] = $8; nref = $9
    }
    END {
      c = 0; k = 0; np = 0
      for (i = 1; i <= n; i++) if (mode[i] == "path") { np++; c += mse[i] / (1 / spp[i] + 1 / nref); k += cpu[i] / spp[i] }
      if (np == 0) { print "No path-traced run: nothing to compare with."; exit }
      c /= np; k /= np; noise = c / nref
      printf "%d x %d pixels. Path tracing: c = %.4g, k = %.4g CPU-s per spp (from %d runs); the reference'"'"'s noise c / N_ref = %.3g.\n\n", w[1], w[1], c, k, np, noise
      print "| mode | spp | seed | CPU-s | wall s | MSE | corrected MSE | path MSE at this CPU time | path CPU-s for this MSE | ratio |"
      print "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|"
      for (pass = 1; pass <= 2; pass++)
        for (i = 1; i <= n; i++) {
          if ((pass == 1) != (mode[i] == "pm")) continue
          e = mse[i] - noise
          ce = e > 0 ? sprintf("%.4g", e) : "< ref"
          pe = ""; pt = ""; r = ""
          if (mode[i] == "pm") {
            pe = sprintf("%.4g", c * k / cpu[i])
            u = e < noise ? mse[i] : e; b = u != e; al = b ? "at least " : "" # LOWER BOUNDS
            if (u > 0) { pt = sprintf("%s%.3g", al, k * c / u); r = sprintf("%s%.2fx", al, k * c / u / cpu[i]) }
            if (u > 0 && (!(spp[i] in worst) || k * c / u / cpu[i] < worst[spp[i]])) { worst[spp[i]] = k * c / u / cpu[i]; wb[spp[i]] = b }
            if (u > 0 && !b && k * c / u / cpu[i] < 10) ex[spp[i]]++ # an exact run under 10x: not met, whatever the bounds
            if (u > 0 && (!(spp[i] in best) || k * c / u / cpu[i] > best[spp[i]])) best[spp[i]] = k * c / u / cpu[i]
            if (u > 0) { se[spp[i]] += u; sc[spp[i]] += cpu[i]; sn[spp[i]]++; if (b) mb[spp[i]] = 1 }
            else below[spp[i]]++
            if (!(spp[i] in seen)) { seen[spp[i]] = 1; order[++no] = spp[i] }
          }
          printf "| %s | %d | %d | %.2f | %.2f | %.4g | %s | %s | %s | %s |\n", mode[i], spp[i], seed[i], cpu[i], wall[i], mse[i], ce, pe, pt, r
        }
      printf "\nPhoton mapping, the seeds'"'"' mean corrected MSE and CPU time per sample count:"
      for (j = 1; j <= no; j++) {
        q = order[j]
        if (sn[q] > 0) {
          ratio = k * c / (se[q] / sn[q]) / (sc[q] / sn[q])
          printf " %d spp, %.3g CPU-s, ratio %s%.2fx (the worst run %s%.2fx)%s", q, sc[q] / sn[q], mb[q] ? "at least " : "", ratio, wb[q] ? "at least " : "", worst[q], j < no ? ";" : "."
          printf "%s %d %.6g %.6g %.6g %d %.6g %d %d %d\n", s, q, ratio, sc[q] / sn[q], worst[q], below[q], best[q], wb[q], mb[q], ex[q] >> sf
        } else {
          printf " %d spp: every run below the reference'"'"'s noise%s", q, j < no ? ";" : "."
          printf "%s %d NA 0 NA %d NA 0 0 0\n", s, q, below[q] >> sf
        }
      }
      printf "\n"
    }' "$dir/runs.csv"
  echo
  [ -n "$budget_csv" ] && awk -F, -v s="$s" -v sf="$bsummary" '
    FNR == 1 { file++ }
    file == 1 && FNR > 1 && $1 == s && $2 == "path" { np++; c += $8 / (1 / $4 + 1 / $9) }
    file == 2 && FNR > 1 && $1 == s { n++; mode[n] = $2; T = $4; seed[n] = $5; passes[n] = $6; pspp[n] = $7; cpu[n] = $8; wall[n] = $9; mse[n] = $10; nref = $11 }
    END {
      if (n == 0 || np == 0) exit
      noise = c / np / nref
      printf "At a time budget of %s s (`render --time %s` at the defaults: no flag but the size, seed and threads; the passes'"'"' samples are the default'"'"'s):\n\n", T, T
      print "| mode | seed | passes | spp a pass | CPU-s | wall s | MSE | corrected MSE |"
      print "|---|---:|---:|---:|---:|---:|---:|---:|"
      for (i = 1; i <= n; i++) {
        e = mse[i] - noise
        ce = e > 0 ? sprintf("%.4g", e) : "< ref"
        printf "| %s | %d | %d | %d | %.2f | %.2f | %.4g | %s |\n", mode[i], seed[i], passes[i], pspp[i], cpu[i], wall[i], mse[i], ce
        # LOWER BOUNDS: a photon-mapping run under the noise of the reference counts with its whole MSE
        u = mode[i] == "pm" && e < noise ? mse[i] : e
        if (u > 0) { se[mode[i]] += u; sc[mode[i]] += cpu[i]; sn[mode[i]]++; if (u != e) rmb = 1 } else low[mode[i]]++
        q = seed[i] + 0
        if (!(q in has)) { has[q] = 1; sd[++ns] = q }
        if (got[mode[i], q]) { printf "gen-hard-scenes-md: budget.csv has two %s runs of %s, seed %d\n", mode[i], s, q > "/dev/stderr"; exit 2 }
        E[mode[i], q] = e; M[mode[i], q] = mse[i]; C[mode[i], q] = cpu[i]; got[mode[i], q] = 1
      }
      for (i = 2; i <= ns; i++) for (j = i; j > 1 && sd[j] < sd[j - 1]; j--) { t = sd[j]; sd[j] = sd[j - 1]; sd[j - 1] = t }
      rm = "NA"
      if (sn["pm"] > 0 && sn["path"] > 0 && !low["pm"] && !low["path"] && sc["pm"] > 0 && sc["path"] > 0)
        rm = (se["path"] / sn["path"]) * (sc["path"] / sn["path"]) / ((se["pm"] / sn["pm"]) * (sc["pm"] / sn["pm"]))
      printf "\nEach seed'"'"'s ratio: path tracing'"'"'s corrected MSE over photon mapping'"'"'s, the same seed and wall time, times path tracing'"'"'s CPU-s over photon mapping'"'"'s (the time-to-equal-error ratio at photon mapping'"'"'s CPU time):\n\n"
      print "| seed | MSE, path / pm | CPU-s, path / pm | ratio |"
      print "|---:|---:|---:|---:|"
      for (j = 1; j <= ns; j++) {
        q = sd[j]
        if (!got["pm", q] || !got["path", q]) why = got["pm", q] ? "no path-traced run" : "no photon-mapping run"
        else if (M["pm", q] <= 0 || E["path", q] <= 0) why = "a run below the reference'"'"'s noise"
        else if (C["pm", q] <= 0 || C["path", q] <= 0) why = "a run without CPU time"
        else why = ""
        if (why != "") { printf "| %d | %s | | no ratio |\n", q, why; nm++; miss = miss (miss == "" ? "" : ", ") q; continue }
        b = E["pm", q] < noise
        mr = E["path", q] / (b ? M["pm", q] : E["pm", q]); cr = C["path", q] / C["pm", q]
        al = b ? "at least " : ""
        printf "| %d | %s%.2f | %.2f | %s%.2fx |\n", q, al, mr, cr, al, mr * cr
        rv[++nr] = mr * cr; rs[nr] = q; lb[nr] = b; nb += b
        if (mr * cr < 10) { if (b) lowb++; else below++ }
      }
      for (i = 2; i <= nr; i++)
        for (j = i; j > 1 && rv[j] < rv[j - 1]; j--) {
          t = rv[j]; rv[j] = rv[j - 1]; rv[j - 1] = t; t = rs[j]; rs[j] = rs[j - 1]; rs[j - 1] = t
          t = lb[j]; lb[j] = lb[j - 1]; lb[j - 1] = t
        }
      printf "\n"
      if (nr == 0) {
        printf "No seed has a ratio (seed%s %s): the 10x target is not judged at this budget.\n\n", nm == 1 ? "" : "s", miss
        printf "%s %s %d 0 NA 0 NA NA 0 %s %d 0 0 0 0 0\n", s, T, ns, rm, nm >> sf
        exit
      }
      med = nr % 2 ? rv[(nr + 1) / 2] : (rv[nr / 2] + rv[nr / 2 + 1]) / 2
      # LOWER BOUNDS: an order statistic is a bound when a bound lies at or below it (the best: any)
      lbw = lb[1]; lbm = 0; lbb = nb > 0; lbr = rm != "NA" && rmb
      for (j = 1; j <= nr; j++) if (lb[j] && rv[j] <= med) lbm = 1
      if (nb) printf "%d seed%s ratio%s a lower bound (\"at least\"): photon mapping'"'"'s corrected MSE is under the reference'"'"'s own noise (%.3g), a difference of two close figures, so its whole MSE is used instead, which can only overstate its error.\n\n", nb, nb == 1 ? "'"'"'s" : "s'"'"'", nb == 1 ? " is" : "s are", noise
      printf "Over the %d seed%s with a ratio: the worst, seed %d, %s%.2fx; the median %s%.2fx; the best, seed %d, %s%.2fx", nr, nr == 1 ? "" : "s", rs[1], lbw ? "at least " : "", rv[1], lbm ? "at least " : "", med, rs[nr], lbb ? "at least " : "", rv[nr]
      if (rm != "NA") printf ". The ratio of the means: path tracing'"'"'s mean corrected MSE %.4g in %.3g CPU-s, photon mapping'"'"'s %.4g%s in %.3g CPU-s, %s%.2fx", se["path"] / sn["path"], sc["path"] / sn["path"], se["pm"] / sn["pm"], lbr ? " (with the whole MSE of the seeds under the noise)" : "", sc["pm"] / sn["pm"], lbr ? "at least " : "", rm
      else printf ". No ratio of the means (a run below the reference'"'"'s noise, or no CPU time)"
      if (below) printf ". %d of the %d seeds below 10x: the 10x target is not met at this budget (the worst seed decides%s).\n", below, nr, (rm != "NA" && rm >= 10) ? sprintf(", though the ratio of the means, %.2fx, is above it", rm) : ""
      else if (lowb) printf ". %d of the %d seeds ha%s a lower bound under 10x: the 10x target is not judged at this budget.\n", lowb, nr, lowb == 1 ? "s" : "ve"
      else if (nm) printf ". Every seed with a ratio is at 10x or more, but seed%s %s ha%s none: the 10x target is not judged at this budget.\n", nm == 1 ? "" : "s", miss, nm == 1 ? "s" : "ve"
      else printf ". Every seed at 10x or more%s: the 10x target is met at this budget, on these seeds.\n", nb ? " (by a lower bound where the seed has one)" : ""
      printf "\n"
      printf "%s %s %d %d %.6g %d %.6g %.6g %d %s %d %d %d %d %d\n", s, T, ns, nr, rv[1], rs[1], med, rv[nr], rs[nr], rm == "NA" ? "NA" : sprintf("%.6g", rm), nm, lbw, lbm, lbb, lbr, below >> sf
    }' "$dir/runs.csv" "$budget_csv"
done
echo "## Against the target"
echo
bT=
[ -n "$budget_csv" ] && bT=$(awk -F, 'NR == 2 { print $4 }' "$budget_csv")
echo "| scene | ratio at the lower spp | ratio at the higher spp | at ${bT:-a time budget}${bT:+ s}: worst seed | median | best seed | ratio of the means | 10x met (every seed) |"
echo "|---|---:|---:|---:|---:|---:|---:|---|"
for s in $scenes; do
  awk -v s="$s" -v nf="$notes" '
    FNR == 1 { file++ }
    file == 1 && $1 == s { n++; q[n] = $2; r[n] = $3; w[n] = $5; lo[n] = $6; hi[n] = $7; fw[n] = $8 ? "at least " : ""; fr[n] = $9 ? "at least " : ""; fex[n] = $10 }
    file == 2 && $1 == s { hb = 1; T = $2; nr = $4; bw = $5; bws = $6; bm = $7; bb = $8; bbs = $9; bmeans = $10; bmiss = $11; lw = $12 ? "at least " : ""; lm = $13 ? "at least " : ""; lbst = $14 ? "at least " : ""; lr = $15 ? "at least " : ""; bex = $16 }
    function cell(i) { return i > n ? "-" : r[i] == "NA" ? "n/a" : sprintf("%s%.2fx (%d spp), worst %s%.2fx", fr[i], r[i], q[i], fw[i], w[i]) }
    function add(l, x) { return l (l == "" ? "" : ", ") x }
    function r2(x) { return sprintf("%.2f", x) + 0 }
    function outside(m, lo, hi) { return r2(m) < r2(lo) || r2(m) > r2(hi) }
    END {
      for (i = 1; i <= n; i++)
        if (r[i] != "NA" && outside(r[i], w[i], hi[i]))
          printf "%s at %d spp (%.2fx; its runs %.2fx to %.2fx)\n", s, q[i], r[i], w[i], hi[i] >> nf
      if (hb && nr > 0 && bmeans != "NA" && outside(bmeans, bw, bb))
        printf "%s at %s s (%.2fx; its seeds %.2fx to %.2fx)\n", s, T, bmeans, bw, bb >> nf
      met = ""; unj = ""
      for (i = 1; i <= n; i++) if (r[i] != "NA" && w[i] >= 10) { if (lo[i]) unj = add(unj, "at " q[i] " spp"); else met = add(met, "at " q[i] " spp") }
        else if (r[i] != "NA" && fw[i] != "" && !fex[i]) unj = add(unj, "at " q[i] " spp")
      if (hb && nr > 0 && bw >= 10) { if (bmiss) unj = add(unj, "at " T " s"); else met = add(met, "at " T " s") }
      else if (hb && nr > 0 && lw != "" && !bex) unj = add(unj, "at " T " s")
      v = met == "" ? "" : "yes, " met
      if (unj != "") v = v (v == "" ? "" : "; ") "not judged " unj
      if (hb && nr > 0) b = sprintf("%s%.2fx (seed %d) | %s%.2fx | %s%.2fx (seed %d) | %s", lw, bw, bws, lm, bm, lbst, bb, bbs, bmeans == "NA" ? "n/a" : sprintf("%s%.2fx", lr, bmeans))
      else b = hb ? "n/a | n/a | n/a | n/a" : "- | - | - | -"
      printf "| %s | %s | %s | %s | %s |\n", s, cell(1), cell(2), b, v == "" ? "no" : v
    }' "$summary" "$bsummary"
done
echo
echo "The target is for 2 threads at the defaults within a time budget; this table applies it"
echo "to the small images and the few seeds above."
if [ -s "$notes" ]; then
  echo
  printf "The ratio of the means is not a mean of the seeds' ratios, and can lie outside their range (a product of\n"
  printf "mean error and mean CPU time against each seed's own). Outside it here: "
  awk '{ printf "%s%s", (NR > 1) ? "; " : "", $0 } END { printf ".\n" }' "$notes"
fi
if [ -s "$bsummary" ]; then
  echo
  awk -v seeds="$(seeds_in "$budget_csv")" '
    { T = $2; nsc++ }
    $4 == 0 || ($11 > 0 && $5 >= 10) || ($12 && $5 < 10 && !$16) { unj = unj (unj == "" ? "" : ", ") $1; next }
    $5 >= 10 { nmet++; met = met (met == "" ? "" : ", ") sprintf("%s (worst seed %s%.2fx)", $1, $12 ? "at least " : "", $5); next }
    { not = not (not == "" ? "" : ", ") sprintf("%s (%.2fx, seed %d)", $1, $5, $6) }
    END {
      printf "\"10x met\" judges the worst seed: a sample count or the budget meets the target only where every"
      printf " seed'"'"'s ratio (at a sample count, every run'"'"'s) is 10x or more, whatever the mean. At the %s s budget,", T
      printf " %s, the target is met by %d of the %d scenes%s", seeds, nmet, nsc, met == "" ? "" : ": " met
      if (not != "") printf "; not met by %s", not
      if (unj != "") printf "; not judged (a seed without a ratio) for %s", unj
      printf ".\n"
    }' "$bsummary"
fi
regions_csv="$dir/regions.csv"
if [ -f "$regions_csv" ] && [ "$(wc -l < "$regions_csv")" -gt 1 ]; then
  echo
  echo "## pinhole_room's region means at a time budget"
  echo
  echo "The issue's other target: pinhole_room's region means within 2% of the reference (the regions of"
  echo "tests/test_render_hard.c; \`render --compare --rect\`), photon mapping at the defaults with"
  echo "\`render --time T\`, one run per seed:"
  echo
  echo "| seed | passes | CPU-s | region | reference | photon mapping | relative |"
  echo "|---:|---:|---:|---|---:|---:|---:|"
  awk -F, 'NR > 1 { printf "| %d | %d | %.2f | %s | %.5g | %.5g | %+.2f%% |\n", $3, $4, $5, $6, $7, $8, 100 * $9 }' "$regions_csv"
  echo
  awk -F, '
    NR > 1 {
      T = $2; if (!($3 in s)) { s[$3] = 1; ns++ }
      if (!($6 in lo)) { order[++nr] = $6; lo[$6] = $9; hi[$6] = $9 }
      if ($9 < lo[$6]) lo[$6] = $9; if ($9 > hi[$6]) hi[$6] = $9
      if ($9 > 0.02 || $9 < -0.02) out++
    }
    END {
      printf "At %s s, %d seed%s:", T, ns, ns == 1 ? "" : "s"
      for (i = 1; i <= nr; i++) printf " %s %+.2f..%+.2f%%%s", order[i], 100 * lo[order[i]], 100 * hi[order[i]], i < nr ? ";" : "."
      if (out) printf " %d of the %d region means are outside 2%%: the target is not met at this budget.\n", out, ns * nr
      else printf " All %d region means are within 2%%: the target is met at this budget, on these seeds.\n", ns * nr
    }' "$regions_csv"
fi
if [ -f "$dir/ceiling/runs.csv" ]; then
  echo
  sh "$here/scripts/gen-gather-ceiling-md.sh" "$dir/ceiling" "$bsummary"
fi
