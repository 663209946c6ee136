#!/bin/sh
# gen-gather-ceiling-md.sh: the section "The final gather's ceiling" of docs/HARD_SCENES.md, from
# what scripts/measure-gather-ceiling.sh measured (DIR/runs.csv, DIR/measurement.txt). Called by
# scripts/gen-hard-scenes-md.sh when docs/hard_scenes/ceiling/ exists.
#
#   scripts/gen-gather-ceiling-md.sh DIR [BUDGET_SUMMARY]
#
# BUDGET_SUMMARY: gen-hard-scenes-md.sh's line per scene of its budget table (scene, budget,
# seeds, seeds with a ratio, worst, its seed, median, best, its seed, ratio of the means, ...,
# whether the median is a lower bound in field 13), for the column that sets each scene's
# measured median beside its ceiling. Prints markdown.
#
# Computed per scene, as scripts/gen-hard-scenes-md.sh does for its tables: path tracing's
# variance constant c, the mean over its runs of MSE / (1/spp + 1/N_ref), and the reference's
# noise c / N_ref, taken out of every error below. P: path tracing's corrected squared error
# times its rendering seconds, the median over its seeds (of an even count, the mean of the
# middle two). Per map and gather setting: V, one oracle run's variance, the mean over the pairs
# of seeds of half their squared difference (V_min: the calmest pair's); T, the oracle's mean
# rendering seconds; the rest, the oracle's mean squared error against the reference less V and
# the reference's noise (what its seeds share: the loaded map's own error and the estimator's
# bias). The ceiling: P / (V T), up to P / (V_min T). With the map's own error at the budget B:
# P / (V T + B max(rest, 0)), path tracing's corrected error at B over the oracle's at B, its
# map free but not its error. A scene's figures are its best map and setting's. The camera's
# share: photon mapping at the defaults at the budget, its camera samples' seconds over its
# passes' (maps and camera), the median over its seeds; the ceiling times that share is what the
# camera samples could do in the time the defaults leave them.
# The last is not a bound (photon mapping at the defaults averages the maps of its passes, whose
# radii shrink), only what one free map's error does to the oracle.
# Verdicts: "no" when even the calmest pair's ceiling is under 10x; "no, in the defaults' time"
# when it is under 10x times the camera's share; "at the edge" when the ceiling times the share
# is under 10x but the calmest pair's is not; "yes" otherwise. A scene whose measured median at
# the budget exceeds its highest ceiling is named: there the premise (the camera samples cost
# and vary as in the oracle) does not hold.
set -eu
here=$(cd "$(dirname "$0")/.." && pwd)
case "${1:-}" in -h|--help|"") awk 'NR > 1 && /^#/ { sub(/^# ?/, ""); print; next } NR > 1 { exit }' "$0"; exit 0 ;; esac
dir=$1
bsum=${2:-/dev/null}
for f in runs.csv measurement.txt; do
  [ -f "$dir/$f" ] || { echo "gen-gather-ceiling-md: $dir/$f missing: run scripts/measure-gather-ceiling.sh" >&2; exit 2; }
done
m() { awk -v k="$1" '$1 == k { sub(/^[^ ]+ /, ""); print; exit }' "$dir/measurement.txt"; }
budget=$(m budget)

echo "## The final gather's ceiling"
echo
echo "Measured sources (stamp $(m commit | cut -d' ' -f1)): \`photonmap/\` \`render/\` \`Makefile\`"
echo
echo "Measured by \`scripts/measure-gather-ceiling.sh\` ($(m date), $(m machine), load $(m load), $(m threads) threads):"
echo "how far photon mapping could go if its maps cost nothing. Each scene's maps are traced once with"
echo "$(m photons | sed 's/ / and /') photons (a map of each size; global photons, and as many volume photons in a"
echo "medium), saved, and loaded by every run (\`--load-photons\`), with the gathers' rays forced (gather and"
echo "secondary rays a camera sample, as the table says; the sample pilot chooses from 1/1 to 4/2). A run's"
echo "time is its rendering alone: the camera samples, not the loading, the precomputed irradiance or the"
echo "pilots. The runs of a map share it, so their differences are the camera samples' own variance (half"
echo "the mean squared difference of two seeds' images, over every pair of $(m seeds) seeds; the calmest pair's"
echo "too). Path tracing runs beside them, \`--time $budget\`, the same seeds. Errors are less the reference's own"
echo "noise, as in the tables above. The ceiling is path tracing's squared error times its time (the median"
echo "of its seeds) over the oracle's variance times its time: how many times less time the camera side"
echo "alone needs for path tracing's error (\"up to\": with the calmest pair's variance; in the summary, the"
echo "highest of those over the maps and settings). Photon mapping at the defaults also pays for its maps,"
echo "and their noise and bias add to its error, so its ratio at the budget should lie under its ceiling:"
echo "ports, guided photons, importance emission and more photons act on the maps and cannot lift a ratio"
echo "above it. The last column keeps the"
echo "loaded map's own error (the rest: what the seeds share, less the reference's noise) in the oracle's"
echo "error at the budget: one map that costs nothing but errs as a traced one does. It is not a bound:"
echo "photon mapping at the defaults averages the fresh maps of its passes, with shrinking radii. And"
echo "photon mapping at the defaults runs beside them too (\`--mode pm --time $budget\`, the same seeds): the"
echo "share of its passes' time that its camera samples get (the rest traces its maps) scales the ceiling to"
echo "the time the defaults leave the camera samples."
echo
echo "| scene | path: MSE x s (median) | map's photons | gather/secondary | spp | rendering s (mean) | variance a run (the calmest pair's) | the rest | ceiling (up to) | with the map's error at $budget s |"
echo "|---|---:|---:|---|---:|---:|---:|---:|---:|---:|"
res=$(mktemp)
trap 'rm -f "$res"' EXIT
awk -F, -v rf="$res" -v B="$budget" '
  NR == 1 { next }
  !($1 in seen) { seen[$1] = 1; order[++ns] = $1 }
  { nref[$1] = $10 }
  $2 == "path" { np[$1]++; pm[$1, np[$1]] = $9; pt[$1, np[$1]] = $8; c[$1] += $9 / (1 / $7 + 1 / $10) }
  $2 == "oracle" { k = $1 SUBSEP $3 "," $4; if (!(k in no)) sets[$1] = sets[$1] " " $3 "," $4; no[k]++; mo[k] += $9; to[k] += $8; spp[k] = $7 }
  $2 == "pair" { k = $1 SUBSEP $3 "," $4; npr[k]++; vp[k] += $9 / 2; if (!(k in vmin) || $9 / 2 < vmin[k]) vmin[k] = $9 / 2 }
  $2 == "pm" && $11 > 0 { nq[$1]++; Q[$1, nq[$1]] = $8 / $11 }
  function x(v) { return v > 0 ? sprintf("%.2fx", v) : "n/a" }
  END {
    for (i = 1; i <= ns; i++) {
      s = order[i]; n = np[s]
      if (n == 0) { printf "| %s | no path-traced run | | | | | | | | |\n", s; continue }
      noise = c[s] / n / nref[s]
      for (a = 1; a <= n; a++) P[a] = (pm[s, a] - noise) * pt[s, a]
      for (a = 2; a <= n; a++) for (b = a; b > 1 && P[b] < P[b - 1]; b--) { t = P[b]; P[b] = P[b - 1]; P[b - 1] = t }
      med = n % 2 ? P[(n + 1) / 2] : (P[n / 2] + P[n / 2 + 1]) / 2
      cnt = split(substr(sets[s], 2), st, " "); best = -1; bup = -1; bwm = -1; bset = ""; wset = ""
      for (j = 1; j <= cnt; j++) {
        k = s SUBSEP st[j]; split(st[j], ps, ",")
        if (!npr[k]) { printf "| %s | %.4g | %d | %s | %d | | no pair of seeds | | | |\n", s, med, ps[1], ps[2], spp[k]; continue }
        V = vp[k] / npr[k]; T = to[k] / no[k]; rest = mo[k] / no[k] - V - noise
        cl = V > 0 && T > 0 ? med / (V * T) : -1
        up = vmin[k] > 0 && T > 0 ? med / (vmin[k] * T) : -1
        wm = V > 0 && T > 0 ? med / (V * T + B * (rest > 0 ? rest : 0)) : -1
        printf "| %s | %.4g | %d | %s | %d | %.2f | %.4g (%.4g) | %.4g | %s (%s) | %s |\n", s, med, ps[1], ps[2], spp[k], T, V, vmin[k], rest, x(cl), x(up), x(wm)
        if (cl > best) { best = cl; bset = ps[2] ", " ps[1] " photons" }
        if (up > bup) bup = up
        if (wm > bwm) { bwm = wm; wset = ps[2] ", " ps[1] " photons" }
      }
      q = nq[s]
      for (a = 2; a <= q; a++) for (b = a; b > 1 && Q[s, b] < Q[s, b - 1]; b--) { t = Q[s, b]; Q[s, b] = Q[s, b - 1]; Q[s, b - 1] = t }
      share = q == 0 ? -1 : q % 2 ? Q[s, (q + 1) / 2] : (Q[s, q / 2] + Q[s, q / 2 + 1]) / 2
      if (best > 0) printf "%s|%.6g|%s|%.6g|%.6g|%s|%.6g\n", s, best, bset, bup, bwm, wset, share >> rf
    }
  }' "$dir/runs.csv"
echo
[ -s "$res" ] || { echo "No scene has a ceiling."; exit 0; }
echo "| scene | ceiling: the camera samples alone (up to) | in the defaults' time: the camera's share, the ceiling times it (up to) | with the map's error at $budget s | at $budget s at the defaults: median ratio (worst to best seed) | 10x within the ceiling |"
echo "|---|---:|---:|---:|---:|---|"
awk -F'|' -v bs="$bsum" '
  BEGIN {
    while ((getline l < bs) > 0) {
      split(l, f, " ")
      med[f[1]] = f[7]; worst[f[1]] = f[5]; bst[f[1]] = f[8]; have[f[1]] = f[4] > 0
      lw[f[1]] = f[12] ? "at least " : ""; lb[f[1]] = f[13]; lbb[f[1]] = f[14] ? "at least " : ""
    }
  }
  function add(l, v) { return l (l == "" ? "" : ", ") v }
  {
    s = $1; cl = $2; up = $4; wm = $5; sh = $7 > 0 ? $7 : 1
    m = have[s] ? sprintf("%s%.2fx (%s%.2fx to %s%.2fx)", lb[s] ? "at least " : "", med[s], lw[s], worst[s], lbb[s], bst[s]) : "-"
    d = $7 > 0 ? sprintf("%.0f%%: %.2fx (up to %.2fx)", 100 * sh, cl * sh, up * sh) : "no run at the defaults"
    v = up < 10 ? "no" : up * sh < 10 ? "no, in the defaults'"'"' time" : cl * sh < 10 ? "at the edge" : "yes"
    printf "| %s | %.2fx (%s; up to %.2fx) | %s | %.2fx (%s) | %s | %s |\n", s, cl, $3, up, d, wm, $6, m, v
    if (v == "no") no = add(no, sprintf("%s (%.2fx, up to %.2fx)", s, cl, up))
    else if (v == "yes") yes = add(yes, sprintf("%s (%.2fx)", s, cl))
    else if (v == "at the edge") edge = add(edge, $7 > 0 ? sprintf("%s (%.2fx, up to %.2fx, in the defaults'"'"' time)", s, cl * sh, up * sh) : sprintf("%s (%.2fx, up to %.2fx, with no run at the defaults to scale them)", s, cl, up))
    else nod = add(nod, sprintf("%s (%.2fx, up to %.2fx; the camera samples get %.0f%% of the passes'"'"' time: %.2fx, up to %.2fx)", s, cl, up, 100 * sh, cl * sh, up * sh))
    if (have[s] && med[s] > up) above = add(above, sprintf("%s (%s%.2fx against up to %.2fx)", s, lb[s] ? "at least " : "", med[s], up))
  }
  END {
    printf "\n"
    t = ""
    if (no != "") t = t sprintf("Ceilings under 10x: %s. There even the calmest pair of seeds leaves the camera samples alone, with maps free of cost and error, needing more than a tenth of path tracing'"'"'s time for its error: photon mapping with this final gather cannot meet the 10x target by any change to its maps.", no)
    if (nod != "") t = t (t == "" ? "" : " ") sprintf("Under 10x in the time the defaults leave the camera samples: %s. With maps free of cost and error the camera samples could come near 10x, but the defaults spend the rest of their passes on the maps, and in the time left even the calmest pair of seeds is under 10x.", nod)
    if (edge != "") t = t (t == "" ? "" : " ") sprintf("At the edge of 10x: %s.", edge)
    if (yes != "") t = t (t == "" ? "" : " ") sprintf("Ceilings at 10x or more: %s.", yes)
    if (above != "") t = t sprintf(" Measured above the ceiling (the ceiling'"'"'s premise fails there, or one of the two is noise): %s.", above)
    else if (bs != "/dev/null") t = t " No scene'"'"'s measured median is above its ceiling."
    print t
  }' "$res"
