#!/bin/sh
# gen-accuracy-md.sh: write docs/ACCURACY.md from what bench_estimate measured.
#
#   scripts/gen-accuracy-md.sh [--out FILE] [RESULTS_DIR]
#   scripts/gen-accuracy-md.sh --run BUILD_DIR [--quick | --reduced]
#
# RESULTS_DIR (default docs/accuracy) holds accuracy.csv and irradiance_lookup.csv, written by
# `bench_estimate --accuracy-only` and `bench_estimate --lookup-only`, and measurement.txt:
# the commit, date, machine and command of the measurement. Every figure and stamp in the
# document comes from those files, never from the checkout or the clock at generation time,
# so the same files always give the same document (tests/test_estimate.c regenerates it from
# the committed files and compares). --out FILE writes FILE instead of docs/ACCURACY.md (-
# for standard output).
#
# --run BUILD_DIR measures first: it runs BUILD_DIR/bench_estimate into docs/accuracy (with
# --quick into a temporary directory, for a look, and prints the document to standard
# output instead of writing docs/ACCURACY.md), records measurement.txt, then generates.
# --reduced: the published files, with the lookup race's timed runs cut from 5 to 3 (the
# fewest bench_estimate allows; its medians are then of 3 runs) and the accuracy tables as at
# the defaults (they are untimed and take well under a minute); measurement.txt says so in its
# "protocol" line, which the document prints.
# The commit is the binary's (scripts/commit-stamp.sh, sources photonmap/ and bench/): HEAD,
# "plus uncommitted changes" when git status lists any there, refused when a source file is
# newer than BUILD_DIR/bench_estimate (rebuild it); PM_BENCH_COMMIT=TEXT stamps TEXT instead.
set -eu
here=$(cd "$(dirname "$0")/.." && pwd)
doc="$here/docs/ACCURACY.md"
res="$here/docs/accuracy"
run=""
quick=""
reduced=0
while [ $# -gt 0 ]; do
  case "$1" in
    -h|--help) awk 'NR > 1 && /^#/ { sub(/^# ?/, ""); print; next } NR > 1 { exit }' "$0"; exit 0 ;;
    --out) [ $# -ge 2 ] || { echo "gen-accuracy-md: --out needs a file" >&2; exit 2; }
           doc=$2; shift 2 ;;
    --run) [ $# -ge 2 ] || { echo "gen-accuracy-md: --run needs a build directory" >&2; exit 2; }
           run=$2; shift 2 ;;
    --quick) quick=--quick; shift ;;
    --reduced) reduced=1; shift ;;
    -*) echo "gen-accuracy-md: unknown option '$1' (see --help)" >&2; exit 2 ;;
    *) res=$1; shift ;;
  esac
done

if [ -n "$run" ]; then
  [ -x "$run/bench_estimate" ] || { echo "gen-accuracy-md: $run/bench_estimate not built (make BUILD=$run bench-bin)" >&2; exit 2; }
  if [ -n "$quick" ]; then
    res=$(mktemp -d)
    trap 'rm -rf "$res"' EXIT
    doc=-
  fi
  [ -z "$quick" ] || [ "$reduced" = 0 ] || { echo "gen-accuracy-md: --quick or --reduced, not both" >&2; exit 2; }
  # The binary's commit, before anything is written.
  . "$here/scripts/commit-stamp.sh"
  commit=$(CS_SOURCES="photonmap bench" CS_EXCLUDE=bench/results commit_stamp "$here" "$run/bench_estimate") || exit 2
  lruns=""
  [ "$reduced" = 1 ] && lruns="--runs 3"
  load0=$(cut -d' ' -f1-3 /proc/loadavg 2>/dev/null || echo '?')
  mkdir -p "$res"
  "$run/bench_estimate" $quick --accuracy-only --out "$res"
  # shellcheck disable=SC2086
  "$run/bench_estimate" $quick $lruns --lookup-only --out "$res"
  {
    echo "commit $commit"
    echo "date $(date -u '+%Y-%m-%d %H:%M UTC')"
    echo "machine $(uname -m), $(getconf _NPROCESSORS_ONLN 2>/dev/null || echo '?') cores, $(awk -F': ' '/model name/ { print $2; exit }' /proc/cpuinfo 2>/dev/null || echo 'unknown CPU')"
    echo "load $load0 before, $(cut -d' ' -f1-3 /proc/loadavg 2>/dev/null || echo '?') after"
    if [ -n "$quick" ]; then echo "protocol quick (bench_estimate --quick: fewer photons and points; not for publication)"
    elif [ "$reduced" = 1 ]; then echo "protocol reduced: the lookup race's medians are of 3 timed runs (bench_estimate's default is 5); the accuracy tables as at the defaults"
    else echo "protocol full (bench_estimate's defaults)"; fi
    echo "command bench_estimate${quick:+ $quick} --accuracy-only; bench_estimate${quick:+ $quick}${lruns:+ $lruns} --lookup-only"
  } > "$res/measurement.txt"
fi

for f in accuracy.csv irradiance_lookup.csv measurement.txt; do
  [ -f "$res/$f" ] || { echo "gen-accuracy-md: $res/$f missing: run scripts/gen-accuracy-md.sh --run BUILD_DIR" >&2; exit 2; }
done
m() { awk -v k="$1" '$1 == k { sub(/^[^ ]+ /, ""); print; exit }' "$res/measurement.txt"; }
A="$res/accuracy.csv"
L="$res/irradiance_lookup.csv"

# One table: the rows of layout $1, region $2 (and photons $3, or any), one line per estimator
# and variant, one column per k: "mean ± sem (rms)" in percent.
table() {
  awk -F, -v lay="$1" -v reg="$2" -v np="$3" '
    NR == 1 { next }
    $1 == lay && $2 == reg && (np == "" || $3 == np) {
      key = $4 ($5 == "" ? "" : " (" $5 ")")
      if (!(key in seen)) { seen[key] = 1; order[++n] = key }
      if (!($6 in kseen)) { kseen[$6] = 1; ks[++nk] = $6 }
      cell[key, $6] = sprintf("%+.1f%% ± %.1f (%.0f%%)", 100 * $8, 100 * $9, 100 * $10)
      pts = $7
    }
    END {
      printf "| estimator |"; for (j = 1; j <= nk; j++) printf " k = %s |", ks[j]; printf "\n"
      printf "|---|"; for (j = 1; j <= nk; j++) printf "---|"; printf "\n"
      for (i = 1; i <= n; i++) {
        printf "| %s |", order[i]
        for (j = 1; j <= nk; j++) printf " %s |", ((order[i], ks[j]) in cell) ? cell[order[i], ks[j]] : "–"
        printf "\n"
      }
      printf "\n%s points per column.\n", pts
    }' "$A"
}
photons() { awk -F, -v lay="$1" 'NR > 1 && $1 == lay { print $3 }' "$A" | sort -n -u; }

emit() {
# Whether the two lookups agreed, from the mismatches column (not assumed).
lookup_same=$(awk -F, 'NR > 1 { n++; bad += $9 }
  END { if (n && !bad) print "Both give the same answers (checked before timing: `mismatches` is 0 in every row);"
        else printf "In %d answers of the rows below the two disagree (`mismatches`), so their times compare different work;", bad }' "$L")
cat <<HDR
# Accuracy of the radiance estimates

Generated by \`scripts/gen-accuracy-md.sh\` from \`docs/accuracy/\` (written by
\`bench/bench_estimate.c\`); do not edit by hand. Measured at commit $(m commit), $(m date),
on $(m machine)$(lo=$(m load); [ -z "$lo" ] || echo ", load average $lo").$(pr=$(m protocol); [ -z "$pr" ] || printf '\nProtocol: %s.' "$pr")
Measured sources (stamp $(m commit | cut -d' ' -f1)): \`photonmap/\` \`bench/bench_estimate.c\`

Each cell is the mean relative error of the irradiance estimate over the points (its bias), ±
its standard error, and in parentheses the RMS relative error (bias and noise together), all in
percent, against the analytic irradiance. Estimators (photonmap/estimate.h): \`disc\` with no
bias correction (\`none\`) and with the area correction k/(k − ½) (\`area\`, the default),
the cone filter (k_c = 1), the Gaussian filter, differential checking, and the convex hull with
its default boundary weight 0.2 and with weight 0 (the correction for random photons:
interior photons over the hull's area).

What to expect, derived (tests/test_estimate.c checks these): on random photons in a uniform
density, a k-photon estimate whose rim photon has weight w(rim) (halved by a bias correction)
over a filter of disc mean N_w has mean (k − 1 + w(rim)/N_w)/(k − 1) times its area factor,
because the other k − 1 photons are uniform in the disc and π r² λ is a Gamma(k) variable
(E[1/Gamma(k)] = 1/(k − 1)). So the corrected disc reads high by ½/(k − 1) and the
uncorrected one by 1/(k − 1), and the cone with k_c = 1 (rim weight 0) is unbiased. On
stratified photons the disc's rim photon is the only bias and the correction removes it. The
hull misses part of the region its photons came from; with random photons the default boundary
weight does not make up for it (hull vertices are few), and weight 0 does.

## Random photons (uniform, independent: what photon tracing gives)

Unit square lit uniformly, $(photons random) photons. Interior: points in [0.25, 0.75]².

HDR
table random interior ""
cat <<HDR

Edge: points within 3 photon spacings of an edge, where the true irradiance steps from E to 0
(the value at the point is E).

HDR
table random edge ""
cat <<HDR

## Stratified photons (one per cell of a jittered grid)

The same square, $(photons stratified) photons. Interior:

HDR
table stratified interior ""
cat <<HDR

Edge:

HDR
table stratified edge ""
cat <<HDR

## A focused caustic

Random photons drawn from a 2D Gaussian of standard deviation σ = 0.05, total power 1, so
E(d) = exp(−d²/2σ²)/(2πσ²) at distance d from its centre. At the centre a k-photon disc has
radius r = σ √(2k/N): with N photons the caustic's curvature inside the disc grows with k/N
(the "focus"). Centre: d < σ/2 (the curvature makes every disc-like estimate read low there as
r grows); flank: σ < d < 1.5σ.

HDR
for n in $(photons caustic); do
  echo "### N = $n photons: centre"
  echo
  table caustic centre "$n"
  echo
  echo "### N = $n photons: flank"
  echo
  table caustic flank "$n"
  echo
done
cat <<HDR
## Precomputed irradiance: the module's lookup against a private tree

\`pm_irradiance_lookup\` answers "the nearest precomputed photon whose normal is within
cos_min of n" from its own kd-tree over the precomputed photons alone. The race below is
against what a renderer would build by hand: a pm_photon kd-tree (bucket 8) over copies of
the precomputed photons with the irradiance as power, queried with a predicate that decodes
each normal. $lookup_same the ratio is
private time over module time (> 1: the module is faster), medians of alternating runs, one
thread, random photons on three planes, a quarter precomputed, cos_min = 0.7.

| photons | precomputed | max_dist2 | method | ns/lookup | ratio private/module | bytes per precomputed photon | mismatches |
|---|---|---|---|---|---|---|---|
HDR
awk -F, 'NR > 1 { printf "| %s | %s | %s | %s | %.0f | %.3f | %.2f | %s |\n", $1, $2, $4, $5, $6, $7, $8, $9 }' "$L"
echo
echo "Command: \`$(m command)\`."
}

if [ "$doc" = "-" ]; then emit; else emit > "$doc"; fi
