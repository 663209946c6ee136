#!/bin/sh
# check-layout.sh [ROOT [OBJDIR]]: the rules of render/'s layout (render/README.md), checked.
#
#   1. Stages in pipeline order: a file includes only its own stage and stages before it
#      (an include of a later stage is an import that runs back up).
#   2. No file over 600 lines.
#   3. No function over 120 lines (a function: a line at column 0 that ends in ") {", up to the
#      next "}" at column 0; the style of every file in render/).
#   4. No circle of includes among the headers (a.h includes b.h, which includes a.h, directly
#      or further round): each header stands on the ones it includes.
#   5. No circle of calls among render/'s files (a.c calls b.c, which calls a.c, directly or
#      further round; reading another file's global counts as a call): each file stands on the
#      ones it calls. Read from the build's object files with nm: a symbol a file's object
#      leaves undefined and another file's object defines is a call of that file. OBJDIR is the
#      objects of render/ (default ROOT/build/release/obj/render; render-mpi's are in it after
#      `make MPI=1 render-mpi`); an object whose source is gone is left out. Without objects
#      the rule is skipped with a note on stderr (it checks the last build: build first).
# What breaks a rule today is listed below as a known exception, each with its size, so the
# debt is visible and cannot grow: an exception that no longer applies is reported too, so the
# list only shrinks. Prints one line per violation; exit 1 if there is any, else 0.
root=${1:-.}
objdir=${2:-$root/build/release/obj/render}
case $objdir in /*) ;; *) objdir=$(pwd)/$objdir ;; esac
cd "$root/render" || exit 2
STAGES="base scene load photons guiding integrators photon_mapping image run app mpi"
# Known exceptions: "include FILE STAGE/HEADER", "file FILE MAXLINES", "func FILE NAME MAXLINES",
# one a line (none left: the list stays, for tests/test_layout.c to plant one in a copy).
EXCEPTIONS='
'
# One awk over every file (the checker must stay cheap: it runs in the test suite).
awk -v stages="$STAGES" -v ex="$EXCEPTIONS" '
  BEGIN {
    ns = split(stages, S, " "); for (i = 1; i <= ns; i++) rank[S[i]] = i
    n = split(ex, L, "\n")
    for (i = 1; i <= n; i++) {
      if (split(L[i], w, " ") < 3) continue
      if (w[1] == "include") inc_ok[w[2] " " w[3]] = 1
      if (w[1] == "file") file_lim[w[2]] = w[3]
      if (w[1] == "func") func_lim[w[2] " " w[3]] = w[4]
    }
  }
  FNR == 1 { if (prev != "") end_file(); prev = FILENAME; st = FILENAME; sub(/\/.*/, "", st); start = 0; pend = 0 }
  /^#include "[a-z_0-9]+\/[a-z_0-9]+\.h"/ {
    h = $2; gsub(/"/, "", h); is = h; sub(/\/.*/, "", is)
    if (is in rank) {
      if (rank[is] > rank[st]) {
        if ((FILENAME " " h) in inc_ok) seen_inc[FILENAME " " h] = 1
        else { printf "back-import: %s includes %s (stage %s comes after %s)\n", FILENAME, h, is, st; bad = 1 }
      }
    }
  }
  FILENAME ~ /\.h$/ && /^#include "[a-z_0-9\/]+\.h"/ {
    h = $2; gsub(/"/, "", h)
    if (h !~ /\//) { d = FILENAME; sub(/\/[^\/]*$/, "", d); h = d "/" h } # "x.h": beside the file
    if (!(FILENAME in hedge)) hdrs[++nh] = FILENAME
    hedge[FILENAME] = hedge[FILENAME] " " h
  }
  /^[A-Za-z_][^;=]*\(/ && !/^(typedef|struct|enum|union|static const|const)/ {
    name = $0; sub(/\(.*/, "", name); sub(/.*[ *]/, "", name); cand = FNR; pend = 1 }
  pend && /\) *\{ *$/ { start = cand; pend = 0; next }
  pend && /;/ && !/\(/ { pend = 0 }
  /^\}/ && start {
    len = FNR - start + 1; k = FILENAME " " name; l = (k in func_lim) ? func_lim[k] : 120
    if (len > l) { printf "long function: %s %s() has %d lines (limit %d)\n", FILENAME, name, len, l; bad = 1 }
    if ((k in func_lim) && len <= 120) { printf "stale exception: func %s %s (now %d lines)\n", FILENAME, name, len; bad = 1 }
    start = 0
  }
  { lines[FILENAME] = FNR }
  # rule 4: a depth-first walk of the headers; an include of a header still on the walk closes a circle
  function visit(v,   n, i, j, w, E, c) {
    color[v] = 1; path[++depth] = v
    n = split(hedge[v], E, " ")
    for (i = 1; i <= n; i++) {
      w = E[i]
      if (color[w] == 1) {
        for (j = depth; j > 0 && path[j] != w; j--) {}
        c = path[j]; for (j++; j <= depth; j++) c = c " -> " path[j]
        printf "include circle: %s -> %s\n", c, w; bad = 1
      } else if (!color[w]) visit(w)
    }
    color[v] = 2; depth--
  }
  function end_file() {
    l = (prev in file_lim) ? file_lim[prev] : 600
    if (lines[prev] > l) { printf "long file: %s has %d lines (limit %d)\n", prev, lines[prev], l; bad = 1 }
    if ((prev in file_lim) && lines[prev] <= 600) { printf "stale exception: file %s (now %d lines)\n", prev, lines[prev]; bad = 1 }
  }
  END {
    if (prev != "") end_file()
    for (i = 1; i <= nh; i++) if (!color[hdrs[i]]) visit(hdrs[i])
    for (k in inc_ok) if (!(k in seen_inc)) { printf "stale exception: include %s\n", k; bad = 1 }
    exit bad
  }' */*.c */*.h
bad=$?

# Rule 5: the objects of the sources that are here, sorted (so a circle is always named alike).
objs=$(for c in */*.c; do o=$objdir/${c%.c}.o; [ -f "$o" ] && printf '%s\n' "$o"; done)
if [ -z "$objs" ]; then
  echo "check-layout: rule 5 (no circle of calls) skipped: no objects of render/ in $objdir (build first)" >&2
  exit $bad
fi
# shellcheck disable=SC2086 # one object a word (the paths have no blanks: render/'s names do not)
nm -P -A $objs | awk -v dir="$objdir/" '
  { f = $1; sub(/:$/, "", f); if (index(f, dir) == 1) f = substr(f, length(dir) + 1); sub(/\.o$/, ".c", f)
    if (!(f in seen)) { seen[f] = 1; files[++nf] = f } }
  $3 == "U" { nu++; uf[nu] = f; us[nu] = $2 }
  $3 ~ /^[TDBRCGSVW]$/ { def[$2] = f }
  END {
    for (i = 1; i <= nu; i++) {
      if (!(us[i] in def) || def[us[i]] == uf[i]) continue
      k = uf[i] " " def[us[i]]; if (k in e) continue
      e[k] = 1; out[uf[i]] = out[uf[i]] " " def[us[i]]
    }
    for (i = 1; i <= nf; i++) if (!color[files[i]]) visit(files[i])
    exit bad
  }
  # a depth-first walk of the calls, as rule 4 walks the includes
  function visit(v,   n, i, j, w, E, c) {
    color[v] = 1; path[++depth] = v
    n = split(out[v], E, " ")
    for (i = 1; i <= n; i++) {
      w = E[i]
      if (color[w] == 1) {
        for (j = depth; j > 0 && path[j] != w; j--) {}
        c = path[j]; for (j++; j <= depth; j++) c = c " -> " path[j]
        printf "call circle: %s -> %s\n", c, w; bad = 1
      } else if (!color[w]) visit(w)
    }
    color[v] = 2; depth--
  }' || bad=1
exit $bad
