//! The mesh primitives a skin's matrices draw, read for vertex textures and players:
//! bind-space positions and normals (morph targets applied at their default weights) and each
//! vertex's joints and weights, checked against the skin and normalized. A mesh that hangs
//! from a skin's joint without a skin (a rigid part) is drawn too, bound to that joint with
//! weight 1 ([`RigidBinding`]); what cannot be drawn that way is named. Read on demand, so
//! that a file whose meshes are broken still bakes bone textures.

use super::gltf::{check_accessor, Element, GltfFile};
use quatcurve_anim::error::{FormatError, InputError};
use quatcurve_anim::Animation;
use quatcurve_eval::skeleton::{self, Affine, SkinnedMesh};

/// The largest `|sum of weights - 1|` a vertex may have before its weights are said to be
/// normalized (they are divided by their sum either way); normalized-integer weights are also
/// allowed half a quantum per influence.
pub const WEIGHT_SUM_TOLERANCE: f64 = 1e-3;

/// The glTF extension of Draco-compressed primitives (their accessors have no buffer views;
/// `draco-core` decodes them).
pub const DRACO: &str = "KHR_draco_mesh_compression";

/// How a rigid part (a mesh on a node without a skin) moves with a skin: bound with weight 1
/// to the nearest joint of a skin at or above its node, its vertices taken into that skin's
/// bind space, so that the joint's skin matrix puts them where the node's world transform does.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct RigidBinding {
    /// The joint, an index into its skin's joints.
    pub joint: usize,
    /// 3x4 row-major, from the mesh's space to the skin's bind space: the joint's bind matrix
    /// (its inverse bind matrix inverted) times the rest transforms from below the joint down
    /// to the mesh's node. Normals take its inverse transpose.
    pub bind: [f64; 12],
}

/// A mesh primitive drawn by a skin's matrices (a skinned node's, or a rigid part's): what
/// linear blend skinning needs of it.
#[derive(Clone, Debug, PartialEq)]
pub struct SkinnedPrimitive {
    /// `node 'N', mesh 'M', primitive p`, for messages and the sidecar.
    pub name: String,
    /// The node that draws it.
    pub node: usize,
    /// The node's mesh.
    pub mesh: usize,
    /// The primitive's index in the mesh.
    pub primitive: usize,
    /// Index into [`quatcurve_anim::Animation::skins`].
    pub skin: usize,
    /// A rigid part's binding (its vertices are bound to its joint alone); `None` when skinned.
    pub rigid: Option<RigidBinding>,
    /// What skinning needs of it: bind-space positions and normals (morph targets applied at
    /// their default weights), and per vertex four influences per `JOINTS_n`/`WEIGHTS_n` set,
    /// weights summing to 1.
    pub bind: SkinnedMesh,
    /// Vertices whose weights were off 1 by more than [`WEIGHT_SUM_TOLERANCE`] (normalized).
    pub normalized: usize,
    /// The primitive's vertex indices, each checked to be a vertex; `None`: drawn in order.
    pub indices: Option<Vec<u32>>,
    /// glTF's topology (`mode`: 4 triangles, the default; 0 points, 1-3 lines, 5-6 strips and fans).
    pub mode: u32,
}

impl SkinnedPrimitive {
    /// Vertices.
    #[must_use]
    pub fn vertices(&self) -> usize {
        self.bind.vertices()
    }
}

fn error(rule: String) -> InputError {
    InputError::Gltf(FormatError::rule(rule))
}

/// How a node's mesh is drawn from a skin's matrices.
enum Drawing {
    /// By its node's skin.
    Skinned(usize),
    /// As a rigid part of skin `.0`.
    Rigid(usize, RigidBinding),
    /// Not at all, for this reason.
    NotDrawn(String),
}

/// How `node`'s mesh is drawn: by its skin; else bound to the nearest joint of a skin at or
/// above it, when no node between that joint and it is animated (the binding holds their rest
/// transforms) and the joint's inverse bind matrix can be inverted; else not drawn.
fn drawing(animation: &Animation, animated: &[bool], node: &gltf::Node) -> Drawing {
    if let Some(skin) = node.skin() {
        return Drawing::Skinned(skin.index());
    }
    let joint_of = |at: usize| {
        animation.skins.iter().enumerate().find_map(|(s, skin)| Some((s, skin.joints.iter().position(|&j| j == at)?)))
    };
    let name = |at: usize| &animation.joints[at].name;
    // The rest transforms from the mesh's node up to (not including) the joint.
    let mut below = skeleton::trs([0.0, 0.0, 0.0, 1.0], [0.0; 3], [1.0; 3]);
    let mut at = node.index();
    let (skin, joint) = loop {
        if let Some(found) = joint_of(at) {
            break found;
        }
        if animated.get(at).copied().unwrap_or(false) {
            return Drawing::NotDrawn(format!(
                "node '{}' between it and a skin's joint is animated, so it does not move with a joint",
                name(at)
            ));
        }
        let rest = &animation.joints[at];
        below = skeleton::compose(&skeleton::trs(rest.rotation, rest.translation, rest.scale), &below);
        match rest.parent {
            Some(parent) => at = parent,
            None => return Drawing::NotDrawn("no joint of a skin is at or above its node".into()),
        }
    };
    let Some(bind) = skeleton::inverse(&animation.skins[skin].inverse_bind[joint]) else {
        return Drawing::NotDrawn(format!("the inverse bind matrix of joint '{}' it hangs from is singular", name(at)));
    };
    Drawing::Rigid(skin, RigidBinding { joint, bind: skeleton::compose(&bind, &below) })
}

/// Per joint of `animation`, whether a clip animates it.
fn animated_joints(animation: &Animation) -> Vec<bool> {
    let mut animated = vec![false; animation.joints.len()];
    for channel in animation.clips.iter().flat_map(|c| &c.channels) {
        if let Some(a) = animated.get_mut(channel.joint) {
            *a = true;
        }
    }
    animated
}

/// `node 'N', mesh 'M'`, naming a node's mesh in messages.
fn node_mesh_name(node: &gltf::Node, mesh: &gltf::Mesh) -> String {
    let node_name = node.name().map_or_else(|| format!("node{}", node.index()), str::to_string);
    let mesh_name = mesh.name().map_or_else(|| format!("mesh{}", mesh.index()), str::to_string);
    format!("node '{node_name}', mesh '{mesh_name}'")
}

/// What a skin's matrices draw of a glTF file, and what they cannot.
#[derive(Clone, Debug, PartialEq)]
pub struct Drawn<P> {
    /// The primitives drawn, skinned and rigid, in node then primitive order.
    pub primitives: Vec<P>,
    /// Each mesh left out, `node 'N', mesh 'M': why`.
    pub not_drawn: Vec<String>,
}

impl<P> Default for Drawn<P> {
    fn default() -> Self {
        Self { primitives: Vec::new(), not_drawn: Vec::new() }
    }
}

/// Every primitive a skin's matrices draw, in node then primitive order: those of skinned
/// nodes, and rigid parts bound to their joint ([`RigidBinding`]); the meshes left out, named
/// with why. A rigid node's primitive that carries joints or weights is an error (its skin is
/// missing), and so is a skinned node's without `JOINTS_0` and `WEIGHTS_0`.
///
/// # Errors
/// [`InputError::Gltf`] naming the node, mesh, primitive, vertex and rule broken; also when
/// nothing is drawn.
pub fn skinned_primitives(file: &GltfFile) -> Result<Drawn<SkinnedPrimitive>, InputError> {
    let (document, buffers) = file.document()?;
    let animation = &file.animation;
    let animated = animated_joints(animation);
    let mut drawn = Drawn::default();
    for node in document.nodes() {
        let Some(mesh) = node.mesh() else { continue };
        let drawing = drawing(animation, &animated, &node);
        for primitive in mesh.primitives() {
            let name = format!("{}, primitive {}", node_mesh_name(&node, &mesh), primitive.index());
            let weighted = primitive.get(&gltf::Semantic::Joints(0)).is_some()
                || primitive.get(&gltf::Semantic::Weights(0)).is_some();
            let binding = match &drawing {
                Drawing::Skinned(skin) => {
                    let Some(joints) = animation.skins.get(*skin).map(|s| s.joints.len()) else {
                        return Err(error(format!("{name}: skin {skin} does not exist")));
                    };
                    Binding::Skin { skin: *skin, joints }
                }
                _ if weighted => {
                    return Err(error(format!(
                        "{name}: has JOINTS_0 or WEIGHTS_0 but its node has no skin to bind them to"
                    )))
                }
                Drawing::Rigid(skin, rigid) => Binding::Rigid { skin: *skin, rigid },
                Drawing::NotDrawn(_) => continue,
            };
            let draco = file.primitive_extension(mesh.index(), primitive.index(), DRACO);
            let weights = node.weights().or_else(|| mesh.weights()).unwrap_or(&[]);
            drawn.primitives.push(read_primitive(
                &document,
                buffers,
                &primitive,
                name,
                binding,
                weights,
                (node.index(), mesh.index()),
                draco,
            )?);
        }
        if let Drawing::NotDrawn(why) = drawing {
            drawn.not_drawn.push(format!("{}: {why}", node_mesh_name(&node, &mesh)));
        }
    }
    if drawn.primitives.is_empty() {
        let why = if drawn.not_drawn.is_empty() { String::new() } else { format!(" ({})", drawn.not_drawn.join("; ")) };
        return Err(error(format!(
            "no mesh is skinned or hangs from a skin's joint{why}: there are no vertices to bake"
        )));
    }
    Ok(drawn)
}

/// A skinned primitive as the file declares it, without reading its vertices: what a renderer
/// binds for it (a `skin-trs` bake's sidecar lists these).
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default)]
pub struct DeclaredPrimitive {
    /// `node 'N', mesh 'M', primitive p`, as [`SkinnedPrimitive::name`].
    pub name: String,
    /// The node that draws it, its mesh, the primitive's index in the mesh and its skin.
    pub node: usize,
    /// See [`Self::node`].
    pub mesh: usize,
    /// See [`Self::node`].
    pub primitive: usize,
    /// See [`Self::node`].
    pub skin: usize,
    /// A rigid part's binding: a renderer binds `JOINTS_0` `(joint, 0, 0, 0)` and `WEIGHTS_0`
    /// `(1, 0, 0, 0)`, and takes `POSITION` and `NORMAL` into bind space by it.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub rigid: Option<RigidBinding>,
    /// Whether it has `NORMAL` and `TEXCOORD_0`.
    pub normals: bool,
    /// See [`Self::normals`].
    pub texcoords: bool,
}

/// Every primitive a skin's matrices draw ([`skinned_primitives`]'s, skinned and rigid), from
/// the file's declarations alone (a Draco primitive declares its attributes too), and the
/// meshes left out.
///
/// # Errors
/// A file whose JSON is not glTF's.
pub fn declared_skinned_primitives(file: &GltfFile) -> Result<Drawn<DeclaredPrimitive>, InputError> {
    let (document, _) = file.document()?;
    let animated = animated_joints(&file.animation);
    let mut drawn = Drawn::default();
    for node in document.nodes() {
        let Some(mesh) = node.mesh() else { continue };
        let (skin, rigid) = match drawing(&file.animation, &animated, &node) {
            Drawing::Skinned(skin) => (skin, None),
            Drawing::Rigid(skin, rigid) => (skin, Some(rigid)),
            Drawing::NotDrawn(why) => {
                drawn.not_drawn.push(format!("{}: {why}", node_mesh_name(&node, &mesh)));
                continue;
            }
        };
        for primitive in mesh.primitives() {
            drawn.primitives.push(DeclaredPrimitive {
                name: format!("{}, primitive {}", node_mesh_name(&node, &mesh), primitive.index()),
                node: node.index(),
                mesh: mesh.index(),
                primitive: primitive.index(),
                skin,
                rigid: rigid.clone(),
                normals: primitive.get(&gltf::Semantic::Normals).is_some(),
                texcoords: primitive.get(&gltf::Semantic::TexCoords(0)).is_some(),
            });
        }
    }
    Ok(drawn)
}

/// Checks `accessor` (a primitive's attribute) as `kind` and that it has `count` elements.
fn check(
    document: &gltf::Document,
    name: &str,
    what: &str,
    accessor: &gltf::Accessor,
    kind: Element,
    count: Option<usize>,
) -> Result<(), InputError> {
    let json = &document.as_json().accessors[accessor.index()];
    check_accessor(accessor, json, kind).map_err(|e| {
        InputError::Gltf(FormatError::caused(format!("{name}: {what} (accessor {})", accessor.index()), e))
    })?;
    match count {
        Some(count) if accessor.count() != count => Err(error(format!(
            "{name}: {what} (accessor {}) has {} elements for {count} vertices",
            accessor.index(),
            accessor.count()
        ))),
        _ => Ok(()),
    }
}

/// One `JOINTS_n`/`WEIGHTS_n` set: each vertex's four joints and weights.
type WeightSet = (Vec<[u16; 4]>, Vec<[f64; 4]>);

/// What a primitive stores per vertex, read from its accessors or decoded from Draco.
struct Stored {
    positions: Vec<[f64; 3]>,
    normals: Option<Vec<[f64; 3]>>,
    sets: Vec<WeightSet>,
    /// The largest step of the weights' normalized integers (0 for floats).
    quantum: f64,
    indices: Option<Vec<u32>>,
    /// glTF's topology.
    mode: u32,
}

/// The `JOINTS_n`/`WEIGHTS_n` sets of `primitive` (counted from 0 while either is present).
fn weight_sets(primitive: &gltf::Primitive) -> u32 {
    use gltf::Semantic;
    let mut sets = 0;
    while primitive.get(&Semantic::Joints(sets)).is_some() || primitive.get(&Semantic::Weights(sets)).is_some() {
        sets += 1;
    }
    sets
}

/// The largest step of a weights accessor's normalized integers (0 for floats).
fn quantum(weights: &gltf::Accessor) -> f64 {
    match weights.data_type() {
        gltf::accessor::DataType::U8 => 1.0 / 255.0,
        gltf::accessor::DataType::U16 => 1.0 / 65535.0,
        _ => 0.0,
    }
}

/// `primitive`'s vertices from its accessors, each checked against its bytes first (the
/// crate's readers trust the counts).
fn from_accessors(
    document: &gltf::Document,
    buffers: &[Vec<u8>],
    primitive: &gltf::Primitive,
    name: &str,
) -> Result<Stored, InputError> {
    use gltf::Semantic;
    let reader = primitive.reader(|b| buffers.get(b.index()).map(Vec::as_slice));
    let position = primitive.get(&Semantic::Positions).ok_or_else(|| error(format!("{name}: has no POSITION")))?;
    check(document, name, "POSITION", &position, Element::Vectors, None)?;
    let count = position.count();
    let wide = |p: [f32; 3]| p.map(f64::from);
    let positions: Vec<[f64; 3]> = reader.read_positions().into_iter().flatten().map(wide).collect();
    let normals = match primitive.get(&Semantic::Normals) {
        Some(accessor) => {
            check(document, name, "NORMAL", &accessor, Element::Vectors, Some(count))?;
            Some(reader.read_normals().into_iter().flatten().map(wide).collect::<Vec<_>>())
        }
        None => None,
    };
    let (mut sets, mut step) = (Vec::new(), 0.0f64);
    for set in 0..weight_sets(primitive) {
        let (Some(j), Some(w)) = (primitive.get(&Semantic::Joints(set)), primitive.get(&Semantic::Weights(set))) else {
            return Err(error(format!("{name}: JOINTS_{set} and WEIGHTS_{set} must come in pairs")));
        };
        check(document, name, &format!("JOINTS_{set}"), &j, Element::Joints, Some(count))?;
        check(document, name, &format!("WEIGHTS_{set}"), &w, Element::Weights, Some(count))?;
        step = step.max(quantum(&w));
        let joints = reader.read_joints(set).expect("checked: JOINTS_n is present").into_u16().collect();
        let weights = reader.read_weights(set).expect("checked: WEIGHTS_n is present").into_f32();
        sets.push((joints, weights.map(|w| w.map(f64::from)).collect()));
    }
    let indices = match primitive.indices() {
        Some(accessor) => {
            check(document, name, "indices", &accessor, Element::Indices, None)?;
            Some(reader.read_indices().expect("checked: indices are present").into_u32().collect())
        }
        None => None,
    };
    Ok(Stored { positions, normals, sets, quantum: step, indices, mode: primitive.mode().as_gl_enum() })
}

/// `primitive`'s vertices decoded from its Draco bytes (`extension`, the primitive's
/// [`DRACO`] object): the extension's attribute ids name the decoded attributes, and the
/// primitive's accessors give their counts and whether weights are normalized.
fn from_draco(
    document: &gltf::Document,
    buffers: &[Vec<u8>],
    primitive: &gltf::Primitive,
    name: &str,
    extension: &serde_json::Value,
) -> Result<Stored, InputError> {
    use gltf::Semantic;
    let fail = |what: String| error(format!("{name}: {DRACO}: {what}"));
    let failed = |what: String, e: super::draco::DracoError| {
        InputError::Gltf(FormatError::caused(format!("{name}: {DRACO}: {what}"), e))
    };
    let view = extension["bufferView"].as_u64().ok_or_else(|| fail("no bufferView".into()))?;
    let view = document.views().nth(view as usize).ok_or_else(|| fail(format!("bufferView {view} does not exist")))?;
    let bytes = buffers
        .get(view.buffer().index())
        .and_then(|b| b.get(view.offset()..view.offset().checked_add(view.length())?))
        .ok_or_else(|| fail(format!("bufferView {} lies outside its buffer", view.index())))?;
    let decoded = super::draco::Decoded::new(bytes).map_err(|e| failed("cannot decode".into(), e))?;
    let id = |attribute: &str| -> Result<u32, InputError> {
        let id = extension["attributes"][attribute].as_u64();
        id.and_then(|i| u32::try_from(i).ok()).ok_or_else(|| fail(format!("its attributes name no {attribute}")))
    };
    let four = |attribute: &str, normalized: bool| -> Result<Vec<[f64; 4]>, InputError> {
        decoded.attribute::<4>(id(attribute)?, normalized).map_err(|e| failed(attribute.into(), e))
    };
    let three = |attribute: &str| -> Result<Vec<[f64; 3]>, InputError> {
        decoded.attribute::<3>(id(attribute)?, false).map_err(|e| failed(attribute.into(), e))
    };
    let position = primitive.get(&Semantic::Positions).ok_or_else(|| error(format!("{name}: has no POSITION")))?;
    if decoded.points() != position.count() {
        return Err(fail(format!("{} points decoded for POSITION's {} vertices", decoded.points(), position.count())));
    }
    let positions = three("POSITION")?;
    let normals = if primitive.get(&Semantic::Normals).is_some() { Some(three("NORMAL")?) } else { None };
    let (mut sets, mut step) = (Vec::new(), 0.0f64);
    for set in 0..weight_sets(primitive) {
        let (Some(_), Some(w)) = (primitive.get(&Semantic::Joints(set)), primitive.get(&Semantic::Weights(set))) else {
            return Err(error(format!("{name}: JOINTS_{set} and WEIGHTS_{set} must come in pairs")));
        };
        step = step.max(quantum(&w));
        let mut joints = Vec::with_capacity(positions.len());
        for (v, js) in four(&format!("JOINTS_{set}"), false)?.into_iter().enumerate() {
            if js.iter().any(|&j| j.fract() != 0.0 || !(0.0..=f64::from(u16::MAX)).contains(&j)) {
                return Err(fail(format!("vertex {v}: JOINTS_{set} is {js:?}, not joint indices")));
            }
            joints.push(js.map(|j| j as u16));
        }
        sets.push((joints, four(&format!("WEIGHTS_{set}"), w.normalized())?));
    }
    // Draco meshes are triangle lists.
    Ok(Stored { positions, normals, sets, quantum: step, indices: Some(decoded.indices()), mode: 4 })
}

/// What a primitive's vertices are bound to.
enum Binding<'a> {
    /// Skin `skin` of `joints` joints, by the primitive's own joints and weights.
    Skin { skin: usize, joints: usize },
    /// A rigid part of skin `skin`.
    Rigid { skin: usize, rigid: &'a RigidBinding },
}

#[allow(clippy::too_many_arguments)]
fn read_primitive(
    document: &gltf::Document,
    buffers: &[Vec<u8>],
    primitive: &gltf::Primitive,
    name: String,
    binding: Binding<'_>,
    morph_weights: &[f32],
    (node, mesh): (usize, usize),
    draco: Option<&serde_json::Value>,
) -> Result<SkinnedPrimitive, InputError> {
    let Stored { mut positions, mut normals, sets, quantum, indices, mode } = match draco {
        Some(extension) => from_draco(document, buffers, primitive, &name, extension)?,
        None => from_accessors(document, buffers, primitive, &name)?,
    };
    let count = positions.len();
    let reader = primitive.reader(|b| buffers.get(b.index()).map(Vec::as_slice));
    // Each target's deltas checked first: the crate's readers trust the counts.
    for (t, target) in primitive.morph_targets().enumerate() {
        for (attribute, accessor) in [("POSITION", target.positions()), ("NORMAL", target.normals())] {
            if let Some(accessor) = accessor {
                let what = format!("morph target {t} {attribute}");
                check(document, &name, &what, &accessor, Element::Vectors, Some(count))?;
            }
        }
    }
    for (t, (position_deltas, normal_deltas, _)) in reader.read_morph_targets().enumerate() {
        let weight = f64::from(morph_weights.get(t).copied().unwrap_or(0.0));
        if weight == 0.0 {
            continue;
        }
        let add = |values: &mut Vec<[f64; 3]>, deltas: gltf::accessor::Iter<'_, [f32; 3]>| {
            for (v, d) in values.iter_mut().zip(deltas) {
                for (c, d) in v.iter_mut().zip(d) {
                    *c += weight * f64::from(d);
                }
            }
        };
        if let Some(deltas) = position_deltas {
            add(&mut positions, deltas);
        }
        if let (Some(normals), Some(deltas)) = (normals.as_mut(), normal_deltas) {
            add(normals, deltas);
        }
    }
    let (skin, rigid, influences, joints, mut weights, quantum) = match binding {
        Binding::Skin { skin, joints } => {
            let (influences, js, ws) = weights_of(&name, &sets, count, joints)?;
            (skin, None, influences, js, ws, quantum)
        }
        Binding::Rigid { skin, rigid } => {
            for p in &mut positions {
                *p = skeleton::transform_point(&rigid.bind, *p);
            }
            if let Some(normals) = &mut normals {
                let normal_matrix = normal_matrix(&rigid.bind);
                for n in normals.iter_mut() {
                    *n = std::array::from_fn(|r| (0..3).map(|c| normal_matrix[r][c] * n[c]).sum());
                }
            }
            let joint = u32::try_from(rigid.joint).unwrap_or(u32::MAX);
            let joints = (0..count).flat_map(|_| [joint, 0, 0, 0]).collect();
            let weights = (0..count).flat_map(|_| [1.0, 0.0, 0.0, 0.0]).collect();
            (skin, Some(rigid.clone()), 4, joints, weights, 0.0)
        }
    };
    if let Some(normals) = &mut normals {
        for n in normals.iter_mut() {
            let length = n.iter().map(|c| c * c).sum::<f64>().sqrt();
            if length > 0.0 {
                *n = n.map(|c| c / length);
            }
        }
    }
    if let Some((k, i)) = indices.iter().flatten().enumerate().find(|(_, &i)| i as usize >= count) {
        return Err(error(format!("{name}: indices[{k}] is {i}, but the primitive has {count} vertices")));
    }
    let tolerance = WEIGHT_SUM_TOLERANCE + 0.5 * quantum * influences as f64;
    let mut normalized = 0;
    for (v, ws) in weights.chunks_exact_mut(influences).enumerate() {
        let sum: f64 = ws.iter().sum();
        if sum <= 0.0 {
            return Err(error(format!("{name}: vertex {v}: its weights are all zero, so no joint moves it")));
        }
        if (sum - 1.0).abs() > tolerance {
            normalized += 1;
        }
        for w in ws.iter_mut() {
            *w /= sum;
        }
    }
    Ok(SkinnedPrimitive {
        name,
        node,
        mesh,
        primitive: primitive.index(),
        skin,
        rigid,
        bind: SkinnedMesh { positions, normals, influences, joints, weights },
        normalized,
        indices,
        mode,
    })
}

/// Each vertex's influences from a skinned primitive's `JOINTS_n`/`WEIGHTS_n` `sets` (four a
/// set), each joint checked against the skin's `skin_joints`: influences a vertex, joints and
/// weights (not yet normalized).
fn weights_of(
    name: &str,
    sets: &[WeightSet],
    count: usize,
    skin_joints: usize,
) -> Result<(usize, Vec<u32>, Vec<f64>), InputError> {
    if sets.is_empty() {
        return Err(error(format!("{name}: its node has a skin but the primitive has no JOINTS_0 and WEIGHTS_0")));
    }
    let influences = 4 * sets.len();
    let mut joints = vec![0u32; count * influences];
    let mut weights = vec![0.0f64; count * influences];
    for (set, (set_joints, set_weights)) in sets.iter().enumerate() {
        for (v, (js, ws)) in set_joints.iter().zip(set_weights).enumerate() {
            for k in 0..4 {
                let slot = v * influences + 4 * set + k;
                let (joint, weight) = (js[k], ws[k]);
                if usize::from(joint) >= skin_joints {
                    return Err(error(format!(
                        "{name}: vertex {v}: JOINTS_{set}[{k}] is {joint}, but its skin has {skin_joints} joints"
                    )));
                }
                if !weight.is_finite() || weight < 0.0 {
                    return Err(error(format!(
                        "{name}: vertex {v}: WEIGHTS_{set}[{k}] is {weight}; weights are finite and not negative"
                    )));
                }
                joints[slot] = u32::from(joint);
                weights[slot] = weight;
            }
        }
    }
    Ok((influences, joints, weights))
}

/// The inverse transpose of `m`'s linear part, up to a positive factor (the cofactor matrix,
/// its sign kept by the determinant's): what takes normals where `m` takes surfaces.
fn normal_matrix(m: &Affine) -> [[f64; 3]; 3] {
    let a = |r: usize, c: usize| m[4 * r + c];
    let cofactor = |r: usize, c: usize| {
        let (r1, r2) = ((r + 1) % 3, (r + 2) % 3);
        let (c1, c2) = ((c + 1) % 3, (c + 2) % 3);
        a(r1, c1) * a(r2, c2) - a(r1, c2) * a(r2, c1)
    };
    let det: f64 = (0..3).map(|c| a(0, c) * cofactor(0, c)).sum();
    let sign = if det < 0.0 { -1.0 } else { 1.0 };
    std::array::from_fn(|r| std::array::from_fn(|c| sign * cofactor(r, c)))
}
