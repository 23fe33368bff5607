#!/bin/sh
# make demo: run the main job on a built-in example and write its output.
# Meshes the built-in torus (R = 10, r = 1) with the curvature metric, writes the mesh
# (OFF), its per-vertex metric tensors (Medit .sol) and statistics (JSON), and renders it
# to PNG coloured by anisotropy; also probes the surface and metric at one point.
set -eu
build=$1
out=$2
tool="$build/anistar"
mkdir -p "$out"
"$tool" --version
echo "demo: anistar probe --builtin torus --metric curvature --at 11,0,0"
"$tool" probe --builtin torus --metric curvature --at 11,0,0 | tee "$out/torus_probe.json"

# A coarse resolution so that the run takes seconds. power=0.75 softens the curvature
# metric's anisotropy (1 : 11 on this torus at power 1, 1 : 6 here): at power 1 the
# consistency refinement takes minutes. --max-seconds is a guard only (a run stopped there
# exits 3 and still writes the consistent part of the mesh).
metric="curvature,power=0.75"
params="--r0 0.2 --gamma0 2 --max-seconds 25"
echo "demo: anistar mesh --builtin torus --metric $metric $params"
rc=0
# shellcheck disable=SC2086
"$tool" mesh --builtin torus --metric "$metric" $params -o "$out/torus.off" \
    --sol "$out/torus.sol" --stats "$out/torus.json" || rc=$?
if [ "$rc" -eq 3 ]; then
    echo "demo: the mesher stopped at its time limit: the mesh is incomplete"
elif [ "$rc" -ne 0 ]; then
    exit "$rc"
fi
sed -n '2,9p' "$out/torus.json"
echo "demo: anistar render $out/torus.off -o $out/torus.png --color anisotropy --sol $out/torus.sol"
"$tool" render "$out/torus.off" -o "$out/torus.png" --color anisotropy --sol "$out/torus.sol" \
    --view 30,40
echo "demo: wrote $out/torus_probe.json, $out/torus.off, $out/torus.sol, $out/torus.json" \
    "and $out/torus.png"
