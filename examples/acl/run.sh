#!/usr/bin/env bash
# ACL 2.1.0 beside quatcurve on this machine, the documented way to compare the two (DESIGN
# section 10): first the ratios, at the clips' 120 Hz and at 24 Hz (each clip baked to 24 Hz
# with slerp, as ACL's published CMU figure resamples), ACL's at its defaults and quatcurve's
# fit at 0.01 cm; then ACL's decompression time alternated ROUNDS times with `quatcurve bench
# --fitted` on one thread, since a shared machine's speed drifts from minute to minute.
#
# Usage: examples/acl/run.sh DATA_DIR FITTED_DIR [ROUNDS]
#   DATA_DIR    holds cmu_131_01.bvh and cmu_131_03.bvh (../shared/data)
#   FITTED_DIR  holds their containers: quatcurve fit --input DATA_DIR/cmu_131_0{1,3}.bvh
#               --unit-cm 5.644 --max-error-cm 0.01 --output FITTED_DIR
#   ACL_DIR     ACL v2.1.0's headers with RTM's under external/rtm; by default the copy in
#               ../shared/vendor/acl-2.1.0 (no network needed)
set -euo pipefail
cd "$(dirname "$0")/../.."
acl=${ACL_DIR:-../shared/vendor/acl-2.1.0}
data=${1:?DATA_DIR}
fitted=${2:?FITTED_DIR}
rounds=${3:-4}
[[ -d $acl/includes/acl && -d $acl/external/rtm/includes ]] \
    || { echo "run.sh: no ACL headers at $acl (set ACL_DIR; see the head of $0)" >&2; exit 2; }
clips=(cmu_131_01 cmu_131_03)
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
cargo build --release --quiet --example acl_raw --bin quatcurve
# -mavx as ACL's own CMake builds for x64.
g++ -O3 -std=c++14 -DNDEBUG -mavx -I"$acl/includes" -I"$acl/external/rtm/includes" \
    examples/acl/harness.cpp -o "$work/harness"
for clip in "${clips[@]}"; do
    target/release/examples/acl_raw "$data/$clip.bvh" "$work/$clip.raw" 5.644
    target/release/quatcurve bake --input "$data/$clip.bvh" --rate 24 --curve slerp --output "$work/24hz" >/dev/null
    target/release/examples/acl_raw "$work/24hz/$clip.bvh" "$work/$clip.24hz.raw" 5.644
done
echo "ratios (ACL at its defaults; quatcurve fit at 0.01 cm, its clip bytes as ACL counts them):"
for clip in "${clips[@]}"; do
    for raw in "$work/$clip.raw" "$work/$clip.24hz.raw"; do "$work/harness" "$raw" 1 1 | head -1; done
done
target/release/quatcurve fit --input "$work"/24hz/*.bvh --unit-cm 5.644 --max-error-cm 0.01 --output "$work/24fit" \
    2>/dev/null | grep -E '^\| (input|.*cmu)'
containers=()
for clip in "${clips[@]}"; do containers+=("$fitted/$clip.qcf"); done
for round in $(seq "$rounds"); do
    echo "round $round"
    for clip in "${clips[@]}"; do "$work/harness" "$work/$clip.raw" 10 9; done
    RAYON_NUM_THREADS=1 target/release/quatcurve bench --fitted "${containers[@]}" --copies 10 --runs 9 --devices cpu
done
