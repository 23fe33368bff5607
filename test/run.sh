#!/bin/sh
# Run every test program of a build tree (default build/) from the project root, JOBS
# at a time (default: the number of CPUs), and print one closing line: "check: N passed,
# M failed" counting test cases (as cmocka reports them). Exit status 1 if any test case
# or program failed. The slowest programs start first. Each program writes only its own
# temporary files, so programs may run at the same time (not two builds' suites).
set -u
build=${1:-build}
jobs=${JOBS:-$(getconf _NPROCESSORS_ONLN 2>/dev/null || echo 1)}
total_pass=0
total_fail=0
failed_progs=""
list=""
for first in test_defaults_image test_defaults test_e2e test_mesher test_optimize test_predicates; do
    [ -x "$build/test/$first" ] && list="$list $build/test/$first"
done
for t in "$build"/test/test_*; do
    [ -x "$t" ] || continue
    case " $list " in *" $t "*) continue ;; esac
    list="$list $t"
done
[ -n "$list" ] || { echo "no test ran"; exit 1; }
# each program: its log in NAME.log, "exit start end" in NAME.rc
printf '%s\n' $list | xargs -P "$jobs" -I{} sh -c \
    's=$(date +%s); "$1" >"$1.log" 2>&1; rc=$?; echo "$rc $s $(date +%s)" >"$1.rc"' _ {}
for t in $list; do
    name=$(basename "$t")
    log="$t.log"
    read -r rc start end <"$t.rc" || { rc=1; start=0; end=0; }
    pass=$(sed -n 's/^\[  PASSED  \] \([0-9]*\) test(s)\./\1/p' "$log" | awk '{s+=$1} END {print s+0}')
    fail=$(sed -n 's/^\[  FAILED  \] \([0-9]*\) test(s), listed below:/\1/p' "$log" | awk '{s+=$1} END {print s+0}')
    if [ "$rc" -ne 0 ] && [ "$fail" -eq 0 ]; then fail=1; fi
    total_pass=$((total_pass + pass))
    total_fail=$((total_fail + fail))
    if [ "$rc" -ne 0 ]; then
        failed_progs="$failed_progs $name"
        echo "FAIL $name ($pass passed, $fail failed, exit $rc, $((end - start)) s) — log:"
        sed 's/^/    /' "$log" | tail -n 60
    else
        echo "ok   $name ($pass passed, $((end - start)) s)"
    fi
done
echo "check: $total_pass passed, $total_fail failed"
[ -z "$failed_progs" ] || { echo "failed programs:$failed_progs"; exit 1; }
[ "$total_pass" -gt 0 ] || { echo "no test ran"; exit 1; }
exit 0
