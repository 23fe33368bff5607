#!/bin/sh
# Mesh every file of test/data (the copies of ../shared/data) and the paper's built-in
# cases as a user would, with the command-line tool: first with the defaults
# (`anistar mesh FILE -o OUT`), then with the paper's parameters where the paper gives
# them. Prints one markdown table row per run (copy it into docs/benchmarks.md):
# input, options, exit status, seconds, vertices, vertices per second, closed, Euler
# characteristic, rho max, mean approximation error, and how the run ended.
# Then the recipes of docs/recipes.md.
# Usage: bench/defaults.sh [ANISTAR [MAX_SECONDS [PART]]]  (default build/anistar, 60 s per
# run, PART all | defaults | paper | recipes)
set -u
tool=${1:-build/anistar}
maxs=${2:-60}
part=${3:-all}
data=test/data
tmp=${TMPDIR:-/tmp}/anistar-defaults.$$
mkdir -p "$tmp" || exit 1
trap 'rm -rf "$tmp"' EXIT

num() { # num KEY FILE: the first number after "KEY": in a JSON file
    sed -n "s/^ *\"$1\": \([-0-9.eE+]*\).*/\1/p" "$2" | head -n 1
}

row() { # row LABEL ARGS...
    label=$1
    shift
    start=$(date +%s.%N)
    "$tool" mesh "$@" -o "$tmp/o.off" --stats "$tmp/o.json" --max-seconds "$maxs" \
        --quiet 2>"$tmp/err"
    rc=$?
    end=$(date +%s.%N)
    t=$(echo "$end - $start" | bc)
    if [ -s "$tmp/o.json" ]; then
        v=$(num vertices "$tmp/o.json")
        closed=$(sed -n 's/^ *"closed_manifold": \([a-z]*\).*/\1/p' "$tmp/o.json")
        chi=$(num euler_characteristic "$tmp/o.json")
        rho=$(num rho_max "$tmp/o.json")
        err=$(sed -n 's/^ *"approx_error": {"mean": \([-0-9.eE+]*\).*/\1/p' "$tmp/o.json")
        stop=$(sed -n 's/^ *"stop_reason": "\([a-z_]*\)".*/\1/p' "$tmp/o.json")
        inc=$(num inconsistent_facets "$tmp/o.json")
        vps=$(echo "$v / $t" | bc)
        printf '| %s | `%s` | %s | %.1f | %s | %s | %s | %s | %.3g | %.3g | %s, %s inconsistent |\n' \
            "$label" "$*" "$rc" "$t" "$v" "$vps" "$closed" "$chi" "$rho" "${err:-0}" \
            "$stop" "$inc"
    else
        printf '| %s | `%s` | %s | %.1f | | | | | | | %s |\n' "$label" "$*" "$rc" "$t" \
            "$(head -c 160 "$tmp/err")"
    fi
    rm -f "$tmp/o.off" "$tmp/o.json"
}

echo "<!-- bench/defaults.sh $tool $maxs: $(date -u '+%Y-%m-%d %H:%M UTC'), $(grep -m1 'model name' /proc/cpuinfo 2>/dev/null | sed 's/.*: //'), $(nproc) cores -->"
echo '| input | options | exit | s | V | V/s | closed | χ | ρ max | mean error | end |'
echo '|---|---|---|---|---|---|---|---|---|---|---|'
if [ "$part" = all ] || [ "$part" = defaults ]; then
for f in sphere_r0.5.off ellipsoid.off knot1.off hinge.stl lever.stl elephant.off \
    fandisk.off bunny00.off skull_2.9.inr brain_t1.mhd liver_labels_half.inr; do
    row "$f (defaults)" "$data/$f"
done
fi
if [ "$part" = all ] || [ "$part" = paper ]; then
# the paper's parameters (its sections 6.1-6.3): knot1 of Fig. 8, the torus of Table 2,
# the shock sphere, the chair, the tori of Table 1
row "knot1 (Fig. 8)" "$data/knot1.off" --metric curvature,grad=0 --r0 1 --gamma0 1.5
row "torus (Table 2)" --builtin torus,R=10,r=1 --metric curvature,eps=0.1 --r0 0.1 --gamma0 1.5
row "shock sphere" --builtin sphere --metric shock --r0 0.1 --gamma0 1.4
row "chair" --builtin chair,a=0.8,b=0.4,k=1 --metric curvature --r0 0.1 --gamma0 1.3
for R in 10 50 200; do
    row "torus R=$R (Table 1)" --builtin torus,R=$R,r=1 --metric curvature --approx 0.001 \
        --r0 1 --gamma0 1.8
done
fi
if [ "$part" = all ] || [ "$part" = recipes ]; then
    row "lever (CAD)" "$data/lever.stl" --metric euclidean --r0 2
    row "hinge (CAD)" "$data/hinge.stl" --metric euclidean --r0 2
    row "hinge (CAD, graded)" "$data/hinge.stl" --metric curvature,grad=2
    row "fandisk (CAD)" "$data/fandisk.off" --metric euclidean --r0 0.2
    row "elephant (scan)" "$data/elephant.off" --metric euclidean --r0 1
    row "bunny (scan)" "$data/bunny00.off" --metric euclidean --r0 0.02
    row "brain (MRI)" "$data/brain_t1.nhdr" --iso 40 --metric euclidean --r0 6
    row "liver (labels)" "$data/liver_labels_half.inr" --iso 64 --metric euclidean --r0 5
    row "skull (CT)" "$data/skull_2.9.inr" --iso 2.9 --metric euclidean --r0 8
fi
