#!/usr/bin/env bash
# Whether two quatcurve binaries write the same bytes: each bakes the same 37 configurations
# (the crowd and every real file of ../shared/data: glTF, FBX, BVH, SMPL; every texture kind,
# npy/exr/png16, atlas f16, exact rate, vertex, error budgets, root motion; cpu and gpu; a fit and bakes of its
# containers) into one directory,
# and the sha256 of every file but manifests (times, hosts) is compared. For refactors that
# must not change output.
#   scripts/same-outputs.sh OLD_BINARY NEW_BINARY [DATA_DIR]
set -euo pipefail
old=$1 new=$2 data=${3:-"$(dirname "$0")/../../shared/data"}
work=$(mktemp -d)
hashes() {
    local bin=$1 out=$work/out i=0
    rm -rf "$out" && mkdir -p "$out"
    run() { i=$((i + 1)); "$bin" bake --output "$out/c$i" "$@" >/dev/null 2>&1 || echo "config $i failed: $*" >&2; }
    local real="$data/Fox.glb $data/CesiumMan.glb $data/BrainStem.glb $data/SimpleSkin.gltf $data/cmu_131_01.bvh $data/cmu_131_03.bvh"
    for dev in cpu gpu; do
        run --device $dev --characters 50
        for tex in local model skin model-trs skin-trs; do run --device $dev --input $real --texture $tex --rate 30; done
        run --device $dev --input "$data/Fox.glb" "$data/CesiumMan.glb" "$data/BrainStem.glb" --texture vertex --rate 15
        run --device $dev --input $real --atlas --precision f16 --rate 60
        run --device $dev --input $real --exact-rate --rate 24 --curve slerp
        run --device $dev --input "$data/CesiumMan.glb" "$data/Fox.glb" --texture skin-trs --format exr --rate 30
        run --device $dev --input "$data/CesiumMan.glb" --texture skin --format png16 --rate 30
        run --device $dev --input "$data/CesiumMan.glb" --texture skin-trs --max-error-deg 1 --max-error-cm 0.5
        run --device $dev --input "$data/Fox.glb" --texture local --max-error-deg 2 --max-error-cm 5
        run --device $dev --input "$data/CesiumMan.glb" --root-motion extract --rate 30
        run --device $dev --input "$data/CesiumMan.fbx" "$data/Fox.fbx" "$data/Samba_Dancing.fbx" --texture skin --rate 30
        run --device $dev --input "$data/RobotExpressive.glb" --texture skin-trs --format exr --rate 30
        run --device $dev --input "$data/amass_sample.npz" --rate 60
    done
    "$bin" fit --input "$data/CesiumMan.glb" "$data/Fox.glb" --output "$out/fit" >/dev/null 2>&1 || echo "fit failed" >&2
    for dev in cpu gpu; do run --device $dev --input "$out"/fit/*.qcf --rate 30; done
    (cd "$out" && find . -type f ! -name '*manifest*' | sort | xargs sha256sum)
}
hashes "$old" > "$work/old.txt"
hashes "$new" > "$work/new.txt"
if diff "$work/old.txt" "$work/new.txt"; then
    echo "identical: $(wc -l < "$work/new.txt") files"
else
    echo "different (above)"; exit 1
fi
