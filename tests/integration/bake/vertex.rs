//! Vertex skinning (the core of vertex textures) on the real skinned glTF files: the f64 CPU
//! path against an independent f64 skinning written here from the glTF crate's own readers
//! and glam (at the first and last frames, which are keys), the GPU kernel against the f64
//! path at every frame, and the mesh reader's refusals.

use super::data_dir;
use glam::{DMat4, DQuat, DVec3};
use quatcurve::anim::loops::LoopMode;
use quatcurve::bake::vertex_encoding::Bounds;
use quatcurve::bake::{texture, ClipRate};
use quatcurve::curve::{Curve, CurveSpec};
use quatcurve::device::Device;
use quatcurve::formats::gltf::{self, UriPolicy};
use quatcurve::formats::mesh::{skinned_primitives, SkinnedPrimitive};
use quatcurve::output::VERTEX_CHANNELS;
use quatcurve::skeleton;

/// Positions agree within this fraction of the mesh's bounding-box diagonal.
const POSITION_BOUND: f64 = 1e-4;
/// Normals agree within this angle (rad).
const NORMAL_BOUND: f64 = 1e-3;
/// Half-float images: DESIGN section 8's half precision (2.3e-4 of the box's diagonal,
/// 2.0e-3 rad), with room for the f32 skinning.
const HALF_POSITION_BOUND: f64 = 2.5e-4;
const HALF_NORMAL_BOUND: f64 = 2.5e-3;

const FILES: [&str; 4] = ["CesiumMan.glb", "Fox.glb", "BrainStem.glb", "SimpleSkin.gltf"];

/// Worst position difference (as a fraction of `scale`) and worst normal angle between two
/// `[vertices, VERTEX_CHANNELS]` frames; `has_normals` says whether normals are compared.
fn worst(a: &[f64], b: &[f64], scale: f64, has_normals: bool) -> (f64, f64) {
    let (mut position, mut normal) = (0.0f64, 0.0f64);
    for (x, y) in a.chunks_exact(VERTEX_CHANNELS).zip(b.chunks_exact(VERTEX_CHANNELS)) {
        let d = (0..3).map(|c| (x[c] - y[c]).powi(2)).sum::<f64>().sqrt();
        position = position.max(d / scale);
        if has_normals {
            let (p, q) = (DVec3::new(x[3], x[4], x[5]), DVec3::new(y[3], y[4], y[5]));
            normal = normal.max(p.angle_between(q));
        }
    }
    (position, normal)
}

/// Each node's local transform at `time` of animation `clip`, straight from the glTF crate's
/// readers: a key at `time` (within 1e-6 s), else the channel's first or last key when `time`
/// lies outside it. Only called at the first and last frames, which are keys or clamped.
fn local_at(document: &::gltf::Document, buffers: &[Vec<u8>], clip: usize, time: f64) -> Vec<DMat4> {
    let mut trs: Vec<(DVec3, DQuat, DVec3)> = document
        .nodes()
        .map(|n| {
            let (t, r, s) = n.transform().decomposed();
            (DVec3::from(t.map(f64::from)), DQuat::from_array(r.map(f64::from)), DVec3::from(s.map(f64::from)))
        })
        .collect();
    let animation = document.animations().nth(clip).unwrap();
    for channel in animation.channels() {
        let reader = channel.reader(|b| buffers.get(b.index()).map(Vec::as_slice));
        let times: Vec<f64> = reader.read_inputs().unwrap().map(f64::from).collect();
        let key = if time <= times[0] {
            0
        } else if time >= times[times.len() - 1] - 1e-6 {
            times.len() - 1
        } else {
            times.iter().position(|&k| (k - time).abs() < 1e-6).expect("the time is a key of every channel inside it")
        };
        let cubic = channel.sampler().interpolation() == ::gltf::animation::Interpolation::CubicSpline;
        let at = if cubic { 3 * key + 1 } else { key };
        let node = channel.target().node().index();
        use ::gltf::animation::util::ReadOutputs;
        match reader.read_outputs().unwrap() {
            ReadOutputs::Translations(mut t) => trs[node].0 = DVec3::from(t.nth(at).unwrap().map(f64::from)),
            ReadOutputs::Rotations(r) => trs[node].1 = DQuat::from_array(r.into_f32().nth(at).unwrap().map(f64::from)),
            ReadOutputs::Scales(mut s) => trs[node].2 = DVec3::from(s.nth(at).unwrap().map(f64::from)),
            ReadOutputs::MorphTargetWeights(_) => {}
        }
    }
    trs.into_iter().map(|(t, r, s)| DMat4::from_scale_rotation_translation(s, r.normalize(), t)).collect()
}

/// The document and its buffers as the glTF crate reads them: the GLB's binary chunk, or
/// base64 `data:` URIs (the files used here have no others).
pub(super) fn open(path: &std::path::Path) -> (::gltf::Document, Vec<Vec<u8>>) {
    use base64::Engine;
    // Without validation: the crate refuses files that require Draco, which it cannot decode.
    let ::gltf::Gltf { document, blob } =
        ::gltf::Gltf::from_slice_without_validation(&std::fs::read(path).unwrap()).unwrap();
    let buffers = document
        .buffers()
        .map(|b| match b.source() {
            ::gltf::buffer::Source::Bin => blob.clone().unwrap(),
            ::gltf::buffer::Source::Uri(uri) => {
                let data = uri.split_once(";base64,").expect("a base64 data URI").1;
                base64::engine::general_purpose::STANDARD.decode(data).unwrap()
            }
        })
        .collect();
    (document, buffers)
}

/// `primitive` skinned at `time` of `clip`, computed without quatcurve's bake: glam forward
/// kinematics over the glTF nodes, the skin's inverse bind matrices from the crate's reader,
/// and the weights as the file stores them (normalized here); a rigid part moved by its node's
/// world transform, as glTF draws a mesh without a skin (its morph targets at zero weights).
pub(super) fn independent(path: &std::path::Path, primitive: &SkinnedPrimitive, clip: usize, time: f64) -> Vec<f64> {
    let (document, buffers) = open(path);
    let local = local_at(&document, &buffers, clip, time);
    let mut parent = vec![None; local.len()];
    for node in document.nodes() {
        for child in node.children() {
            parent[child.index()] = Some(node.index());
        }
    }
    let world = |mut j: usize| {
        let mut m = local[j];
        while let Some(p) = parent[j] {
            m = local[p] * m;
            j = p;
        }
        m
    };
    let skin = document.skins().nth(primitive.skin).unwrap();
    let reader = skin.reader(|b| buffers.get(b.index()).map(Vec::as_slice));
    let inverse_bind: Vec<DMat4> = reader
        .read_inverse_bind_matrices()
        .map(|m| m.map(|c| DMat4::from_cols_array_2d(&c.map(|r| r.map(f64::from)))).collect())
        .unwrap_or_else(|| vec![DMat4::IDENTITY; skin.joints().count()]);
    let joints: Vec<DMat4> = skin.joints().zip(&inverse_bind).map(|(j, ibm)| world(j.index()) * *ibm).collect();
    let mesh = document.meshes().nth(primitive.mesh).unwrap();
    let prim = mesh.primitives().nth(primitive.primitive).unwrap();
    let reader = prim.reader(|b| buffers.get(b.index()).map(Vec::as_slice));
    // Per vertex: position, normal, and its (joint, weight) pairs (none: placed already).
    type Vertex = ([f64; 3], Option<[f64; 3]>, Vec<(usize, f64)>);
    let vertices: Vec<Vertex> = match reader.read_positions() {
        Some(positions) if primitive.rigid.is_some() => {
            let node = world(primitive.node);
            let normals: Option<Vec<[f32; 3]>> = reader.read_normals().map(Iterator::collect);
            let at = |v: usize, p: [f32; 3]| -> Vertex {
                let p = node.transform_point3(DVec3::from(p.map(f64::from)));
                let n = normals
                    .as_ref()
                    .map(|n| node.inverse().transpose().transform_vector3(DVec3::from(n[v].map(f64::from))));
                (p.to_array(), n.map(|n| n.to_array()), Vec::new())
            };
            positions.enumerate().map(|(v, p)| at(v, p)).collect()
        }
        Some(positions) => {
            let normals: Option<Vec<[f32; 3]>> = reader.read_normals().map(Iterator::collect);
            let js: Vec<[u16; 4]> = reader.read_joints(0).unwrap().into_u16().collect();
            let ws: Vec<[f32; 4]> = reader.read_weights(0).unwrap().into_f32().collect();
            positions
                .enumerate()
                .map(|(v, p)| {
                    let pairs = (0..4).map(|k| (js[v][k] as usize, f64::from(ws[v][k]))).collect();
                    (p.map(f64::from), normals.as_ref().map(|n| n[v].map(f64::from)), pairs)
                })
                .collect()
        }
        // Draco: the crate does not decode it, so the vertices are quatcurve's decoding (held to
        // the file's own bounds in `draco_vertices_...`); the skinning here stays independent.
        None => (0..primitive.vertices())
            .map(|v| {
                let n = primitive.bind.influences;
                let pairs = (v * n..(v + 1) * n)
                    .map(|i| (primitive.bind.joints[i] as usize, primitive.bind.weights[i]))
                    .collect();
                (primitive.bind.positions[v], primitive.bind.normals.as_ref().map(|n| n[v]), pairs)
            })
            .collect(),
    };
    let mut out = Vec::with_capacity(vertices.len() * VERTEX_CHANNELS);
    for (position, normal, pairs) in vertices {
        let total: f64 = pairs.iter().map(|(_, w)| w).sum();
        // A rigid part's vertices (no joints) are already where its node puts them.
        let m = if pairs.is_empty() {
            DMat4::IDENTITY
        } else {
            pairs.iter().fold(DMat4::ZERO, |m, &(j, w)| m + joints[j] * (w / total))
        };
        let p = m.transform_point3(DVec3::from(position));
        let n = normal.map_or(DVec3::ZERO, |n| m.transform_vector3(DVec3::from(n)));
        let n = n.normalize_or_zero();
        out.extend([p.x, p.y, p.z, n.x, n.y, n.z]);
    }
    out
}

/// The skinning matrices of every skin at every frame of clip `clip`, baked as `bake` does
/// (`bspline-interp` through the keys at 30 Hz, fitted), on the f64 reference.
fn skin_matrices(animation: &quatcurve::anim::Animation, clip: usize) -> (Vec<Vec<f32>>, Vec<f64>) {
    let spec =
        quatcurve::anim::curves::CurveChoice::Family(CurveSpec { curve: Curve::BSplineInterp, ..CurveSpec::default() });
    let baked =
        quatcurve::bake::bake(animation, &spec, ClipRate::Fit(30.0), LoopMode::Auto, &Device::Reference).unwrap();
    let order = animation.parents_first().unwrap();
    let model = skeleton::forward_kinematics(&animation.parents(), &order, &texture::local(animation, &baked, clip));
    let skins = animation.skins.iter().map(|s| texture::skin(s, animation.joints.len(), &model)).collect();
    (skins, baked.clips[clip].times.clone())
}

#[test]
fn skinned_vertices_match_an_independent_skinning_at_keys_and_the_gpu_kernel_at_every_frame() {
    let Some(data) = data_dir() else { return };
    let gpu = crate::shared_gpu();
    for name in FILES {
        let path = data.join(name);
        let file = gltf::read(&path, UriPolicy::default()).unwrap();
        let animation = &file.animation;
        let primitives = skinned_primitives(&file).unwrap_or_else(|e| panic!("{name}: {e}")).primitives;
        let (matrices, times) = skin_matrices(animation, 0);
        let frames = times.len();
        let (mut worst_key, mut worst_gpu) = ((0.0f64, 0.0f64), (0.0f64, 0.0f64));
        for primitive in &primitives {
            let joints = animation.skins[primitive.skin].joints.len();
            let ours = skeleton::skin(&primitive.bind, joints, &matrices[primitive.skin]);
            let frame_len = primitive.vertices() * VERTEX_CHANNELS;
            assert_eq!(ours.len(), frames * frame_len, "{name}");
            let has_normals = primitive.bind.normals.is_some();
            for frame in [0, frames - 1] {
                let theirs = independent(&path, primitive, 0, times[frame]);
                let scale = Bounds::of(&theirs).unwrap().diagonal();
                let ours = &ours[frame * frame_len..(frame + 1) * frame_len];
                let (p, n) = worst(ours, &theirs, scale, has_normals);
                worst_key = (worst_key.0.max(p), worst_key.1.max(n));
                assert!(
                    p <= POSITION_BOUND && n <= NORMAL_BOUND,
                    "{name}, {}, frame {frame}: {p:e}, {n:e} rad",
                    primitive.name
                );
            }
            let Some(gpu) = gpu else { continue };
            let got = gpu
                .skin_mesh(&quatcurve::gpu::skinning::BindMesh::of(&primitive.bind), joints, &matrices[primitive.skin])
                .unwrap();
            assert_eq!(got.len(), ours.len());
            for frame in 0..frames {
                let range = frame * frame_len..(frame + 1) * frame_len;
                let got: Vec<f64> = got[range.clone()].iter().map(|&v| f64::from(v)).collect();
                let (p, n) =
                    worst(&got, &ours[range.clone()], Bounds::of(&ours[range]).unwrap().diagonal(), has_normals);
                worst_gpu = (worst_gpu.0.max(p), worst_gpu.1.max(n));
                assert!(
                    p <= POSITION_BOUND && n <= NORMAL_BOUND,
                    "{name}, {}, frame {frame}: GPU {p:e}, {n:e} rad",
                    primitive.name
                );
            }
        }
        eprintln!(
            "{name}: {} primitives, {frames} frames; at keys against the independent skinning: {:.1e} of the diagonal, \
             {:.1e} rad; GPU against f64: {:.1e}, {:.1e} rad",
            primitives.len(),
            worst_key.0,
            worst_key.1,
            worst_gpu.0,
            worst_gpu.1
        );
    }
}

/// A glTF with one joint (node 0) and a node drawing a three-vertex triangle (node 1), with
/// `skin` on it or not, `joints` and `weights` per vertex (none: the attributes are left out);
/// `positions` elements claimed for POSITION (3 is honest).
fn skinned_triangle(
    skin: bool,
    joints: Option<[[u16; 4]; 3]>,
    weights: Option<[[f32; 4]; 3]>,
    positions: usize,
) -> Vec<u8> {
    use base64::Engine;
    let mut bin: Vec<u8> = Vec::new();
    for p in [[0.0f32, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]] {
        bin.extend(p.iter().flat_map(|v| v.to_le_bytes()));
    }
    let mut accessors =
        vec![serde_json::json!({"bufferView": 0, "componentType": 5126, "count": positions, "type": "VEC3"})];
    let mut views = vec![serde_json::json!({"buffer": 0, "byteOffset": 0, "byteLength": 36})];
    let mut attributes = serde_json::json!({"POSITION": 0});
    if let Some(joints) = joints {
        let offset = bin.len();
        bin.extend(joints.iter().flatten().flat_map(|j| j.to_le_bytes()));
        views.push(serde_json::json!({"buffer": 0, "byteOffset": offset, "byteLength": 24}));
        accessors.push(
            serde_json::json!({"bufferView": views.len() - 1, "componentType": 5123, "count": 3, "type": "VEC4"}),
        );
        attributes["JOINTS_0"] = (accessors.len() - 1).into();
    }
    if let Some(weights) = weights {
        let offset = bin.len();
        bin.extend(weights.iter().flatten().flat_map(|w| w.to_le_bytes()));
        views.push(serde_json::json!({"buffer": 0, "byteOffset": offset, "byteLength": 48}));
        accessors.push(
            serde_json::json!({"bufferView": views.len() - 1, "componentType": 5126, "count": 3, "type": "VEC4"}),
        );
        attributes["WEIGHTS_0"] = (accessors.len() - 1).into();
    }
    let mut mesh_node = serde_json::json!({"name": "body", "mesh": 0});
    if skin {
        mesh_node["skin"] = 0.into();
    }
    let uri =
        format!("data:application/octet-stream;base64,{}", base64::engine::general_purpose::STANDARD.encode(&bin));
    let doc = serde_json::json!({
        "asset": {"version": "2.0"},
        "scene": 0,
        "scenes": [{"nodes": [0, 1]}],
        "nodes": [{"name": "bone"}, mesh_node],
        "skins": [{"joints": [0]}],
        "meshes": [{"name": "tri", "primitives": [{"attributes": attributes}]}],
        "buffers": [{"uri": uri, "byteLength": bin.len()}],
        "bufferViews": views,
        "accessors": accessors,
    });
    serde_json::to_vec(&doc).unwrap()
}

/// A triangle on node `body` without a skin, hung under joint `bone` (at `(0, 2, 0)`, its
/// inverse bind matrix the identity) at `(1, 0, 0)`; a clip moves the bone, and with
/// `animated` the body too.
fn rigid_triangle(animated: bool) -> Vec<u8> {
    use base64::Engine;
    let floats: Vec<f32> = [0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0] // POSITION
        .into_iter()
        .chain([0.0, 1.0]) // key times
        .chain([0.0, 2.0, 0.0, 0.0, 3.0, 0.0]) // translations
        .collect();
    let bin: Vec<u8> = floats.iter().flat_map(|f| f.to_le_bytes()).collect();
    let uri =
        format!("data:application/octet-stream;base64,{}", base64::engine::general_purpose::STANDARD.encode(&bin));
    let mut channels = vec![serde_json::json!({"sampler": 0, "target": {"node": 0, "path": "translation"}})];
    if animated {
        channels.push(serde_json::json!({"sampler": 0, "target": {"node": 1, "path": "translation"}}));
    }
    let doc = serde_json::json!({
        "asset": {"version": "2.0"},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [
            {"name": "bone", "translation": [0.0, 2.0, 0.0], "children": [1]},
            {"name": "body", "mesh": 0, "translation": [1.0, 0.0, 0.0]},
        ],
        "skins": [{"joints": [0]}],
        "meshes": [{"name": "tri", "primitives": [{"attributes": {"POSITION": 0}}]}],
        "animations": [{"name": "move", "channels": channels, "samplers": [{"input": 1, "output": 2}]}],
        "buffers": [{"uri": uri, "byteLength": bin.len()}],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": 36},
            {"buffer": 0, "byteOffset": 36, "byteLength": 8},
            {"buffer": 0, "byteOffset": 44, "byteLength": 24},
        ],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3"},
            {"bufferView": 1, "componentType": 5126, "count": 2, "type": "SCALAR", "min": [0.0], "max": [1.0]},
            {"bufferView": 2, "componentType": 5126, "count": 2, "type": "VEC3"},
        ],
    });
    serde_json::to_vec(&doc).unwrap()
}

/// A mesh without a skin under a joint is drawn bound to that joint with weight 1, its
/// vertices in the skin's bind space (the joint's skin matrix then puts them where the node
/// does); one whose node moves on its own is named as not drawn, never dropped silently.
#[test]
fn rigid_parts_are_bound_to_their_joint_or_named_as_not_drawn() {
    let file = |animated| gltf::from_bytes(&rigid_triangle(animated), std::path::Path::new("."), UriPolicy::default());
    let drawn = skinned_primitives(&file(false).unwrap()).unwrap();
    assert_eq!((drawn.primitives.len(), drawn.not_drawn.len()), (1, 0));
    let p = &drawn.primitives[0];
    assert_eq!((p.skin, p.rigid.as_ref().map(|r| r.joint)), (0, Some(0)));
    // Bind space is the bone's at identity: the body's offset alone.
    assert_eq!(p.bind.positions, [[1.0, 0.0, 0.0], [2.0, 0.0, 0.0], [1.0, 1.0, 0.0]]);
    assert_eq!(
        (p.bind.influences, &p.bind.joints[..4], &p.bind.weights[..4]),
        (4, &[0, 0, 0, 0][..], &[1.0, 0.0, 0.0, 0.0][..])
    );
    // The skin matrix at rest (the bone's world transform, at (0, 2, 0)) puts the triangle
    // where glTF draws the body: its world transform, at (1, 2, 0).
    let rest = [1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 2.0, 0.0, 0.0, 1.0, 0.0].map(|v: f64| v as f32);
    let skinned = skeleton::skin(&p.bind, 1, &rest);
    assert_eq!(skinned[..3], [1.0, 2.0, 0.0]);
    // Animated on its own, the body does not move with the bone: not drawn, and named.
    let message = skinned_primitives(&file(true).unwrap()).unwrap_err().to_string();
    assert!(
        message.contains("node 'body', mesh 'tri': node 'body' between it and a skin's joint is animated"),
        "{message}"
    );
}

#[test]
fn bad_skinned_meshes_are_refused_naming_the_primitive_vertex_and_rule() {
    let read = |bytes: Vec<u8>| {
        let file = gltf::from_bytes(&bytes, std::path::Path::new("."), UriPolicy::default()).unwrap();
        skinned_primitives(&file).map(|d| d.primitives).map_err(|e| e.to_string())
    };
    let joints = Some([[0u16; 4]; 3]);
    let weights = Some([[1.0f32, 0.0, 0.0, 0.0]; 3]);
    let ok = read(skinned_triangle(true, joints, weights, 3)).unwrap();
    assert_eq!((ok.len(), ok[0].vertices(), ok[0].normalized), (1, 3, 0));
    let cases = [
        (
            skinned_triangle(true, Some([[0, 0, 0, 0], [0, 0, 0, 0], [1, 0, 0, 0]]), weights, 3),
            "vertex 2: JOINTS_0[0] is 1, but its skin has 1 joints",
        ),
        (skinned_triangle(false, joints, weights, 3), "has JOINTS_0 or WEIGHTS_0 but its node has no skin"),
        (skinned_triangle(true, None, None, 3), "has a skin but the primitive has no JOINTS_0 and WEIGHTS_0"),
        (skinned_triangle(true, joints, None, 3), "JOINTS_0 and WEIGHTS_0 must come in pairs"),
        (
            skinned_triangle(true, joints, Some([[1.0, 0.0, 0.0, 0.0], [0.0; 4], [1.0, 0.0, 0.0, 0.0]]), 3),
            "vertex 1: its weights are all zero",
        ),
        (skinned_triangle(true, joints, Some([[1.0, -0.5, 0.0, 0.0]; 3]), 3), "vertex 0: WEIGHTS_0[1] is -0.5"),
        (skinned_triangle(true, joints, weights, 5), "POSITION (accessor 0): count 5 with stride 12 needs 60 bytes"),
        (
            skinned_triangle(false, None, None, 3),
            "no mesh is skinned or hangs from a skin's joint (node 'body', mesh 'tri': no joint of a skin is at or \
             above its node)",
        ),
    ];
    for (bytes, expected) in cases {
        let message = read(bytes).expect_err(expected);
        assert!(message.contains(expected), "{message}\nlacks: {expected}");
        if !expected.starts_with("no mesh") {
            assert!(message.contains("node 'body', mesh 'tri', primitive 0"), "{message}");
        }
    }
    // Weights that do not sum to 1 are normalized, and counted.
    let halves = read(skinned_triangle(true, joints, Some([[0.5, 0.0, 0.0, 0.0]; 3]), 3)).unwrap();
    assert_eq!(halves[0].normalized, 3);
    assert!(halves[0].bind.weights.chunks_exact(4).all(|w| (w.iter().sum::<f64>() - 1.0).abs() < 1e-15));
}

/// A unit normal from an octahedral texel, as the sidecar's `vertex.normal` states it (written
/// here from that text, not with the library's decoder).
fn octahedral(u: f64, v: f64) -> [f64; 3] {
    let (u, v) = (2.0 * u - 1.0, 2.0 * v - 1.0);
    let z = 1.0 - u.abs() - v.abs();
    let f = (-z).max(0.0);
    let sign = |c: f64| if c < 0.0 { -1.0 } else { 1.0 };
    let n = DVec3::new(u - f * sign(u), v - f * sign(v), z).normalize();
    [n.x, n.y, n.z]
}

/// Each mesh's `TEXCOORD_0` in the mesh file a vertex bake wrote, by the glTF crate's reader.
pub(super) fn addresses(path: &std::path::Path) -> Vec<Vec<[f32; 2]>> {
    let (document, buffers) = open(path);
    document
        .meshes()
        .map(|mesh| {
            let primitive = mesh.primitives().next().unwrap();
            let reader = primitive.reader(|b| buffers.get(b.index()).map(Vec::as_slice));
            reader.read_tex_coords(0).unwrap().into_f32().collect()
        })
        .collect()
}

/// A 16-bit PNG's RGBA samples as `0..1`, by the `image` crate's reader.
fn read_png16(path: &std::path::Path) -> (usize, usize, Vec<[f32; 4]>) {
    let image::DynamicImage::ImageRgba16(buffer) = image::open(path).unwrap() else { panic!("not 16-bit RGBA") };
    let texels = buffer.pixels().map(|p| p.0.map(|c| f32::from(c) / 65535.0)).collect();
    (buffer.width() as usize, buffer.height() as usize, texels)
}

/// Frame `frame` of primitive `k` of clip `clip` (a sidecar entry) as stored in `dir`, decoded
/// with the sidecar's numbers and the mesh file's addresses: `[vertices, VERTEX_CHANNELS]`;
/// for images also the diagonal of the box their positions were remapped into.
fn decoded(
    dir: &std::path::Path,
    sidecar: &serde_json::Value,
    clip: &serde_json::Value,
    k: usize,
    frame: usize,
) -> (Vec<f64>, Option<f64>) {
    let files: Vec<&str> = clip["files"].as_array().unwrap().iter().map(|f| f.as_str().unwrap()).collect();
    let file = |part: &str| files.iter().find(|f| f.contains(&format!(".mesh{k}{part}"))).map(|f| dir.join(f));
    let row = clip["first_row"].as_u64().unwrap() as usize + frame;
    if sidecar["format"] == "npy" {
        let (shape, values) = super::read_npy(&file("").unwrap());
        let width = (shape[1] * shape[2]) as usize;
        return (values[row * width..(row + 1) * width].iter().map(|&v| f64::from(v)).collect(), None);
    }
    let mesh_file = dir.join(sidecar["vertex"]["mesh_file"].as_str().unwrap());
    let address = &addresses(&mesh_file)[k];
    let record = |path: &std::path::Path| {
        let name = path.file_name().unwrap().to_str().unwrap();
        sidecar["textures"].as_array().unwrap().iter().find(|t| t["file"] == name).unwrap().clone()
    };
    let read = |path: &std::path::Path| {
        let (width, _, texels) =
            if sidecar["format"] == "exr" { super::images::read_exr(path) } else { read_png16(path) };
        let grid = record(path);
        let n = |key: &str| grid[key].as_u64().unwrap() as usize;
        address
            .iter()
            .map(|&[u, v]| {
                let x = (row / n("frames_per_column")) * n("frame_width") + u as usize;
                let y = (row % n("frames_per_column")) * n("rows_per_frame") + v as usize;
                texels[y * width + x].map(f64::from)
            })
            .collect::<Vec<[f64; 4]>>()
    };
    let positions = file(".pos").unwrap();
    let box_of = record(&positions);
    let three = |key: &str| -> [f64; 3] { std::array::from_fn(|c| box_of[key][c].as_f64().unwrap()) };
    let (low, span) = (three("low"), three("span"));
    let normals = file(".nrm").map(|path| read(&path));
    let mut out = Vec::new();
    for (v, texel) in read(&positions).into_iter().enumerate() {
        out.extend((0..3).map(|c| low[c] + texel[c] * span[c]));
        out.extend(normals.as_ref().map_or([0.0; 3], |n| octahedral(n[v][0], n[v][1])));
    }
    (out, Some(span.iter().map(|s| s * s).sum::<f64>().sqrt()))
}

#[test]
fn baked_vertex_textures_decode_to_an_independent_skinning_in_every_format_and_device() {
    let Some(data) = data_dir() else { return };
    let out = tempfile::tempdir().unwrap();
    let devices: &[&str] = if crate::shared_gpu().is_some() { &["cpu", "gpu"] } else { &["cpu"] };
    // Format, precision, largest image side, and the bounds each holds to (position /
    // diagonal, normal rad): DESIGN section 8's precision of its encoding, plus the f32
    // skinning's. At 1,024 texels a side, CesiumMan's 3,273 vertices wrap to four rows a frame.
    let variants = [
        ("npy", "f32", "4096", POSITION_BOUND, NORMAL_BOUND),
        ("exr", "f32", "4096", POSITION_BOUND, NORMAL_BOUND),
        ("png16", "f32", "1024", POSITION_BOUND, NORMAL_BOUND),
        ("exr", "f16", "4096", HALF_POSITION_BOUND, HALF_NORMAL_BOUND),
    ];
    // RobotExpressive: 15 of its 19 primitives are rigid parts, bound to their bones.
    let names = ["CesiumMan.glb", "Fox.glb", "SimpleSkin.gltf", "RobotExpressive.glb"];
    for device in devices {
        for (format, precision, side, position_bound, normal_bound) in variants {
            let dir = out.path().join(format!("{device}-{format}-{precision}"));
            let mut args = vec!["--texture", "vertex", "--rate", "30", "--format", format, "--precision", precision];
            args.extend(["--max-texture-size", side]);
            let output = dir.to_str().unwrap();
            args.extend(["--device", device, "--output", output, "--input"]);
            let inputs: Vec<String> = names.iter().map(|n| data.join(n).display().to_string()).collect();
            args.extend(inputs.iter().map(String::as_str));
            let result = super::bake(&args);
            assert!(result.status.success(), "{}", super::stderr(&result));
            let summary = String::from_utf8_lossy(&result.stdout);
            assert!(summary.contains("M vertex-frames/s on"), "{summary}");
            let mut largest = (0.0f64, 0.0f64);
            for name in names {
                let path = data.join(name);
                let stem = path.file_stem().unwrap().to_str().unwrap();
                let sidecar = super::json(&dir.join(format!("{stem}.json")));
                let file = gltf::read(&path, UriPolicy::default()).unwrap();
                let primitives = skinned_primitives(&file).unwrap().primitives;
                assert_eq!(sidecar["vertex"]["primitives"].as_array().unwrap().len(), primitives.len());
                let clip = &sidecar["clips"][0];
                let frames = clip["frames"].as_u64().unwrap() as usize;
                for (k, primitive) in primitives.iter().enumerate() {
                    for (frame, time) in
                        [(0, clip["start"].as_f64().unwrap()), (frames - 1, clip["end"].as_f64().unwrap())]
                    {
                        let theirs = independent(&path, primitive, 0, time);
                        let (ours, animated) = decoded(&dir, &sidecar, clip, k, frame);
                        assert_eq!(ours.len(), theirs.len());
                        // Images: against the box they were encoded in (the mesh's over the
                        // clip, as DESIGN section 8 states their precision); npy: against
                        // this frame's box, which is smaller.
                        let scale = animated.unwrap_or_else(|| Bounds::of(&theirs).unwrap().diagonal());
                        let (p, n) = worst(&ours, &theirs, scale, primitive.bind.normals.is_some());
                        largest = (largest.0.max(p), largest.1.max(n));
                        assert!(
                            p <= position_bound && n <= normal_bound,
                            "{device} {format} {precision}: {name}, {}, frame {frame}: {p:e} of the diagonal, {n:e} rad",
                            primitive.name
                        );
                    }
                }
            }
            eprintln!(
                "{device} {format} {precision}: worst against the independent skinning {:.1e} of the diagonal, {:.1e} rad",
                largest.0, largest.1
            );
        }
    }
}

#[test]
fn vertex_bakes_refuse_what_they_cannot_make_naming_it_and_leave_nothing_behind() {
    let Some(data) = data_dir() else { return };
    let out = tempfile::tempdir().unwrap();
    let input = |name: &str| data.join(name).display().to_string();
    let cases: [(Vec<String>, &str); 5] = [
        (vec!["--input".into(), input("cmu_131_01.bvh")], "vertex textures skin a glTF's meshes, and this is a BVH file"),
        (vec![], "vertex skins a glTF's meshes, and the built-in crowd has none"),
        (vec!["--input".into(), input("CesiumMan.glb"), "--max-error-deg".into(), "1".into()], "bake vertex textures at a fixed rate"),
        // 11,751 frames (1.958 s at 6 kHz) of 3,273 vertices, 28 bytes each (three floats
        // gathered, one RGBA texel): 1,028 MiB of position image in memory.
        (
            vec![
                "--input".into(),
                input("CesiumMan.glb"),
                "--rate".into(),
                "6000".into(),
                "--format".into(),
                "exr".into(),
                "--max-texture-size".into(),
                "65536".into(),
            ],
            "clip 'animation0': its exr image CesiumMan.animation0.mesh0.pos.exr would take 1028 MiB of memory while it \
             is gathered and encoded, over IMAGE_MEMORY_LIMIT = 1024 MiB",
        ),
        // 1,396 frames of BrainStem's 34,239 vertices in 59 primitives, 24 bytes each (a
        // position and a normal), every image of the clip gathered at once: 1,095 MiB.
        (
            vec!["--input".into(), input("BrainStem.glb"), "--rate".into(), "40".into(), "--format".into(), "exr".into()],
            "clip 'animation0': its 118 exr images would gather 1095 MiB of rows in memory together (the largest, node \
             'node1', mesh 'Figure_2_geometry', primitive 25's normals: 54 MiB), over IMAGE_MEMORY_LIMIT = 1024 MiB",
        ),
    ];
    for (k, (args, expected)) in cases.iter().enumerate() {
        let dir = out.path().join(format!("case{k}"));
        let mut all: Vec<&str> = vec!["--texture", "vertex", "--output", dir.to_str().unwrap()];
        all.extend(args.iter().map(String::as_str));
        let result = super::bake(&all);
        let message = super::stderr(&result);
        assert_eq!(result.status.code(), Some(2), "{args:?}: {message}");
        assert!(message.contains(expected), "{args:?}: {message}\nlacks: {expected}");
        let left: Vec<_> = std::fs::read_dir(&dir).map(|d| d.flatten().map(|e| e.path()).collect()).unwrap_or_default();
        assert!(left.is_empty(), "{args:?}: left behind {left:?}");
    }
}

#[test]
fn bench_times_skinning_on_the_cpu_and_the_gpu_side_by_side() {
    let Some(data) = data_dir() else { return };
    let file = data.join("CesiumMan.glb");
    let out = assert_cmd::Command::cargo_bin("quatcurve")
        .unwrap()
        .args(["bench", "--skinning", file.to_str().unwrap(), "--samples", "40", "--runs", "1", "--json"])
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", super::stderr(&out));
    let doc: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(
        (doc["primitives"].as_u64(), doc["vertices"].as_u64(), doc["frames"].as_u64()),
        (Some(1), Some(3273), Some(40))
    );
    let devices: Vec<&str> = doc["results"].as_array().unwrap().iter().map(|r| r["device"].as_str().unwrap()).collect();
    let expected: &[&str] = if crate::shared_gpu().is_some() { &["cpu", "gpu"] } else { &["cpu"] };
    assert_eq!(devices, expected);
    for r in doc["results"].as_array().unwrap() {
        assert_eq!(r["vertex_frames"], 3273 * 40, "{r}");
        assert!(r["vertex_frames_per_s"].as_f64().unwrap() > 0.0, "{r}");
    }
}

/// BrainStem's primitives are Draco-compressed (`KHR_draco_mesh_compression`), which the glTF
/// crate does not decode; what `draco-core` decodes is held to what the file says of its
/// vertices without Draco: each POSITION accessor's `min` and `max` (the encoder's, from the
/// uncompressed data), its vertex count, unit normals and weights that sum to 1.
#[test]
fn draco_vertices_match_the_bounds_counts_and_weights_the_file_states() {
    let Some(data) = data_dir() else { return };
    let path = data.join("BrainStem.glb");
    let file = gltf::read(&path, UriPolicy::default()).unwrap();
    let primitives = skinned_primitives(&file).unwrap().primitives;
    let bytes = std::fs::read(&path).unwrap();
    let json: serde_json::Value =
        serde_json::from_slice(&::gltf::binary::Glb::from_slice(&bytes).unwrap().json).unwrap();
    assert_eq!(primitives.len(), 59);
    let (mut worst_box, mut worst_normal, mut normalized) = (0.0f64, 0.0f64, 0);
    for p in &primitives {
        let attributes = &json["meshes"][p.mesh]["primitives"][p.primitive]["attributes"];
        assert!(
            json["meshes"][p.mesh]["primitives"][p.primitive]["extensions"]["KHR_draco_mesh_compression"].is_object()
        );
        let accessor = &json["accessors"][attributes["POSITION"].as_u64().unwrap() as usize];
        assert_eq!(p.vertices() as u64, accessor["count"].as_u64().unwrap(), "{}", p.name);
        let bound = |key: &str| -> [f64; 3] { std::array::from_fn(|c| accessor[key][c].as_f64().unwrap()) };
        let (min, max) = (bound("min"), bound("max"));
        let diagonal = (0..3).map(|c| (max[c] - min[c]).powi(2)).sum::<f64>().sqrt();
        let decoded = Bounds::of_positions(p.bind.positions.iter().copied()).unwrap();
        for c in 0..3 {
            let off = (decoded.low[c] - min[c]).abs().max((decoded.high[c] - max[c]).abs()) / diagonal;
            worst_box = worst_box.max(off);
        }
        for n in p.bind.normals.as_ref().unwrap() {
            worst_normal = worst_normal.max((n.iter().map(|c| c * c).sum::<f64>().sqrt() - 1.0).abs());
        }
        normalized += p.normalized;
        let triangles = p.indices.as_ref().unwrap();
        assert!(triangles.len() % 3 == 0 && triangles.iter().all(|&i| (i as usize) < p.vertices()), "{}", p.name);
    }
    eprintln!(
        "BrainStem: 59 Draco primitives, {} vertices; decoded box off the accessors' min/max by {worst_box:.1e} of \
         the diagonal; normals unit within {worst_normal:.1e}; {normalized} vertices' weights normalized",
        primitives.iter().map(SkinnedPrimitive::vertices).sum::<usize>()
    );
    assert!(worst_box <= 1e-3, "{worst_box}");
    assert!(worst_normal <= 1e-12, "{worst_normal}");
}
