#!/bin/sh
# Called by test_api: install into a scratch DESTDIR, check the layout, that DESTDIR does not
# leak into installed files, that a program links and runs against the installed shared
# library through pkg-config metadata, and that uninstall removes everything.
# Usage: install_check.sh BUILD_DIR
set -eu
build=$1
tmp=$(mktemp -d "${TMPDIR:-/tmp}/anistar-install.XXXXXX")
trap 'rm -rf "$tmp"' EXIT
mk() { env -u MAKEFLAGS -u MAKELEVEL -u MFLAGS make --no-print-directory -s BUILD="$build" "$@"; }
prefix=/opt/anistar-test
mk install DESTDIR="$tmp/root" PREFIX="$prefix" >/dev/null
r="$tmp/root$prefix"
for f in include/anistar.h lib/libanistar.a lib/libanistar.so lib/libanistar.so.0 \
         lib/pkgconfig/anistar.pc bin/anistar; do
    [ -e "$r/$f" ] || { echo "missing after install: $f"; exit 1; }
done
[ -L "$r/lib/libanistar.so" ] && [ -L "$r/lib/libanistar.so.0" ] || { echo "library symlinks missing"; exit 1; }
[ "$(readlink "$r/lib/libanistar.so")" = libanistar.so.0 ] || { echo "bad libanistar.so link"; exit 1; }
if grep -rq "$tmp" "$r"; then echo "DESTDIR leaked into installed files"; exit 1; fi
grep -q "^prefix=$prefix\$" "$r/lib/pkgconfig/anistar.pc" || { echo "bad prefix in anistar.pc"; exit 1; }
grep -q '^Libs: -L${libdir} -lanistar' "$r/lib/pkgconfig/anistar.pc" || { echo "bad Libs in anistar.pc"; exit 1; }
cat > "$tmp/prog.c" <<'C'
#include <anistar.h>
#include <stdio.h>
#include <string.h>
int main(void) {
    double a[3] = {0, 0, 0}, b[3] = {1, 0, 0}, c[3] = {0, 1, 0}, d[3] = {0, 0, -1};
    anistar_context *ctx = anistar_context_new(NULL);
    if (!ctx) return 1;
    int ok = anistar_orient3d(a, b, c, d) > 0 && strcmp(anistar_version(), "") != 0;
    anistar_context_free(ctx);
    return ok ? 0 : 1;
}
C
${CC:-cc} -std=c11 ${PROG_CFLAGS:-} -I"$r/include" "$tmp/prog.c" -L"$r/lib" -lanistar -lm -o "$tmp/prog"
LD_LIBRARY_PATH="$r/lib" "$tmp/prog" || { echo "program linked against the installed library failed"; exit 1; }
# The program must really use the shared library (not a static copy).
LD_LIBRARY_PATH="$r/lib" ldd "$tmp/prog" | grep -q "libanistar.so.0 => $r/lib/libanistar.so.0" \
    || { echo "program does not load libanistar.so.0 from the install"; exit 1; }
"$r/bin/anistar" --version >/dev/null || { echo "installed tool does not run"; exit 1; }
mk uninstall DESTDIR="$tmp/root" PREFIX="$prefix" >/dev/null
left=$(find "$r" -type f -o -type l | wc -l)
[ "$left" -eq 0 ] || { echo "uninstall left $left files"; find "$r" -type f -o -type l; exit 1; }
echo "install ok"
