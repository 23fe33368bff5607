#!/bin/sh
# The scaling series of issue 15 (docs/benchmarks.md, "Scaling to 2·10^6 vertices"): the
# paper's torus (torus,R=10,r=1, curvature metric, gamma0 1.5) with r0 falling from 0.068
# to 0.0035, about 10^4, 10^5, 5·10^5, 10^6 and 2·10^6 output vertices (the count grows
# about as r0^-1.7 here: the distortion bound sizes most facets). Each run is
# timed with /usr/bin/time -v (wall seconds, max RSS) and reads its --stats (vertices,
# peak_bytes: the library's own count of the bytes it held at once). Prints one markdown
# row per run: r0, vertices, wall s, microseconds per vertex, peak bytes per vertex, max
# RSS bytes per vertex, exit status.
# One run at a time (the largest takes minutes and about 6 GB).
# Usage: bench/scaling.sh [ANISTAR [SIZES]]   (default build/anistar; SIZES: small = up
# to 10^5, medium = up to 10^6 (the default), all = up to 2·10^6 (about 9 minutes and
# 6 GB more), or a quoted list of r0 values); THREADS=N in the environment passes
# --threads N (default: the tool's, every online core)
set -u
tool=${1:-build/anistar}
sizes=${2:-medium}
tmp=${TMPDIR:-/tmp}/anistar-scaling.$$
mkdir -p "$tmp" || exit 1
trap 'rm -rf "$tmp"' EXIT

case $sizes in
small) list="0.068 0.017" ;;
medium) list="0.068 0.017 0.0072 0.005" ;;
all) list="0.068 0.017 0.0072 0.005 0.0035" ;;
*[!0-9.\ ]* | "") echo "usage: bench/scaling.sh [ANISTAR [small|medium|all|'R0 ...']]" >&2; exit 2 ;;
*) list=$sizes ;;
esac

num() { # num KEY FILE: the first number after "KEY": in a JSON file
    sed -n "s/^ *\"$1\": \([-0-9.eE+]*\).*/\1/p" "$2" | head -n 1
}

threads=${THREADS:-}
echo "<!-- bench/scaling.sh $tool $sizes${threads:+ THREADS=$threads}: $(date -u '+%Y-%m-%d %H:%M UTC'), $(grep -m1 'model name' /proc/cpuinfo 2>/dev/null | sed 's/.*: //'), $(nproc) cores -->"
echo '| r0 | vertices | wall s | µs / vertex | peak bytes / vertex | max RSS bytes / vertex | exit |'
echo '|---|---|---|---|---|---|---|'
for r0 in $list; do
    /usr/bin/time -v -o "$tmp/time" "$tool" mesh --builtin torus,R=10,r=1 --metric curvature \
        --r0 "$r0" --gamma0 1.5 --max-vertices 0 ${threads:+--threads "$threads"} \
        -o "$tmp/o.mesh" --stats "$tmp/o.json" --quiet 2>"$tmp/err"
    rc=$?
    wall=$(sed -n 's/.*Elapsed (wall clock) time (h:mm:ss or m:ss): //p' "$tmp/time" |
        awk -F: '{ s = 0; for (i = 1; i <= NF; i++) s = s * 60 + $i; print s }')
    rss=$(sed -n 's/.*Maximum resident set size (kbytes): //p' "$tmp/time")
    if [ -s "$tmp/o.json" ]; then
        v=$(num vertices "$tmp/o.json")
        peak=$(num peak_bytes "$tmp/o.json")
        awk -v r0="$r0" -v v="$v" -v t="$wall" -v p="$peak" -v rss="$rss" -v rc="$rc" 'BEGIN {
            printf "| %s | %d | %.1f | %.0f | %.0f | %.0f | %s |\n", r0, v, t, 1e6 * t / v,
                p / v, 1024 * rss / v, rc }'
    else
        printf '| %s | | %s | | | | %s: %s |\n' "$r0" "$wall" "$rc" "$(head -c 160 "$tmp/err")"
    fi
    rm -f "$tmp/o.mesh" "$tmp/o.json"
done
