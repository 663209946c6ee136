# reference-check.sh: sourced by make-equal-time.sh, make-hard-scenes.sh, make-survey.sh and
# measure-gather-ceiling.sh,
# which judge renders against path-traced references made by make-reference.sh (NAME.pfm and
# its NAME.info of "key value" lines).
#   ref_info DIR NAME KEY     prints KEY's value from DIR/NAME.info
#   ref_state DIR NAME SCENE  prints "missing" (no DIR/NAME.pfm or .info), "stale" (SCENE's
#                             SHA-256 is not the one the reference was rendered from) or "ok"
#   ref_require PROG DIR NAME SCENE [HINT]   (below)
ref_info() { awk -v k="$3" '$1 == k { print $2 }' "$1/$2.info"; }
ref_state() {
  if [ ! -f "$1/$2.pfm" ] || [ ! -f "$1/$2.info" ]; then echo missing
  elif [ "$(ref_info "$1" "$2" scene_sha256)" != "$(sha256sum "$3" | cut -d' ' -f1)" ]; then echo stale
  else echo ok; fi
}
# ref_require PROG DIR NAME SCENE [HINT]: exits with status 2 and PROG's message when NAME's
# reference is missing (HINT: how to make it) or stale.
ref_require() {
  case $(ref_state "$2" "$3" "$4") in
    missing) echo "$1: no reference for $3 in $2${5:+: $5}" >&2; exit 2 ;;
    stale) echo "$1: $4 changed since its reference was rendered" >&2; exit 2 ;;
  esac
}
