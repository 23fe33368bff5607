#!/bin/sh
# Make sure the test dependencies (GMP: exact oracle; cmocka: runner; pkg-config: the
# install test) are installed.
# Installs them with apt-get when they are missing and we run as root; otherwise prints
# the exact command and fails. Debian's python3-meshio (test_interop's independent reader
# of our files) is installed the same way when it is missing and we may; without it that
# test says it cannot run and how to install it, and the rest runs.
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
optional="" # wanted, not required: test_interop says it cannot run without it
/usr/bin/python3 -c 'import meshio' >/dev/null 2>&1 || optional="python3-meshio"
[ -z "$missing$optional" ] && exit 0
if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1; then
    echo "deps: installing$missing${optional:+ $optional} with apt-get" >&2
    apt-get update -qq >&2 || { echo "deps: apt-get update failed" >&2; [ -z "$missing" ]; exit; }
    if [ -n "$missing" ]; then
        DEBIAN_FRONTEND=noninteractive apt-get install -y -qq $missing >&2 ||
            { echo "deps: apt-get failed; run: apt-get install -y$missing" >&2; exit 1; }
    fi
    if [ -n "$optional" ]; then
        DEBIAN_FRONTEND=noninteractive apt-get install -y -qq $optional >&2 ||
            echo "deps: apt-get could not install $optional; test_interop will not run" >&2
    fi
    exit 0
fi
[ -n "$optional" ] && {
    echo "deps: $optional is missing (test_interop will not run); install it with:" >&2
    echo "    sudo apt-get install -y $optional" >&2
}
[ -z "$missing" ] && exit 0
echo "deps: missing$missing. Install them with:" >&2
echo "    sudo apt-get install -y$missing" >&2
exit 1
