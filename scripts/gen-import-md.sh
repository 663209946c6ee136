#!/bin/sh
# gen-import-md.sh: write docs/IMPORT.md from the scene-import measurements in docs/import/.
#
#   scripts/gen-import-md.sh [--out FILE] [RESULTS_DIR]
#   scripts/gen-import-md.sh --run BUILD_DIR [--reduced]
#   scripts/gen-import-md.sh --run-ply BUILD_DIR
#   scripts/gen-import-md.sh --run-pbrt BUILD_DIR
#
# RESULTS_DIR (default docs/import) holds what a measurement found: comparisons.csv (section,
# region, series, rel_mean_pct, pixels: the relative difference of mean radiance of two renders
# over the pixels of a region, empty with 0 pixels when the region is not in view), load.csv
# (the medians of three loads of a 1M-triangle OBJ) and measurement.txt (commit, date, build
# directory, load average and CPUs of the run, and its settings: resolution, samples per pixel,
# the OBJ sphere's segments and triangles, the number of loads). Every figure and stamp in the document comes
# from those files, never from the checkout or the clock at generation time, so the same files
# always give the same document (tests/test_docs.c regenerates it from the committed files and
# compares). --out FILE writes FILE instead of docs/IMPORT.md (- for standard output).
#
# --run BUILD_DIR measures first, with BUILD_DIR/render, into docs/import: the renders and
# comparisons of the import proofs at 64x64 (the tests run the same comparisons at 32x32), and
# the time to load a 1M-triangle OBJ and build its BVH (three runs; wall-clock from render's
# statistics, CPU time from /usr/bin/time, and the machine's load average, since the machine
# may be shared). Work files go to a temporary directory that is removed at the end. Takes
# 10-20 minutes. --reduced: the same renders at 32x32 (the tests' size; a quarter of the
# pixels, so about a quarter of the time) with the same samples per pixel; measurement.txt
# says so in its "protocol" line, which the document prints.
#
# The commits of --run, --run-ply and --run-pbrt are the binary's (scripts/commit-stamp.sh):
# HEAD, "plus uncommitted changes in the sources" when git status lists any in photonmap/,
# render/ or the Makefile; refused when a source file is newer than BUILD_DIR/render (rebuild
# it); PM_BENCH_COMMIT=TEXT stamps TEXT instead.
#
# --run-ply BUILD_DIR measures only the PLY section: it builds scripts/ply-load-time.c against
# BUILD_DIR's objects and Debian's libassimp-dev, which write PLY files of a 1M-triangle grid
# (ASCII, binary LE and BE, triangle strips, degenerate quads) into a temporary directory and
# load each with our reader and with assimp (medians of 3), into docs/import/ply.csv and
# ply_measurement.txt. A minute or two. The section is left out while ply.csv is missing.
#
# --run-pbrt BUILD_DIR measures only the pbrt section: data/pbrt/cornell_box.pbrt against
# data/scenes/cornell_box.json at 64x64 (path 1024 spp, pm 256 spp, different seeds; regions
# from the JSON scene's --mode objects), into docs/import/pbrt.csv and pbrt_measurement.txt,
# and the gallery: 128x128 PNGs (path, 256 spp) of each importer's Cornell box beside ours in
# docs/import/gallery/. A few minutes. The section is left out while pbrt.csv is missing.
set -eu
here=$(cd "$(dirname "$0")/.." && pwd)
doc="$here/docs/IMPORT.md"
res="$here/docs/import"
run=""
runply=""
runpbrt=""
reduced=0
while [ $# -gt 0 ]; do
  case "$1" in
    -h|--help) awk 'NR > 1 && /^#/ { sub(/^# ?/, ""); print; next } NR > 1 { exit }' "$0"; exit 0 ;;
    --out) [ $# -ge 2 ] || { echo "gen-import-md: --out needs a file" >&2; exit 2; }
           doc=$2; shift 2 ;;
    --run) [ $# -ge 2 ] || { echo "gen-import-md: --run needs a build directory" >&2; exit 2; }
           run=$2; shift 2 ;;
    --run-ply) [ $# -ge 2 ] || { echo "gen-import-md: --run-ply needs a build directory" >&2; exit 2; }
           runply=$2; shift 2 ;;
    --run-pbrt) [ $# -ge 2 ] || { echo "gen-import-md: --run-pbrt needs a build directory" >&2; exit 2; }
           runpbrt=$2; shift 2 ;;
    --reduced) reduced=1; shift ;;
    -*) echo "gen-import-md: unknown option '$1' (see --help)" >&2; exit 2 ;;
    *) res=$1; shift ;;
  esac
done

# The settings of a measurement: --run uses them and writes them into measurement.txt, and the
# document reads them from there (so it describes the run that made the files, whatever these
# lines say later).
RES=64                # pixels per side of every comparison render
CORNELL_PATH_SPP=1024 # the two Cornell boxes, path tracing
CORNELL_PM_SPP=256    # and photon mapping
SPHERE_SEG="128 64"   # the OBJ sphere's segments (around, pole to pole)
SPHERE_SPP=1024       # the sphere renders (path tracing)
WATER_PATH_SPP=4096   # the water caustic's reference
WATER_PM_SPP=256      # and its photon-mapped render
LOAD_RUNS=3           # loads of the 1M-triangle OBJ (medians)
PROTOCOL=full
if [ "$reduced" = 1 ]; then
  RES=32
  PROTOCOL="reduced: every comparison at 32x32 pixels (the full protocol: 64x64), the same samples per pixel"
fi
. "$here/scripts/commit-stamp.sh"

if [ -n "$run" ]; then
BUILD=$run
R="$BUILD/render"
[ -x "$R" ] || { echo "gen-import-md: $R not found (make BUILD=$BUILD render)" >&2; exit 2; }
COMMIT=$(commit_stamp "$here" "$R") || exit 2
T=$(mktemp -d)
trap 'rm -rf "$T"' EXIT
S="$here/data/scenes"
SIZE="--width $RES --height $RES --quiet"
cd "$here"

# One row of comparisons.csv: section, region, series, then rel_mean of A against B (percent)
# and the pixel count, optionally over a mask id and a rectangle (empty and 0 when the region
# is not in view).
row() {
    sec=$1 reg=$2 ser=$3
    shift 3
    "$R" --compare "$@" 2>/dev/null | awk -v s="$sec" -v r="$reg" -v t="$ser" '
        $1 == "rel_mean" { m = sprintf("%.6f", 100 * $2) } $1 == "pixels" { n = $2 }
        END { if (m == "") { m = ""; n = 0 } printf "%s,%s,%s,%s,%d\n", s, r, t, m, n }' >> "$T/comparisons.csv"
}

echo "rendering the Cornell boxes..." >&2
"$R" $S/cornell_rect.json $SIZE --mode objects --spp 16 --hdr "$T/ids_c.pfm" >/dev/null
"$R" $S/cornell_tungsten.json $SIZE --mode path --spp $CORNELL_PATH_SPP --seed 3 --hdr "$T/ct_path.pfm" >/dev/null 2>&1
"$R" $S/cornell_rect.json $SIZE --mode path --spp $CORNELL_PATH_SPP --seed 4 --hdr "$T/cr_path.pfm" >/dev/null
"$R" $S/cornell_tungsten.json $SIZE --mode pm --spp $CORNELL_PM_SPP --seed 3 --hdr "$T/ct_pm.pfm" >/dev/null 2>&1
"$R" $S/cornell_rect.json $SIZE --mode pm --spp $CORNELL_PM_SPP --seed 4 --hdr "$T/cr_pm.pfm" >/dev/null

echo "rendering the spheres..." >&2
sh scripts/gen-mesh.sh sphere $SPHERE_SEG 100 278 150 300 > "$T/sphere.obj"
cat > "$T/sphere_scene.in" <<'EOF'
{"camera": {"eye": [278, 273, -800], "look_at": [278, 273, 0], "fov_deg": 39.3, "width": 64, "height": 64},
 "materials": {"w": {"type": "lambert", "reflectance": 0.7}, "r": {"type": "lambert", "reflectance": [0.6, 0.1, 0.1]},
               "light": {"type": "lambert", "reflectance": 0, "emission": 15}},
 "objects": [
  {"type": "quad", "vertices": [[0, 0, 0], [0, 0, 560], [556, 0, 560], [556, 0, 0]], "material": "w"},
  {"type": "quad", "vertices": [[0, 0, 560], [0, 550, 560], [556, 550, 560], [556, 0, 560]], "material": "w"},
  {"type": "quad", "vertices": [[556, 0, 0], [556, 0, 560], [556, 550, 560], [556, 550, 0]], "material": "r"},
  {"type": "quad", "vertices": [[0, 550, 0], [556, 550, 0], [556, 550, 560], [0, 550, 560]], "material": "w"},
  {"type": "quad", "vertices": [[200, 549, 200], [350, 549, 200], [350, 549, 350], [200, 549, 350]], "material": "light"},
  OBJECT]}
EOF
sed 's|OBJECT|{"type": "sphere", "center": [278, 150, 300], "radius": 100, "material": "w"}|' "$T/sphere_scene.in" > "$T/analytic.json"
sed 's|OBJECT|{"type": "mesh", "file": "sphere.obj", "smooth": true, "material": "w"}|' "$T/sphere_scene.in" > "$T/mesh.json"
"$R" "$T/analytic.json" $SIZE --spp $SPHERE_SPP --seed 5 --hdr "$T/analytic.pfm" >/dev/null
"$R" "$T/mesh.json" $SIZE --spp $SPHERE_SPP --seed 6 --hdr "$T/mesh.pfm" >/dev/null
"$R" "$T/analytic.json" $SIZE --mode objects --spp 16 --hdr "$T/ids_s.pfm" >/dev/null

echo "rendering the water caustic..." >&2
"$R" $S/water_caustic.json $SIZE --mode path --spp $WATER_PATH_SPP --seed 8 --hdr "$T/w_path.pfm" >/dev/null
"$R" $S/water_caustic.json $SIZE --mode pm --spp $WATER_PM_SPP --seed 9 --hdr "$T/w_pm.pfm" >/dev/null
"$R" $S/water_caustic.json $SIZE --mode objects --spp 16 --hdr "$T/ids_w.pfm" >/dev/null

echo "section,region,series,rel_mean_pct,pixels" > "$T/comparisons.csv"
row tungsten image path "$T/ct_path.pfm" "$T/cr_path.pfm"
row tungsten image pm "$T/ct_pm.pfm" "$T/cr_pm.pfm"
for id in 1 2 3 4 5 7 8; do
    case $id in 1) n=floor;; 2) n=ceiling;; 3) n="back wall";; 4) n="red wall";; 5) n="green wall";;
                7) n="short block";; 8) n="tall block";; esac
    row tungsten "$n" path "$T/ct_path.pfm" "$T/cr_path.pfm" --mask "$T/ids_c.pfm" --id $id
    row tungsten "$n" pm "$T/ct_pm.pfm" "$T/cr_pm.pfm" --mask "$T/ids_c.pfm" --id $id
done
row sphere image obj "$T/mesh.pfm" "$T/analytic.pfm"
for id in 1 2 3 4 6; do
    case $id in 1) n=floor;; 2) n="back wall";; 3) n="red wall";; 4) n=ceiling;; 6) n=sphere;; esac
    row sphere "$n" obj "$T/mesh.pfm" "$T/analytic.pfm" --mask "$T/ids_s.pfm" --id $id
done
row water image pm "$T/w_pm.pfm" "$T/w_path.pfm"
for id in 1 2 3 4 5 7; do
    case $id in 1) n=floor;; 2) n=ceiling;; 3) n="back wall";; 4) n="red wall";; 5) n="blue wall";; 7) n=water;; esac
    row water "$n" pm "$T/w_pm.pfm" "$T/w_path.pfm" --mask "$T/ids_w.pfm" --id $id
done
row water "caustic (floor below the slab)" pm "$T/w_pm.pfm" "$T/w_path.pfm" --mask "$T/ids_w.pfm" --id 1 --rect $(echo 20 36 24 16 | awk -v r=$RES '{ printf "%d %d %d %d", $1 * r / 64, $2 * r / 64, $3 * r / 64, $4 * r / 64 }')

echo "timing a 1M-triangle OBJ..." >&2
sh scripts/gen-mesh.sh sphere 1002 500 100 278 150 300 > "$T/big.obj"
sed 's|OBJECT|{"type": "mesh", "file": "big.obj", "smooth": true, "material": "w"}|' "$T/sphere_scene.in" > "$T/big.json"
: > "$T/times.txt"
for run in $(seq "$LOAD_RUNS"); do
    /usr/bin/time -f "cpu %U %S" "$R" "$T/big.json" --width 8 --height 8 --spp 1 --threads 1 --quiet \
        --hdr "$T/big.pfm" > "$T/big.out" 2> "$T/big.err"
    awk '/^Scene /{ ntri = $3 } /Mesh loading  / { ml = $(NF-1) } /BVH build  / { bvh = $(NF-1) }
         /Mesh loading \(CPU\)/ { mlc = $(NF-1) } /BVH build \(CPU/ { bvhc = $(NF-1) }
         END { printf "%s %s %s %s %s ", ntri, ml, bvh, mlc, bvhc }' "$T/big.out" >> "$T/times.txt"
    awk '/^cpu /{ printf "%.2f\n", $2 + $3 }' "$T/big.err" >> "$T/times.txt"
done
LOAD=$(cut -d' ' -f1-3 /proc/loadavg 2>/dev/null || echo "?")
NCPU=$(nproc 2>/dev/null || echo "?")
med() { sort -n | awk '{ a[NR] = $1 } END { print a[int((NR + 1) / 2)] }'; }
NTRI=$(head -1 "$T/times.txt" | cut -d' ' -f1)
ML=$(cut -d' ' -f2 "$T/times.txt" | med)
BVH=$(cut -d' ' -f3 "$T/times.txt" | med)
MLC=$(cut -d' ' -f4 "$T/times.txt" | med)
BVHC=$(cut -d' ' -f5 "$T/times.txt" | med)
CPU=$(cut -d' ' -f6 "$T/times.txt" | med)
BYTES=$(wc -c < "$T/big.obj")
mkdir -p "$res"
cp "$T/comparisons.csv" "$res/comparisons.csv"
{
    echo "triangles,obj_bytes,mesh_loading_cpu_s,bvh_build_cpu_s,process_cpu_s,mesh_loading_wall_s,bvh_build_wall_s"
    echo "$NTRI,$BYTES,$MLC,$BVHC,$CPU,$ML,$BVH"
} > "$res/load.csv"
{
    echo "commit $COMMIT"
    echo "date $(date -u '+%Y-%m-%d %H:%M UTC')"
    echo "build $BUILD"
    echo "protocol $PROTOCOL"
    echo "load $LOAD"
    echo "cpus $NCPU"
    echo "resolution $RES"
    echo "cornell_path_spp $CORNELL_PATH_SPP"
    echo "cornell_pm_spp $CORNELL_PM_SPP"
    echo "sphere_segments $SPHERE_SEG"
    echo "sphere_triangles $(awk '/^f / { t += NF - 3 } END { print t }' "$T/sphere.obj")"
    echo "sphere_spp $SPHERE_SPP"
    echo "water_path_spp $WATER_PATH_SPP"
    echo "water_pm_spp $WATER_PM_SPP"
    echo "load_runs $LOAD_RUNS"
    echo "load_obj_triangles $(awk '/^f / { t += NF - 3 } END { print t }' "$T/big.obj")"
} > "$res/measurement.txt"
fi

if [ -n "$runply" ]; then
O="$runply/obj/render"
for o in load/mesh load/obj load/ply load/wo3 scene/shapes base/sampling; do
    [ -f "$O/$o.o" ] || { echo "gen-import-md: $O/$o.o not found (make BUILD=$runply render)" >&2; exit 2; }
done
[ -f /usr/include/assimp/cimport.h ] || { echo "gen-import-md: libassimp-dev is not installed (apt-get install libassimp-dev)" >&2; exit 2; }
T=$(mktemp -d)
trap 'rm -rf "$T"' EXIT
cc -O2 -std=c11 -D_POSIX_C_SOURCE=200809L -I"$here/render" -I"$here" -I"$here/photonmap" "$here/scripts/ply-load-time.c" \
    "$O/load/mesh.o" "$O/load/obj.o" "$O/load/ply.o" "$O/load/wo3.o" "$O/scene/shapes.o" "$O/base/sampling.o" \
    -lassimp -lm -o "$T/ply-load-time"
echo "timing PLY loads (ours and assimp)..." >&2
"$T/ply-load-time" "$T" 708 3 > "$T/ply.csv"   # grid side, loads (ply_measurement.txt: loads)
mkdir -p "$res"
cp "$T/ply.csv" "$res/ply.csv"
{
    echo "commit $(git -C "$here" rev-parse --short HEAD 2>/dev/null || echo unknown)$(git -C "$here" diff --quiet HEAD -- render 2>/dev/null || echo ' (with uncommitted changes to render/)')"
    echo "date $(date -u '+%Y-%m-%d %H:%M UTC')"
    echo "build $runply"
    echo "assimp $(dpkg-query -W -f='${Version}' libassimp-dev 2>/dev/null || echo '?')"
    echo "loads 3"
    echo "load $(cut -d' ' -f1-3 /proc/loadavg 2>/dev/null || echo '?')"
    echo "cpus $(nproc 2>/dev/null || echo '?')"
} > "$res/ply_measurement.txt"
fi

if [ -n "$runpbrt" ]; then
R="$runpbrt/render"
[ -x "$R" ] || { echo "gen-import-md: $R not found (make BUILD=$runpbrt render)" >&2; exit 2; }
T=$(mktemp -d)
trap 'rm -rf "$T"' EXIT
S="$here/data/scenes"
PB="$here/data/pbrt/cornell_box.pbrt"
PB_RES=64 PB_PATH_SPP=1024 PB_PM_SPP=256 GAL_RES=128 GAL_SPP=256
SZ="--width $PB_RES --height $PB_RES --quiet"
PB_COMMIT=$(commit_stamp "$here" "$R") || exit 2
echo "rendering the pbrt Cornell box and ours..." >&2
"$R" $S/cornell_box.json $SZ --mode objects --spp 16 --hdr "$T/ids.pfm" >/dev/null
"$R" "$PB" $SZ --mode path --spp $PB_PATH_SPP --seed 3 --hdr "$T/pb_path.pfm" >/dev/null
"$R" $S/cornell_box.json $SZ --mode path --spp $PB_PATH_SPP --seed 4 --hdr "$T/js_path.pfm" >/dev/null
"$R" "$PB" $SZ --mode pm --spp $PB_PM_SPP --seed 3 --hdr "$T/pb_pm.pfm" >/dev/null
"$R" $S/cornell_box.json $SZ --mode pm --spp $PB_PM_SPP --seed 4 --hdr "$T/js_pm.pfm" >/dev/null
prow() {
    reg=$1 ser=$2
    shift 2
    "$R" --compare "$@" 2>/dev/null | awk -v r="$reg" -v t="$ser" '
        $1 == "rel_mean" { m = sprintf("%.6f", 100 * $2) } $1 == "pixels" { n = $2 }
        END { if (m == "") { m = ""; n = 0 } printf "pbrt,%s,%s,%s,%d\n", r, t, m, n }' >> "$T/pbrt.csv"
}
echo "section,region,series,rel_mean_pct,pixels" > "$T/pbrt.csv"
for ser in path pm; do prow image $ser "$T/pb_$ser.pfm" "$T/js_$ser.pfm"; done
for id in 1 2 3 4 5 6 7 8 9 10 11 12 13 14 15 16; do
    case $id in 1) n=floor;; 2) n=ceiling;; 3) n="back wall";; 4) n="green wall";; 5) n="red wall";; 6) n=light;;
                7|8|9|10|11) n="short block";; *) n="tall block";; esac
    [ $id = 7 ] || [ $id = 12 ] || [ $id -lt 7 ] || continue
    ids="--id $id"
    [ $id = 7 ] && ids="--id 7 --id 8 --id 9 --id 10 --id 11"
    [ $id = 12 ] && ids="--id 12 --id 13 --id 14 --id 15 --id 16"
    for ser in path pm; do prow "$n" $ser "$T/pb_$ser.pfm" "$T/js_$ser.pfm" --mask "$T/ids.pfm" $ids; done
done
echo "rendering the gallery..." >&2
mkdir -p "$res/gallery"
G="--width $GAL_RES --height $GAL_RES --quiet --mode path --spp $GAL_SPP --seed 1"
"$R" $S/cornell_box.json $G -o "$res/gallery/cornell_box_json.png" >/dev/null
"$R" "$PB" $G -o "$res/gallery/cornell_box_pbrt.png" >/dev/null
"$R" $S/cornell_rect.json $G -o "$res/gallery/cornell_rect_json.png" >/dev/null
"$R" $S/cornell_tungsten.json $G -o "$res/gallery/cornell_tungsten.png" >/dev/null 2>&1
# each gallery scene's load time (reading, converting, BVH: render's "Scene loading and BVH
# build", one thread), the median of 3 loads
gl() { for i in 1 2 3; do "$R" "$1" --width 8 --height 8 --spp 1 --mode path --threads 1 --hdr "$T/gl.pfm" 2>/dev/null |
       awk '/Scene loading and BVH build/ && !/CPU/ { print $(NF-1) }'; done | sort -g | sed -n 2p; }
GL_BOX_JSON=$(gl $S/cornell_box.json); GL_BOX_PBRT=$(gl "$PB")
GL_RECT_JSON=$(gl $S/cornell_rect.json); GL_TUNGSTEN=$(gl $S/cornell_tungsten.json)
mkdir -p "$res"
cp "$T/pbrt.csv" "$res/pbrt.csv"
{
    echo "commit $PB_COMMIT"
    echo "date $(date -u '+%Y-%m-%d %H:%M UTC')"
    echo "build $runpbrt"
    echo "resolution $PB_RES"
    echo "path_spp $PB_PATH_SPP"
    echo "pm_spp $PB_PM_SPP"
    echo "gallery_resolution $GAL_RES"
    echo "gallery_spp $GAL_SPP"
    echo "gallery_load_s $GL_BOX_JSON $GL_BOX_PBRT $GL_RECT_JSON $GL_TUNGSTEN"
    echo "load $(cut -d' ' -f1-3 /proc/loadavg 2>/dev/null || echo '?')"
    echo "cpus $(nproc 2>/dev/null || echo '?')"
    if cmp -s "$res/gallery/cornell_box_json.png" "$res/gallery/cornell_box_pbrt.png"; then echo "gallery_same yes"; else echo "gallery_same no"; fi
} > "$res/pbrt_measurement.txt"
fi

for f in comparisons.csv load.csv measurement.txt; do
  [ -f "$res/$f" ] || { echo "gen-import-md: $res/$f missing: run scripts/gen-import-md.sh --run BUILD_DIR" >&2; exit 2; }
done
m() { awk -v k="$1" '$1 == k { sub(/^[^ ]+ /, ""); print; f = 1; exit } END { exit !f }' "$res/measurement.txt" ||
      { echo "gen-import-md: $res/measurement.txt has no '$1' (measured by an older --run)" >&2; echo "?"; }; }
C="$res/comparisons.csv"
# The cell of section $1, region $2, series $3: "+0.12% (302 px)", or "no pixel".
cell() {
  awk -F, -v s="$1" -v r="$2" -v t="$3" '
    $1 == s && $2 == r && $3 == t { found = 1; if ($5 + 0 == 0) print "no pixel"; else printf "%+.2f%% (%d px)\n", $4, $5 }
    END { if (!found) print "–" }' "$C"
}
# The regions of section $1 in file order, one per line.
regions() { awk -F, -v s="$1" 'NR > 1 && $1 == s && !seen[$2]++ { print $2 }' "$C"; }
load() { awk -F, -v k="$1" 'NR == 1 { for (i = 1; i <= NF; i++) col[$i] = i; next } NR == 2 { print $col[k] }' "$res/load.csv"; }

out=$doc
[ "$doc" = - ] || out="$doc.tmp"
{
echo "# Scene import: measurements"
echo
echo "Measured by \`scripts/gen-import-md.sh --run $(m build)\` on $(m date) at $(m commit);"
echo "generated from \`docs/import/\` by \`scripts/gen-import-md.sh\`: do not edit by hand. The tests"
echo "in \`tests/test_render_import.c\` check the same comparisons at 32x32 with fewer samples; here"
echo "they run at $(m resolution)x$(m resolution). A figure is the relative difference of mean radiance, first image against"
echo "the second (the reference), over the pixels that see the object (from \`render --mode objects\`)."
pr=$(awk '$1 == "protocol" { sub(/^[^ ]+ /, ""); print; exit }' "$res/measurement.txt")
[ -z "$pr" ] || echo "Protocol: $pr."
echo "Measured sources (stamp $(m commit | cut -d' ' -f1)): \`photonmap/\` \`render/\` \`Makefile\`"
echo
echo "## The Tungsten Cornell box against the same box in our format"
echo
echo "\`data/scenes/cornell_tungsten.json\` (converted on load) against \`data/scenes/cornell_rect.json\`"
echo "(written by hand), different seeds, so the differences include the two renders' noise."
echo
echo "| region | path tracing, $(m cornell_path_spp) spp | photon mapping, $(m cornell_pm_spp) spp |"
echo "|---|---|---|"
regions tungsten | while IFS= read -r n; do
    echo "| $n | $(cell tungsten "$n" path) | $(cell tungsten "$n" pm) |"
done
echo
echo "## A tessellated OBJ sphere against the analytic sphere"
echo
echo "A UV sphere of $(m sphere_segments | sed 's/ / x /') segments ($(m sphere_triangles | sed -e :a -e 's/\([0-9]\)\([0-9]\{3\}\)\($\|,\)/\1,\2\3/;ta') triangles, smooth, the file's normals) against a"
echo "sphere of the same radius; path tracing, $(m sphere_spp) spp, different seeds."
echo
echo "| region | OBJ against analytic |"
echo "|---|---|"
regions sphere | while IFS= read -r n; do echo "| $n | $(cell sphere "$n" obj) |"; done
echo
echo "## Water caustic: photon mapping against path tracing"
echo
echo "\`data/scenes/water_caustic.json\`: a glass slab with a wavy top (\`data/meshes/water.obj\`, from"
echo "\`scripts/gen-mesh.sh water 48 20 80 20 80 40 50 6\`) under an area light. Photon mapping"
echo "$(m water_pm_spp) spp against path tracing $(m water_path_spp) spp. The caustic is the floor below the slab (a rectangle"
echo "of the floor's pixels)."
echo
echo "| region | pm against path |"
echo "|---|---|"
regions water | while IFS= read -r n; do echo "| $n | $(cell water "$n" pm) |"; done
echo
echo "## Loading 1M triangles"
echo
echo "A scene of $(load triangles) triangles, all but $(( $(load triangles) - $(m load_obj_triangles) )) of them a UV sphere OBJ ($(load obj_bytes) bytes, with a"
echo "normal per vertex, smooth), loaded by \`render\` (one thread) $(m load_runs | sed 's/^3$/three/') times; medians. The times"
echo "are render's statistics: \`Time/Mesh loading\` (reading and parsing the file, transforming it,"
echo "making its smooth normals) and \`Time/BVH build\`, each as wall-clock and as CPU time; and the"
echo "whole process's CPU time (user + system, with scene setup and an 8x8 1-spp render), from"
echo "/usr/bin/time. Load average during the runs: $(m load) on $(m cpus) CPUs; on a busy machine the"
echo "wall clock runs ahead of the CPU time, which is the figure to compare."
echo
echo "| | mesh loading | BVH build | whole process |"
echo "|---|---|---|---|"
echo "| CPU time | $(load mesh_loading_cpu_s) s | $(load bvh_build_cpu_s) s | $(load process_cpu_s) s |"
echo "| wall clock | $(load mesh_loading_wall_s) s | $(load bvh_build_wall_s) s | |"
if [ -f "$res/pbrt.csv" ] && [ -f "$res/pbrt_measurement.txt" ]; then
Q="$res/pbrt.csv"
qm() { awk -v k="$1" '$1 == k { sub(/^[^ ]+ /, ""); print; exit }' "$res/pbrt_measurement.txt"; }
# a setting of the run, or (measured before --run-pbrt recorded it) the value it then used
qs() { v=$(qm "$1"); echo "${v:-$2}"; }
qcell() {
  awk -F, -v r="$1" -v t="$2" '
    $2 == r && $3 == t { found = 1; if ($5 + 0 == 0) print "no pixel"; else printf "%+.2f%% (%d px)\n", $4, $5 }
    END { if (!found) print "–" }' "$Q"
}
echo
echo "## The pbrt-v3 Cornell box against the same box in our format"
echo
echo "Measured by \`scripts/gen-import-md.sh --run-pbrt $(qm build)\` on $(qm date) at $(qm commit); load"
echo "average $(qm load) on $(qm cpus) CPUs. \`data/pbrt/cornell_box.pbrt\` (a hand translation into"
echo "pbrt-v3's syntax: named materials, an Include for the walls, the light in an AttributeBegin"
echo "block, \`Scale -1 1 1\` before \`LookAt\` as pbrt's own Cornell scenes do) against"
echo "\`data/scenes/cornell_box.json\`, $(qs resolution 64)x$(qs resolution 64), different seeds, so the differences are the renders'"
echo "noise; the regions come from the JSON scene's \`--mode objects\` (the converted scene keeps"
echo "pbrt's picture, which here is ours)."
echo "Measured sources (stamp $(qm commit | cut -d' ' -f1)): \`photonmap/\` \`render/\` \`Makefile\` \`data/pbrt/\`"
echo
echo "| region | path tracing, $(qs path_spp 1024) spp | photon mapping, $(qs pm_spp 256) spp |"
echo "|---|---|---|"
awk -F, 'NR > 1 && !seen[$2]++ { print $2 }' "$Q" | while IFS= read -r n; do
    echo "| $n | $(qcell "$n" path) | $(qcell "$n" pm) |"
done
echo
echo "## Gallery"
echo
echo "Each importer's scene beside the same scene written in our format ($(qs gallery_resolution 128)x$(qs gallery_resolution 128), path tracing,"
echo "$(qs gallery_spp 256) spp, same seed; rendered by \`--run-pbrt\` with the table above)."
if [ "$(qm gallery_same)" = yes ]; then
echo "The pbrt file's PNG and the JSON scene's are the same bytes: the converted scene has the"
echo "JSON scene's triangles in the JSON scene's order, so with one seed every path is the same;"
echo "the linear images differ only by the rounding of the camera's fov (the file's 39.307648"
echo "degrees against the JSON's focal length and sensor), which \`tests/test_render_import_pbrt.c\`"
echo "bounds at 16x16 (relative rmse below 1e-6, path and pm)."
fi
echo
echo "| ours (JSON) | imported |"
echo "|---|---|"
echo "| ![cornell_box.json](import/gallery/cornell_box_json.png) \`cornell_box.json\` | ![cornell_box.pbrt](import/gallery/cornell_box_pbrt.png) \`data/pbrt/cornell_box.pbrt\` (pbrt-v3) |"
echo "| ![cornell_rect.json](import/gallery/cornell_rect_json.png) \`cornell_rect.json\` | ![cornell_tungsten.json](import/gallery/cornell_tungsten.png) \`cornell_tungsten.json\` (Tungsten) |"
if [ -n "$(qm gallery_load_s)" ]; then
# load times: render's "Scene loading and BVH build" (read, convert, BVH; one thread), median of 3
set -- $(qm gallery_load_s)
echo "| load: $1 s | load: $2 s (read, converted, BVH) |"
echo "| load: $3 s | load: $4 s (read, converted, BVH) |"
echo
echo "Load times: render's \`Time/Scene loading and BVH build\` (reading the file, converting it, the"
echo "BVH; one thread), the median of 3 loads, as printed (to the millisecond)."
fi
fi
if [ -f "$res/ply.csv" ] && [ -f "$res/ply_measurement.txt" ]; then
P="$res/ply.csv"
pm() { awk -v k="$1" '$1 == k { sub(/^[^ ]+ /, ""); print; exit }' "$res/ply_measurement.txt"; }
# field $3 (triangles or cpu_s) of file $1, reader $2
pv() { awk -F, -v f="$1" -v r="$2" -v c="$3" 'NR == 1 { for (i = 1; i <= NF; i++) col[$i] = i; next }
       $1 == f && $3 == r { print $col[c] }' "$P"; }
echo
echo "## PLY: our reader against libassimp"
echo
echo "Measured by \`scripts/gen-import-md.sh --run-ply $(pm build)\` on $(pm date) at $(pm commit), with"
echo "Debian's libassimp-dev $(pm assimp) (its C API, \`aiImportFile\` with \`aiProcess_Triangulate\`). Load average"
# The grid's side and the collapsed quads, from the construction's expected counts (2 side²
# triangles; the degenerate file 2 per collapsed quad fewer).
side=$(awk -v t="$(pv grid_le.ply ours triangles_expected)" 'BEGIN { printf "%d", sqrt(t / 2) + 0.5 }')
ncol=$(( ($(pv grid_le.ply ours triangles_expected) - $(pv grid_degenerate_le.ply ours triangles_expected)) / 2 ))
loads=$(pm loads); [ -n "$loads" ] || loads=3
echo "$(pm load) on $(pm cpus) CPUs. \`scripts/ply-load-time.c\` writes a grid of $side x $side quads"
echo "($(pv grid_le.ply ours triangles_expected | sed -e :a -e 's/\([0-9]\)\([0-9]\{3\}\)\($\|,\)/\1,\2\3/;ta') triangles; vertices with a normal, an RGB colour and a confidence; faces of 4"
echo "corners) in each encoding, the same grid as triangle strips (one per row), and the grid with"
echo "every 100th quad collapsed to zero area; each file is loaded by our \`mesh_load\` and by assimp,"
echo "$loads times each, and the table gives the median process CPU time of one load and the"
echo "triangles returned. The expected count is the construction's (2 x $side^2, less the collapsed"
echo "quads' 2 x $ncol in the last file)."
# the objects --run-ply links (its loop above), and the timing program
echo "Measured sources (stamp $(pm commit | cut -d' ' -f1)): $(for f in load/mesh load/obj load/ply load/wo3 scene/shapes base/sampling; do printf '`render/%s.c` ' $f; done)\`scripts/ply-load-time.c\`"
echo
echo "| file | bytes | expected triangles | ours: triangles | ours: CPU s | assimp: triangles | assimp: CPU s |"
echo "|---|---|---|---|---|---|---|"
awk -F, 'NR > 1 && !seen[$1]++ { print $1 }' "$P" | while IFS= read -r f; do
    echo "| $f | $(pv "$f" ours bytes) | $(pv "$f" ours triangles_expected) | $(pv "$f" ours triangles) | $(pv "$f" ours cpu_s) | $(pv "$f" assimp triangles) | $(pv "$f" assimp cpu_s) |"
done
echo
# "close" within 20%, else which is faster and by how much: a sentence that follows the CSV.
vs() { awk -v a="$1" -v b="$2" 'BEGIN { q = a / b
  if (q > 0.8 && q < 1.25) print "the two are close"
  else if (q < 1) printf "ours is %.2fx as fast\n", b / a
  else printf "assimp is %.2fx as fast\n", a / b }'; }
echo "Decision: we keep our own reader (\`render/load/ply.c\`) and do not link"
echo "assimp. By correctness: assimp returned $(pv grid_strips_le.ply assimp triangles) triangles for the"
echo "$(pv grid_strips_le.ply ours triangles_expected) of the triangle-strip file (ours: $(pv grid_strips_le.ply ours triangles)), and it returned"
echo "$(pv grid_degenerate_le.ply assimp triangles) for the $(pv grid_degenerate_le.ply ours triangles_expected) non-degenerate triangles of the last file (ours: $(pv grid_degenerate_le.ply ours triangles); ours skips and counts"
echo "zero-area faces, as the OBJ and wo3 readers do). By time: little-endian, $(vs "$(pv grid_le.ply ours cpu_s)" "$(pv grid_le.ply assimp cpu_s)")"
echo "($(pv grid_le.ply ours cpu_s) s against $(pv grid_le.ply assimp cpu_s) s); big-endian, $(vs "$(pv grid_be.ply ours cpu_s)" "$(pv grid_be.ply assimp cpu_s)") ($(pv grid_be.ply ours cpu_s) s against $(pv grid_be.ply assimp cpu_s) s);"
echo "ASCII, $(vs "$(pv grid_ascii.ply ours cpu_s)" "$(pv grid_ascii.ply assimp cpu_s)") (ours $(pv grid_ascii.ply ours cpu_s) s against $(pv grid_ascii.ply assimp cpu_s) s). Our times include the degeneracy pass and the checks every error message needs"
echo "(file:line or byte offset, counts against the bytes left before allocating). Keeping our"
echo "reader also keeps render/'s libraries to cJSON, libpng and OpenEXRCore (assimp brings"
echo "libdraco, minizip and a C++ runtime) and gives PLY errors in the same form as OBJ and wo3."
fi
} > "$out"
if [ "$doc" != - ]; then
  mv "$out" "$doc"
  echo "wrote $doc" >&2
fi
