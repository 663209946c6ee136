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
#
# The sources are photonmap/, render/ and the Makefile unless the caller sets CS_SOURCES
# (files and directories under ROOT, separated by spaces) and, for results kept among them,
# CS_EXCLUDE (one directory whose files never count). run-bench.sh, whose binaries are also
# made from bench/ and which writes bench/results:
#   CS_SOURCES="photonmap render bench Makefile" CS_EXCLUDE=bench/results
# The text names them: "... (N files in photonmap/, render/, bench/ or the Makefile)".

commit_stamp() { # ROOT BINARY...
  cs_root=$1
  shift
  if [ -n "${PM_BENCH_COMMIT:-}" ]; then
    printf '%s\n' "$PM_BENCH_COMMIT"
    return 0
  fi
  cs_src=${CS_SOURCES:-photonmap render Makefile}
  cs_ex=${CS_EXCLUDE:-}
  cs_head=$(git -C "$cs_root" rev-parse --short HEAD 2>/dev/null) || {
    echo "commit-stamp: $cs_root is not a git checkout; name the binaries' commit with PM_BENCH_COMMIT" >&2
    return 1
  }
  for cs_bin in "$@"; do
    cs_abs=$(cd "$(dirname "$cs_bin")" && pwd)/$(basename "$cs_bin")
    # shellcheck disable=SC2086 # cs_src is a list of paths
    cs_newer=$(cd "$cs_root" && find $cs_src -type f -newer "$cs_abs" 2>/dev/null |
      { if [ -n "$cs_ex" ]; then grep -v "^$cs_ex/" || true; else cat; fi; } | sort)
    if [ -n "$cs_newer" ]; then
      echo "commit-stamp: $cs_bin is older than $(printf '%s\n' "$cs_newer" | wc -l | tr -d ' ') source file(s) of the checkout ($(printf '%s\n' "$cs_newer" | head -3 | tr '\n' ' ' | sed 's/ $//')$([ "$(printf '%s\n' "$cs_newer" | wc -l)" -gt 3 ] && echo ', ...')), so it was not built from them; rebuild it (make), or name the commit it was built from with PM_BENCH_COMMIT" >&2
      return 1
    fi
  done
  # shellcheck disable=SC2086
  cs_dirty=$(git -C "$cs_root" status --porcelain -- $cs_src ${cs_ex:+":(exclude)$cs_ex"} 2>/dev/null | wc -l | tr -d ' ')
  if [ "$cs_dirty" -gt 0 ]; then
    # "photonmap/, render/ or the Makefile": directories with a slash, the last after "or".
    cs_n=0
    for cs_w in $cs_src; do cs_n=$((cs_n + 1)); done
    cs_i=0
    cs_names=
    for cs_w in $cs_src; do
      cs_i=$((cs_i + 1))
      if [ "$cs_w" = Makefile ]; then cs_it="the Makefile"
      elif [ -d "$cs_root/$cs_w" ]; then cs_it="$cs_w/"
      else cs_it=$cs_w; fi
      if [ "$cs_i" = 1 ]; then cs_names=$cs_it
      elif [ "$cs_i" = "$cs_n" ]; then cs_names="$cs_names or $cs_it"
      else cs_names="$cs_names, $cs_it"; fi
    done
    echo "$cs_head plus uncommitted changes in the sources ($cs_dirty file$([ "$cs_dirty" = 1 ] || echo s) in $cs_names)"
  else
    echo "$cs_head"
  fi
}

# measured_lines STAMP THREADS: the first lines of a measurement.txt (commit, date, machine, the
# load at the end, threads), as make-hard-scenes.sh and measure-gather-ceiling.sh write them.
measured_lines() {
  echo "commit $1"
  echo "date $(date -u '+%Y-%m-%d %H:%M UTC')"
  echo "machine $(nproc) cores, $(awk -F': ' '/model name/ { print $2; exit }' /proc/cpuinfo)"
  echo "load $(cut -d' ' -f1-3 /proc/loadavg) (1, 5, 15 min, at the end)"
  echo "threads $2"
}
