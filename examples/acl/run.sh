#!/usr/bin/env bash
# ACL 2.1.0 beside quatcurve on this machine: ACL's ratio and decompression time on the raw CMU
# clips, then `quatcurve bench --fitted` (one thread) on their fitted containers, alternated
# ROUNDS times, since a shared machine's speed drifts from minute to minute.
#
# Usage: ACL_DIR=path/to/acl examples/acl/run.sh DATA_DIR FITTED_DIR [ROUNDS]
#   ACL_DIR     a checkout of ACL v2.1.0 with its submodule external/rtm
#               (git clone --branch v2.1.0 --recurse-submodules https://github.com/nfrechette/acl)
#   DATA_DIR    holds cmu_131_01.bvh and cmu_131_03.bvh
#   FITTED_DIR  holds their containers: quatcurve fit --input DATA_DIR/cmu_131_0{1,3}.bvh
#               --unit-cm 5.644 --max-error 0.01 --output FITTED_DIR
set -euo pipefail
: "${ACL_DIR:?set ACL_DIR to an ACL v2.1.0 checkout with external/rtm}"
data=${1:?DATA_DIR}
fitted=${2:?FITTED_DIR}
rounds=${3:-4}
clips=(cmu_131_01 cmu_131_03)
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
cd "$(dirname "$0")/../.."
cargo build --release --quiet --example acl_raw --bin quatcurve
# -mavx as ACL's own CMake builds for x64.
g++ -O3 -std=c++14 -DNDEBUG -mavx -I"$ACL_DIR/includes" -I"$ACL_DIR/external/rtm/includes" \
    examples/acl/harness.cpp -o "$work/harness"
for clip in "${clips[@]}"; do
    target/release/examples/acl_raw "$data/$clip.bvh" "$work/$clip.raw" 5.644
done
containers=()
for clip in "${clips[@]}"; do containers+=("$fitted/$clip.qcf"); done
for round in $(seq "$rounds"); do
    echo "round $round"
    for clip in "${clips[@]}"; do "$work/harness" "$work/$clip.raw" 10 9; done
    RAYON_NUM_THREADS=1 target/release/quatcurve bench --fitted "${containers[@]}" --copies 10 --runs 9 --devices cpu
done
