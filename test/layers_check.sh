#!/bin/sh
# The library's layers call only downward (issue 14): core (lib/core.c), geom, mesh (the
# triangle-mesh type and its topology), io (files), surface, mesher, api (lib/api.c).
# For every object of BUILD/obj/lib, each symbol it uses (nm -u) that another object of
# the library defines (nm -g --defined-only) must be defined in the same layer or a lower
# one. Prints every violation ("lib/core.o (core) uses anistar_status_string from
# lib/api.o (api)") and exits 1 if there is one, or if no object is found.
# Usage: layers_check.sh BUILD
set -u
b=${1:?usage: layers_check.sh BUILD}
command -v nm >/dev/null 2>&1 || { echo "layers_check: nm is missing (binutils)"; exit 1; }
rank() {
    case "$1" in
    */obj/lib/core.o | */obj/lib/pool.o) echo 0 ;;
    */obj/lib/geom/*) echo 1 ;;
    */obj/lib/mesh/*) echo 2 ;;
    */obj/lib/io/*) echo 3 ;;
    */obj/lib/surface/*) echo 4 ;;
    */obj/lib/mesher/*) echo 5 ;;
    */obj/lib/api.o) echo 6 ;;
    *) echo 9 ;;
    esac
}
tmp=$(mktemp -d "${TMPDIR:-/tmp}/anistar-layers.XXXXXX") || exit 1
trap 'rm -rf "$tmp"' EXIT
objs=$(find "$b/obj/lib" -name '*.o' 2>/dev/null | LC_ALL=C sort)
[ -n "$objs" ] || { echo "layers_check: no object under $b/obj/lib"; exit 1; }
for o in $objs; do
    r=$(rank "$o")
    [ "$r" = 9 ] && { echo "layers_check: $o is in no layer (add its directory to rank())"; exit 1; }
    nm -g --defined-only "$o" | awk -v r="$r" -v o="$o" 'NF >= 3 {print $3, r, o}'
done | LC_ALL=C sort -k1,1 >"$tmp/defs"
bad=0
for o in $objs; do
    r=$(rank "$o")
    nm -u "$o" | awk '{print $NF}' | LC_ALL=C sort -u >"$tmp/used"
    LC_ALL=C join "$tmp/used" "$tmp/defs" | awk -v r="$r" -v o="$o" \
        '$2 > r {print o " (layer " r ") uses " $1 " from " $3 " (layer " $2 ")"}' >"$tmp/v"
    if [ -s "$tmp/v" ]; then
        cat "$tmp/v"
        bad=1
    fi
done
[ "$bad" = 0 ] && echo "layers_check: $(echo "$objs" | wc -l) objects, every call downward"
exit "$bad"
