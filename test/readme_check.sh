#!/bin/sh
# Called by test_api: the C block of README.md's "The API in ..." section must compile
# against the build's static library and run: it meshes a torus and writes torus.ply.
# Usage: readme_check.sh BUILD_DIR
set -eu
build=$1
tmp=$(mktemp -d "${TMPDIR:-/tmp}/anistar-readme.XXXXXX")
trap 'rm -rf "$tmp"' EXIT
# the first ```c block after the heading: its #include lines stay on top, the rest is main
awk '/^## The API in/ {s = 1} s && /^```c$/ {b = 1; next} b && /^```$/ {exit} b {print}' \
    README.md >"$tmp/block.c"
[ -s "$tmp/block.c" ] || { echo "README.md: no C block under 'The API in'"; exit 1; }
{
    echo '#include <stdio.h>'
    grep '^#include' "$tmp/block.c"
    echo 'int main(void) {'
    grep -v '^#include' "$tmp/block.c"
    echo 'return 0;'
    echo '}'
} >"$tmp/prog.c"
${CC:-cc} -std=c11 -Wall -Wextra -Werror ${PROG_CFLAGS:-} -Iinclude "$tmp/prog.c" \
    "$build/libanistar.a" -lm -o "$tmp/prog"
(cd "$tmp" && ./prog >out.txt 2>err.txt) || { echo "the README program failed"; cat "$tmp/err.txt"; exit 1; }
[ ! -s "$tmp/err.txt" ] || { echo "the README program printed an error:"; cat "$tmp/err.txt"; exit 1; }
head -c 4 "$tmp/torus.ply" | grep -q '^ply' || { echo "the README program wrote no torus.ply"; exit 1; }
grep -a -q '^element vertex [1-9]' "$tmp/torus.ply" || { echo "torus.ply has no vertices"; exit 1; }
echo "readme ok"
