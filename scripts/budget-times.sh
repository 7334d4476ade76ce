#!/usr/bin/env bash
# How long an error budget takes against a fixed-rate bake: each shared file baked
# `--texture skin-trs --max-error-deg 0.5` by two quatcurve binaries, and at a fixed rate (the
# highest the budget chooses for it) by the second, alternated over ROUNDS rounds; prints
# min-median-max seconds of each. The machine is shared: read ranges, not one run.
#   scripts/budget-times.sh OLD_BINARY NEW_BINARY [ROUNDS] [DATA_DIR]
set -euo pipefail
old=$1 new=$2 rounds=${3:-5} data=${4:-"$(dirname "$0")/../../shared/data"}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
seconds() { /usr/bin/time -f %e "$@" --output "$work/out" 2>&1 >/dev/null | tail -1; }
for input in Samba_Dancing.fbx:120 BrainStem.glb:112.5 RobotExpressive.glb:72 Fox.glb:120 CesiumMan.glb:24; do
    file=${input%%:*} rate=${input##*:}
    for _ in $(seq "$rounds"); do
        echo "before $(seconds "$old" bake --input "$data/$file" --texture skin-trs --max-error-deg 0.5)"
        echo "now $(seconds "$new" bake --input "$data/$file" --texture skin-trs --max-error-deg 0.5)"
        echo "fixed $(seconds "$new" bake --input "$data/$file" --texture skin-trs --rate "$rate")"
    done | sort -k1,1 -k2n | awk -v f="$file" '
        { n[$1]++; v[$1, n[$1]] = $2 }
        END {
            printf "%s", f
            for (k in n) printf " | %s %s-%s-%s", k, v[k, 1], v[k, int((n[k] + 1) / 2)], v[k, n[k]]
            print ""
        }'
done
