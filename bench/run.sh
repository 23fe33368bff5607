#!/bin/sh
# Run every benchmark of a build tree (default build/bench) and print their tables, with
# the machine and the date on top (copy them into docs/benchmarks.md).
set -u
build=${1:-build/bench}
echo "# anistar benchmarks — $(date -u '+%Y-%m-%d %H:%M UTC')"
echo "# machine: $(uname -m), $(grep -m1 'model name' /proc/cpuinfo 2>/dev/null | sed 's/.*: //'), $(nproc) cores, $(awk '/MemTotal/ {printf "%.0f GiB", $2/1048576}' /proc/meminfo 2>/dev/null)"
echo "# compiler: $(${CC:-cc} --version | head -n 1)"
rc=0
for b in "$build"/bench/bench_*; do
    [ -x "$b" ] || continue
    echo
    echo "## $(basename "$b")"
    "$b" || rc=1
done
exit $rc
