# measured-table.sh: sourced by gen-equal-time-md.sh and gen-hard-scenes-md.sh, which read the same
# measurement.txt keys. measured_table DIR "SCENES" prints a section's "Measured sources" line and
# the table of its run (commit, date, machine, load, each scene's reference) from
# DIR/measurement.txt.
# Their --readme modes: readme_doc SCRIPT ARGS runs the generator into the temp file $tmpd (and
# makes $tmpr for the block), with the document's stamp in $stampline; readme_put START END
# replaces README.md's lines between the line that starts with START and the one that starts with
# END by $tmpr ($here: the source tree).
readme_doc() {
  tmpd=$(mktemp)
  tmpr=$(mktemp)
  trap 'rm -f "$tmpd" "$tmpr"' EXIT
  sh "$@" > "$tmpd"
  stampline=$(grep -m1 '^Measured sources (stamp ' "$tmpd" | sed 's/^Measured sources (stamp \([^)]*\)).*/\1/')
}
readme_put() {
  awk -v block="$tmpr" -v a="$1" -v b="$2" '
    index($0, a) == 1 { print; while ((getline l < block) > 0) print l; skip = 1; next }
    index($0, b) == 1 { skip = 0 }
    !skip { print }' "$here/README.md" > "$here/README.md.tmp"
  mv "$here/README.md.tmp" "$here/README.md"
}
measured_key() { awk -v k="$2" '$1 == k { sub(/^[^ ]+ /, ""); print; exit }' "$1/measurement.txt"; }
measured_table() {
  echo "Measured sources (stamp $(measured_key "$1" commit | cut -d' ' -f1)): \`photonmap/\` \`render/\` \`Makefile\`"
  echo
  echo "| | |"
  echo "|---|---|"
  echo "| commit | $(measured_key "$1" commit) |"
  echo "| date | $(measured_key "$1" date) |"
  echo "| machine | $(measured_key "$1" machine) |"
  echo "| load during the run | $(measured_key "$1" load) |"
  for s in $2; do echo "| reference $s | path tracing, $(measured_key "$1" "ref_$s") |"; done
}
