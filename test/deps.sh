#!/bin/sh
# Make sure the test dependencies (GMP: exact oracle; cmocka: runner; pkg-config: the
# install test) are installed.
# Installs them with apt-get when they are missing and we run as root; otherwise prints
# the exact command and fails.
set -u
have() { printf '#include <%s>\n' "$1" | ${CC:-cc} -E -x c - >/dev/null 2>&1; }
missing=""
have gmp.h || missing="$missing libgmp-dev"
have_cmocka() {
    printf '#include <stdarg.h>\n#include <stddef.h>\n#include <setjmp.h>\n#include <stdint.h>\n#include <cmocka.h>\n' |
        ${CC:-cc} -E -x c - >/dev/null 2>&1
}
have_cmocka || missing="$missing libcmocka-dev"
command -v pkg-config >/dev/null 2>&1 || missing="$missing pkg-config"
[ -z "$missing" ] && exit 0
if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1; then
    echo "deps: installing$missing with apt-get" >&2
    { apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq $missing; } >&2 \
        || { echo "deps: apt-get failed; run: apt-get install -y$missing" >&2; exit 1; }
    exit 0
fi
echo "deps: missing$missing. Install them with:" >&2
echo "    sudo apt-get install -y$missing" >&2
exit 1
