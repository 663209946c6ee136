#!/bin/sh
# plot-bench.sh: PNG plots of the benchmark CSVs with gnuplot.
#
#   sh scripts/plot-bench.sh RESULTS_DIR IMG_DIR
#
# Each plot is a set of series cut out of a CSV by awk (one data file per series, named by
# its key, e.g. "kdtree iterative B=8"), then drawn by one gnuplot call. Plots:
#   param_<dist>.png   queries/s against B, octree capacity and FLANN leaf size (1 thread)
#   radius_<dist>.png  queries/s against the maximum radius (relative to the radius finding 50)
#   k_<dist>.png       queries/s against k (unlimited radius)
#   recall_<dist>.png  FLANN forest recall against queries/s, beside the exact searches
#   n_photon.png       queries/s against N; build_photon.png: build time against N
#   estimate_<region>.png  RMS relative error of each estimator against ns per estimate
#   knn_ratio_<mode>_<N>M.png  the workload race: kd-tree / FLANN best exact against k, per
#                      workload and query set (bench_knn's knn_best.csv)
set -eu
case "${1:-}" in
  -h|--help) awk 'NR > 1 && /^#/ { sub(/^# ?/, ""); print; next } NR > 1 { exit }' "$0"; exit 0 ;;
esac
R=${1:?usage: plot-bench.sh RESULTS_DIR IMG_DIR}
IMG=${2:?usage: plot-bench.sh RESULTS_DIR IMG_DIR}
mkdir -p "$IMG"
T=$(mktemp -d)
trap 'rm -rf "$T"' EXIT

# series CSV AWK_FILTER X_EXPR Y_EXPR KEY_EXPR: writes $T/s/<n>.dat and $T/s/<n>.key
series() {
  rm -rf "$T/s"; mkdir -p "$T/s"
  awk -F, -v dir="$T/s" "
    NR > 1 && ($2) {
      key = $5; x = $3; y = $4
      if (!(key in id)) { id[key] = ++n; print key > (dir \"/\" n \".key\"); close(dir \"/\" n \".key\") }
      print x, y >> (dir \"/\" id[key] \".dat\")
    }" "$1"
}

# plot OUT.png TITLE XLABEL YLABEL LOGX LOGY [extra gnuplot lines] [nosort]
# Points are joined in x order, or with "nosort" in the CSV's row order (e.g. along k).
plot() {
  out=$1 title=$2 xl=$3 yl=$4 logx=$5 logy=$6 extra=${7:-} order=${8:-sort}
  [ -n "$(ls "$T/s" 2>/dev/null)" ] || return 0
  {
    echo "set terminal png size 900,560 font 'DejaVuSans,9' noenhanced"
    echo "set output '$out'"
    echo "set title '$title'"
    echo "set xlabel '$xl'; set ylabel '$yl'"
    echo "set grid; set key outside right top"
    [ "$logx" = 1 ] && echo "set logscale x"
    [ "$logy" = 1 ] && echo "set logscale y"
    echo "$extra"
    printf 'plot '
    first=1
    for k in $(ls "$T/s"/*.key | sort -t/ -k1,1 -V); do
      b=${k%.key}
      [ -s "$b.dat" ] || continue
      if [ "$order" = nosort ]; then cp "$b.dat" "$b.sorted"; else sort -g "$b.dat" > "$b.sorted"; fi
      [ $first = 1 ] || printf ', '
      first=0
      printf "'%s' using 1:2 with linespoints title '%s'" "$b.sorted" "$(cat "$k" | tr "'" ' ')"
    done
    echo
  } > "$T/plot.gp"
  gnuplot "$T/plot.gp" 2>"$T/gp.err" || { cat "$T/gp.err" >&2; return 1; }
}

Q="$R/queries.csv"
B="$R/build.csv"
# queries.csv columns: 1 sweep 2 dist 3 n 4 index 5 variant 6 param 7 k 8 r_rel 9 r2 10 threads
#  11 queries 12 runs 13 qps 14 qps_min 15 qps_max 16 ns 17 nodes 18 evals 19 found 20 recall
for d in photon uniform file; do
  [ -f "$Q" ] || break
  grep -q ",$d," "$Q" 2>/dev/null || continue
  series "$Q" "\$1==\"param\" && \$2==\"$d\" && \$10==1 && \$4!=\"flann_forest4\" && \$4!=\"brute\"" \
    '$6' '$13' '$4 " " $5'
  n=$(awk -F, -v d="$d" '$1=="param" && $2==d {print $3; exit}' "$Q")
  plot "$IMG/param_$d.png" "$d, n=$n, k=50, max radius finding ~50, 1 thread" \
    'kd-tree bucket B / octree capacity / FLANN leaf_max_size' 'queries per second' 1 1

  series "$Q" "\$1==\"radius\" && \$2==\"$d\"" \
    '($8=="inf" ? 16 : $8)' '$13' '$4 " " $5 " " $6'
  plot "$IMG/radius_$d.png" "$d, n=$n, k=50 (radius variants: all within r), 1 thread" \
    'maximum radius / radius finding 50 (16 = unlimited)' 'queries per second' 1 1 'set xrange [0.08:20]'

  series "$Q" "\$1==\"k\" && \$2==\"$d\"" '$7' '$13' '$4 " " $5 " " $6'
  plot "$IMG/k_$d.png" "$d, n=$n, unlimited radius, 1 thread" 'k' 'queries per second' 1 1

  series "$Q" "\$1==\"param\" && \$2==\"$d\" && \$10==1 && (\$4==\"flann_forest4\" || (\$4==\"kdtree\" && \$5==\"iterative\") || (\$4==\"flann_single\" && \$5==\"knn_batch\"))" \
    '$13' '$20' '($4=="flann_forest4" ? "flann_forest4 (checks 16..256)" : $4 " " $5 " (all B / leaf sizes)")'
  plot "$IMG/recall_$d.png" "$d, n=$n, k=50: recall against speed, 1 thread" \
    'queries per second' 'recall' 1 0 'set yrange [0:1.05]'
done

if [ -f "$Q" ] && [ -f "$B" ]; then
  series "$Q" '$1=="n" && $2=="photon"' '$3' '$13' '$4 " " $5 " " $6'
  plot "$IMG/n_photon.png" 'photon-like, k=50, max radius finding ~50, 1 thread' 'N (photons)' \
    'queries per second' 1 1
  # build.csv columns: 1 sweep 2 dist 3 n 4 index 5 param 6 build_s
  series "$B" '$1=="n" && $2=="photon"' '$3' '$6' '$4 " " $5'
  plot "$IMG/build_photon.png" 'photon-like: build time (median)' 'N (photons)' 'seconds' 1 1
fi

# knn_best.csv columns: 1 workload 2 n 3 queries 4 k 5 mode ... 15 ratio_flann
KB="$R/knn_best.csv"
if [ -f "$KB" ]; then
  for n in $(awk -F, 'NR > 1 {printf "%.0f\n", $2 / 1e6}' "$KB" | sort -un); do
    for mode in unlimited radius; do
      series "$KB" "int(\$2 / 1e6 + 0.5)==$n && \$5==\"$mode\"" '$4' '$15' '$1 " " $3'
      plot "$IMG/knn_ratio_${mode}_${n}M.png" "workload race, N=${n}M, $mode radius: kd-tree / FLANN best exact (1 = par), 1 thread" \
        'k' 'queries/s ratio' 1 0 'set yrange [0:*]; set arrow from graph 0,first 1 to graph 1,first 1 nohead dt 2; set arrow from graph 0,first 2 to graph 1,first 2 nohead dt 3'
    done
  done
fi

# estimate.csv columns: 1 region 2 estimator 3 bias 4 k ... ns_per_estimate, rms_rel_error
E="$R/estimate.csv"
if [ -f "$E" ]; then
  for region in interior edge; do
    series "$E" "\$1==\"$region\"" '$6' '$7' '$2 ($3=="none" || $3=="" ? "" : " bias=" $3)'
    plot "$IMG/estimate_$region.png" "uniform square, $region: k = 15, 50, 100, 500 along each line (k=15 labelled)" \
      'nanoseconds per estimate' 'RMS relative error' 1 1 "$(awk -F, -v r="$region" 'NR > 1 && $1 == r && $4 == 15 {
        printf "set label \"k=15\" at %s,%s offset 0.5,0.5 font \",7\"\n", $6, $7 }' "$E")" nosort
  done
fi
