#!/bin/sh
# Called by test_api: install into a scratch DESTDIR, check the layout, that DESTDIR does not
# leak into installed files, that a program links and runs against the installed shared
# library, and that uninstall removes everything. Then the README's order: the build made
# first (as by make check) with one PREFIX, `make install PREFIX=<tmp>` with another, and an
# external program that meshes a sphere, compiled and linked from that prefix with
# `pkg-config --cflags --libs anistar` alone, shared (LD_LIBRARY_PATH) and static.
# Usage: install_check.sh BUILD_DIR
set -eu
build=$1
if ! command -v pkg-config >/dev/null 2>&1; then
    echo "install_check: pkg-config is missing. Install it with:"
    echo "    sudo apt-get install -y pkg-config"
    exit 1
fi
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

# ---- the README's order: build (one PREFIX), then make install PREFIX=<tmp> -------------
mk all PREFIX=/opt/anistar-built-with-another-prefix >/dev/null
p="$tmp/prefix"
mk install PREFIX="$p" >/dev/null
grep -q "^prefix=$p\$" "$p/lib/pkgconfig/anistar.pc" \
    || { echo "anistar.pc of 'make install PREFIX=$p' does not say prefix=$p:"; cat "$p/lib/pkgconfig/anistar.pc"; exit 1; }
export PKG_CONFIG_PATH="$p/lib/pkgconfig"
cflags=$(pkg-config --cflags anistar) || { echo "pkg-config --cflags anistar failed"; exit 1; }
libs=$(pkg-config --libs anistar) || { echo "pkg-config --libs anistar failed"; exit 1; }
case " $cflags " in *" -I$p/include "*) ;; *) echo "pkg-config --cflags: '$cflags' (expected -I$p/include)"; exit 1 ;; esac
case " $libs " in *" -L$p/lib "*) ;; *) echo "pkg-config --libs: '$libs' (expected -L$p/lib)"; exit 1 ;; esac
cat > "$tmp/mesh.c" <<'C'
/* Mesh the unit sphere coarsely; print "V F" and exit 0 for a closed certified mesh. */
#include <anistar.h>
#include <stdio.h>
int main(void) {
    anistar_context *ctx = anistar_context_new(NULL);
    anistar_surface *s = NULL;
    anistar_metric *m = NULL;
    anistar_mesher *me = NULL;
    anistar_mesh *mesh = NULL;
    int rc = 1;
    if (!ctx) return 1;
    if (anistar_surface_builtin(ctx, "sphere", &s) || anistar_metric_from_spec(ctx, s, "euclidean", &m) ||
        anistar_mesher_new(ctx, s, m, &me) || anistar_mesher_set(me, ANISTAR_PARAM_R0, 0.4) ||
        anistar_mesher_run(me, &mesh)) {
        fprintf(stderr, "%s\n", anistar_last_error(ctx));
    } else {
        anistar_mesh_stats st;
        anistar_mesh_get_stats(mesh, &st);
        size_t v = anistar_mesh_vertex_count(mesh), f = anistar_mesh_triangle_count(mesh);
        /* a closed sphere: F = 2V - 4 */
        if (v >= 4 && f == 2 * v - 4 && st.closed_manifold && st.euler_characteristic == 2) {
            printf("%zu %zu\n", v, f);
            rc = 0;
        }
    }
    anistar_mesh_free(mesh);
    anistar_mesher_free(me);
    anistar_metric_free(m);
    anistar_surface_free(s);
    anistar_context_free(ctx);
    return rc;
}
C
# shared: exactly what pkg-config says
# shellcheck disable=SC2086
${CC:-cc} -std=c11 ${PROG_CFLAGS:-} $cflags "$tmp/mesh.c" $libs -o "$tmp/mesh_shared"
out=$(LD_LIBRARY_PATH="$p/lib" "$tmp/mesh_shared") || { echo "the shared pkg-config program failed"; exit 1; }
LD_LIBRARY_PATH="$p/lib" ldd "$tmp/mesh_shared" | grep -q "libanistar.so.0 => $p/lib/libanistar.so.0" \
    || { echo "the shared pkg-config program does not load $p/lib/libanistar.so.0"; exit 1; }
echo "shared: $out" | grep -q '^shared: [0-9][0-9]* [0-9][0-9]*$' || { echo "unexpected output '$out'"; exit 1; }
# static: the archive through pkg-config's -L and --static (Libs.private: -lm)
slibs=$(pkg-config --static --libs anistar | sed 's/-lanistar/-Wl,-Bstatic -lanistar -Wl,-Bdynamic/')
# shellcheck disable=SC2086
${CC:-cc} -std=c11 ${PROG_CFLAGS:-} $cflags "$tmp/mesh.c" $slibs -o "$tmp/mesh_static"
if ldd "$tmp/mesh_static" | grep -q libanistar; then
    echo "the static pkg-config program loads a shared libanistar"; exit 1
fi
out2=$("$tmp/mesh_static") || { echo "the static pkg-config program failed"; exit 1; }
[ "$out2" = "$out" ] || { echo "static and shared programs disagree: '$out2' vs '$out'"; exit 1; }
mk uninstall PREFIX="$p" >/dev/null
left=$(find "$p" -type f -o -type l | wc -l)
[ "$left" -eq 0 ] || { echo "uninstall left $left files in $p"; exit 1; }
echo "install ok (pkg-config program: $out vertices/triangles)"
