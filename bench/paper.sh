#!/bin/sh
# Reproduce the paper's experiments (its section 6 and the appendix on beta and delta)
# with the command-line tool, and print the results as the markdown of docs/paper.md:
#   fig4    the shock sphere (Fig. 4: lambda 0.6, rho0 3, r0 0.1, gamma0 1.4), rendered
#   fig5    the chair (Fig. 5: a 0.8, b 0.4, k 1, r0 0.1, gamma0 1.3), rendered
#   fig7    the torus R=10 r=1 at r0 0.1 for gamma0 from 1.3 to 1.8: vertices and time
#   table2  the same torus at r0 0.1, gamma0 1.5 for beta 2..5 x delta 0.1, 0.3, 0.5:
#           vertices, time and mean error, with the default curvature metric, with and
#           without the anisotropy cap (--aniso-cap), side by side
#   table1  tori r=1, R = 10, 50, 200, approximation bound 0.001 (r0 1, gamma0 1.8):
#           the curvature metric against the euclidean one, whole tori and the piece
#           0 <= atan2(y, x) <= 2 pi / R (a length 2 pi along the big circle, as long
#           for every R); kappa = N_aniso / N_iso
#   fig8    the squared radius-edge histogram before and after --optimize on a polyhedral
#           model (knot1.off at the paper's r0 1, gamma0 1.5; the paper's "fertility" is
#           not in our data), and the time of each stage
#   fig9    a render of Table 1's R=50 mesh when it finished
# Usage: bench/paper.sh [ANISTAR [MAX_SECONDS [PARTS [IMAGES_DIR]]]]
#   defaults: build/anistar, 120 s per run (--max-seconds), PARTS "fig4 fig5 fig7 table2
#   table1 fig8 fig9", IMAGES_DIR docs/images (the PNG renders).
set -u
tool=${1:-build/anistar}
maxs=${2:-120}
parts=${3:-"fig4 fig5 fig7 table2 table1 fig8 fig9"}
imgdir=${4:-docs/images}
data=test/data
tmp=${TMPDIR:-/tmp}/anistar-paper.$$
mkdir -p "$tmp" "$imgdir" || exit 1
trap 'rm -rf "$tmp"' EXIT

has() { case " $parts " in *" $1 "*) return 0 ;; esac; return 1; }
num() { # num KEY FILE: the first number after "KEY": in a JSON file
    sed -n "s/.*\"$1\": \([-0-9.eE+]*\).*/\1/p" "$2" | head -n 1
}
arr() { # arr KEY FILE: the numbers of the array "KEY": [...], space separated
    sed -n "s/.*\"$1\": \[\([-0-9., eE+]*\)\].*/\1/p" "$2" | head -n 1 | tr -d ','
}

# run TAG ARGS...: mesh into $tmp/TAG.ply with --stats $tmp/TAG.json; sets rc, t (s), v,
# err (mean error), stop, inc
run() {
    tag=$1
    shift
    start=$(date +%s.%N)
    "$tool" mesh "$@" -o "$tmp/$tag.ply" -o "$tmp/$tag.off" --stats "$tmp/$tag.json" --max-seconds "$maxs" \
        --quiet 2>"$tmp/$tag.err"
    rc=$?
    end=$(date +%s.%N)
    t=$(printf '%.1f' "$(echo "$end - $start" | bc)")
    v= err= stop= inc=
    if [ -s "$tmp/$tag.json" ]; then
        v=$(num vertices "$tmp/$tag.json")
        err=$(num mean "$tmp/$tag.json")
        [ -n "$err" ] && err=$(printf '%.3g' "$err")
        stop=$(sed -n 's/.*"stop_reason": "\([a-z_]*\)".*/\1/p' "$tmp/$tag.json")
        inc=$(num inconsistent_facets "$tmp/$tag.json")
    fi
}
status() { # how a run ended, for a table cell
    if [ "$rc" = 0 ]; then echo "certified"; elif [ -n "$stop" ]; then
        echo "exit $rc ($stop, $inc inconsistent)"
    else echo "exit $rc: $(head -c 120 "$tmp/$tag.err")"; fi
}
# piece TAG R: vertices of $tmp/TAG.ply with 0 <= atan2(y, x) <= 2 pi / R
piece() {
    awk -v R="$2" 'BEGIN { pi = atan2(0, -1); lim = 2 * pi / R }
        /^#/ || NF == 0 { next }
        state == 0 { state = 1; next }
        state == 1 { nv = $1; state = 2; next }
        state == 2 && n < nv { n++; a = atan2($2, $1); if (a >= 0 && a <= lim) c++ }
        END { print c + 0 }' "$tmp/$1.off"
}
render() { # render TAG NAME [VIEW]: docs picture of a run, coloured by anisotropy
    [ "$rc" = 0 ] || [ "$rc" = 3 ] || return 0
    "$tool" render "$tmp/$1.ply" -o "$imgdir/$2.png" --color anisotropy --size 800x600 \
        --view "${3:-30,20}" >/dev/null 2>&1 && echo "![$2]($(basename "$imgdir")/$2.png)"
}

echo "<!-- bench/paper.sh $tool $maxs: $(date -u '+%Y-%m-%d %H:%M UTC'), $(grep -m1 'model name' /proc/cpuinfo 2>/dev/null | sed 's/.*: //'), $(nproc) cores -->"

if has fig4; then
    echo
    echo "### Fig. 4: the shock sphere"
    echo
    run fig4 --builtin sphere --metric shock,lambda=0.6 --rho0 3 --r0 0.1 --gamma0 1.4
    echo "Paper: 18,323 vertices. Ours: $v vertices in $t s, mean error $err, $(status)."
    echo
    render fig4 paper_fig4_shock 30,20
fi
if has fig5; then
    echo
    echo "### Fig. 5: the chair"
    echo
    run fig5 --builtin chair,a=0.8,b=0.4,k=1 --metric curvature --rho0 3 --r0 0.1 --gamma0 1.3
    echo "Paper: 24,164 vertices. Ours: $v vertices in $t s, mean error $err, $(status)."
    echo
    render fig5 paper_fig5_chair 30,20
fi
if has fig7; then
    echo
    echo "### Fig. 7: time against gamma0 (torus R 10, r 1, r0 0.1, default curvature)"
    echo
    echo "| gamma0 | vertices | s | vertices/s | mean error | end |"
    echo "|---|---|---|---|---|---|"
    for g in 1.3 1.4 1.5 1.6 1.7 1.8; do
        run fig7 --builtin torus,R=10,r=1 --metric curvature --r0 0.1 --gamma0 "$g"
        vps=$(echo "${v:-0} / $t" | bc 2>/dev/null)
        echo "| $g | $v | $t | $vps | $err | $(status) |"
    done
fi
if has table2; then
    echo
    echo "### Table 2: beta x delta (torus R 10, r 1, r0 0.1, gamma0 1.5)"
    echo
    echo "Each cell: vertices, seconds, mean error. Paper (its metric's eps not given): delta 0.1:"
    echo "5,687 / 5,652 / 5,660 / 5,643; delta 0.3: 5,227 / 5,104 / 5,130 / 5,065; delta 0.5:"
    echo "4,926 / 4,979 / 4,903 / 4,973 (beta 2 / 3 / 4 / 5), in 72-512 s."
    for cap in 1 0; do
        echo
        echo "\`--metric curvature --aniso-cap $cap\`$([ $cap = 1 ] && echo ' (the default)'):"
        echo
        echo "| delta \\\\ beta | 2 | 3 | 4 | 5 |"
        echo "|---|---|---|---|---|"
        for d in 0.1 0.3 0.5; do
            line="| $d |"
            for b in 2 3 4 5; do
                run t2 --builtin torus,R=10,r=1 --metric curvature --r0 0.1 --gamma0 1.5 \
                    --beta "$b" --delta "$d" --aniso-cap "$cap"
                if [ "$rc" = 0 ]; then cell="$v, $t s, $err"
                else cell="$v, $t s, $(status)"; fi
                line="$line $cell |"
            done
            echo "$line"
        done
    done
fi
if has table1; then
    echo
    echo "### Table 1: anisotropic against isotropic at the same error bound (0.001)"
    echo
    echo "Tori r = 1; \`--approx 0.001 --r0 1 --gamma0 1.8\`, the metric \`curvature\` (N_aniso)"
    echo "or \`euclidean\` (N_iso). The piece: the vertices with 0 <= atan2(y, x) <= 2 pi / R."
    echo "Paper (a piece): R 10: 2,314 / 6,310 (36%); R 50: 1,217 / 6,120 (19.9%); R 200: 898 /"
    echo "6,040 (14.9%)."
    echo
    echo "| R | aniso-cap | N_aniso whole | error | s | end | N_iso whole | error | s | end | kappa whole | N_aniso piece | N_iso piece | kappa piece |"
    echo "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"
    for rc_ in 10:1 50:1 200:1 10:0; do
        R=${rc_%:*} cap=${rc_#*:}
        run t1a --builtin torus,R=$R,r=1 --metric curvature --approx 0.001 --r0 1 --gamma0 1.8 \
            --aniso-cap "$cap"
        va=$v ea=$err ta=$t sa=$(status) pa=
        [ "$rc" = 0 ] && pa=$(piece t1a $R)
        [ "$R" = 50 ] && [ "$cap" = 1 ] && [ "$rc" = 0 ] && cp "$tmp/t1a.off" "$tmp/fig9.off" && rc9=0
        :
        run t1i --builtin torus,R=$R,r=1 --metric euclidean --approx 0.001 --r0 1 --gamma0 1.8
        vi=$v ei=$err ti=$t si=$(status) pi=
        [ "$rc" = 0 ] && pi=$(piece t1i $R)
        kw= kp=
        [ -n "$va" ] && [ -n "$vi" ] && [ "$vi" -gt 0 ] 2>/dev/null &&
            kw=$(echo "scale=1; 100 * $va / $vi" | bc)%
        [ -n "$pa" ] && [ -n "$pi" ] && [ "$pi" -gt 0 ] &&
            kp=$(echo "scale=1; 100 * $pa / $pi" | bc)%
        echo "| $R | $cap | $va | $ea | $ta | $sa | $vi | $ei | $ti | $si | $kw | $pa | $pi | $kp |"
    done
fi
if has fig8; then
    echo
    echo "### Fig. 8: squared radius-edge ratios before and after --optimize"
    echo
    # the paper's field: the jets as fitted (a mesh's curvature is graded by default since
    # session 18; grad=0 keeps the runs comparable with the paper's and with docs/paper.md)
    run fig8 "$data/knot1.off" --metric curvature,grad=0 --r0 1 --gamma0 1.5 --optimize
    f="$tmp/fig8.json"
    echo "knot1.off, \`--metric curvature,grad=0 --r0 1 --gamma0 1.5 --optimize\`: $v vertices, $(status);"
    echo "refinement $(num refine "$f") s, optimisation $(sed -n 's/.*"optimize": {"done": [a-z]*, "moved": \([0-9]*\), "tries": \([0-9]*\), "passes": \([0-9]*\), "seconds": \([-0-9.eE+]*\).*/\4 s (\1 vertices moves in \3 passes)/p' "$f");"
    echo "mean rho^2 $(num rho2_mean_before "$f") before, $(num rho2_mean "$f") after."
    echo
    w=$(num histogram_width "$f")
    echo "| rho^2 | before | after |"
    echo "|---|---|---|"
    set -- $(arr histogram_before "$f")
    before="$*"
    set -- $(arr histogram "$f")
    after="$*"
    i=0
    for b in $before; do
        a=$(echo "$after" | cut -d' ' -f$((i + 1)))
        if [ "$b" != 0 ] || [ "$a" != 0 ]; then
            printf "| %.2f-%.2f | %s | %s |\n" "$(echo "$i * $w" | bc)" "$(echo "($i + 1) * $w" | bc)" "$b" "$a"
        fi
        i=$((i + 1))
    done
fi
if has fig9; then
    echo
    echo "### Fig. 9: a piece of the torus R 50"
    echo
    if [ "${rc9:-1}" = 0 ]; then
        # the triangles whose three vertices lie within 0 <= atan2(y, x) <= 4 / R (a length
        # 4, four tube radii, along the big circle), vertices renumbered; coloured by the
        # triangles' aspect ratio (an OFF carries no tensors)
        awk 'BEGIN { lim = 4 / 50 }
            /^#/ || NF == 0 { next }
            st == 0 { st = 1; next }
            st == 1 { nv = $1; nf = $2; st = 2; next }
            st == 2 { x[n] = $1; y[n] = $2; z[n] = $3; a = atan2($2, $1);
                      keep[n] = (a >= 0 && a <= lim); n++; if (n == nv) st = 3; next }
            st == 3 && $1 == 3 { if (keep[$2] && keep[$3] && keep[$4]) { t[m++] = $2 " " $3 " " $4 } }
            END { k = 0; for (i = 0; i < nv; i++) if (keep[i]) id[i] = k++;
                  print "OFF"; print k, m, 0
                  for (i = 0; i < nv; i++) if (keep[i]) print x[i], y[i], z[i]
                  for (j = 0; j < m; j++) { split(t[j], v, " "); print 3, id[v[1]], id[v[2]], id[v[3]] } }' \
            "$tmp/fig9.off" >"$tmp/piece.off"
        "$tool" render "$tmp/piece.off" -o "$imgdir/paper_fig9_torus50.png" --color quality \
            --size 800x600 --view 0,35 >/dev/null 2>&1 &&
            echo "![paper_fig9_torus50]($(basename "$imgdir")/paper_fig9_torus50.png)"
    else
        echo "Not rendered: Table 1's R = 50 mesh did not finish within $maxs s (or table1 was not run)."
    fi
fi
