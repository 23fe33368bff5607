#!/bin/sh
# bench/threads.sh — issue 15: wall time of `anistar mesh` with 1 and 2 threads (and,
# optionally, an older build on one thread), interleaved run by run, on the paper's torus
# (Table 2 parameters) and the shock sphere, or on the cases given.
#
#   sh bench/threads.sh [ROUNDS] [OLD_ANISTAR]
#
# ROUNDS (default 5) interleaved rounds; each round runs every case with every build in
# turn. Prints, per case, the minimum and the median wall time of each build, the speedups
# of 2 threads over 1 and of the new build on one thread over OLD_ANISTAR, and checks that
# the 1- and 2-thread outputs are byte-identical. Run it on an otherwise idle machine.
# OLD_THREADS=N passes --threads N to OLD_ANISTAR (a build that has the option: without
# it, such a build takes every online core).
set -eu
rounds=${1:-5}
old=${2:-}
new=${ANISTAR:-build/anistar}
[ -x "$new" ] || { echo "build $new first (make)"; exit 1; }
tmp=${TMPDIR:-/tmp}/anistar-bench-threads.$$
mkdir -p "$tmp"
trap 'rm -rf "$tmp"' EXIT INT TERM

cases="torus|--builtin torus,R=10,r=1 --r0 0.1 --gamma0 1.5
shock|--builtin sphere --metric shock --r0 0.1 --gamma0 1.4"
[ -n "${CASES:-}" ] && cases=$CASES

now() { date +%s.%N; }
# run NAME TAG BIN THREADS ARGS...: one timed run, its wall time appended to NAME.TAG
run() {
    name=$1 tag=$2 bin=$3 th=$4
    shift 4
    extra=""
    [ "$th" != "-" ] && extra="--threads $th"
    t0=$(now)
    # shellcheck disable=SC2086
    "$bin" mesh "$@" $extra -o "$tmp/$name.$tag.off" --quiet
    t1=$(now)
    echo "$t0 $t1" | awk '{printf "%.3f\n", $2 - $1}' >>"$tmp/$name.$tag"
}

r=0
while [ "$r" -lt "$rounds" ]; do
    echo "$cases" | while IFS='|' read -r name args; do
        # shellcheck disable=SC2086
        [ -n "$old" ] && run "$name" old "$old" "${OLD_THREADS:--}" $args
        # shellcheck disable=SC2086
        run "$name" t1 "$new" 1 $args
        # shellcheck disable=SC2086
        run "$name" t2 "$new" 2 $args
        cmp -s "$tmp/$name.t1.off" "$tmp/$name.t2.off" ||
            { echo "$name: 1 and 2 threads differ"; exit 1; }
    done
    r=$((r + 1))
done

stat() { sort -n "$1" | awk '{a[NR] = $1} END {printf "%.3f %.3f", a[1], a[int((NR + 1) / 2)]}'; }
echo "| case | old, 1 thread (min / median s) | new, 1 thread | new, 2 threads | 2 vs 1 thread | new vs old, 1 thread |"
echo "|---|---|---|---|---|---|"
echo "$cases" | while IFS='|' read -r name args; do
    t1=$(stat "$tmp/$name.t1")
    t2=$(stat "$tmp/$name.t2")
    o="—"
    so="—"
    if [ -n "$old" ]; then
        o=$(stat "$tmp/$name.old")
        so=$(echo "$o $t1" | awk '{printf "%.2fx", $1 / $3}')
    fi
    s2=$(echo "$t1 $t2" | awk '{printf "%.2fx", $1 / $3}')
    echo "| $name | $o | $t1 | $t2 | $s2 | $so |"
done
