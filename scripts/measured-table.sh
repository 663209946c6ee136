# measured-table.sh: sourced by gen-equal-time-md.sh and gen-hard-scenes-md.sh, which read the same
# measurement.txt keys. measured_table DIR "SCENES" prints a section's "Measured sources" line and
# the table of its run (commit, date, machine, load, each scene's reference) from
# DIR/measurement.txt.
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
