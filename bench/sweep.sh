#!/bin/sh
# bench/sweep.sh — inputs nobody wrote a test for (session 21's sweep, condensed): scale and
# translation, loose bounds, --approx, creases, near contacts, thin shapes. One run at a
# time, one thread, each under a time limit; prints exit status, seconds, vertices,
# estimate, Euler characteristic, whether the mesh is closed, and the stop reason.
#
#   sh bench/sweep.sh [ANISTAR] [SECONDS]
#
# Exit 0 must mean a certified mesh: a row with exit 0 and "closed" no is a bug.
set -u
bin=${1:-build/anistar}
lim=${2:-90}
[ -x "$bin" ] || { echo "build $bin first (make)"; exit 1; }
tmp=${TMPDIR:-/tmp}/anistar-sweep.$$
mkdir -p "$tmp"
trap 'rm -rf "$tmp"' EXIT INT TERM
G='max(sin(3*x)*cos(3*y)+sin(3*y)*cos(3*z)+sin(3*z)*cos(3*x),x^2+y^2+z^2-1.5^2)'
printf '| case | exit | s | V | estimate | chi | closed | stop |\n|---|---|---|---|---|---|---|---|\n'
while IFS='|' read -r name args; do
    [ -z "$name" ] && continue
    t0=$(date +%s.%N)
    # shellcheck disable=SC2086
    eval timeout "$lim" "$bin" mesh $args --threads 1 --quiet --stats "$tmp/s.json" -o "$tmp/o.off" \
        >/dev/null 2>"$tmp/err"
    rc=$?
    t1=$(date +%s.%N)
    python3 - "$tmp/s.json" "$name" "$rc" "$t0" "$t1" <<'PY'
import json, sys
f, name, rc, t0, t1 = sys.argv[1:]
try:
    a = json.load(open(f))
    print("| %s | %s | %.1f | %d | %.0f | %d | %s | %s |" % (name, rc, float(t1) - float(t0),
          a["vertices"], a["estimate"]["vertices"], a["euler_characteristic"],
          "yes" if a["closed_manifold"] else "no", a["stop_reason"]))
except Exception:
    print("| %s | %s | %.1f | | | | | (no statistics) |" % (name, rc, float(t1) - float(t0)))
PY
    rm -f "$tmp/s.json"
done <<LIST
sphere at 0|--implicit x^2+y^2+z^2-1 --bound 0,0,0,1.25
sphere at x 1e7|--implicit "(x-1e7)^2+y^2+z^2-1" --bound 1e7,0,0,1.25
sphere at x 1e10|--implicit "(x-1e10)^2+y^2+z^2-1" --bound 1e10,0,0,1.25
torus at x 1e7|--implicit "(sqrt((x-1e7)^2+y^2)-1)^2+z^2-0.09" --bound 1e7,0,0,1.4
sphere, bound 1e4|--implicit x^2+y^2+z^2-1 --bound 0,0,0,1e4
sphere --approx 1e-4|--builtin sphere --approx 1e-4
sphere --approx 1e-6 (refused)|--builtin sphere --approx 1e-6
sphere euclidean r0 0.02|--builtin sphere --metric euclidean --r0 0.02
clipped gyroid euclidean r0 0.05|--implicit "$G" --bound 0,0,0,2 --metric euclidean --r0 0.05
clipped gyroid curvature,grad=1.3|--implicit "$G" --bound 0,0,0,2 --metric curvature,grad=1.3
clipped gyroid curvature|--implicit "$G" --bound 0,0,0,2 --max-seconds 60
two spheres, gap 1e-3|--implicit "min((x-1.0005)^2+y^2+z^2-1,(x+1.0005)^2+y^2+z^2-1)" --bound 0,0,0,2.5 --metric euclidean --r0 0.1
two spheres, gap 1e-4|--implicit "min((x-1.00005)^2+y^2+z^2-1,(x+1.00005)^2+y^2+z^2-1)" --bound 0,0,0,2.5 --metric euclidean --r0 0.1 --max-seconds 60
chair r0 1|--builtin chair --r0 1
chair r0 3|--builtin chair --r0 3
chair r0 10|--builtin chair --r0 10 --max-seconds 60
flat ellipsoid (1, 1, 0.02)|--implicit "x^2+y^2+(z/0.02)^2-1" --bound 0,0,0,1.25
heart (singular point)|--implicit "(x^2+9/4*y^2+z^2-1)^3-x^2*z^3-9/80*y^2*z^3" --bound 0,0,0,1.6 --metric euclidean --r0 0.05
f = (r^2 - 1)^2 (no sign change)|--implicit "(x^2+y^2+z^2-1)^2" --bound 0,0,0,1.5
LIST
