//! FBX in, through ufbx (its C loader, built by the crate), as the glTF scene it converts to:
//! every node but the scene root a node (with its rest transform), every mesh a mesh of
//! triangles (positions, normals, the first UV set, and skin weights where a skin deforms it),
//! every skin deformer a skin (its clusters' bones, each cluster's geometry-to-bone matrix
//! the inverse bind matrix), every animation stack an animation (ufbx's baked keys of each
//! animated node, LINEAR). The GLB is read back by the glTF reader ([`crate::gltf`]), so an
//! FBX bakes as a glTF does, and its baked file is that GLB with the baked frames.
//!
//! ufbx converts the scene to glTF's space as it loads: metres and +Y up, right-handed, by
//! adjusting the nodes' transforms (`SpaceConversion::AdjustTransforms`), so that mesh data
//! and inverse bind matrices stay the file's. The file's own unit and up axis are kept
//! ([`FbxFile::source_unit_metres`], [`FbxFile::source_up`]). A node that does not inherit
//! its parent's scale (Mixamo's bones) is compensated by ufbx so that glTF's inheritance,
//! which always multiplies scales down the chain, poses it as FBX does.

use crate::glb_builder::{heaviest, Buffer, Scene};
use crate::gltf::{self, GltfFile, UriPolicy};
use quatcurve_anim::error::{FormatError, InputError};
use serde_json::{json, Value};
use std::collections::HashMap;
use std::path::Path;

/// The extension of FBX files.
pub const EXTENSION: &str = "fbx";

/// An FBX file read for baking: the glTF scene it converts to.
#[derive(Clone, Debug)]
pub struct FbxFile {
    /// The scene as a glTF (read back from the GLB the file converts to).
    pub gltf: GltfFile,
    /// The length of the file's unit in metres (Blender writes 0.01).
    pub source_unit_metres: f64,
    /// The file's up axis (`+Y`, `+Z`, ...).
    pub source_up: &'static str,
}

/// A rule of the scene broken, found here.
fn bad(rule: String) -> InputError {
    InputError::Fbx(FormatError::rule(rule))
}

/// ufbx's refusal (its description is the only form it has) of `what`.
fn refused(what: String, error: &ufbx::Error) -> InputError {
    InputError::Fbx(FormatError::caused(what, error.description.to_string()))
}

/// Reads an FBX file (binary or ASCII).
///
/// # Errors
/// [`InputError::Read`] for an unreadable file; [`InputError::Fbx`] with ufbx's description
/// for a file it cannot load, a stack it cannot bake, or a skin cluster without a bone.
pub fn read(path: &Path) -> Result<FbxFile, InputError> {
    from_bytes(&std::fs::read(path).map_err(InputError::Read)?)
}

/// Reads an FBX file from its bytes (see [`read`]).
///
/// # Errors
/// As [`read`].
pub fn from_bytes(bytes: &[u8]) -> Result<FbxFile, InputError> {
    let options = ufbx::LoadOpts {
        target_axes: ufbx::CoordinateAxes::right_handed_y_up(),
        target_unit_meters: 1.0,
        space_conversion: ufbx::SpaceConversion::AdjustTransforms,
        // A geometric transform (a pivot glTF has no word for) becomes a child node of its own
        // holding the mesh, so that a mesh that is not skinned is drawn where the FBX puts it.
        geometry_transform_handling: ufbx::GeometryTransformHandling::HelperNodes,
        inherit_mode_handling: ufbx::InheritModeHandling::Compensate,
        // No file beside it is opened: an FBX's external references are not followed.
        load_external_files: false,
        ..Default::default()
    };
    let scene = ufbx::load_memory(bytes, options).map_err(|e| refused("not a readable FBX file".into(), &e))?;
    let glb = to_glb(&scene)?;
    // Only the GLB's own chunk is read: no URI is followed.
    let gltf = gltf::from_bytes(&glb, Path::new(""), UriPolicy::default())?;
    let settings = &scene.settings;
    Ok(FbxFile { gltf, source_unit_metres: settings.unit_meters, source_up: axis_name(settings.axes.up) })
}

/// The scene as a GLB (see the module's documentation).
fn to_glb(scene: &ufbx::Scene) -> Result<Vec<u8>, InputError> {
    let mut buffer = Buffer::default();
    // Nodes: every node but the scene root, in ufbx's order (parents first).
    let nodes: Vec<&ufbx::Node> = scene.nodes.iter().filter(|n| !n.is_root).map(|n| &**n).collect();
    let index: HashMap<u32, usize> = nodes.iter().enumerate().map(|(i, n)| (n.element.typed_id, i)).collect();
    let skins = skins(scene, &index, &mut buffer)?;
    let mut meshes = Vec::new();
    let mut mesh_of: HashMap<u32, (usize, Option<usize>)> = HashMap::new();
    for mesh in scene.meshes.iter() {
        let skin = mesh.skin_deformers.first().map(|d| d.element.typed_id);
        let skin_index = skin.and_then(|id| scene.skin_deformers.iter().position(|d| d.element.typed_id == id));
        meshes.push(mesh_json(mesh, skin_index.map(|k| &scene.skin_deformers[k]), &mut buffer));
        mesh_of.insert(mesh.element.typed_id, (meshes.len() - 1, skin_index));
    }
    let mut node_json: Vec<Value> = nodes
        .iter()
        .map(|node| {
            let t = &node.local_transform;
            let mut n = json!({
                "name": &*node.element.name,
                "translation": [t.translation.x, t.translation.y, t.translation.z],
                "rotation": [t.rotation.x, t.rotation.y, t.rotation.z, t.rotation.w],
                "scale": [t.scale.x, t.scale.y, t.scale.z],
            });
            if let Some((mesh, skin)) = node.mesh.as_ref().and_then(|m| mesh_of.get(&m.element.typed_id)) {
                n["mesh"] = json!(mesh);
                if let Some(skin) = skin {
                    n["skin"] = json!(skin);
                }
            }
            n
        })
        .collect();
    let mut roots = Vec::new();
    for (i, node) in nodes.iter().enumerate() {
        match node.parent.as_ref().filter(|p| !p.is_root).and_then(|p| index.get(&p.element.typed_id)) {
            Some(&parent) => {
                let children = node_json[parent].as_object_mut().expect("a node is an object");
                children
                    .entry("children")
                    .or_insert_with(|| json!([]))
                    .as_array_mut()
                    .expect("an array")
                    .push(json!(i));
            }
            None => roots.push(i),
        }
    }
    let animations = animations(scene, &nodes, &index, &mut buffer)?;
    let scene = Scene { generator: "quatcurve (FBX through ufbx)", roots, nodes: node_json, meshes, skins, animations };
    buffer.glb(scene, "the FBX's scene would exceed 4 GiB as a GLB")
}

/// Every skin deformer as a glTF skin: its clusters' bones and their geometry-to-bone
/// matrices as inverse bind matrices (column-major 4x4).
fn skins(scene: &ufbx::Scene, index: &HashMap<u32, usize>, buffer: &mut Buffer) -> Result<Vec<Value>, InputError> {
    let mut skins = Vec::new();
    for deformer in scene.skin_deformers.iter() {
        let (mut joints, mut matrices) = (Vec::new(), Vec::new());
        for cluster in deformer.clusters.iter() {
            let Some(&joint) = cluster.bone_node.as_ref().and_then(|b| index.get(&b.element.typed_id)) else {
                return Err(bad(format!(
                    "skin '{}': cluster '{}' has no bone",
                    &*deformer.element.name, &*cluster.element.name
                )));
            };
            let m = &cluster.geometry_to_bone;
            joints.push(joint);
            matrices.extend(
                [
                    m.m00, m.m10, m.m20, 0.0, m.m01, m.m11, m.m21, 0.0, m.m02, m.m12, m.m22, 0.0, m.m03, m.m13, m.m23,
                    1.0,
                ]
                .map(|x| x as f32),
            );
        }
        let inverse_bind = buffer.floats(&matrices, 16, "MAT4", false);
        skins.push(json!({"name": &*deformer.element.name, "joints": joints, "inverseBindMatrices": inverse_bind}));
    }
    Ok(skins)
}

/// A mesh as one indexed glTF primitive of triangles: positions, normals and the first UV set
/// where the mesh has them, and with `skin` its four heaviest weights per vertex.
fn mesh_json(mesh: &ufbx::Mesh, skin: Option<&ufbx::SkinDeformer>, buffer: &mut Buffer) -> Value {
    let mut triangles: Vec<u32> = Vec::with_capacity(mesh.num_triangles * 3);
    let mut scratch = vec![0u32; mesh.max_face_triangles * 3];
    for face in mesh.faces.iter() {
        let count = mesh.triangulate_face(&mut scratch, *face) as usize;
        triangles.extend_from_slice(&scratch[..count * 3]);
    }
    // One glTF vertex per distinct (vertex, normal, UV) of the corners; `corners` holds a
    // corner of each, `indices` the triangles in them.
    let attribute = |indices: &ufbx::List<u32>, exists: bool, c: usize| if exists { indices[c] } else { u32::MAX };
    let (mut corners, mut indices, mut seen) = (Vec::new(), Vec::with_capacity(triangles.len()), HashMap::new());
    for &c in &triangles {
        let i = c as usize;
        let key = (
            mesh.vertex_indices[i],
            attribute(&mesh.vertex_normal.indices, mesh.vertex_normal.exists, i),
            attribute(&mesh.vertex_uv.indices, mesh.vertex_uv.exists, i),
        );
        let next = u32::try_from(corners.len()).unwrap_or(u32::MAX);
        indices.push(*seen.entry(key).or_insert_with(|| {
            corners.push(c);
            next
        }));
    }
    let vec3 = |attribute: &ufbx::VertexVec3| -> Vec<f32> {
        corners
            .iter()
            .flat_map(|&c| {
                let v = attribute.values[attribute.indices[c as usize] as usize];
                [v.x as f32, v.y as f32, v.z as f32]
            })
            .collect()
    };
    let mut attributes = json!({"POSITION": buffer.attribute(&vec3(&mesh.vertex_position), 3, "VEC3", true)});
    if mesh.vertex_normal.exists {
        attributes["NORMAL"] = json!(buffer.attribute(&vec3(&mesh.vertex_normal), 3, "VEC3", false));
    }
    if mesh.vertex_uv.exists {
        let uv = &mesh.vertex_uv;
        // glTF's V runs down the image, FBX's up.
        let values: Vec<f32> = corners
            .iter()
            .flat_map(|&c| {
                let v = uv.values[uv.indices[c as usize] as usize];
                [v.x as f32, 1.0 - v.y as f32]
            })
            .collect();
        attributes["TEXCOORD_0"] = json!(buffer.attribute(&values, 2, "VEC2", false));
    }
    if let Some(skin) = skin {
        let influences: Vec<_> = corners
            .iter()
            .map(|&c| {
                let vertex = mesh.vertex_indices[c as usize] as usize;
                heaviest(
                    skin.vertices
                        .get(vertex)
                        .map(|v| {
                            (v.weight_begin..v.weight_begin + v.num_weights)
                                .filter_map(|w| skin.weights.get(w as usize).map(|w| (w.cluster_index, w.weight)))
                                .collect()
                        })
                        .unwrap_or_default(),
                )
            })
            .collect();
        let (joints, weights) = buffer.influences(&influences);
        attributes["JOINTS_0"] = json!(joints);
        attributes["WEIGHTS_0"] = json!(weights);
    }
    let indices = buffer.indices(&indices);
    json!({"name": &*mesh.element.name, "primitives": [{"attributes": attributes, "indices": indices, "mode": 4}]})
}

/// Every animation stack as a glTF animation of ufbx's baked keys (LINEAR), one sampler per
/// animated property of each node. A property a stack holds constant is a one-key sampler
/// where its value is not the node's rest value (an FBX curve of one key poses the node for
/// the whole stack, as FBX readers play it), and no sampler where it is.
fn animations(
    scene: &ufbx::Scene,
    nodes: &[&ufbx::Node],
    index: &HashMap<u32, usize>,
    buffer: &mut Buffer,
) -> Result<Vec<Value>, InputError> {
    let mut animations = Vec::new();
    for (stack, name) in scene.anim_stacks.iter().zip(clip_names(scene)) {
        let baked = ufbx::bake_anim(scene, &stack.anim, ufbx::BakeOpts::default())
            .map_err(|e| refused(format!("animation stack '{}'", &*stack.element.name), &e))?;
        let (mut samplers, mut channels) = (Vec::new(), Vec::new());
        for node in baked.nodes.iter() {
            let Some(&target) = index.get(&node.typed_id) else { continue };
            let rest = &nodes[target].local_transform;
            let mut add = |path: &str, times: Vec<f32>, values: Vec<f32>, width: usize, kind: &str| {
                let input = buffer.floats(&times, 1, "SCALAR", true);
                let output = buffer.floats(&values, width, kind, false);
                samplers.push(json!({"input": input, "output": output}));
                channels.push(json!({"sampler": samplers.len() - 1, "target": {"node": target, "path": path}}));
            };
            let rotation = |q: ufbx::Quat| [q.x, q.y, q.z, q.w];
            let at_rest = |k: &ufbx::BakedQuat| {
                let (q, r) = (rotation(k.value), rotation(rest.rotation));
                // q and -q are one rotation.
                let dot: f64 = q.iter().zip(&r).map(|(a, b)| a * b).sum();
                q.iter().zip(&r).all(|(a, b)| (a - dot.signum() * b).abs() <= REST_TOLERANCE)
            };
            if let Some(keys) = baked_keys(node.constant_rotation, &node.rotation_keys, at_rest) {
                let values = keys.iter().flat_map(|k| rotation(k.value).map(|x| x as f32));
                add("rotation", keys.iter().map(|k| k.time as f32).collect(), values.collect(), 4, "VEC4");
            }
            for (constant, keys, path, rest) in [
                (node.constant_translation, &node.translation_keys, "translation", rest.translation),
                (node.constant_scale, &node.scale_keys, "scale", rest.scale),
            ] {
                let vector = |v: ufbx::Vec3| [v.x, v.y, v.z];
                let at_rest = |k: &ufbx::BakedVec3| {
                    vector(k.value)
                        .iter()
                        .zip(vector(rest))
                        .all(|(a, b)| (a - b).abs() <= REST_TOLERANCE * b.abs().max(1.0))
                };
                if let Some(keys) = baked_keys(constant, keys, at_rest) {
                    let values = keys.iter().flat_map(|k| vector(k.value).map(|x| x as f32));
                    add(path, keys.iter().map(|k| k.time as f32).collect(), values.collect(), 3, "VEC3");
                }
            }
        }
        if !channels.is_empty() {
            animations.push(json!({"name": name, "samplers": samplers, "channels": channels}));
        }
    }
    Ok(animations)
}

/// How far (relative to 1, or to a vector's own size) a stack's constant value may be from the
/// node's rest value and still be the rest value: f32 rounding.
const REST_TOLERANCE: f64 = 1e-6;

/// The keys of a baked property: all of them where it moves, its one value where a stack holds
/// it off the node's rest value (`at_rest` of the key says which), none where at rest.
fn baked_keys<K>(constant: bool, keys: &[K], at_rest: impl Fn(&K) -> bool) -> Option<&[K]> {
    match keys.first() {
        Some(first) if constant && at_rest(first) => None,
        Some(_) if constant => Some(&keys[..1]),
        Some(_) => Some(keys),
        None => None,
    }
}

/// Each stack's clip name: Blender names a stack `<object>|<action>`; where every stack is
/// named so after a node of the scene and the actions are distinct, the action alone (the
/// name the clip had before export), else the stack's name.
fn clip_names(scene: &ufbx::Scene) -> Vec<String> {
    let stacks: Vec<String> = scene.anim_stacks.iter().map(|s| s.element.name.to_string()).collect();
    let actions: Vec<Option<&str>> = stacks
        .iter()
        .map(|s| {
            s.split_once('|')
                .filter(|(object, _)| scene.nodes.iter().any(|n| &*n.element.name == *object))
                .map(|(_, a)| a)
        })
        .collect();
    let distinct = actions.iter().flatten().collect::<std::collections::HashSet<_>>().len() == stacks.len();
    if actions.iter().all(Option::is_some) && distinct {
        actions.into_iter().flatten().map(str::to_string).collect()
    } else {
        stacks
    }
}

fn axis_name(axis: ufbx::CoordinateAxis) -> &'static str {
    match axis {
        ufbx::CoordinateAxis::PositiveX => "+X",
        ufbx::CoordinateAxis::NegativeX => "-X",
        ufbx::CoordinateAxis::PositiveY => "+Y",
        ufbx::CoordinateAxis::NegativeY => "-Y",
        ufbx::CoordinateAxis::PositiveZ => "+Z",
        ufbx::CoordinateAxis::NegativeZ => "-Z",
        ufbx::CoordinateAxis::Unknown => "unknown",
    }
}
