#!/bin/sh
# remeasure-docs.sh: re-measure the measured sections of docs/ACCURACY.md, docs/IMPORT.md,
# docs/MEDIA.md, docs/MPI.md and docs/PROFILE.md on the binaries of the checkout, in one command, each
# section stamped with the binaries' commit (scripts/commit-stamp.sh) by the script that measures it.
#
#   sh scripts/remeasure-docs.sh [--budget-min N] [--build DIR] [--media-before COMMIT]
#                                [--only STEP,...] [--all] [--full] [--list] [--dry-run]
#
# Build first: `make -j2 all` and, for MPI, `make -j2 MPI=1 render-mpi` (the same BUILD
# directory: render-mpi is linked from render's objects). The steps, in order, each the
# quickest protocol that still measures what its section says (each section prints its
# protocol from its run's own measurement file):
#
#   accuracy     scripts/gen-accuracy-md.sh --run DIR (its defaults)  docs/ACCURACY.md
#   import       scripts/gen-import-md.sh --run DIR --reduced        docs/IMPORT.md "Scene import: measurements"
#   import_pbrt  scripts/gen-import-md.sh --run-pbrt DIR             docs/IMPORT.md "The pbrt-v3 Cornell box ..." (and its gallery)
#   media_fog    scripts/media-time-error.sh cornell_fog             docs/MEDIA.md "cornell_fog: the whole image"
#   media_vc     scripts/media-time-error.sh --reduced volumetric_caustic   "volumetric_caustic: the beam in the fog"
#   media_cost   scripts/media-cost.sh, 3 runs, on render built from `git archive COMMIT` (--media-before)
#                against DIR/render                                  "Cost: scenes without media"
#   mpi          scripts/mpi-scaling.sh --reps 1                     docs/MPI.md (its three sections);
#                only when DIR/render-mpi is built (said when skipped)
#   profile      scripts/profile-pm.sh --build DIR                  docs/PROFILE.md (needs perf)
#   import_ply   scripts/gen-import-md.sh --run-ply DIR              docs/IMPORT.md "PLY: our reader against libassimp"
#                (needs libassimp-dev)
#
# A step runs only when one of its sections is stale: a commit after the section's stamp, other
# than a merge, touched the sources its "Measured sources" line names (what the test
# docs_measured_sections_are_not_stale checks); --all runs them all. Steps whose sections are
# fresh are named as such.
#
# Each step prints the wall time and the CPU seconds it took. --budget-min N: before each step, the step is skipped
# (and named at the end) when the minutes already spent plus its expected minutes (the table
# EXPECT below: measured on an idle 2-core machine, or from CPU seconds measured on a busy one)
# would pass N. A failed step is reported and its files in docs/ are put back as they were; the
# others go on; the exit status is 1 when a step failed, else 0. --only runs the named steps.
# --list prints the steps and their expected minutes and exits; --dry-run says which steps
# would run (stale, within the budget) and measures nothing.
#
# --full: the scripts' full protocols instead (import at 64x64, the beam's 4096-spp path-traced
# run, which is what shows the 10x target by measurement rather than by extrapolation, and
# mpi-scaling.sh's 3 repetitions), with the expected minutes of EXPECT_FULL.
#
# --media-before COMMIT: the "before" binary of the media cost section, built here from a
# clean export of COMMIT (into a temporary directory, about 2 minutes on 2 cores); without it
# media_cost is skipped. Use the last commit before the media change the section is about.
# When COMMIT's photonmap/, render/ and Makefile are those of the binaries, the section says it
# is an A/A run (the measurement's own spread).
#
# Writes only into docs/ (the five documents and docs/accuracy, docs/import, docs/media,
# docs/mpi, docs/profile) and its own temporary directories (removed at the end).
set -eu
here=$(cd "$(dirname "$0")/.." && pwd)
B="$here/build/release"
budget=""
before=""
only=""
list=0
full=0
all=0
dry=0
while [ $# -gt 0 ]; do
  case "$1" in
    -h|--help) awk 'NR > 1 && /^#/ { sub(/^# ?/, ""); print; next } NR > 1 { exit }' "$0"; exit 0 ;;
    --budget-min) [ $# -ge 2 ] || { echo "remeasure-docs: --budget-min needs a number of minutes" >&2; exit 2; }
                  case "$2" in ''|*[!0-9.]*) echo "remeasure-docs: --budget-min '$2' is not a number" >&2; exit 2 ;; esac
                  budget=$2; shift 2 ;;
    --build) [ $# -ge 2 ] || { echo "remeasure-docs: --build needs a directory" >&2; exit 2; }
             B=$(cd "$2" && pwd) || exit 2; shift 2 ;;
    --media-before) [ $# -ge 2 ] || { echo "remeasure-docs: --media-before needs a commit" >&2; exit 2; }
                    before=$2; shift 2 ;;
    --only) [ $# -ge 2 ] || { echo "remeasure-docs: --only needs step names" >&2; exit 2; }
            only=$(echo "$2" | tr ',' ' '); shift 2 ;;
    --list) list=1; shift ;;
    --all) all=1; shift ;;
    --full) full=1; shift ;;
    --dry-run) dry=1; shift ;;
    *) echo "remeasure-docs: unknown argument '$1' (see --help)" >&2; exit 2 ;;
  esac
done

STEPS="accuracy import import_pbrt media_fog media_vc media_cost mpi profile import_ply"
# Expected minutes of each step on an idle 2-core machine, estimated from each step's CPU
# seconds as measured by this script on 2026-12-04 at load 14-17 (the machine was never idle):
# accuracy 10 CPU-s on one thread; import 48 and import_pbrt 46 (renders on 2 threads);
# media_fog 85 and media_vc 66 (one thread); media_cost 74 (the before build on 2 threads, then
# 41 on one); mpi 74 (2 ranks or threads); profile 12; import_ply 16 (33 s at load 13). Rounded up, since wall time on 2 cores is at least CPU / 2.
EXPECT="accuracy 0.5
import 1
import_pbrt 1
media_fog 1.5
media_vc 1.5
media_cost 2.5
mpi 2
profile 0.5
import_ply 1"
# With --full, the steps whose protocol changes (the others as above).
# (import: 4x the pixels of its renders; media_vc: + the 4096-spp run, about 150 CPU-s; mpi:
# 3 repetitions of the timing and partitioned runs)
EXPECT_FULL="import 2.5
media_vc 4
mpi 4"
expect() { [ $full = 0 ] || { echo "$EXPECT_FULL" | awk -v s="$1" '$1 == s { print $2; f = 1 } END { exit !f }' && return 0; }
  echo "$EXPECT" | awk -v s="$1" '$1 == s { print $2 }'; }
for s in $only; do
  case " $STEPS " in *" $s "*) ;; *) echo "remeasure-docs: unknown step '$s' (steps: $STEPS)" >&2; exit 2 ;; esac
done
if [ $list = 1 ]; then
  tot=0
  for s in $STEPS; do echo "$s $(expect "$s") min"; tot=$(awk -v a=$tot -v b="$(expect "$s")" 'BEGIN { print a + b }'); done
  echo "total $tot min"
  exit 0
fi

for p in "$B/render" "$B/bench_estimate"; do
  [ -x "$p" ] || { echo "remeasure-docs: $p not built (make -j2 all)" >&2; exit 2; }
done
# The build directory as the documents name it: relative to the checkout when inside it.
cd "$here"
case $B in "$here"/*) B=${B#"$here"/} ;; esac
. "$here/scripts/commit-stamp.sh"
stamp=$(commit_stamp "$here" "$B/render") || exit 2
echo "remeasure-docs: binaries of $B, stamp $stamp"
cd "$here"
T=$(mktemp -d "${TMPDIR:-/tmp}/remeasure-docs.XXXXXX")
trap 'rm -rf "$T"' EXIT
# Interrupted: the step under way puts its files back, as a failed one does.
cur=""
restore() { for f in $(files_of "$1"); do rm -rf "$f"; [ ! -e "$T/save/$f" ] || cp -R "$T/save/$f" "$f"; done; }
trap 'if [ -n "$cur" ]; then echo "remeasure-docs: interrupted in $cur; its files are put back" >&2; restore "$cur"; fi; exit 130' INT TERM
t0=$(date +%s)
ran=""
skipped=""
failed=""

# The sections a step measures: "DOC|HEADING" (HEADING empty: every section of DOC).
sections_of() {
  case $1 in
    accuracy) echo "docs/ACCURACY.md|Accuracy of the radiance estimates" ;;
    import) echo "docs/IMPORT.md|Scene import: measurements" ;;
    import_pbrt) echo "docs/IMPORT.md|The pbrt-v3 Cornell box against the same box in our format" ;;
    import_ply) echo "docs/IMPORT.md|PLY: our reader against libassimp" ;;
    media_fog) echo "docs/MEDIA.md|cornell_fog: the whole image" ;;
    media_vc) echo "docs/MEDIA.md|volumetric_caustic: the beam in the fog" ;;
    media_cost) echo "docs/MEDIA.md|Cost: scenes without media" ;;
    mpi) echo "docs/MPI.md|" ;;
    profile) echo "docs/PROFILE.md|" ;;
  esac
}
# Whether a step's sections are stale (status 0) or all fresh (1), as the test judges them:
# the stamp and the sources of each section's "Measured sources (stamp S): `a` `b`" line, and
# git rev-list --no-merges S..HEAD -- a b. A section without the line, or a stamp that is no
# commit of this history, is stale.
is_stale() {
  sec=$(sections_of "$1"); doc=${sec%%|*}; head=${sec#*|}
  awk -v want="$head" '/^#/ { h = $0; sub(/^#+ */, "", h) }
    /^Measured sources \(stamp [0-9a-f]+\): / { s = $0; sub(/^Measured sources \(stamp /, "", s); st = s
      sub(/\).*/, "", st); sub(/^[^:]*: /, "", s); gsub(/`/, "", s); if (want == "" || h == want) { print st " " s; f = 1 } }
    END { if (!f) print "none" }' "$doc" > "$T/secs"
  while read -r st src; do
    [ "$st" != none ] || return 0
    git cat-file -e "$st^{commit}" 2>/dev/null || return 0
    # shellcheck disable=SC2086
    [ "$(git rev-list --no-merges --count "$st..HEAD" -- $src)" = 0 ] || return 0
  done < "$T/secs"
  return 1
}
# CPU seconds (user + system) of the finished children so far (the shell's `times`).
childcpu() { times > "$T/times"; awk 'NR == 2 { t = 0; for (i = 1; i <= 2; i++) { v = $i; m = v; sub(/m.*/, "", m); sub(/^[0-9]+m/, "", v); sub(/s$/, "", v); t += 60 * m + v } print t }' "$T/times"; }
# The files a step rewrites, saved before it and put back when it fails.
files_of() {
  case $1 in
    accuracy) echo "docs/ACCURACY.md docs/accuracy" ;;
    import*) echo "docs/IMPORT.md docs/import" ;;
    media_*) echo "docs/MEDIA.md docs/media" ;;
    mpi) echo "docs/MPI.md docs/mpi" ;;
    profile) echo "docs/PROFILE.md docs/profile" ;;
  esac
}
run_step() { # name
  case $1 in
    accuracy) sh scripts/gen-accuracy-md.sh --run "$B" ;;
    import) sh scripts/gen-import-md.sh --run "$B" $([ $full = 1 ] || echo --reduced) ;;
    import_pbrt) sh scripts/gen-import-md.sh --run-pbrt "$B" ;;
    import_ply) sh scripts/gen-import-md.sh --run-ply "$B" ;;
    media_fog) PM_BUILD_DIR="$B" sh scripts/media-time-error.sh cornell_fog ;;
    media_vc) PM_BUILD_DIR="$B" sh scripts/media-time-error.sh $([ $full = 1 ] || echo --reduced) volumetric_caustic ;;
    media_cost)
      mkdir -p "$T/before"
      git -C "$here" archive "$before" | tar -x -C "$T/before"
      echo "remeasure-docs: building render of $before in a temporary directory" >&2
      make -C "$T/before" -j2 render > "$T/before.log" 2>&1 || { tail -20 "$T/before.log" >&2; return 1; }
      bl="$(git -C "$here" rev-parse --short "$before")-export"
      al=$(echo "$stamp" | cut -d' ' -f1)
      same=no
      case $stamp in *uncommitted*) ;; *) git -C "$here" diff --quiet "$before" HEAD -- photonmap render Makefile && same=yes ;; esac
      COST_SAME_SOURCES=$same COST_NOTE="Before ($bl) is render built from a clean export of $before (git archive); after is $B/render at $stamp. Both with the Makefile's default flags." \
        sh scripts/media-cost.sh "$T/before/build/release/render" "$bl" "$B/render" "$al" 3 &&
      sh scripts/gen-media-md.sh ;;
    mpi) PM_BUILD_DIR="$B" sh scripts/mpi-scaling.sh --reps $([ $full = 1 ] && echo 3 || echo 1) ;;
    profile) sh scripts/profile-pm.sh --build "$B" ;;
  esac
}
for s in $STEPS; do
  if [ -n "$only" ]; then case " $only " in *" $s "*) ;; *) continue ;; esac; fi
  if [ $s = mpi ] && [ ! -x "$B/render-mpi" ]; then
    echo "remeasure-docs: mpi skipped: $B/render-mpi is not built (make -j2 MPI=1 render-mpi); docs/MPI.md stays as it was"
    skipped="$skipped mpi(no render-mpi)"
    continue
  fi
  if [ $s = media_cost ] && [ -n "$before" ] && ! git -C "$here" rev-parse -q --verify "$before^{commit}" >/dev/null; then
    echo "remeasure-docs: media_cost skipped: --media-before $before is not a commit"
    skipped="$skipped media_cost(bad --media-before)"
    continue
  fi
  if [ $s = media_cost ] && [ -z "$before" ]; then
    echo "remeasure-docs: media_cost skipped: no --media-before COMMIT"
    skipped="$skipped media_cost(no --media-before)"
    continue
  fi
  if [ $all = 0 ] && ! is_stale $s; then
    echo "remeasure-docs: $s skipped: its section is not stale (--all runs it anyway)"
    skipped="$skipped $s(fresh)"
    continue
  fi
  if [ $s = profile ] && ! command -v perf >/dev/null 2>&1; then
    echo "remeasure-docs: profile skipped: perf is not installed"
    skipped="$skipped profile(no perf)"
    continue
  fi
  if [ $s = import_ply ] && [ ! -f /usr/include/assimp/cimport.h ]; then
    echo "remeasure-docs: import_ply skipped: libassimp-dev is not installed"
    skipped="$skipped import_ply(no assimp)"
    continue
  fi
  now=$(date +%s)
  if [ -n "$budget" ] && awk -v u=$((now - t0)) -v e="$(expect $s)" -v b="$budget" 'BEGIN { exit !(u / 60 + e > b) }'; then
    echo "remeasure-docs: $s skipped: $(( (now - t0) / 60 )) min spent + $(expect $s) min expected > budget $budget min"
    skipped="$skipped $s(budget)"
    continue
  fi
  if [ $dry = 1 ]; then
    echo "remeasure-docs: $s would run (expected $(expect $s) min on an idle machine)"
    ran="$ran $s(dry)"
    t0=$((t0 - $(expect $s | awk '{ printf "%d", $1 * 60 }')))
    continue
  fi
  echo "remeasure-docs: $s (expected $(expect $s) min on an idle machine; load $(cut -d' ' -f1-3 /proc/loadavg))"
  rm -rf "$T/save"; mkdir -p "$T/save"
  for f in $(files_of $s); do mkdir -p "$T/save/$(dirname "$f")"; [ ! -e "$f" ] || cp -R "$f" "$T/save/$f"; done
  s0=$(date +%s)
  childcpu > "$T/c0"; c0=$(cat "$T/c0")
  cur=$s
  if (run_step $s) > "$T/$s.log" 2>&1; then
    cur=""
    childcpu > "$T/c1"; c1=$(cat "$T/c1")
    ran="$ran $s($(( $(date +%s) - s0 ))s)"
    echo "remeasure-docs: $s done in $(( $(date +%s) - s0 )) s wall, $(awk -v a="$c0" -v b="$c1" 'BEGIN { printf "%.0f", b - a }') CPU-s (load now $(cut -d' ' -f1 /proc/loadavg))"
  else
    echo "remeasure-docs: $s FAILED after $(( $(date +%s) - s0 )) s; its files are put back:" >&2
    tail -15 "$T/$s.log" >&2
    restore $s
    failed="$failed $s"
    cur=""
  fi
done
echo "remeasure-docs: $(( ($(date +%s) - t0) ))s in all; ran:${ran:- none}; skipped:${skipped:- none}; failed:${failed:- none}"
echo "remeasure-docs: not covered: docs/BENCHMARKS.md (scripts/gen-benchmarks-md.sh), docs/RESULTS.md (make results)"
[ -z "$failed" ]
