#!/bin/sh
# Run every test program of a build tree (default build/) from the project root, one at
# a time, and print one closing line: "check: N passed, M failed" counting test cases
# (as cmocka reports them). Exit status 1 if any test case or program failed.
set -u
build=${1:-build}
total_pass=0
total_fail=0
failed_progs=""
for t in "$build"/test/test_*; do
    [ -x "$t" ] || continue
    name=$(basename "$t")
    log="$build/test/$name.log"
    start=$(date +%s)
    "$t" >"$log" 2>&1
    rc=$?
    end=$(date +%s)
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
