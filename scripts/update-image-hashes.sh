#!/bin/sh
# update-image-hashes.sh: rewrite tests/data/image_hashes.txt, the table of image hashes that
# the tests render_images_keep_their_hashes and render_images_same_on_one_thread
# (tests/test_render_images.c) check, from the render program of a build:
#
#   scripts/update-image-hashes.sh [BUILD_DIR]        default: build/release
#
# Renders every shipped scene (data/scenes/*.json) in --mode pm and --mode path, 16x16, 4 spp,
# seed 1, 2 threads, with small photon maps (the ARGS below: the plan's own photon counts would
# take minutes), and writes one row per render: scene, mode, width, height, spp and the SHA-256
# of the linear image (--hdr X.pfm, whose bytes are the image's floats). The table's "args"
# line keeps the options common to every row, so the test renders exactly what the table says.
#
# A commit that changes images on purpose runs this script and says so in its message (which
# scenes and modes changed: this script prints them); a commit that should not change them
# (a refactor, a file moved) leaves the table as it is, and the test fails if an image moved.
# Prints each changed, new or dropped row and a summary; exits 1 (the table untouched) if a
# render fails, 2 on bad usage. The images go to a temporary directory, removed at the end.
set -eu
here=$(cd "$(dirname "$0")/.." && pwd)
case "${1:-}" in
  -h|--help) awk 'NR > 1 && /^#/ { sub(/^# ?/, ""); print; next } NR > 1 { exit }' "$0"; exit 0 ;;
esac
build=${1:-$here/build/release}
bin=$build/render
[ -x "$bin" ] || { echo "update-image-hashes: $bin is not a program (build it: make all)" >&2; exit 2; }
table=$here/tests/data/image_hashes.txt
ARGS="--seed 1 --pm global_photons=10000 --pm caustic_photons=10000 --pm volume_photons=5000 \
--pm volume_caustic_photons=5000"
W=16 H=16 SPP=4 THREADS=2
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
{
  echo "# image_hashes.txt: the SHA-256 of the linear image (render --hdr X.pfm) of every shipped"
  echo "# scene in --mode pm and --mode path, rendered small with the options of the args line,"
  echo "# --threads $THREADS, and a row's mode, --width, --height and --spp. Written by"
  echo "# scripts/update-image-hashes.sh; checked by tests/test_render_images.c. A commit that"
  echo "# changes images on purpose regenerates it and says so in its message."
  echo "args $ARGS"
  echo "# scene mode width height spp sha256"
} > "$work/table"
for f in "$here"/data/scenes/*.json; do
  name=$(basename "$f" .json)
  for mode in pm path; do
    # shellcheck disable=SC2086 # ARGS is a list of words
    if ! "$bin" "$f" --mode "$mode" --width $W --height $H --spp $SPP --threads $THREADS $ARGS \
        --quiet --hdr "$work/img.pfm" -o "$work/img.png" > /dev/null 2> "$work/err"; then
      echo "update-image-hashes: $name --mode $mode failed: $(head -c 300 "$work/err")" >&2
      exit 1
    fi
    echo "$name $mode $W $H $SPP $(sha256sum "$work/img.pfm" | cut -d' ' -f1)" >> "$work/table"
  done
done
# What changed, for the commit message.
old=$table
[ -f "$old" ] || { old=$work/none; : > "$old"; }
awk 'FILENAME == ARGV[1] { if ($0 !~ /^#/ && $1 != "args") was[$1 " " $2] = $0; next }
     $0 ~ /^#/ || $1 == "args" { next }
     { k = $1 " " $2; if (!(k in was)) { print "new: " $0; n++ } else if (was[k] != $0) { print "changed: " $0; n++ }
       seen[k] = 1; rows++ }
     END { for (k in was) if (!(k in seen)) { print "dropped: " was[k]; n++ }
           printf "%d rows, %d changed, new or dropped\n", rows, n }' "$old" "$work/table"
if [ -f "$table" ] && [ "$(sed -n '/^args /p' "$table")" != "$(sed -n '/^args /p' "$work/table")" ]; then
  echo "the args line changed: every row is rendered with the new options"
fi
mkdir -p "$(dirname "$table")"
cp "$work/table" "$table.tmp"
mv "$table.tmp" "$table"
