//! The skinned mesh primitives of a glTF file, read for vertex textures: bind-space positions
//! and normals (morph targets applied at their default weights) and each vertex's joints and
//! weights, checked against the skin and normalized. Read on demand, so that a file whose
//! meshes are broken still bakes bone textures.

use super::gltf::{check_accessor, Element, GltfFile};
use crate::error::InputError;
use quatcurve_eval::skeleton::SkinnedMesh;

/// The largest `|sum of weights - 1|` a vertex may have before its weights are said to be
/// normalized (they are divided by their sum either way); normalized-integer weights are also
/// allowed half a quantum per influence.
pub const WEIGHT_SUM_TOLERANCE: f64 = 1e-3;

/// The glTF extension of Draco-compressed primitives (their accessors have no buffer views;
/// `draco-core` decodes them).
pub const DRACO: &str = "KHR_draco_mesh_compression";

/// A mesh primitive drawn by a skinned node: what linear blend skinning needs of it.
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
    /// Index into [`super::Animation::skins`].
    pub skin: usize,
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

fn error(msg: String) -> InputError {
    InputError::Gltf(msg)
}

/// Every primitive drawn by a node with a skin, in node then primitive order. A mesh drawn by a
/// node without a skin is rigid and left out, unless it carries joints or weights (then the
/// skin is missing, an error); a skinned node's primitive without `JOINTS_0` and `WEIGHTS_0`
/// is an error.
///
/// # Errors
/// [`InputError::Gltf`] naming the node, mesh, primitive, vertex and rule broken; also when no
/// node draws a skinned mesh.
pub fn skinned_primitives(file: &GltfFile) -> Result<Vec<SkinnedPrimitive>, InputError> {
    let (document, buffers) = file.document()?;
    let skins = &file.animation.skins;
    let mut out = Vec::new();
    for node in document.nodes() {
        let Some(mesh) = node.mesh() else { continue };
        let node_name = node.name().map_or_else(|| format!("node{}", node.index()), str::to_string);
        let mesh_name = mesh.name().map_or_else(|| format!("mesh{}", mesh.index()), str::to_string);
        for primitive in mesh.primitives() {
            let name = format!("node '{node_name}', mesh '{mesh_name}', primitive {}", primitive.index());
            let weighted = primitive.get(&gltf::Semantic::Joints(0)).is_some()
                || primitive.get(&gltf::Semantic::Weights(0)).is_some();
            let skin = match (node.skin(), weighted) {
                (None, false) => continue,
                (None, true) => {
                    return Err(error(format!(
                        "{name}: has JOINTS_0 or WEIGHTS_0 but its node has no skin to bind them to"
                    )))
                }
                (Some(skin), _) => skin.index(),
            };
            let Some(skin_joints) = skins.get(skin).map(|s| s.joints.len()) else {
                return Err(error(format!("{name}: skin {skin} does not exist")));
            };
            let draco = file.primitive_extension(mesh.index(), primitive.index(), DRACO);
            let weights = node.weights().or_else(|| mesh.weights()).unwrap_or(&[]);
            out.push(read_primitive(
                &document,
                buffers,
                &primitive,
                name,
                skin,
                skin_joints,
                weights,
                (node.index(), mesh.index()),
                draco,
            )?);
        }
    }
    if out.is_empty() {
        return Err(error("no node draws a skinned mesh: there are no vertices to bake".into()));
    }
    Ok(out)
}

/// A skinned primitive as the file declares it, without reading its vertices: what a renderer
/// binds for it (a `skin-trs` bake's sidecar lists these).
#[derive(Clone, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
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
    /// Whether it has `NORMAL` and `TEXCOORD_0`.
    pub normals: bool,
    /// See [`Self::normals`].
    pub texcoords: bool,
}

/// Every primitive a skinned node draws, from the file's declarations alone (a Draco
/// primitive declares its attributes too).
///
/// # Errors
/// A file whose JSON is not glTF's.
pub fn declared_skinned_primitives(file: &GltfFile) -> Result<Vec<DeclaredPrimitive>, InputError> {
    let (document, _) = file.document()?;
    let mut out = Vec::new();
    for node in document.nodes() {
        let (Some(mesh), Some(skin)) = (node.mesh(), node.skin()) else { continue };
        let node_name = node.name().map_or_else(|| format!("node{}", node.index()), str::to_string);
        let mesh_name = mesh.name().map_or_else(|| format!("mesh{}", mesh.index()), str::to_string);
        for primitive in mesh.primitives() {
            out.push(DeclaredPrimitive {
                name: format!("node '{node_name}', mesh '{mesh_name}', primitive {}", primitive.index()),
                node: node.index(),
                mesh: mesh.index(),
                primitive: primitive.index(),
                skin: skin.index(),
                normals: primitive.get(&gltf::Semantic::Normals).is_some(),
                texcoords: primitive.get(&gltf::Semantic::TexCoords(0)).is_some(),
            });
        }
    }
    Ok(out)
}

/// Every mesh drawn by a node without a skin (a rigid part, moved by its node's transform
/// alone), as `node 'N', mesh 'M'`: what textures of skinned meshes do not draw.
///
/// # Errors
/// A file whose JSON is not glTF's.
pub fn rigid_meshes(file: &GltfFile) -> Result<Vec<String>, InputError> {
    let (document, _) = file.document()?;
    Ok(document
        .nodes()
        .filter(|node| node.skin().is_none())
        .filter_map(|node| {
            let mesh = node.mesh()?;
            let node_name = node.name().map_or_else(|| format!("node{}", node.index()), str::to_string);
            let mesh_name = mesh.name().map_or_else(|| format!("mesh{}", mesh.index()), str::to_string);
            Some(format!("node '{node_name}', mesh '{mesh_name}'"))
        })
        .collect())
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
    check_accessor(accessor, json, kind)
        .map_err(|e| error(format!("{name}: {what} (accessor {}): {e}", accessor.index())))?;
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
    let view = extension["bufferView"].as_u64().ok_or_else(|| fail("no bufferView".into()))?;
    let view = document.views().nth(view as usize).ok_or_else(|| fail(format!("bufferView {view} does not exist")))?;
    let bytes = buffers
        .get(view.buffer().index())
        .and_then(|b| b.get(view.offset()..view.offset().checked_add(view.length())?))
        .ok_or_else(|| fail(format!("bufferView {} lies outside its buffer", view.index())))?;
    let decoded = super::draco::Decoded::new(bytes).map_err(|e| fail(format!("cannot decode: {e}")))?;
    let id = |attribute: &str| -> Result<u32, InputError> {
        let id = extension["attributes"][attribute].as_u64();
        id.and_then(|i| u32::try_from(i).ok()).ok_or_else(|| fail(format!("its attributes name no {attribute}")))
    };
    let four = |attribute: &str, normalized: bool| -> Result<Vec<[f64; 4]>, InputError> {
        decoded.attribute::<4>(id(attribute)?, normalized).map_err(|e| fail(format!("{attribute}: {e}")))
    };
    let three = |attribute: &str| -> Result<Vec<[f64; 3]>, InputError> {
        decoded.attribute::<3>(id(attribute)?, false).map_err(|e| fail(format!("{attribute}: {e}")))
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

#[allow(clippy::too_many_arguments)]
fn read_primitive(
    document: &gltf::Document,
    buffers: &[Vec<u8>],
    primitive: &gltf::Primitive,
    name: String,
    skin: usize,
    skin_joints: usize,
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
    if let Some(normals) = &mut normals {
        for n in normals.iter_mut() {
            let length = n.iter().map(|c| c * c).sum::<f64>().sqrt();
            if length > 0.0 {
                *n = n.map(|c| c / length);
            }
        }
    }
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
        bind: SkinnedMesh { positions, normals, influences, joints, weights },
        normalized,
        indices,
        mode,
    })
}
