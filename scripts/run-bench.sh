#!/bin/sh
# run-bench.sh: run the benchmarks, then make the plots and the benchmarks document from the CSVs.
#
#   sh scripts/run-bench.sh BUILD full  [OUTDIR]   (make bench: bench/results, docs/BENCHMARKS.md)
#   sh scripts/run-bench.sh BUILD quick [OUTDIR]   (make bench-quick: everything into OUTDIR)
#
# The full run writes bench/results/*.csv (committed), the PNG plots to docs/bench/ and
# docs/BENCHMARKS.md; it also profiles the headline configurations with callgrind (and its
# cache simulator) when valgrind is installed (scripts/install-deps.sh --bench). The quick
# run writes all of that into OUTDIR (default BUILD/bench-quick), so the scripts are
# exercised by the test suite too.
# A real photon map dumped by the renderer (data/scenes/cornell_spheres.json) is the third
# workload of the search bench; PM_BENCH_MAP=file.pmap (pm_map_save format) replaces it.
# Progress goes to stderr; every number in the document comes from the CSVs.
# PM_BENCH_COMMIT=TEXT stamps the run with TEXT instead of this checkout's HEAD (and its
# uncommitted changes): for binaries BUILD built from a clean export of a commit while other
# people's uncommitted work sits in the checkout, e.g. PM_BENCH_COMMIT="cd87fe2 (clean export)".
set -eu
# Idle OpenMP threads must not spin on a core that a one-thread measurement needs.
export OMP_WAIT_POLICY=${OMP_WAIT_POLICY:-PASSIVE}

case "${1:-}" in
  -h|--help) awk 'NR > 1 && /^#/ { sub(/^# ?/, ""); print; next } NR > 1 { exit }' "$0"; exit 0 ;;
esac
BUILD=${1:?usage: run-bench.sh BUILD full|quick [OUTDIR]}
MODE=${2:-quick}
case "$MODE" in
  full)  OUT=${3:-bench/results}; DOCS=docs; IMG=docs/bench; IMGREL=bench; QFLAG= ;;
  quick) OUT=${3:-$BUILD/bench-quick}; DOCS=$OUT; IMG=$OUT/img; IMGREL=img; QFLAG=--quick ;;
  *) echo "run-bench.sh: mode must be full or quick" >&2; exit 2 ;;
esac
# The commit, taken before anything is written (bench/results is the output, so it never
# counts as a change), by the rule of the other measuring scripts (scripts/commit-stamp.sh):
# HEAD, "plus uncommitted changes in the sources (N files in photonmap/, render/, bench/ or
# the Makefile)" when git status lists any there, or PM_BENCH_COMMIT's text. A full run
# (results to commit) also refuses binaries older than a source file (exit 2: they were not
# built from the checkout as it is); the quick run (the test suite's, into OUTDIR) does not,
# since others may edit sources while it runs, and outside a git checkout it says "unknown".
. ./scripts/commit-stamp.sh
STAMP_BINS=
if [ "$MODE" = full ]; then
  for b in bench_search bench_knn bench_estimate render; do
    if [ -x "$BUILD/$b" ]; then STAMP_BINS="$STAMP_BINS $BUILD/$b"; fi
  done
fi
# shellcheck disable=SC2086 # a list of paths
if ! COMMIT_STAMP=$(CS_SOURCES="photonmap render bench Makefile" CS_EXCLUDE=bench/results commit_stamp . $STAMP_BINS); then
  [ "$MODE" = quick ] || exit 2
  COMMIT_STAMP=unknown
fi
mkdir -p "$OUT" "$IMG" "$DOCS"
start=$(date +%s)
log() { echo "run-bench: [$(( $(date +%s) - start ))s] $*" >&2; }

# PM_BENCH_ONLY=knn runs the workload race alone (bench_knn, its maps, plots, the document
# and the README headline) and keeps the committed results of the other benchmarks, whose
# own machine.csv then still says when and at which commit they were measured; the race's
# stamp is always knn_machine.csv.
ONLY=${PM_BENCH_ONLY:-all}
case "$ONLY" in all|knn) ;; *) echo "run-bench.sh: PM_BENCH_ONLY must be all or knn" >&2; exit 2 ;; esac
MACH="$OUT/machine.csv"
[ "$ONLY" = knn ] && MACH="$OUT/knn_machine.csv"

# The machine, for the document.
{
  echo "key,value"
  echo "cpu,$(lscpu 2>/dev/null | sed -n 's/^Model name:[[:space:]]*//p' | head -n 1 | tr ',' ' ')"
  echo "cpu_id,$(awk -F': *' '/^cpu family/ {f = $2} /^model[ \t]*:/ {m = $2} /^stepping/ {s = $2}
    /^cache size/ {c = $2} /^flags/ {h = ($2 ~ /hypervisor/) ? "virtual machine" : "bare metal"}
    END {printf "family %s model %s stepping %s; cache size %s per /proc/cpuinfo; %s", f, m, s, c, h}' /proc/cpuinfo 2>/dev/null | tr ',' ' ')"
  echo "cores,$(nproc 2>/dev/null || echo '?')"
  echo "compiler,$(${CC:-cc} --version 2>/dev/null | head -n 1 | tr ',' ' ')"
  echo "flags,$(echo "${PM_BENCH_CFLAGS:-see Makefile (run-bench.sh run directly)}" | tr ',' ' ' | sed 's/  */ /g; s/ *$//')"
  echo "flann,$(dpkg-query -W -f='${Version}' libflann-dev 2>/dev/null || echo unknown)"
  echo "date,$(date -u '+%Y-%m-%d %H:%M UTC')"
  echo "commit,$COMMIT_STAMP"
  echo "mode,$MODE"
  echo "load_before,$(cut -d' ' -f1-3 /proc/loadavg 2>/dev/null || echo '?')"
} > "$MACH"

# The real photon map: the global map of data/scenes/cornell_spheres.json, traced by the
# renderer in its fast preview mode (a tiny image, so almost all the time is photon tracing:
# about 2 s for 1M photons here) and saved with --save-photons (pm_map_save format, in the
# renderer's tree order; bench_search shuffles it before building). The quick run uses a small
# map. PM_BENCH_MAP=file.pmap uses that file instead; PM_BENCH_MAP=none skips the workload.
MAPARG=
MAP=${PM_BENCH_MAP:-}
if [ "$ONLY" = knn ] && [ "$MODE" = full ]; then MAP=none; fi
if [ -z "$MAP" ]; then
  if [ -x "$BUILD/render" ]; then
    if [ "$MODE" = full ]; then np=1000000; else np=20000; fi
    mapdir="$OUT/map.tmp"
    rm -rf "$mapdir"
    mkdir -p "$mapdir"
    log "photon map: render --mode preview data/scenes/cornell_spheres.json, $np global photons"
    "$BUILD/render" data/scenes/cornell_spheres.json --mode preview --quiet \
      --width 16 --height 16 --spp 1 --seed 1 --pm global_photons=$np --pm caustics=false \
      --pm shadow=false --save-photons "$mapdir" -o "$mapdir/preview.png" > "$mapdir.log" 2>&1 ||
      { cat "$mapdir.log" >&2; exit 1; }
    MAP="$mapdir/global.pmap"
  else
    log "no $BUILD/render: no real photon map workload"
  fi
fi
if [ -n "$MAP" ] && [ "$MAP" != none ]; then
  MAPARG="--map $MAP"
  echo "map,${PM_BENCH_MAP:-render --mode preview data/scenes/cornell_spheres.json --pm global_photons=$np --seed 1}" >> "$MACH"
fi

if [ "$ONLY" = all ]; then
  log "search benchmark ($MODE)"
  # shellcheck disable=SC2086
  "$BUILD/bench_search" $QFLAG --out "$OUT" $MAPARG
fi

# The workload race (bench_knn): clustered, slab and planar-caustic points it generates, plus
# the global photon maps of two shipped scenes at each N, dumped by the renderer as above.
# The quick run reuses the small map above.
KNNMAPS=
if [ -x "$BUILD/render" ] && [ -z "${PM_BENCH_MAP:-}" ]; then
  if [ "$MODE" = full ]; then
    for scene in cornell_spheres sun_spheres; do
      for np in 1000000 4000000; do
        d="$OUT/map.tmp/$scene.$np"
        mkdir -p "$d"
        log "photon map: render --mode preview data/scenes/$scene.json, $np global photons"
        "$BUILD/render" "data/scenes/$scene.json" --mode preview --quiet --width 16 --height 16 \
          --spp 1 --seed 1 --pm global_photons=$np --pm caustics=false --pm shadow=false \
          --save-photons "$d" -o "$d/preview.png" > "$d.log" 2>&1 || { cat "$d.log" >&2; exit 1; }
        KNNMAPS="$KNNMAPS --map $scene=$d/global.pmap"
      done
    done
    echo "knn_maps,render --mode preview data/scenes/{cornell_spheres;sun_spheres}.json --pm global_photons={1000000;4000000} --seed 1" >> "$MACH"
  elif [ -n "$MAP" ] && [ "$MAP" != none ]; then
    KNNMAPS="--map cornell_spheres=$MAP"
  fi
fi
log "k-NN workload race ($MODE)"
# The machine's load during the race (other people's jobs share it): the 1-minute load average
# every 15 s while bench_knn runs; the sampler stops by itself when this script has ended.
( while kill -0 $$ 2>/dev/null && [ ! -f "$OUT/load.stop" ]; do
    cut -d' ' -f1 /proc/loadavg 2>/dev/null; sleep 15; done ) > "$OUT/load.tmp" &
# shellcheck disable=SC2086
"$BUILD/bench_knn" $QFLAG --out "$OUT" $KNNMAPS
: > "$OUT/load.stop"
cut -d' ' -f1 /proc/loadavg 2>/dev/null >> "$OUT/load.tmp" || true
echo "load_during,$(sort -n "$OUT/load.tmp" | awk '{ v[NR] = $1 } END { if (NR) printf "min %s median %s max %s (%d samples)", v[1], v[int((NR + 1) / 2)], v[NR], NR; else printf "?" }')" >> "$MACH"
rm -f "$OUT/load.tmp"
rm -rf "$OUT/map.tmp" "$OUT/map.tmp.log"
if [ "$ONLY" = knn ]; then
  # the race's own stamp, complete; the other benchmarks are not rerun
  echo "load_after,$(cut -d' ' -f1-3 /proc/loadavg 2>/dev/null || echo '?')" >> "$MACH"
  echo "bench_seconds,$(( $(date +%s) - start ))" >> "$MACH"
else
  cp "$MACH" "$OUT/knn_machine.csv.tmp"
fi

if [ "$ONLY" = all ] && [ -x "$BUILD/bench_estimate" ]; then
  log "estimate benchmark ($MODE)"
  # shellcheck disable=SC2086
  "$BUILD/bench_estimate" $QFLAG --out "$OUT"
fi

# Profiles of the headline configurations (what limits each one), full run only: callgrind
# with its cache simulator, instrumentation switched on around the queries alone. Per-query
# totals go to profile.csv, the self cost by function to profile_*.txt. The simulated last
# level is 1 MB, 16-way, the size of a per-core second-level cache (a virtual machine may
# report no or absurd cache sizes): a miss there costs a trip to L3 or DRAM.
[ "$ONLY" = knn ] || rm -f "$OUT"/profile_*.txt "$OUT/profile.csv"
if [ "$ONLY" = all ] && [ "$MODE" = full ] && command -v valgrind >/dev/null 2>&1 && command -v callgrind_annotate >/dev/null 2>&1; then
  PQ=4000
  echo "probe,queries,instr_per_query,data_reads_per_query,d1_read_misses_per_query,ll_read_misses_per_query,caches" > "$OUT/profile.csv"
  n=$(awk -F, '$1=="headline" && $2=="photon" {print $3; exit}' "$OUT/queries.csv")
  awk -F, '$1=="headline" && $2=="photon" && $10==1 {print $4":"$5":"$6" "$9}' "$OUT/queries.csv" |
  awk '!seen[$1]++' | head -n 5 | while read -r probe r2; do
    case "$probe" in flann_single:radius_maxnn:*) continue ;; esac
    name=$(echo "$probe" | tr ':' '_')
    log "callgrind profile: $probe"
    cg="$OUT/callgrind.$name.tmp"
    valgrind --tool=callgrind --cache-sim=yes --LL=1048576,16,64 --instr-atstart=no --callgrind-out-file="$cg" \
      "$BUILD/bench_search" --probe "$probe" --n "$n" --probe-r2 "$r2" --probe-queries $PQ \
      > "$OUT/probe.$name.tmp" 2>"$OUT/probe.$name.err" || { cat "$OUT/probe.$name.err" >&2; exit 1; }
    caches=$(sed -n 's/^desc: \(.*cache\): *\(.*\)$/\1 \2/p' "$cg" | tr ',' ' ' | tr '\n' ';' | sed 's/;$//; s/;/; /g')
    awk -v probe="$probe" -v q=$PQ -v caches="$caches" '
      /^events:/ { for (i = 2; i <= NF; i++) ev[i - 1] = $i }
      /^totals:/ { for (i = 2; i <= NF; i++) tot[ev[i - 1]] = $i }
      END { printf "%s,%d,%.1f,%.1f,%.2f,%.2f,%s\n", probe, q, tot["Ir"] / q, tot["Dr"] / q,
            tot["D1mr"] / q, tot["DLmr"] / q, caches }' "$cg" >> "$OUT/profile.csv"
    {
      echo "# $(cat "$OUT/probe.$name.tmp")"
      echo "# callgrind, instructions (Ir) of the $PQ queries only, by function (self cost)"
      callgrind_annotate --inclusive=no --auto=no --show=Ir --sort=Ir "$cg" 2>/dev/null | sed -n '/^-*$/!p' |
        grep -E 'PROGRAM TOTALS|^ *[0-9,]+ +\(' | head -n 12
    } > "$OUT/profile_$name.txt"
    rm -f "$cg" "$OUT/probe.$name.tmp" "$OUT/probe.$name.err"
  done
fi

if [ "$ONLY" = all ]; then
  echo "load_after,$(cut -d' ' -f1-3 /proc/loadavg 2>/dev/null || echo '?')" >> "$MACH"
  echo "bench_seconds,$(( $(date +%s) - start ))" >> "$MACH"
  mv "$OUT/knn_machine.csv.tmp" "$OUT/knn_machine.csv"
  cat "$MACH" | sed -n '/^load_after,/p; /^bench_seconds,/p' >> "$OUT/knn_machine.csv"
fi

if command -v gnuplot >/dev/null 2>&1; then
  log "plots -> $IMG"
  sh scripts/plot-bench.sh "$OUT" "$IMG"
else
  log "gnuplot not installed: no plots (scripts/install-deps.sh --bench)"
fi
log "document -> $DOCS/BENCHMARKS.md"
sh scripts/gen-benchmarks-md.sh "$OUT" "$IMGREL" > "$DOCS/BENCHMARKS.md.tmp"
mv "$DOCS/BENCHMARKS.md.tmp" "$DOCS/BENCHMARKS.md"
# The README's `bench/` bullet carries the headline of this run (full run only): the lines
# from "- `bench/`" to the next bullet are replaced by the generated ones.
if [ "$MODE" = full ] && [ -f "$OUT/knn_best.csv" ] && [ -f README.md ]; then
  log "README.md headline"
  sh scripts/gen-benchmarks-md.sh --readme-headline "$OUT" > README.md.headline.tmp
  awk -v H=README.md.headline.tmp '
    /^- `bench\/`/ { while ((getline l < H) > 0) print l; skip = 1; next }
    skip && /^- / { skip = 0 }
    skip && /^[^ ]/ { skip = 0 }
    !skip { print }' README.md > README.md.tmp
  rm -f README.md.headline.tmp
  mv README.md.tmp README.md
fi
rm -f "$OUT/load.stop" # the sampler also stops once this script has ended
log "done"
