"""The bake's OpenUSD stage (`bake --usd`) read by Pixar's own library (usd-core): each joint's
transform at each clip's every time sample, as UsdSkel computes it, is the bake's model texture
(within 1e-5 of the model's extent), each clip chosen by the skeleton's variant set; each mesh
skinned by UsdSkel is the bake's vertex texture; and usdchecker's validators (UsdValidation)
report no error. A stage usd-core writes from a glTF's data bakes as UsdSkel poses it, and
`play --usd`'s crowd poses each instance as its palette. CI requires usd-core
(`QUATCURVE_REQUIRE_USD=1`)."""

import importlib.util
import json
import os
import pathlib
import re
import struct
import subprocess

import numpy as np
import pytest

from test_quatcurve import cli, data_files

if importlib.util.find_spec("pxr") is None:
    if os.environ.get("QUATCURVE_REQUIRE_USD") == "1":
        raise RuntimeError("QUATCURVE_REQUIRE_USD=1 but usd-core is not installed (pip install usd-core)")
    pytest.skip("usd-core is not installed (pip install usd-core)", allow_module_level=True)

from pxr import Gf, Usd, UsdGeom, UsdSkel, UsdValidation, Vt  # noqa: E402


def identifier(name, taken):
    """A name as a USD identifier, unique among `taken`: the rule the stage is written by,
    written again here so that the joints are matched independently of the writer."""
    base = re.sub(r"[^A-Za-z0-9]", "_", name)
    if not base or base[0].isdigit():
        base = "_" + base
    unique, k = base, 2
    while unique in taken:
        unique, k = f"{base}_{k}", k + 1
    taken.add(unique)
    return unique


def joint_paths(names, parents):
    paths, siblings = [None] * len(names), {}
    pending = list(range(len(names)))
    while pending:
        for j in list(pending):
            p = parents[j]
            if p is None or p < 0 or paths[p] is not None:
                own = identifier(names[j], siblings.setdefault(p, set()))
                paths[j] = own if p is None or p < 0 else f"{paths[p]}/{own}"
                pending.remove(j)
    return paths


def bake_both(binary, tmp_path, args, stem):
    usd, model = tmp_path / "usd", tmp_path / "model"
    subprocess.run([str(binary), "bake", *args, "--usd", "--output", str(usd)], check=True, capture_output=True)
    subprocess.run(
        [str(binary), "bake", *args, "--texture", "model", "--output", str(model)], check=True, capture_output=True
    )
    return usd / f"{stem}.usda", json.loads((model / f"{stem}.json").read_text()), model


def hold(stage_path, sidecar, model_dir):
    stage = Usd.Stage.Open(str(stage_path))
    root = stage.GetDefaultPrim()
    skeleton = UsdSkel.Skeleton(root.GetChild("Skeleton"))
    order = [str(t) for t in skeleton.GetJointsAttr().Get()]
    paths = joint_paths(sidecar["joints"], sidecar["parents"])
    columns = [paths.index(p) for p in order]
    tcps = stage.GetTimeCodesPerSecond()
    clips = skeleton.GetPrim().GetVariantSets().GetVariantSet("clip")
    assert len(clips.GetVariantNames()) == len(sidecar["clips"])
    taken = set()
    for clip in sidecar["clips"]:
        clips.SetVariantSelection(identifier(clip["name"], taken))
        query = UsdSkel.Cache().GetSkelQuery(skeleton)
        model = np.load(model_dir / clip["file"]).reshape(clip["frames"], len(paths), 3, 4)
        extent = np.ptp(model[:, :, :, 3].reshape(-1, 3), axis=0).max()
        times = clip["start"] + np.arange(clip["frames"]) / clip["rate"]
        worst = 0.0
        for k, t in enumerate(times):
            got = np.array([np.array(m) for m in query.ComputeJointSkelTransforms((t - times[0]) * tcps)])
            # USD's row vectors: the transpose of our 3x4 rows.
            got = np.transpose(got, (0, 2, 1))[:, :3, :]
            worst = max(worst, np.abs(got - model[k, columns]).max())
        assert worst <= 1e-5 * max(extent, 1e-9), f"{clip['name']}: {worst} against an extent of {extent}"
    # usdchecker's validators (UsdValidation, which replaced UsdUtils.ComplianceChecker).
    validators = UsdValidation.ValidationRegistry().GetOrLoadAllValidators()
    errors = UsdValidation.ValidationContext(validators).Validate(stage)
    assert not errors, [f"{e.GetName()}: {e.GetMessage()}" for e in errors]


def hold_meshes(stage_path, sidecar, vertex_dir):
    """Every mesh of the stage, skinned by UsdSkel at every clip's every time sample, is the
    bake's vertex texture of its primitive (within 1e-5 of the skinned points' extent)."""
    stage = Usd.Stage.Open(str(stage_path))
    root = stage.GetDefaultPrim()
    skeleton = UsdSkel.Skeleton(root.GetChild("Skeleton"))
    taken = {"Skeleton", "Animations"}
    names = [identifier(p["name"], taken) for p in sidecar["vertex"]["primitives"]]
    assert names and all(root.GetChild(n).IsValid() for n in names), names
    clips = skeleton.GetPrim().GetVariantSets().GetVariantSet("clip")
    tcps = stage.GetTimeCodesPerSecond()
    taken_clips = set()
    for clip in sidecar["clips"]:
        clips.SetVariantSelection(identifier(clip["name"], taken_clips))
        cache = UsdSkel.Cache()
        cache.Populate(UsdSkel.Root(root), Usd.PrimDefaultPredicate)
        query = cache.GetSkelQuery(skeleton)
        for k, name in enumerate(names):
            mesh = root.GetChild(name)
            skinning = cache.GetSkinningQuery(mesh)
            rest = UsdGeom.Mesh(mesh).GetPointsAttr().Get()
            expected = np.load(vertex_dir / clip["files"][k])[:, :, :3]
            extent = np.ptp(expected.reshape(-1, 3), axis=0).max()
            worst = 0.0
            for f in range(clip["frames"]):
                code = f / clip["rate"] * tcps
                points = Vt.Vec3fArray(rest)
                assert skinning.ComputeSkinnedPoints(query.ComputeSkinningTransforms(code), points, code)
                worst = max(worst, np.abs(np.array(points) - expected[f]).max())
            assert worst <= 1e-5 * extent, f"{clip['name']}, {name}: {worst} against an extent of {extent}"


def test_the_crowd_s_stage_poses_as_its_model_texture_in_usd(tmp_path):
    stage, sidecar, model = bake_both(cli(), tmp_path, ["--characters", "3"], "crowd")
    hold(stage, sidecar, model)


@pytest.mark.parametrize("name", ["CesiumMan.glb", "Fox.glb", "BrainStem.glb", "cmu_131_01.bvh"])
def test_a_real_file_s_stage_poses_as_its_model_texture_in_usd(name, tmp_path):
    (path,) = map(pathlib.Path, data_files(name))
    extra = ["--unit-cm", "5.644"] if name.endswith(".bvh") else []
    stage, sidecar, model = bake_both(cli(), tmp_path, ["--input", str(path), *extra], path.stem)
    hold(stage, sidecar, model)
    if path.suffix == ".glb":
        vertex = tmp_path / "vertex"
        args = [str(cli()), "bake", "--input", str(path), "--texture", "vertex", "--output", str(vertex)]
        subprocess.run(args, check=True, capture_output=True)
        hold_meshes(stage, json.loads((vertex / f"{path.stem}.json").read_text()), vertex)


def test_python_s_bake_writes_the_stage_the_cli_writes(tmp_path):
    import quatcurve

    quatcurve.bake(output=tmp_path / "py", characters=3, usd=True)
    args = [str(cli()), "bake", "--characters", "3", "--usd", "--output", str(tmp_path / "cli")]
    subprocess.run(args, check=True, capture_output=True)
    assert (tmp_path / "py" / "crowd.usda").read_bytes() == (tmp_path / "cli" / "crowd.usda").read_bytes()


def read_glb(path):
    """A GLB's JSON and a reader of its accessors as arrays (normalized integers as floats)."""
    data = path.read_bytes()
    (json_length,) = struct.unpack_from("<I", data, 12)
    document = json.loads(data[20 : 20 + json_length])
    blob = data[20 + json_length + 8 :]
    widths = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT4": 16}
    types = {5121: np.uint8, 5123: np.uint16, 5125: np.uint32, 5126: np.float32}

    def accessor(index):
        a = document["accessors"][index]
        view = document["bufferViews"][a["bufferView"]]
        dtype, width = np.dtype(types[a["componentType"]]), widths[a["type"]]
        stride = view.get("byteStride") or dtype.itemsize * width
        offset = view.get("byteOffset", 0) + a.get("byteOffset", 0)
        values = np.ndarray((a["count"], width), dtype, blob, offset, (stride, dtype.itemsize)).astype(np.float64)
        if a.get("normalized"):
            values /= np.iinfo(dtype).max
        return values

    return document, accessor


def sample(times, values, at, rotation, step):
    """glTF's LINEAR (slerp for rotations) or STEP of keys at times `at`."""
    k = np.clip(np.searchsorted(times, at, side="right") - 1, 0, len(times) - 1)
    if step or len(times) == 1:
        return values[k]
    j = np.minimum(k + 1, len(times) - 1)
    u = np.clip((at - times[k]) / np.maximum(times[j] - times[k], 1e-12), 0, 1)[:, None]
    a, b = values[k], values[j]
    if not rotation:
        return a + (b - a) * u
    b = b * np.sign(np.sum(a * b, axis=1, keepdims=True) + 1e-300)
    angle = np.arccos(np.clip(np.sum(a * b, axis=1, keepdims=True), -1, 1))
    s = np.sin(angle)
    near = s < 1e-9
    wa = np.where(near, 1 - u, np.sin((1 - u) * angle) / np.where(near, 1, s))
    wb = np.where(near, u, np.sin(u * angle) / np.where(near, 1, s))
    return wa * a + wb * b


TIME_CODES = 24.0
# The stage's space: centimetres, +Z up, the skeleton under a turned and moved Xform, so that
# the importer's units, axes and ancestors' transforms are all on trial.
METRES_PER_UNIT = 0.01
TO_GLTF = np.diag([METRES_PER_UNIT] * 3 + [1.0]) @ np.array(
    [[1, 0, 0, 0], [0, 0, 1, 0], [0, -1, 0, 0], [0, 0, 0, 1]], dtype=float
)


def usd_core_stage(glb, path):
    """A stage written by usd-core from a glTF's first skin: its joints (paths from the node
    tree), rest transforms (the nodes') and bind transforms (the inverse bind matrices
    inverted), each animation a SkelAnimation of every joint at the union of its key times,
    and the skin's first mesh bound by SkelBindingAPI. Returns the stage, the skeleton, the
    animations' paths and first key times, and the mesh's path."""
    document, accessor = read_glb(glb)
    nodes, skin = document["nodes"], document["skins"][0]
    joints = skin["joints"]
    parent = {c: p for p, n in enumerate(nodes) for c in n.get("children", [])}
    names, paths = {}, {}
    for j in joints:
        names[j] = re.sub(r"[^A-Za-z0-9_]", "_", nodes[j].get("name", f"joint{j}")) + f"_{j}"
    for j in joints:
        chain, k = [], j
        while k is not None:
            if k in names:
                chain.append(names[k])
            k = parent.get(k)
        paths[j] = "/".join(reversed(chain))
    order = sorted(joints, key=lambda j: paths[j].count("/"))

    def rest_of(j):
        n = nodes[j]
        return (
            np.array(n.get("translation", [0, 0, 0]), float),
            np.array(n.get("rotation", [0, 0, 0, 1]), float),
            np.array(n.get("scale", [1, 1, 1]), float),
        )

    def matrix(t, r, s):
        x, y, z, w = r
        rotation = np.array(
            [
                [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
            ]
        )
        m = np.eye(4)
        m[:3, :3], m[:3, 3] = rotation * s, t
        return Gf.Matrix4d(m.T.tolist())

    stage = Usd.Stage.CreateNew(str(path))
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.z)
    UsdGeom.SetStageMetersPerUnit(stage, METRES_PER_UNIT)
    stage.SetTimeCodesPerSecond(TIME_CODES)
    root = UsdSkel.Root.Define(stage, "/Character")
    stage.SetDefaultPrim(root.GetPrim())
    offset = UsdGeom.Xform.Define(stage, "/Character/Offset")
    offset.AddTranslateOp().Set(Gf.Vec3d(50, -20, 10))
    offset.AddRotateZOp().Set(30.0)
    skeleton = UsdSkel.Skeleton.Define(stage, "/Character/Offset/Skeleton")
    skeleton.CreateJointsAttr([paths[j] for j in order])
    skeleton.CreateRestTransformsAttr([matrix(*rest_of(j)) for j in order])
    inverse_bind = accessor(skin["inverseBindMatrices"]).reshape(-1, 4, 4)
    at = {j: k for k, j in enumerate(joints)}
    skeleton.CreateBindTransformsAttr([Gf.Matrix4d(np.linalg.inv(inverse_bind[at[j]]).tolist()) for j in order])
    animations = []
    for a, animation in enumerate(document.get("animations", [])):
        channels = [c for c in animation["channels"] if c["target"].get("node") in names]
        keys = {}
        for c in channels:
            sampler = animation["samplers"][c["sampler"]]
            keys[(c["target"]["node"], c["target"]["path"])] = (
                accessor(sampler["input"])[:, 0],
                accessor(sampler["output"]),
                sampler.get("interpolation", "LINEAR") == "STEP",
            )
        times = np.unique(np.concatenate([k[0] for k in keys.values()]))
        name = re.sub(r"[^A-Za-z0-9_]", "_", animation.get("name", f"animation{a}")) or f"animation{a}"
        anim = UsdSkel.Animation.Define(stage, f"/Character/Animations/{name}")
        anim.CreateJointsAttr([paths[j] for j in order])
        rotations, translations, scales = (anim.CreateRotationsAttr(), anim.CreateTranslationsAttr(), anim.CreateScalesAttr())
        sampled = {}
        for j in order:
            rest = rest_of(j)
            for p, (kind, value) in enumerate([("translation", rest[0]), ("rotation", rest[1]), ("scale", rest[2])]):
                if (j, kind) in keys:
                    t, v, step = keys[(j, kind)]
                    sampled[(j, kind)] = sample(t, v, times, kind == "rotation", step)
                else:
                    sampled[(j, kind)] = np.tile(value, (len(times), 1))
        for k, t in enumerate(times):
            code = Usd.TimeCode(t * TIME_CODES)
            rotations.Set([Gf.Quatf(*map(float, sampled[(j, "rotation")][k][[3, 0, 1, 2]])) for j in order], code)
            translations.Set([Gf.Vec3f(*map(float, sampled[(j, "translation")][k])) for j in order], code)
            scales.Set([Gf.Vec3h(*map(float, sampled[(j, "scale")][k])) for j in order], code)
        animations.append((anim.GetPrim().GetPath(), times[0]))
    binding = UsdSkel.BindingAPI.Apply(skeleton.GetPrim())
    binding.CreateAnimationSourceRel().SetTargets([animations[0][0]])
    skinned = next(n["mesh"] for n in nodes if n.get("skin") == 0 and "mesh" in n)
    primitive = document["meshes"][skinned]["primitives"][0]
    attributes = primitive["attributes"]
    mesh = UsdGeom.Mesh.Define(stage, "/Character/Body")
    points = accessor(attributes["POSITION"])
    mesh.CreatePointsAttr([Gf.Vec3f(*map(float, p)) for p in points])
    has_indices = "indices" in primitive
    triangles = accessor(primitive["indices"]).astype(int).ravel() if has_indices else np.arange(len(points))
    mesh.CreateFaceVertexCountsAttr([3] * (len(triangles) // 3))
    mesh.CreateFaceVertexIndicesAttr([int(i) for i in triangles])
    mesh_binding = UsdSkel.BindingAPI.Apply(mesh.GetPrim())
    mesh_binding.CreateSkeletonRel().SetTargets([skeleton.GetPrim().GetPath()])
    # The skin's joints in the skin's order: the vertices' joint indices are into them.
    mesh_binding.CreateJointsAttr([paths[j] for j in joints])
    mesh_binding.CreateJointIndicesPrimvar(False, 4).Set([int(i) for i in accessor(attributes["JOINTS_0"]).ravel()])
    mesh_binding.CreateJointWeightsPrimvar(False, 4).Set([float(w) for w in accessor(attributes["WEIGHTS_0"]).ravel()])
    mesh_binding.CreateGeomBindTransformAttr(Gf.Matrix4d(1.0))
    stage.GetRootLayer().Save()
    return stage, skeleton, [paths[j] for j in order], animations, mesh.GetPrim()


@pytest.mark.parametrize("name", ["CesiumMan.glb", "Fox.glb"])
def test_a_stage_usd_core_writes_bakes_as_usd_skel_poses_it(name, tmp_path):
    """A binary stage written by Pixar's library (usd-core) from a glTF's data, baked by
    quatcurve: every joint's model matrix is UsdSkel's world transform of it (its ancestors'
    transforms, centimetres and +Z up taken to glTF's metres and +Y up) at every baked frame
    of every animation, and every skinned point is UsdSkel's, within 1e-5 of the extent."""
    (glb,) = map(pathlib.Path, data_files(name))
    stage_path = tmp_path / f"{glb.stem}.usdc"
    stage, skeleton, usd_joints, animations, body = usd_core_stage(glb, stage_path)
    model, vertex = tmp_path / "model", tmp_path / "vertex"
    for texture, out in [("model", model), ("vertex", vertex)]:
        args = [str(cli()), "bake", "--input", str(stage_path), "--texture", texture, "--output", str(out)]
        subprocess.run(args, check=True, capture_output=True)
    sidecar = json.loads((model / f"{glb.stem}.json").read_text())
    vertex_sidecar = json.loads((vertex / f"{glb.stem}.json").read_text())
    names, parents = sidecar["joints"], sidecar["parents"]

    def path_of(j):
        chain = []
        while j is not None and j >= 0:
            chain.append(names[j])
            j = parents[j]
        return "/".join(reversed(chain))

    ours = [path_of(j) for j in range(len(names))]
    # The importer's skeleton node is the root above the joints.
    columns = [ours.index(f"Skeleton/{p}") for p in usd_joints]
    assert len(sidecar["clips"]) == len(animations)
    binding = UsdSkel.BindingAPI(skeleton.GetPrim())
    for clip, vertex_clip, (animation, first) in zip(sidecar["clips"], vertex_sidecar["clips"], animations):
        assert clip["name"] == animation.name
        binding.GetAnimationSourceRel().SetTargets([animation])
        cache = UsdSkel.Cache()
        cache.Populate(UsdSkel.Root(stage.GetDefaultPrim()), Usd.PrimDefaultPredicate)
        query = cache.GetSkelQuery(skeleton)
        skinning = cache.GetSkinningQuery(body)
        baked = np.load(model / clip["file"]).reshape(clip["frames"], len(names), 3, 4)[:, columns]
        skinned = np.load(vertex / vertex_clip["files"][0])[:, :, :3]
        extent = np.ptp(baked[:, :, :, 3].reshape(-1, 3), axis=0).max()
        skinned_extent = np.ptp(skinned.reshape(-1, 3), axis=0).max()
        worst = worst_point = 0.0
        rest = body.GetAttribute("points").Get()
        for f in range(clip["frames"]):
            code = Usd.TimeCode((first + f / clip["rate"]) * TIME_CODES)
            xforms = UsdGeom.XformCache(code)
            world = np.array([np.array(m).T for m in query.ComputeJointWorldTransforms(xforms)])
            expected = np.einsum("ij,njk->nik", TO_GLTF, world)[:, :3, :]
            worst = max(worst, np.abs(expected - baked[f]).max())
            points = Vt.Vec3fArray(rest)
            assert skinning.ComputeSkinnedPoints(query.ComputeSkinningTransforms(code), points, code)
            to_world = TO_GLTF @ np.array(xforms.GetLocalToWorldTransform(skeleton.GetPrim())).T
            expected_points = (to_world[:3, :3] @ np.array(points).T).T + to_world[:3, 3]
            worst_point = max(worst_point, np.abs(expected_points - skinned[f]).max())
        assert worst <= 1e-5 * extent, f"{clip['name']}: {worst} against an extent of {extent}"
        assert worst_point <= 1e-5 * skinned_extent, f"{clip['name']}: {worst_point} against {skinned_extent}"


@pytest.mark.parametrize(
    "name, extra", [("Fox.glb", ["--instances", "7"]), ("CesiumMan.glb", ["--instances", "4", "--blend-weight", "0.3"])]
)
def test_play_s_crowd_stage_poses_each_instance_as_its_palette(name, extra, tmp_path):
    """`play --usd`: each instance of the crowd stage, an instance of the one character (a
    shared prototype), posed by UsdSkel at every frame (its skinning transforms, the skin's
    joints by `skel:joints`) is play's palette for that instance within 1e-5 of the extent,
    over three seconds (past a clip's end, where play starts it again); usdchecker's
    validators report no error."""
    (path,) = map(pathlib.Path, data_files(name))
    output = tmp_path / "crowd.npy"
    args = [str(cli()), "play", "--input", str(path), *extra, "--seconds", "3", "--output", str(output), "--usd"]
    subprocess.run(args, check=True, capture_output=True)
    palettes = np.load(output)
    frames, instances, joints, _ = palettes.shape
    palettes = palettes.reshape(frames, instances, joints, 3, 4)
    extent = np.ptp(palettes[..., 3].reshape(-1, 3), axis=0).max()
    stage = Usd.Stage.Open(str(tmp_path / "crowd.usda"))
    assert len(stage.GetPrototypes()) == 1, "the character shared by every instance"
    cache = UsdSkel.Cache()
    worst = 0.0
    for i in range(instances):
        root = stage.GetPrimAtPath(f"/Crowd/Instance_{i}")
        assert root.IsInstance()
        cache.Populate(UsdSkel.Root(root), Usd.TraverseInstanceProxies())
        query = cache.GetSkelQuery(UsdSkel.Skeleton(root.GetChild("Skeleton")))
        assert query.GetAnimQuery().GetPrim().GetPath() == f"/Crowd/Motion/Instance_{i}"
        order = [str(t) for t in query.GetJointOrder()]
        mesh = next(c for c in root.GetFilteredChildren(Usd.TraverseInstanceProxies()) if c.IsA(UsdGeom.Mesh))
        columns = [order.index(str(j)) for j in mesh.GetAttribute("skel:joints").Get()]
        for k in range(frames):
            # USD's row vectors: each matrix transposed is the palette's 3x4 rows.
            got = np.array([np.array(m).T[:3] for m in query.ComputeSkinningTransforms(k)])[columns]
            worst = max(worst, np.abs(got - palettes[k, i]).max())
    assert worst <= 1e-5 * extent, f"{worst} against an extent of {extent}"
    validators = UsdValidation.ValidationRegistry().GetOrLoadAllValidators()
    errors = UsdValidation.ValidationContext(validators).Validate(stage)
    assert not errors, [f"{e.GetName()}: {e.GetMessage()}" for e in errors]
