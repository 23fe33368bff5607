#!/bin/sh
# Build the libFuzzer harnesses of test/fuzz into build/fuzz/ (clang with libFuzzer,
# AddressSanitizer and UndefinedBehaviorSanitizer). Run from anywhere:
#   sh test/fuzz/build.sh            # CC=clang by default; CC=clang-15 sh ... to choose
set -eu
cd "$(dirname "$0")/../.."
CC=${CC:-clang}
OUT=build/fuzz
mkdir -p "$OUT/obj"
SAN="-fsanitize=address,undefined -fno-sanitize-recover=all -fno-omit-frame-pointer"
CFLAGS="-std=c11 -Wall -Wextra -Wpedantic -Werror -ffp-contract=off -fno-strict-aliasing -O1 -g"
CPPFLAGS="-Iinclude -Ilib -D_POSIX_C_SOURCE=200809L"
# The library and the shared targets are instrumented for coverage (fuzzer-no-link);
# each harness links the libFuzzer main.
objs=""
for src in lib/*.c lib/*/*.c test/fuzz/fuzz_targets.c; do
    obj="$OUT/obj/$(echo "$src" | tr / _ | sed 's/\.c$/.o/')"
    if [ ! -f "$obj" ] || [ "$src" -nt "$obj" ] || [ "$0" -nt "$obj" ] ||
       [ -n "$(find lib include test/fuzz -name '*.h' -newer "$obj" 2>/dev/null | head -1)" ]; then
        $CC $CPPFLAGS $CFLAGS $SAN -fsanitize=fuzzer-no-link -c "$src" -o "$obj"
    fi
    objs="$objs $obj"
done
for r in off obj ply stl medit sol inr nrrd metaimage expr vtk vtu meshb solb; do
    $CC $CPPFLAGS $CFLAGS $SAN -fsanitize=fuzzer "test/fuzz/fuzz_$r.c" $objs -lm \
        -o "$OUT/fuzz_$r"
    echo "built $OUT/fuzz_$r"
done
