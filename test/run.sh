#!/bin/sh
# Run every test program of a build tree (default build/) from the project root, JOBS
# at a time (default: the number of CPUs). Each program's result line ("ok   NAME (...)"
# or "FAIL NAME (...)" followed by the tail of its log) is printed as soon as that program
# finishes; then one closing line: "check: N passed, M failed" counting test cases (as
# cmocka reports them). Exit status 1 if any test case or program failed. The slowest
# programs start first. Each program writes only its own temporary files, so programs may
# run at the same time (not two builds' suites). EXCLUDE (space-separated program names)
# leaves programs out, and says which (CI's clang run leaves out the three whole-corpus
# programs, which its gcc and sanitizer runs have run).
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
    case "$t" in *.log | *.rc | *.out) continue ;; esac
    case " $list " in *" $t "*) continue ;; esac
    list="$list $t"
done
if [ -n "${EXCLUDE:-}" ]; then
    kept=""
    for t in $list; do
        case " $EXCLUDE " in *" $(basename "$t") "*) continue ;; esac
        kept="$kept $t"
    done
    list=$kept
    echo "not run (EXCLUDE):$(printf ' %s' $EXCLUDE)"
fi
[ -n "$list" ] || { echo "no test ran"; exit 1; }
for t in $list; do rm -f "$t.rc" "$t.out"; done
# One program: run it (log in NAME.log), count its cmocka cases, record
# "exit start end passed failed" in NAME.rc, and print its report at once, written to
# NAME.out first and then copied out with a single cat so that reports of programs
# finishing together do not interleave.
one='t=$1
s=$(date +%s); "$t" >"$t.log" 2>&1; rc=$?; e=$(date +%s)
pass=$(sed -n "s/^\[  PASSED  \] \([0-9]*\) test(s)\./\1/p" "$t.log" | awk "{s+=\$1} END {print s+0}")
fail=$(sed -n "s/^\[  FAILED  \] \([0-9]*\) test(s), listed below:/\1/p" "$t.log" | awk "{s+=\$1} END {print s+0}")
if [ "$rc" -ne 0 ] && [ "$fail" -eq 0 ]; then fail=1; fi
name=$(basename "$t")
{
    if [ "$rc" -ne 0 ]; then
        echo "FAIL $name ($pass passed, $fail failed, exit $rc, $((e - s)) s) — log:"
        sed "s/^/    /" "$t.log" | tail -n 60
    else
        echo "ok   $name ($pass passed, $((e - s)) s)"
    fi
} >"$t.out"
echo "$rc $s $e $pass $fail" >"$t.rc"
cat "$t.out"'
printf '%s\n' $list | xargs -P "$jobs" -I{} sh -c "$one" _ {}
for t in $list; do
    name=$(basename "$t")
    if ! read -r rc start end pass fail <"$t.rc" 2>/dev/null; then
        rc=1 pass=0 fail=1
        echo "FAIL $name (no result: it did not run to the end)"
    fi
    total_pass=$((total_pass + pass))
    total_fail=$((total_fail + fail))
    [ "$rc" -eq 0 ] || failed_progs="$failed_progs $name"
done
echo "check: $total_pass passed, $total_fail failed"
[ -z "$failed_progs" ] || { echo "failed programs:$failed_progs"; exit 1; }
[ "$total_pass" -gt 0 ] || { echo "no test ran"; exit 1; }
exit 0
