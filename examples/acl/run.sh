#!/usr/bin/env bash
# ACL 2.1.0 beside quatcurve on this machine, the documented way to compare the two (DESIGN
# section 16): three sets of the CMU clips, each compressed by ACL at its defaults and fitted
# by quatcurve at 0.01 cm, then ACL's decompression alternated ROUNDS times with `quatcurve
# bench --fitted`, one thread, every frame in order, as a shared machine's speed drifts from
# minute to minute. The sets:
#   120hz   the two clips as captured (994 and 1102 frames)
#   24hz    each baked to 24 Hz with slerp, as ACL's published CMU figure resamples
#   short   the 24 Hz clips cut into 2 s pieces (48 frames, eight clips): a game's clip length
# quatcurve fits each set into one clip library (`fit --clip-library`: the skeleton stored once).
# Printed: each set's ratios (clip bytes, as ACL counts them), the bytes a bone-pose each
# decoder holds, and per round the ns a bone-pose of each; then each set's min-median-max.
#
# Usage: examples/acl/run.sh DATA_DIR [ROUNDS]
#   DATA_DIR    holds cmu_131_01.bvh and cmu_131_03.bvh (../shared/data)
#   ACL_DIR     ACL v2.1.0's headers with RTM's under external/rtm; by default the copy in
#               ../shared/vendor/acl-2.1.0 (no network needed)
set -euo pipefail
cd "$(dirname "$0")/../.."
acl=${ACL_DIR:-../shared/vendor/acl-2.1.0}
data=${1:?DATA_DIR}
rounds=${2:-5}
[[ -d $acl/includes/acl && -d $acl/external/rtm/includes ]] \
    || { echo "run.sh: no ACL headers at $acl (set ACL_DIR; see the head of $0)" >&2; exit 2; }
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
cargo build --release --quiet --example acl_raw --bin quatcurve
# -mavx as ACL's own CMake builds for x64.
g++ -O3 -std=c++14 -DNDEBUG -mavx -I"$acl/includes" -I"$acl/external/rtm/includes" \
    examples/acl/harness.cpp -o "$work/harness"
qc=target/release/quatcurve
unit=5.644

# A BVH file's frames cut into pieces of $2 frames (the last partial piece dropped), as
# DIR/STEM_K.bvh.
cut() {
    awk -v n="$2" -v out="$3" -v stem="$(basename "$1" .bvh)" '
        /^Frames:/ { motion = 1; next }
        /^Frame Time:/ { frame_time = $0; next }
        !motion { head = head $0 "\n"; next }
        { frames[++count] = $0 }
        END {
            for (p = 0; (p + 1) * n <= count; p++) {
                file = out "/" stem "_" p ".bvh"
                printf "%sFrames: %d\n%s\n", head, n, frame_time > file
                for (i = 1; i <= n; i++) print frames[p * n + i] > file
                close(file)
            }
        }' "$1"
}

sets=(120hz 24hz short)
mkdir -p "$work"/{120hz,24hz,short}/{bvh,raw,qcf}
for clip in cmu_131_01 cmu_131_03; do
    cp "$data/$clip.bvh" "$work/120hz/bvh/"
    "$qc" bake --input "$data/$clip.bvh" --rate 24 --curve slerp --output "$work/24hz/bvh" >/dev/null 2>&1
    cut "$work/24hz/bvh/$clip.bvh" 48 "$work/short/bvh"
done
for set in "${sets[@]}"; do
    for bvh in "$work/$set"/bvh/*.bvh; do
        target/release/examples/acl_raw "$bvh" "$work/$set/raw/$(basename "$bvh" .bvh).raw" "$unit" >/dev/null
    done
    # Each set's clips in one library, as a game keeps a skeleton's clips.
    "$qc" fit --input "$work/$set"/bvh/*.bvh --unit-cm "$unit" --max-error-cm 0.01 --clip-library "$set" --json \
        --output "$work/$set/qcf" >"$work/$set/fit.json" 2>/dev/null
done

# Ratios and bytes a bone-pose: ACL's from the harness, ours from the fit's report and the bench.
echo "set     clips  ACL ratio  ACL B/bone-pose  quatcurve ratio  quatcurve B/bone-pose held"
for set in "${sets[@]}"; do
    acl_line=$(for raw in "$work/$set"/raw/*.raw; do "$work/harness" "$raw" 1 1 | head -1; done |
        awk '{ for (i = 1; i <= NF; i++) { if ($i == "frames") f = $(i - 1); if ($i == "joints,") j = $(i - 1);
                                          if ($i == "bytes,") b = $(i - 1) }
               poses += f * j; bytes += b; n++ }
             END { printf "%d %.2f:1 %.2f", n, poses * 40 / bytes, bytes / poses }')
    ours=$(awk -F'[:,]' '/"raw_bytes"/ && !library { raw += $2 } /"compressed_bytes"/ { packed += $2 }
               /"clip_library"/ { library = 1 } END { printf "%.2f:1", raw / packed }' "$work/$set/fit.json")
    held=$(RAYON_NUM_THREADS=1 "$qc" bench --fitted "$work/$set"/qcf/*.qcf --copies 1 --runs 1 --devices cpu --json |
        sed 's/.*"held_bytes_per_bone_pose":\([0-9.]*\).*/\1/')
    read -r n ratio bpp <<<"$acl_line"
    printf "%-7s %5s  %9s  %15s  %15s  %.2f\n" "$set" "$n" "$ratio" "$bpp" "$ours" "$held"
done

# Decompression, alternated: ACL (each clip 10 copies, the mean over the set's clips) then ours.
for round in $(seq "$rounds"); do
    for set in "${sets[@]}"; do
        acl_ns=$(for raw in "$work/$set"/raw/*.raw; do "$work/harness" "$raw" 10 9 | tail -1; done |
            awk '{ for (i = 1; i <= NF; i++) if ($i == "ns") { sum += $(i - 1); n++ } } END { printf "%.2f", sum / n }')
        ours_ns=$(RAYON_NUM_THREADS=1 "$qc" bench --fitted "$work/$set"/qcf/*.qcf --copies 10 --runs 9 \
            --devices cpu --json | sed 's/.*"decoder":{[^}]*"ns_per_bone_pose":\([0-9.]*\).*/\1/')
        echo "round $round $set ACL $acl_ns quatcurve $ours_ns" | tee -a "$work/rounds.txt"
    done
done
echo "ns a bone-pose over $rounds rounds, min-median-max:"
for set in "${sets[@]}"; do
    for who in ACL quatcurve; do
        awk -v set="$set" -v who="$who" '$3 == set { for (i = 4; i <= NF; i += 2) if ($i == who) print $(i + 1) }' \
            "$work/rounds.txt" | sort -n | awk -v set="$set" -v who="$who" \
            '{ v[NR] = $1 } END { printf "%-7s %-10s %.2f-%.2f-%.2f\n", set, who, v[1], v[int((NR + 1) / 2)], v[NR] }'
    done
done
