#!/bin/sh
# mpi-scaling.sh: measure render-mpi (time and traffic) and write docs/MPI.md from it.
#
#   PM_BUILD_DIR=build/release sh scripts/mpi-scaling.sh [--reps N] [--partitioned] [--memory]
#       [--before DIR LABEL] [OUT_DIR]
#
# Needs $PM_BUILD_DIR/render and render-mpi (make MPI=1). Writes into OUT_DIR (default
# docs/mpi): timing.csv (one row per run: the one-process render with 2 threads, render-mpi
# with 1 rank x 2 threads and with 2 ranks x 1 thread, in pm and path modes, N repetitions
# interleaved, default 3), traffic.csv (one pm run per rank count 1..4, 1 thread each: the
# bytes of the photon exchange and of the pixel pass, the photons stored and emitted, the
# tiles), measurement.txt (commit, date, machine, load, settings); then runs
# scripts/gen-mpi-md.sh, which turns those files into docs/MPI.md. Renders go to a temporary
# directory. Takes about 5 minutes on 2 idle cores.
#
# Partitioned maps: partitioned.csv (the same pm render with 1 thread per rank at 2 and 4
# ranks, replicated and --pm distributed=partitioned, N repetitions interleaved: phase
# timers, the bytes of the lookups, of the precomputed irradiance, of the pixel pass, and the
# partitioned image's worst 32x32 quarter and whole-image mean against the one-process render
# with the shadow-photon map off, which partitioned renders do not use either)
# and partitioned.txt (its own stamp). --partitioned measures only these two files (about
# 3 minutes) and keeps the others.
#
# Partitioned traffic and traces: partitioned.csv also has the lookups of the precomputed
# irradiance (the final gather's), the camera samples, how many were traced twice and past
# twice, and how many with queries kept their trace on guesses (render-mpi's
# "MPI/Partitioned:" statistics).
#
# The stamps' commit is that of the binaries, found before anything is written
# (scripts/commit-stamp.sh): the checkout's HEAD, "plus uncommitted changes in the sources"
# when git status lists any in photonmap/, render/ or the Makefile; refused (exit 2) when a
# source file is newer than render or render-mpi. PM_BENCH_COMMIT=TEXT stamps TEXT instead
# (binaries built from a clean export of a commit).
#
# --before DIR LABEL: also run DIR/render-mpi (a build of an earlier commit, LABEL naming it)
# in partitioned mode beside the current one, in the partitioned and memory tables (mode
# "before"), for a before/after comparison measured under the same load.
#
# Memory: memory.csv (a pm render of larger maps, 1 thread per rank, at 1, 2 and 4 ranks,
# replicated and partitioned: every rank's peak resident memory, from /usr/bin/time's maximum
# resident set size, the bytes of the photon exchange, and in partitioned mode the bytes of
# the precomputed irradiance on the largest rank and on all) and memory.txt (its stamp).
# --memory measures only these two files (about 1 minute) and keeps the others.
set -eu
here=$(cd "$(dirname "$0")/.." && pwd)
B="${PM_BUILD_DIR:-$here/build/release}"
reps=3
only_part=0
only_mem=0
before=""
before_label=""
out="$here/docs/mpi"
while [ $# -gt 0 ]; do
  case "$1" in
    -h|--help) awk 'NR > 1 && /^#/ { sub(/^# ?/, ""); print; next } NR > 1 { exit }' "$0"; exit 0 ;;
    --partitioned) only_part=1; shift ;;
    --memory) only_mem=1; shift ;;
    --before) [ $# -ge 3 ] || { echo "mpi-scaling: --before needs a build directory and a label" >&2; exit 2; }
              before=$2; before_label=$3; shift 3
              [ -x "$before/render-mpi" ] || { echo "mpi-scaling: $before/render-mpi not found" >&2; exit 2; } ;;
    --reps) [ $# -ge 2 ] || { echo "mpi-scaling: --reps needs a number" >&2; exit 2; }
            reps=$2; shift 2 ;;
    -*) echo "mpi-scaling: unknown option '$1' (see --help)" >&2; exit 2 ;;
    *) out=$1; shift ;;
  esac
done
for p in "$B/render" "$B/render-mpi"; do
  [ -x "$p" ] || { echo "mpi-scaling: $p not found (make MPI=1 first)" >&2; exit 2; }
done
# The binaries' commit, before anything is written (scripts/commit-stamp.sh).
. "$here/scripts/commit-stamp.sh"
STAMP=$(commit_stamp "$here" "$B/render" "$B/render-mpi") || exit 2
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
T=$(mktemp -d "${TMPDIR:-/tmp}/mpi-scaling.XXXXXX")
trap 'rm -rf "$T"' EXIT
mkdir -p "$out"
cd "$here"

SCENE=data/scenes/cornell_spheres.json
SIZE="--width 64 --height 64"
PM="--mode pm --spp 16 --pm global_photons=60000 --pm caustic_photons=60000"
PATHM="--mode path --spp 256"
# No binding: a rank's OpenMP threads may use every core (OpenMPI binds small jobs to cores).
MPIRUN="mpirun --oversubscribe --bind-to none"

# A timer from a log's statistics ("    Photon kd-trees     1.234 s"), 0 when absent.
timer() { awk -v k="$1" '{ line = $0; sub(/^ +/, "", line) }
  index(line, k) == 1 && $NF == "s" { v = $(NF - 1) } END { print v == "" ? 0 : v }' "$2"; }
wall() { sed -n 's/^Summary: wall time \([0-9.]*\) s.*/\1/p' "$1"; }

run() { # config log mode-args
  cfg=$1; log=$2; shift 2
  case $cfg in
    render_2t) "$B/render" $SCENE $SIZE "$@" --threads 2 --quiet --hdr "$T/o.pfm" >"$log" 2>&1 ;;
    mpi_1x2) $MPIRUN -np 1 "$B/render-mpi" $SCENE $SIZE "$@" --threads 2 --quiet \
               --hdr "$T/o.pfm" >"$log" 2>&1 ;;
    mpi_2x1) $MPIRUN -np 2 "$B/render-mpi" $SCENE $SIZE "$@" --threads 1 --quiet \
               --hdr "$T/o.pfm" >"$log" 2>&1 ;;
  esac
}

measure_partitioned() {
  echo "ranks,mode,rep,wall_s,tracing_s,trees_s,irradiance_s,rendering_s,lookups,bytes_lookup,side_estimates,bytes_side,bytes_pixel,pixels,worst_quarter_pct,whole_pct,gather_lookups,samples,traces,traced_twice,traces_past_two,kept_on_guesses" > "$out/partitioned.csv"
  modes="replicated partitioned"
  [ -n "$before" ] && modes="$modes before"
  pload0=$(cut -d' ' -f1-3 /proc/loadavg)
  q=$(( ${SIZE##* } / 2 ))
  # shellcheck disable=SC2086
  "$B/render" $SCENE $SIZE $PM --pm shadow=false --threads 2 --quiet --hdr "$T/part.ref.pfm" \
    >"$T/part.ref.log" 2>&1 || { echo "mpi-scaling: the reference render failed" >&2; exit 1; }
  r=1
  while [ "$r" -le "$reps" ]; do
    for np in 2 4; do
      for mode in $modes; do
        log="$T/part.$np.$mode.$r.log"
        bin="$B/render-mpi"; dm=$mode
        [ $mode = before ] && { bin="$before/render-mpi"; dm=partitioned; }
        # shellcheck disable=SC2086
        $MPIRUN -np $np "$bin" $SCENE $SIZE $PM --threads 1 --quiet --pm distributed=$dm \
          --hdr "$T/part.$np.$mode.pfm" >"$log" 2>&1 \
          || { echo "mpi-scaling: -np $np $mode failed" >&2; tail -5 "$log" >&2; exit 1; }
        worst=0; whole=0
        if [ $mode != replicated ]; then
          for rc_ in "0 0" "$q 0" "0 $q" "$q $q"; do
            # shellcheck disable=SC2086
            v=$("$B/render" --compare "$T/part.$np.$mode.pfm" "$T/part.ref.pfm" --rect $rc_ $q $q | sed -n 's/^rel_mean //p')
            worst=$(awk -v a="$v" -v w="$worst" 'BEGIN { a = a < 0 ? -a : a; a *= 100; printf "%.4f", (a > w ? a : w) }')
          done
          whole=$("$B/render" --compare "$T/part.$np.$mode.pfm" "$T/part.ref.pfm" | sed -n 's/^rel_mean //p' | awk '{ printf "%.4f", 100 * $1 }')
        fi
        traffic=$(awk '
          /^Rendering [0-9]+x[0-9]+/ { split($2, wh, "x"); px = wh[1] * wh[2] }
          /^MPI: bytes sent:/ { bx = $9 }
          /^MPI: partitioned maps: [0-9]+ lookups/ { nl = $4; bl = $6; ns = $(NF - 6); bs = $(NF - 4) }
          END { printf "%d,%d,%d,%d,%d,%d", nl, bl, ns, bs, bx, px }' "$log")
        traces=$(awk '
          /^    Partitioned: precomputed irradiance lookups sent/ { gl = $NF }
          /^    Samples  / { sm = $NF }
          /^    Partitioned: camera sample traces \(all/ { tr = $NF }
          /^    Partitioned: camera samples traced (again|twice or more)/ { tw = $NF }
          /^    Partitioned: camera sample traces past the second/ { t3 = $NF }
          /^    Partitioned: samples kept from a trace on guesses/ { kg = $NF }
          END { printf "%d,%d,%d,%d,%d,%d", gl, sm, tr, tw, t3, kg }' "$log")
        echo "$np,$mode,$r,$(wall "$log"),$(timer "Photon tracing" "$log"),$(timer "Photon kd-trees" "$log"),$(timer "Precomputed irradiance" "$log"),$(timer "Rendering" "$log"),$traffic,$worst,$whole,$traces" >> "$out/partitioned.csv"
        echo "mpi-scaling: partitioned table: $(tail -1 "$out/partitioned.csv")" >&2
      done
    done
    r=$((r + 1))
  done
  {
    echo "commit $STAMP"
    echo "date $(date -u +%Y-%m-%dT%H:%MZ)"
    echo "machine $(nproc) cores, $(uname -m), $(mpirun --version 2>/dev/null | head -1)"
    echo "load_before $pload0"
    echo "load_after $(cut -d' ' -f1-3 /proc/loadavg)"
    echo "reps $reps"
    if [ -n "$before" ]; then echo "before $before_label"; fi
  } > "$out/partitioned.txt"
}
MEMPM="--mode pm --spp 1 --pm global_photons=400000 --pm caustic_photons=200000"
measure_memory() {
  [ -x /usr/bin/time ] || { echo "mpi-scaling: /usr/bin/time not found (apt-get install time)" >&2; exit 2; }
  # Each rank under /usr/bin/time, which writes its peak resident set size (KiB) per rank.
  cat > "$T/rss.sh" <<'EOS'
#!/bin/sh
exec /usr/bin/time -f "%M" -o "$RSS_DIR/rss.$OMPI_COMM_WORLD_RANK" "$@"
EOS
  chmod +x "$T/rss.sh"
  echo "ranks,mode,rank,max_rss_kib,bytes_photon,photons_stored,cache_max_bytes,cache_all_bytes" > "$out/memory.csv"
  mload0=$(cut -d' ' -f1-3 /proc/loadavg)
  modes="replicated partitioned"
  [ -n "$before" ] && modes="$modes before"
  for np in 1 2 4; do
    for mode in $modes; do
      [ $np = 1 ] && [ $mode != replicated ] && continue
      log="$T/mem.$np.$mode.log"
      bin="$B/render-mpi"; dm=$mode
      [ $mode = before ] && { bin="$before/render-mpi"; dm=partitioned; }
      rm -rf "$T/rss"; mkdir "$T/rss"
      # shellcheck disable=SC2086
      RSS_DIR="$T/rss" $MPIRUN -np $np -x RSS_DIR "$T/rss.sh" "$bin" $SCENE --width 16 --height 16 \
        $MEMPM --pm distributed=$dm --threads 1 --quiet --hdr "$T/o.pfm" >"$log" 2>&1 ||
        { echo "mpi-scaling: memory -np $np $mode failed" >&2; tail -5 "$log" >&2; exit 1; }
      bp=$(sed -n 's/^MPI: bytes sent: photon exchange \([0-9]*\),.*/\1/p' "$log")
      st=$(awk '/^Photons: / { g = $2; s = $4; c = $9; gsub(/[^0-9]/, "", g); gsub(/[^0-9]/, "", s)
                gsub(/[^0-9]/, "", c); print g + s + c }' "$log")
      # The precomputed irradiance's bytes (render-mpi's partitioned line): the largest rank's
      # part and all parts together.
      cache=$(sed -n 's/^MPI: partitioned precomputed irradiance: .*(at most \([0-9]*\) bytes on a rank, \([0-9]*\) on all).*/\1,\2/p' "$log")
      k=0
      while [ $k -lt $np ]; do
        echo "$np,$mode,$k,$(cat "$T/rss/rss.$k"),${bp:-0},$st,${cache:-0,0}" >> "$out/memory.csv"
        k=$((k + 1))
      done
      echo "mpi-scaling: memory -np $np $mode: $(tail -1 "$out/memory.csv")" >&2
    done
  done
  {
    echo "commit $STAMP"
    echo "date $(date -u +%Y-%m-%dT%H:%MZ)"
    echo "machine $(nproc) cores, $(uname -m), $(mpirun --version 2>/dev/null | head -1)"
    echo "load_before $mload0"
    echo "load_after $(cut -d' ' -f1-3 /proc/loadavg)"
    echo "scene $SCENE, 16x16"
    echo "pm_args $MEMPM"
    if [ -n "$before" ]; then echo "before $before_label"; fi
  } > "$out/memory.txt"
}
if [ "$only_mem" = 1 ]; then
  measure_memory
  sh "$here/scripts/gen-mpi-md.sh" "$out"
  exit 0
fi
if [ "$only_part" = 1 ]; then
  measure_partitioned
  sh "$here/scripts/gen-mpi-md.sh" "$out"
  exit 0
fi

echo "mode,config,rep,wall_s,tracing_s,trees_s,irradiance_s,rendering_s" > "$out/timing.csv"
load0=$(cut -d' ' -f1-3 /proc/loadavg)
r=1
while [ "$r" -le "$reps" ]; do
  for mode in pm path; do
    [ $mode = pm ] && args=$PM || args=$PATHM
    for cfg in render_2t mpi_1x2 mpi_2x1; do
      log="$T/$mode.$cfg.$r.log"
      # shellcheck disable=SC2086
      run $cfg "$log" $args || { echo "mpi-scaling: $cfg $mode failed:" >&2; tail -5 "$log" >&2; exit 1; }
      echo "$mode,$cfg,$r,$(wall "$log"),$(timer "Photon tracing" "$log"),$(timer "Photon kd-trees" "$log"),$(timer "Precomputed irradiance" "$log"),$(timer "Rendering" "$log")" >> "$out/timing.csv"
      echo "mpi-scaling: $mode $cfg rep $r: $(wall "$log") s" >&2
    done
  done
  r=$((r + 1))
done

echo "ranks,photons_stored,emitted_global,emitted_caustic,bytes_photon,pixels,tiles,tiles_rank0,bytes_pixel,stored_global_pass,stored_caustic_pass" > "$out/traffic.csv"
for np in 1 2 3 4; do
  log="$T/traffic.$np.log"
  # shellcheck disable=SC2086
  $MPIRUN -np $np "$B/render-mpi" $SCENE $SIZE $PM --threads 1 --quiet \
    --hdr "$T/o.pfm" >"$log" 2>&1 || { echo "mpi-scaling: -np $np failed" >&2; tail -5 "$log" >&2; exit 1; }
  awk -v np=$np '
    /^Photons: / { g = $2; s = $4; eg = $7; c = $9; ec = $12; gsub(/[^0-9]/, "", g); gsub(/[^0-9]/, "", s)
                   gsub(/[^0-9]/, "", eg); gsub(/[^0-9]/, "", c); gsub(/[^0-9]/, "", ec) }
    /^Rendering [0-9]+x[0-9]+/ { split($2, wh, "x"); px = wh[1] * wh[2] }
    /^MPI: .*tiles rendered per rank:/ { t0 = $0; sub(/.*per rank: /, "", t0); split(t0, a, " "); r0 = a[1]
                                        tot = $NF; gsub(/[^0-9]/, "", tot) }
    /^MPI: bytes sent:/ { bp = $6; gsub(/[^0-9]/, "", bp); bx = $9 }
    END { printf "%d,%d,%d,%d,%d,%d,%d,%d,%d,%d,%d\n", np, g + s + c, eg, ec, bp, px, tot, r0, bx, g + s, c }' \
    "$log" >> "$out/traffic.csv"
  echo "mpi-scaling: traffic -np $np: $(tail -1 "$out/traffic.csv")" >&2
done

{
  echo "commit $STAMP"
  echo "date $(date -u +%Y-%m-%dT%H:%MZ)"
  echo "machine $(nproc) cores, $(uname -m), $(mpirun --version 2>/dev/null | head -1)"
  echo "load_before $load0"
  echo "load_after $(cut -d' ' -f1-3 /proc/loadavg)"
  echo "scene $SCENE, 64x64"
  echo "pm_args $PM"
  echo "path_args $PATHM"
  echo "reps $reps"
} > "$out/measurement.txt"
measure_partitioned
measure_memory
sh "$here/scripts/gen-mpi-md.sh" "$out"
