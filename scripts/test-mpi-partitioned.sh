#!/bin/sh
# test-mpi-partitioned.sh: the tests of render-mpi's distributed precomputed irradiance and
# per-sample lookups in partitioned mode (render/mpi/lookup.h, docs/MPI.md "Partitioned mode").
#
#   PM_BUILD_DIR=build/release sh scripts/test-mpi-partitioned.sh
#
# scripts/test-mpi.sh sources this file, and then its tests count with test-mpi's (the same
# ok/bad, $T, $R, $M, $MPIRUN). The accuracy of partitioned renders against the one-process
# render (quarters within 1% at 2 and 4 ranks) is test-mpi.sh's; these test what is new: that no
# rank holds the whole precomputed irradiance, that the statistics count one trace per camera
# sample, and that samples whose guessed lookups were wrong give the same image whatever the
# threads.
# Run alone, it runs scripts/test-mpi.sh, which sets up what these tests share and sources
# this file (one copy of that set-up).
if [ -z "${MPIRUN:-}" ]; then
  case "${1:-}" in
    -h|--help) awk 'NR > 1 && /^#/ { sub(/^# ?/, ""); print; next } NR > 1 { exit }' "$0"; exit 0 ;;
    "") ;;
    *) echo "test-mpi-partitioned: unknown option '$1' (see --help)" >&2; exit 2 ;;
  esac
  exec sh "$(cd "$(dirname "$0")" && pwd)/test-mpi.sh"
fi

# A log's statistics as "Category/Counter value" lines.
pt_counters() {
  awk '/^Statistics:/ { on = 1; next } !on { next }
       /^  [^ ]/ { cat = $0; sub(/^ +/, "", cat); next }
       /^    [^ ]/ { line = $0; sub(/^ +/, "", line); v = $NF; sub(/ +[^ ]+$/, "", line)
                     print cat "/" line " " v }' "$1"
}
pt_counter() { pt_counters "$2" | awk -v k="$1" 'index($0, k " ") == 1 { print $NF }'; }

PT="--width 32 --height 32 --spp 4 --pm global_photons=30000 --pm caustic_photons=30000 --quiet"

# ---- the precomputed irradiance is split over the ranks ---------------------------------
# Oracle: the records' own count. Each rank keeps the records of the photons it chose in its
# part (about a quarter of its part), so at R ranks the largest rank holds about 1/R of all
# records: its count times R must stay within 5% of the whole (parts differ by a photon or so,
# and each part's tree chooses its quarter by the same rule), and the counts must add up to
# the whole ("A to B of N": with R = 2, A + B = N); the largest rank's cache bytes (records,
# lookup tree, free heights) times R within 10% of all ranks' together. A rank holding the
# whole cache (as before this change) fails: B = N.
for np in 2 4; do
  log="$T/pt.split.$np.log"
  # shellcheck disable=SC2086
  $MPIRUN -np $np "$M" data/scenes/cornell_spheres.json $PT --mode pm --threads 1 \
    --pm distributed=partitioned --hdr "$T/pt.split.$np.pfm" >"$log" 2>&1
  rc=$?
  line=$(sed -n 's/^MPI: partitioned precomputed irradiance: each rank keeps its own records, \([0-9]*\) to \([0-9]*\) of \([0-9]*\) (at most \([0-9]*\) bytes on a rank, \([0-9]*\) on all).*/\1 \2 \3 \4 \5/p' "$log")
  # shellcheck disable=SC2086
  set -- $line
  if [ $rc = 0 ] && [ $# = 5 ] && [ "$3" -gt 0 ] && [ $(($2 * np * 100)) -le $(($3 * 105)) ] \
     && [ $(($1 * np * 100)) -ge $(($3 * 95)) ] && { [ $np != 2 ] || [ $(($1 + $2)) = "$3" ]; } \
     && [ $(($4 * np * 100)) -le $(($5 * 110)) ]; then
    ok "partitioned precomputed irradiance np=$np: ranks keep $1 to $2 of $3 records (1/$np each, within 5%), at most $4 of $5 bytes"
  else
    bad "partitioned precomputed irradiance np=$np" "rc $rc, records line '$line'"
  fi
done

# ---- statistics count one trace per sample --------------------------------------------
# Oracle: the one-process render with the shadow-photon map off. In preview mode no lookup of
# the precomputed irradiance is made and no decision depends on an estimate's value, so the
# kept trace of each camera sample is the one-process trace, ray for ray: the pixel pass's
# counters (camera, indirect and shadow rays, path vertices, Russian roulette) summed over the
# ranks must equal the one-process ones exactly, although each sample with an estimate was
# traced twice (the first trace's counters are taken off per thread). Counting both traces
# doubles the indirect and shadow rays of those samples: the test then fails.
# shellcheck disable=SC2086
"$R" data/scenes/cornell_spheres.json $PT --mode preview --pm shadow=false --threads 2 \
  --hdr "$T/pt.prev.ref.pfm" >"$T/pt.prev.ref.log" 2>&1
# shellcheck disable=SC2086
$MPIRUN -np 2 "$M" data/scenes/cornell_spheres.json $PT --mode preview --threads 2 \
  --pm distributed=partitioned --hdr "$T/pt.prev.pfm" >"$T/pt.prev.log" 2>&1
rc=$?
same=1
for k in "Integrator/Camera rays" "Integrator/Indirect rays" "Integrator/Shadow rays" \
         "Integrator/Path vertices" "Integrator/Paths ended by Russian roulette" "Film/Samples"; do
  a=$(pt_counter "$k" "$T/pt.prev.ref.log"); b=$(pt_counter "$k" "$T/pt.prev.log")
  if [ -z "$a" ] || [ "$a" != "$b" ]; then same=0; echo "  $k: one process '$a', partitioned '$b'"; fi
done
twice=$(pt_counter "MPI/Partitioned: camera samples traced twice or more (all ranks)" "$T/pt.prev.log")
if [ $rc = 0 ] && [ $same = 1 ] && [ "${twice:-0}" -gt 0 ]; then
  ok "partitioned preview np=2: pixel-pass counters equal the one-process render's ($twice samples were traced twice, counted once)"
else
  bad "partitioned statistics" "rc $rc; counters differ (above) or no sample traced twice ('$twice')"
fi

# ---- samples whose guessed lookups were wrong -------------------------------------------
# A lookup of the precomputed irradiance is guessed from the tracing rank's own records
# (found or not), and a wrong guess sends the sample's gather down another path: its new
# queries need a further exchange and a third trace. Oracle: the partitioned render itself,
# with 1 and with 2 threads per rank at -np 3 (each sample's kept trace read answers only,
# so the image cannot depend on the guesses, nor on which samples shared a thread or an
# exchange): the PFM bytes must be equal, the scene must have had samples traced a third time
# (shelf_glass: gathers under a shelf, where a rank's own records often differ from all
# ranks' on whether one is visible; 54 such traces when this was written), and every camera
# sample is counted once.
PW="--width 32 --height 32 --spp 4 --pm global_photons=20000 --pm caustic_photons=5000 --quiet"
for th in 1 2; do
  # shellcheck disable=SC2086
  $MPIRUN -np 3 "$M" data/scenes/shelf_glass.json $PW --mode pm --threads $th \
    --pm distributed=partitioned --hdr "$T/pt.wall.t$th.pfm" >"$T/pt.wall.t$th.log" 2>&1
done
third=$(pt_counter "MPI/Partitioned: camera sample traces past the second (all ranks)" "$T/pt.wall.t1.log")
cam=$(pt_counter "Integrator/Camera rays" "$T/pt.wall.t1.log")
if [ -s "$T/pt.wall.t1.pfm" ] && cmp -s "$T/pt.wall.t1.pfm" "$T/pt.wall.t2.pfm" \
   && [ "${third:-0}" -gt 0 ] && [ "$cam" = $((32 * 32 * 4)) ]; then
  ok "partitioned shelf_glass np=3: $third traces past the second (wrong guesses); 1 and 2 threads give the same bytes; $cam camera rays"
else
  bad "partitioned wrong guesses" "third traces '$third', camera rays '$cam', images $(cmp "$T/pt.wall.t1.pfm" "$T/pt.wall.t2.pfm" 2>&1 | head -1)"
fi

# ---- samples kept from their trace on guesses ------------------------------------------
# A sample whose every guess was the answer (lookups its rank's own records answered as all
# ranks do, found or not; estimates of 0) keeps that trace: its radiance and its counters
# are those of the trace it would be traced again to. Oracle: the same render with
# PM_MPI_TEST_TRACE_AGAIN=1, which traces every sample with queries again: the PFM bytes and
# the pixel-pass counters must be equal, the default run must have kept samples (partition_thin:
# lookups behind the thin wall that no rank's records answer), the other none. A check that
# kept a sample with a wrong guess would change its pixels; not adding a kept trace's counters
# back would lower the rays counted.
for v in 0 1; do
  # shellcheck disable=SC2086
  PM_MPI_TEST_TRACE_AGAIN=$v $MPIRUN -np 3 -x PM_MPI_TEST_TRACE_AGAIN "$M" data/scenes/partition_thin.json $PW \
    --mode pm --threads 1 --pm distributed=partitioned --hdr "$T/pt.keep.$v.pfm" >"$T/pt.keep.$v.log" 2>&1
done
kept0=$(pt_counter "MPI/Partitioned: samples kept from a trace on guesses (all ranks)" "$T/pt.keep.0.log")
kept1=$(pt_counter "MPI/Partitioned: samples kept from a trace on guesses (all ranks)" "$T/pt.keep.1.log")
same=1
for k in "Integrator/Indirect rays" "Integrator/Shadow rays" "Integrator/Path vertices" \
         "Photon mapping/Irradiance lookups" "Photon mapping/Final gather rays" "Film/Samples"; do
  a=$(pt_counter "$k" "$T/pt.keep.1.log"); b=$(pt_counter "$k" "$T/pt.keep.0.log")
  if [ -z "$a" ] || [ "$a" != "$b" ]; then same=0; echo "  $k: traced again '$a', kept '$b'"; fi
done
if [ -s "$T/pt.keep.0.pfm" ] && cmp -s "$T/pt.keep.0.pfm" "$T/pt.keep.1.pfm" && [ $same = 1 ] \
   && [ "${kept0:-0}" -gt 0 ] && [ "${kept1:-x}" = 0 ]; then
  ok "partitioned partition_thin np=3: $kept0 samples kept from their trace on guesses; the same bytes and counters as tracing them again"
else
  bad "partitioned samples kept on guesses" "kept '$kept0' / '$kept1', images $(cmp "$T/pt.keep.0.pfm" "$T/pt.keep.1.pfm" 2>&1 | head -1)"
fi

