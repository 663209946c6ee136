#!/bin/sh
# profile-pm.sh: where `render --mode pm` spends its render phase, measured with perf, into
# docs/profile/ and docs/PROFILE.md.
#
#   sh scripts/profile-pm.sh [--build DIR]          measure, then write docs/PROFILE.md
#   sh scripts/profile-pm.sh --gen [--out FILE] [RESULTS_DIR]   only write the document
#
# For cornell_box and cornell_spheres at 96x96, 16 spp, one thread (the settings of the hand
# measurement this replaces), `perf record -F 499 --call-graph dwarf,16384` of DIR/render
# (default build/release) in pm mode and in path mode (64 spp). A perf sample of the render
# phase is one with `render_tile` on its stack; it goes to the first of these callers found
# going up from the leaf: irradiance lookups (`side_cache_lookup_local`), caustic estimates
# (`caustics_at`), shadow-map queries (`shadow_map_says`), shadow rays (`scene_visible`), other
# rays (`scene_intersect`), `camera_ray`, else "other". The render's own statistics give the
# rays it counted (camera + indirect + shadow), its emission-only rays, irradiance lookups and
# caustic estimates. Writes docs/profile/profile.csv (scene, mode, key, value),
# docs/profile/top.csv (scene, mode, function, samples: the render phase's top functions by
# own samples) and docs/profile/measurement.txt (commit of the binary by
# scripts/commit-stamp.sh, date, machine, load, perf version, settings). Every figure of the
# document comes from those files. About a minute on an idle machine (perf's CPU samples do
# not depend much on the load). Needs perf (linux-perf) and perf_event_paranoid <= 2.
# Work files go to a temporary directory.
set -eu
here=$(cd "$(dirname "$0")/.." && pwd)
B="$here/build/release"
res="$here/docs/profile"
doc="$here/docs/PROFILE.md"
gen=0
while [ $# -gt 0 ]; do
  case "$1" in
    -h|--help) awk 'NR > 1 && /^#/ { sub(/^# ?/, ""); print; next } NR > 1 { exit }' "$0"; exit 0 ;;
    --build) [ $# -ge 2 ] || { echo "profile-pm: --build needs a directory" >&2; exit 2; }
             B=$2; shift 2 ;;
    --gen) gen=1; shift ;;
    --out) [ $# -ge 2 ] || { echo "profile-pm: --out needs a file" >&2; exit 2; }
           doc=$2; shift 2 ;;
    -*) echo "profile-pm: unknown option '$1' (see --help)" >&2; exit 2 ;;
    *) res=$1; shift ;;
  esac
done
RES=96 SPP=16 PATH_SPP=64 HZ=499
SCENES="cornell_box cornell_spheres"
CATS="side_cache_lookup_local caustics_at shadow_map_says scene_visible scene_intersect camera_ray"

if [ $gen = 0 ]; then
  [ -x "$B/render" ] || { echo "profile-pm: $B/render not built (make)" >&2; exit 2; }
  command -v perf >/dev/null 2>&1 || { echo "profile-pm: perf not found (apt-get install linux-perf)" >&2; exit 2; }
  . "$here/scripts/commit-stamp.sh"
  commit=$(commit_stamp "$here" "$B/render") || exit 2
  T=$(mktemp -d "${TMPDIR:-/tmp}/profile-pm.XXXXXX")
  trap 'rm -rf "$T"' EXIT
  load0=$(cut -d' ' -f1-3 /proc/loadavg)
  echo "scene,mode,key,value" > "$T/profile.csv"
  echo "scene,mode,function,samples" > "$T/top.csv"
  for scene in $SCENES; do
    for mode in pm path; do
      spp=$SPP; [ $mode = path ] && spp=$PATH_SPP
      echo "profile-pm: $scene, $mode, $spp spp" >&2
      perf record -q -F $HZ --call-graph dwarf,16384 -o "$T/p.data" "$B/render" "$here/data/scenes/$scene.json" \
        --mode $mode --width $RES --height $RES --spp $spp --threads 1 --quiet -o "$T/x.png" > "$T/log" 2> "$T/err" ||
        { cat "$T/err" "$T/log" >&2; exit 1; }
      perf script -i "$T/p.data" -F comm,tid,ip,sym 2>/dev/null > "$T/script.txt"
      # One sample: a header line, then its frames leaf first, then a blank line.
      awk -v s="$scene" -v m="$mode" -v cats="$CATS" -v top="$T/top.csv" '
        BEGIN { nc = split(cats, c, " "); for (i = 1; i <= nc; i++) iscat[c[i]] = 1 }
        function flush(   i, rt, cat) {
          if (!nf) return
          total++; rt = 0
          for (i = 1; i <= nf; i++) if (f[i] == "render_tile") { rt = i; break }
          if (rt) {
            render++; own[f[1]]++; cat = "other"
            for (i = 1; i < rt; i++) if (f[i] in iscat) { cat = f[i]; break }
            n[cat]++
          }
          nf = 0 }
        /^[^ \t]/ { flush(); next }
        /^[ \t]*$/ { flush(); next }
        { sym = $2; for (i = 3; i <= NF; i++) if ($i != "(inlined)") sym = sym " " $i
          sub(/\..*/, "", sym); f[++nf] = sym }
        END { flush()
          printf "%s,%s,perf_samples_all,%d\n%s,%s,perf_samples_render,%d\n", s, m, total, s, m, render
          for (i = 1; i <= nc; i++) printf "%s,%s,share_%s,%d\n", s, m, c[i], n[c[i]]
          printf "%s,%s,share_other,%d\n", s, m, n["other"]
          for (k in own) printf "%s,%s,%s,%d\n", s, m, k, own[k] | "sort -t, -k4,4nr | head -5 >> \"" top "\"" }' \
        "$T/script.txt" >> "$T/profile.csv"
      awk -v s="$scene" -v m="$mode" '
        function v(name) { return stat[name] + 0 }
        { line = $0; sub(/^ +/, "", line); val = $NF; sub(/ +[0-9.]+( s)?$/, "", line); if ($NF ~ /^[0-9]+$/) stat[line] = val }
        END { printf "%s,%s,samples,%d\n", s, m, v("Samples")
              printf "%s,%s,rays_counted,%d\n", s, m, v("Camera rays") + v("Indirect rays") + v("Shadow rays")
              printf "%s,%s,emission_only_rays,%d\n", s, m, v("Emission-only camera rays")
              printf "%s,%s,irradiance_lookups,%d\n", s, m, v("Irradiance lookups")
              printf "%s,%s,caustic_estimates,%d\n", s, m, v("Caustic estimates") }' "$T/log" >> "$T/profile.csv"
    done
  done
  mkdir -p "$res"
  cp "$T/profile.csv" "$T/top.csv" "$res/"
  {
    echo "commit $commit"
    echo "date $(date -u '+%Y-%m-%d %H:%M UTC')"
    echo "machine $(nproc) cores, $(sed -n 's/^model name[^:]*: //p' /proc/cpuinfo | head -1)"
    echo "load $load0 before, $(cut -d' ' -f1-3 /proc/loadavg) after"
    echo "perf $(perf --version 2>/dev/null)"
    echo "hz $HZ"
    echo "resolution $RES"
    echo "spp $SPP"
    echo "path_spp $PATH_SPP"
    echo "threads 1"
  } > "$res/measurement.txt"
fi

for f in profile.csv top.csv measurement.txt; do
  [ -f "$res/$f" ] || { echo "profile-pm: $res/$f missing: run scripts/profile-pm.sh" >&2; exit 2; }
done
ms() { awk -v k="$1" '$1 == k { sub(/^[^ ]+ /, ""); print; exit }' "$res/measurement.txt"; }
pv() { awk -F, -v s="$1" -v m="$2" -v k="$3" '$1 == s && $2 == m && $3 == k { print $4; f = 1 } END { if (!f) print 0 }' "$res/profile.csv"; }
hz=$(ms hz)
if [ "$doc" = - ]; then out=$(mktemp); else out="$doc.tmp"; fi
{
echo "# Profile of the photon mapper's camera sample"
echo
echo "Generated by \`scripts/profile-pm.sh\` from \`docs/profile/\`; do not edit by hand. Where"
echo "\`render --mode pm\` spends its render phase, measured with \`perf record -F $hz --call-graph dwarf\`"
echo "on one thread at commit $(ms commit), $(ms date), on $(ms machine), load average $(ms load)"
echo "($(ms perf)). perf counts CPU samples, which the machine's load changes little; wall times are not used."
echo "Measured sources (stamp $(ms commit | cut -d' ' -f1)): \`photonmap/\` \`render/\` \`Makefile\`"
echo
echo "A sample of the render phase is one under \`render_tile\`; each is put in the first of these"
echo "callers found going up its stack: irradiance lookups (\`side_cache_lookup_local\`), caustic"
echo "estimates (\`caustics_at\`), shadow-map queries (\`shadow_map_says\`), shadow rays"
echo "(\`scene_visible\`), other rays (\`scene_intersect\`), \`camera_ray\`, else \"other\" (shading,"
echo "sampling, the integrator's own code). Path tracing is profiled the same way at $(ms path_spp) spp, for its"
echo "counted rays per render-phase CPU-second."
for scene in $(awk -F, 'NR > 1 && !seen[$1]++ { print $1 }' "$res/profile.csv"); do
  echo
  echo "## $scene, $(ms resolution)x$(ms resolution), $(ms spp) spp, one thread"
  echo
  rs=$(pv $scene pm perf_samples_render); prs=$(pv $scene path perf_samples_render)
  awk -v hz="$hz" -v rs="$rs" -v n="$(pv $scene pm samples)" -v rays="$(pv $scene pm rays_counted)" \
      -v em="$(pv $scene pm emission_only_rays)" -v il="$(pv $scene pm irradiance_lookups)" \
      -v ce="$(pv $scene pm caustic_estimates)" -v prs="$prs" -v prays="$(pv $scene path rays_counted)" \
      -v all="$(pv $scene pm perf_samples_all)" 'BEGIN {
    t = rs / hz; pt = prs / hz
    print "| | pm |"; print "|---|---:|"
    printf "| render-phase CPU (perf samples / %d Hz) | %.2f s (%d samples) |\n", hz, t, rs
    printf "| the render phase'"'"'s share of the process'"'"'s samples | %.0f%% |\n", (all ? 100 * rs / all : 0)
    printf "| render-phase CPU per camera sample | %.1f us |\n", (n ? 1e6 * t / n : 0)
    printf "| rays counted (camera + indirect + shadow) | %d |\n", rays
    printf "| emission-only rays (not in the count above) | %d |\n", em
    printf "| irradiance lookups | %d |\n", il
    printf "| caustic estimates | %d |\n", ce
    r = t > 0 ? rays / t : 0; pr = pt > 0 ? prays / pt : 0
    printf "| counted rays per render-phase CPU-second | %.2f M |\n", r / 1e6
    printf "| path tracing, the same way | %.2f M |\n", pr / 1e6
    printf "| path'"'"'s rays/s over pm'"'"'s | %.1fx |\n", (r > 0 ? pr / r : 0) }'
  echo
  echo "| share of the render phase | pm |"
  echo "|---|---:|"
  for c in side_cache_lookup_local caustics_at shadow_map_says scene_visible scene_intersect camera_ray other; do
    case $c in side_cache_lookup_local) name="irradiance lookups" ;; caustics_at) name="caustic estimates" ;;
      shadow_map_says) name="shadow-map queries" ;; scene_visible) name="shadow rays (\`scene_visible\`)" ;;
      scene_intersect) name="other rays (\`scene_intersect\`)" ;; camera_ray) name="camera_ray" ;; other) name="other" ;; esac
    awk -v name="$name" -v k="$(pv $scene pm share_$c)" -v rs="$rs" 'BEGIN { printf "| %s | %.1f%% |\n", name, rs ? 100 * k / rs : 0 }'
  done
  echo
  printf "Top functions by own samples in the render phase: "
  awk -F, -v s="$scene" -v rs="$rs" '$1 == s && $2 == "pm" { printf "%s`%s` %.1f%%", n++ ? ", " : "", $3, rs ? 100 * $4 / rs : 0 } END { print "." }' "$res/top.csv"
done
echo
echo "The before/after analysis of the cheap sample (what was removed from the camera sample, and"
echo "why) was measured by hand at acc07e9: \`git show acc07e9:docs/PROFILE.md\`."
} > "$out"
if [ "$doc" = - ]; then cat "$out"; rm -f "$out"; else mv "$out" "$doc"; echo "profile-pm: wrote $doc" >&2; fi
