#!/bin/sh
# commit-stamp.sh: the commit stamp of a measurement, for the scripts that measure binaries and
# commit the results (mpi-scaling.sh, media-results.sh, media-time-error.sh). Sourced:
#
#   . "$here/scripts/commit-stamp.sh"
#   stamp=$(commit_stamp "$here" BINARY...) || exit 2     (before anything is written)
#
# git knows the checkout, not the binaries, and several people may work in one checkout, so
# the checkout's HEAD is the binaries' commit only if they were built from its sources
# (photonmap/, render/ and the Makefile). As scripts/run-bench.sh does:
# - PM_BENCH_COMMIT=TEXT: the stamp is TEXT, nothing is checked (binaries built from a clean
#   export of a commit, e.g. PM_BENCH_COMMIT="cd87fe2 (clean export)");
# - a source file newer than a binary (make would rebuild it): the binary was not built from
#   the checkout as it is; refused, with the files named on stderr (status 1): rebuild, or
#   name the binary's commit with PM_BENCH_COMMIT;
# - otherwise HEAD's short hash, plus " plus uncommitted changes in the sources (N files in
#   photonmap/, render/ or the Makefile)" when git status lists any there (the binaries were
#   built from them as they are now, which is not HEAD).
# Taken before the script writes its results, which are not sources, so they never count.

commit_stamp() { # ROOT BINARY...
  cs_root=$1
  shift
  if [ -n "${PM_BENCH_COMMIT:-}" ]; then
    printf '%s\n' "$PM_BENCH_COMMIT"
    return 0
  fi
  cs_head=$(git -C "$cs_root" rev-parse --short HEAD 2>/dev/null) || {
    echo "commit-stamp: $cs_root is not a git checkout; name the binaries' commit with PM_BENCH_COMMIT" >&2
    return 1
  }
  for cs_bin in "$@"; do
    cs_abs=$(cd "$(dirname "$cs_bin")" && pwd)/$(basename "$cs_bin")
    cs_newer=$(cd "$cs_root" && find photonmap render Makefile -type f -newer "$cs_abs" 2>/dev/null | sort)
    if [ -n "$cs_newer" ]; then
      echo "commit-stamp: $cs_bin is older than $(printf '%s\n' "$cs_newer" | wc -l | tr -d ' ') source file(s) of the checkout ($(printf '%s\n' "$cs_newer" | head -3 | tr '\n' ' ' | sed 's/ $//')$([ "$(printf '%s\n' "$cs_newer" | wc -l)" -gt 3 ] && echo ', ...')), so it was not built from them; rebuild it (make), or name the commit it was built from with PM_BENCH_COMMIT" >&2
      return 1
    fi
  done
  cs_dirty=$(git -C "$cs_root" status --porcelain -- photonmap render Makefile 2>/dev/null | wc -l | tr -d ' ')
  if [ "$cs_dirty" -gt 0 ]; then
    echo "$cs_head plus uncommitted changes in the sources ($cs_dirty file$([ "$cs_dirty" = 1 ] || echo s) in photonmap/, render/ or the Makefile)"
  else
    echo "$cs_head"
  fi
}
