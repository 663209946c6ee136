#!/bin/sh
# same-images.sh: do two render binaries give the same images of every shipped scene? For a
# change meant to keep the images (a refactor, a file moved): build the commit before it and
# the one after, then
#
#   scripts/same-images.sh OLD_RENDER NEW_RENDER [MODE ...]      modes: default "pm path"
#
# renders data/scenes/*.json with each binary at 32x32, 4 spp, seed 1, 2 threads, and compares
# the PFM files byte for byte. Prints one line per scene and mode ("same" or "DIFF") and exits
# 1 if any image differs or a render fails, 0 if all are the same. The images are written to a
# temporary directory, removed at the end. SI_SCENES: scene names instead of all.
set -eu
here=$(cd "$(dirname "$0")/.." && pwd)
case "${1:-}" in
  -h|--help|"") awk 'NR > 1 && /^#/ { sub(/^# ?/, ""); print; next } NR > 1 { exit }' "$0"; [ -n "${1:-}" ]; exit $? ;;
esac
old=$1 new=${2:?usage: same-images.sh OLD_RENDER NEW_RENDER [MODE ...]}
shift 2
[ $# -gt 0 ] || set -- pm path
for b in "$old" "$new"; do [ -x "$b" ] || { echo "same-images: $b is not a program" >&2; exit 2; }; done
scenes=${SI_SCENES:-$(for f in "$here"/data/scenes/*.json; do basename "$f" .json; done)}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
bad=0
for name in $scenes; do
  for mode in "$@"; do
    for side in old new; do
      eval "bin=\$$side"
      if ! "$bin" "$here/data/scenes/$name.json" --mode "$mode" --width 32 --height 32 --spp 4 --seed 1 \
          --threads 2 --quiet --hdr "$work/$side.pfm" -o "$work/$side.png" > /dev/null 2> "$work/err"; then
        echo "$name $mode: the $side binary failed: $(head -c 300 "$work/err")"
        bad=1
        continue 2
      fi
    done
    if cmp -s "$work/old.pfm" "$work/new.pfm"; then echo "$name $mode same"; else echo "$name $mode DIFF"; bad=1; fi
  done
done
exit $bad
