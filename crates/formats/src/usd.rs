//! OpenUSD in (UsdSkel), through the `openusd` crate (its `.usda`, `.usdc` and `.usdz` readers
//! and USD's composition), as the glTF scene it converts to: each `Skeleton` a node (its place
//! in the stage, in glTF's space) over its joints' nodes (their rest transforms), each
//! `SkelAnimation` an animation of the skeleton it animates (its time samples, LINEAR: USD
//! interpolates samples linearly, rotations by slerp, as glTF's LINEAR does; STEP on a stage
//! that holds them), each mesh bound by `SkelBindingAPI` a skinned mesh of triangles. As FBX's,
//! the GLB is read back by the glTF reader ([`crate::gltf`]), so a stage bakes, fits and plays
//! as a glTF does, and its baked file is that GLB with the baked frames.
//!
//! The skeleton's node carries the stage's `metersPerUnit` and `upAxis` into glTF's metres and
//! +Y up, after the transforms of the skeleton and its ancestors (at their first time sample
//! where they move); a
//! mesh's points are taken into the skeleton's space by its `geomBindTransform` and drawn
//! from there, as UsdSkel skins them.

use crate::glb_builder::{heaviest, Buffer, Scene};
use crate::gltf::{self, GltfFile, UriPolicy};
use glam::{DMat4, DQuat, DVec3};
use openusd::gf::Matrix4d;
use openusd::schemas::geom::{Imageable, Xformable};
use openusd::schemas::skel::{InfluenceInterpolation, SkelAnimation, SkelBindingAPI, Skeleton};
use openusd::sdf::{self, Value};
use openusd::usd::{Attribute, InterpolationType, Prim, PrimPredicate, SchemaBase, SchemaKind, Stage, TimeCode};
use quatcurve_anim::error::{FormatError, InputError};
use serde_json::{json, Value as Json};
use std::cell::Cell;
use std::collections::HashMap;
use std::panic::AssertUnwindSafe;
use std::path::Path;
use std::sync::Once;

/// The extensions of USD files: text, binary, either, and the zip package.
pub const EXTENSIONS: [&str; 4] = ["usd", "usda", "usdc", "usdz"];

/// A USD stage read for baking: the glTF scene it converts to.
#[derive(Clone, Debug)]
pub struct UsdFile {
    /// The scene as a glTF (read back from the GLB the stage converts to).
    pub gltf: GltfFile,
    /// The length of the stage's unit in metres (`metersPerUnit`, 0.01 when unauthored).
    pub source_unit_metres: f64,
    /// The stage's up axis (`+Y` or `+Z`).
    pub source_up: &'static str,
}

/// USD's `metersPerUnit` where a stage does not say (UsdGeom's fallback: centimetres).
const DEFAULT_METRES_PER_UNIT: f64 = 0.01;

/// A rule of UsdSkel broken, found here.
fn bad(rule: String) -> InputError {
    InputError::Usd(FormatError::rule(rule))
}

/// openusd's refusal of `what`, with each of its reasons (its chain, where the line is).
fn refused(what: String, error: anyhow::Error) -> InputError {
    InputError::Usd(FormatError::caused(what, format!("{error:#}")))
}

/// Reads a USD stage (`.usda`, `.usdc`, `.usd`, `.usdz`), composed as USD composes it (its
/// sublayers, references and variant selections, read from beside it).
///
/// # Errors
/// [`InputError::Read`] for a file that cannot be opened; [`InputError::Usd`] for a stage
/// openusd cannot read, or a skeleton, animation or mesh that breaks a rule of UsdSkel, named
/// by its prim path.
pub fn read(path: &Path) -> Result<UsdFile, InputError> {
    std::fs::File::open(path).map_err(InputError::Read)?;
    let (glb, metres, z_up) = guarded(|| stage_glb(path))?;
    let gltf = gltf::from_bytes(&glb, Path::new(""), UriPolicy::default())?;
    Ok(UsdFile { gltf, source_unit_metres: metres, source_up: if z_up { "+Z" } else { "+Y" } })
}

thread_local! {
    /// Whether this thread is inside openusd, whose panics are its errors ([`guarded`]).
    static IN_OPENUSD: Cell<bool> = const { Cell::new(false) };
}

/// `read`'s work with openusd's panics (an index out of bounds on a corrupt `.usdc`) caught
/// as the file's error; the panic hook stays quiet for them and as it was for any other.
fn guarded<T>(work: impl FnOnce() -> Result<T, InputError>) -> Result<T, InputError> {
    static QUIET_HOOK: Once = Once::new();
    QUIET_HOOK.call_once(|| {
        let previous = std::panic::take_hook();
        std::panic::set_hook(Box::new(move |info| {
            if !IN_OPENUSD.with(Cell::get) {
                previous(info);
            }
        }));
    });
    IN_OPENUSD.with(|inside| inside.set(true));
    let result = std::panic::catch_unwind(AssertUnwindSafe(work));
    IN_OPENUSD.with(|inside| inside.set(false));
    result.unwrap_or_else(|panic| {
        let reason = panic
            .downcast_ref::<&str>()
            .map(|s| (*s).to_string())
            .or_else(|| panic.downcast_ref::<String>().cloned())
            .unwrap_or_default();
        Err(bad(format!("not a readable USD stage: openusd failed on it ({reason})")))
    })
}

/// The stage at `path` as a GLB, with its `metersPerUnit` and whether it is +Z up.
fn stage_glb(path: &Path) -> Result<(Vec<u8>, f64, bool), InputError> {
    let name = path.to_str().ok_or_else(|| bad("the path is not UTF-8, which openusd needs".into()))?;
    let stage = Stage::open(name).map_err(|e| refused("not a readable USD stage".into(), e))?;
    let metres = match stage.stage_metadata("metersPerUnit") {
        Ok(Some(v)) => v.try_as_double().unwrap_or(DEFAULT_METRES_PER_UNIT),
        _ => DEFAULT_METRES_PER_UNIT,
    };
    if !(metres.is_finite() && metres > 0.0) {
        return Err(bad(format!("metersPerUnit {metres} is not a positive length")));
    }
    let z_up = match stage.stage_metadata("upAxis") {
        Ok(Some(Value::Token(t))) => t.as_str() == "Z",
        Ok(Some(Value::String(t))) => t == "Z",
        _ => false,
    };
    Ok((to_glb(&stage, metres, z_up)?, metres, z_up))
}

/// A skeleton read from the stage, its joints placed among the glTF's nodes.
struct Skel {
    path: sdf::Path,
    joints: Vec<String>,
    /// Each joint's bind transform in the skeleton's space (column vectors).
    bind: Vec<DMat4>,
    /// The glTF node of its joint 0; joint `j` is node `first + j`.
    first: usize,
    /// Its bound animation (`skel:animationSource`), if any.
    animation: Option<sdf::Path>,
}

/// Any prim, for its transform (`xformOpOrder`); one that has none is the identity.
struct Placed(Prim);

impl SchemaBase for Placed {
    const KIND: SchemaKind = SchemaKind::ConcreteTyped;

    fn prim(&self) -> &Prim {
        &self.0
    }
}
impl Imageable for Placed {}
impl Xformable for Placed {}

/// A USD matrix (row vectors, row-major) as glam's (column vectors): the same sixteen numbers.
fn columns(m: &Matrix4d) -> DMat4 {
    DMat4::from_cols_array(&m.0)
}

/// A node of `name` at `m`, decomposed to glTF's translation, rotation and scale.
fn node(name: &str, m: &DMat4) -> Json {
    let (s, r, t) = m.to_scale_rotation_translation();
    json!({"name": name, "translation": t.to_array(), "rotation": r.to_array(), "scale": s.to_array()})
}

/// The stage as a GLB (see the module's documentation).
fn to_glb(stage: &Stage, metres: f64, z_up: bool) -> Result<Vec<u8>, InputError> {
    let (mut skeleton_paths, mut animation_paths, mut mesh_paths) = (Vec::new(), Vec::new(), Vec::new());
    let mut failed = None;
    stage
        .traverse(PrimPredicate::DEFAULT, |path| match stage.prim(path.clone()).type_name() {
            Ok(Some(t)) => match t.as_str() {
                "Skeleton" => skeleton_paths.push(path.clone()),
                "SkelAnimation" => animation_paths.push(path.clone()),
                "Mesh" => mesh_paths.push(path.clone()),
                _ => {}
            },
            Ok(None) => {}
            Err(e) => {
                failed.get_or_insert(refused(format!("prim <{}>", path.as_str()), e));
            }
        })
        .map_err(|e| refused("the stage's prims".into(), e))?;
    if let Some(e) = failed {
        return Err(e);
    }
    // glTF's space from the stage's: metres, and +Z up turned to +Y up.
    let space =
        DMat4::from_quat(if z_up { DQuat::from_rotation_x(-std::f64::consts::FRAC_PI_2) } else { DQuat::IDENTITY })
            * DMat4::from_scale(DVec3::splat(metres));
    let (mut nodes, mut roots, mut skeletons) = (Vec::new(), Vec::new(), Vec::new());
    for path in skeleton_paths {
        skeletons.push(skeleton(stage, &path, &space, &mut nodes, &mut roots)?);
    }
    if skeletons.is_empty() {
        return Err(bad("no Skeleton prim: nothing to animate".into()));
    }
    let mut buffer = Buffer::default();
    let (mut meshes, mut skins) = (Vec::new(), Vec::new());
    for path in mesh_paths {
        let Some(binding) = SkelBindingAPI::get(stage, path.clone()).map_err(|e| at(&path, e))? else { continue };
        let Some(target) = binding.inherited_skeleton().map_err(|e| at(&path, e))? else { continue };
        let Some(skel) = skeletons.iter().find(|s| s.path == target) else {
            return Err(bad(format!(
                "mesh <{}>: skel:skeleton <{}> is not a Skeleton",
                path.as_str(),
                target.as_str()
            )));
        };
        meshes.push(mesh(stage, &path, &binding, skel, &mut buffer)?);
        let inverse_bind: Vec<f32> =
            skel.bind.iter().flat_map(|b| b.inverse().to_cols_array().map(|x| x as f32)).collect();
        skins.push(json!({
            "name": path.name().unwrap_or_default(),
            "joints": (skel.first..skel.first + skel.joints.len()).collect::<Vec<_>>(),
            "skeleton": skel.first - 1,
            "inverseBindMatrices": buffer.floats(&inverse_bind, 16, "MAT4", false),
        }));
        nodes.push(json!({"name": path.name().unwrap_or_default(), "mesh": meshes.len() - 1, "skin": skins.len() - 1}));
        roots.push(nodes.len() - 1);
    }
    let step = stage.interpolation_type() == InterpolationType::Held;
    let seconds = stage.time_codes_per_second();
    if !(seconds.is_finite() && seconds > 0.0) {
        return Err(bad(format!("timeCodesPerSecond {seconds} is not a positive rate")));
    }
    let mut animations = Vec::new();
    for path in animation_paths {
        if let Some(a) = animation(stage, &path, &skeletons, seconds, step, &mut buffer)? {
            animations.push(a);
        }
    }
    let scene = Scene { generator: "quatcurve (USD through openusd)", roots, nodes, meshes, skins, animations };
    buffer.glb(scene, "the USD stage would exceed 4 GiB as a GLB")
}

/// openusd's refusal of what is at `path`.
fn at(path: &sdf::Path, error: anyhow::Error) -> InputError {
    refused(format!("prim <{}>", path.as_str()), error)
}

/// The skeleton at `path` as a node (its place, in glTF's space by `space`) over its joints'
/// nodes (their rest transforms, else those of their bind transforms), added to `nodes`.
fn skeleton(
    stage: &Stage,
    path: &sdf::Path,
    space: &DMat4,
    nodes: &mut Vec<Json>,
    roots: &mut Vec<usize>,
) -> Result<Skel, InputError> {
    let named = |what: &str| format!("Skeleton <{}>: {what}", path.as_str());
    let skeleton =
        Skeleton::get(stage, path.clone()).map_err(|e| at(path, e))?.ok_or_else(|| bad(named("not a Skeleton")))?;
    let joints = skeleton.joints().map_err(|e| at(path, e))?;
    if joints.is_empty() {
        return Err(bad(named("joints is empty")));
    }
    let mut seen = HashMap::new();
    for (j, joint) in joints.iter().enumerate() {
        if let Some(first) = seen.insert(joint.as_str(), j) {
            return Err(bad(named(&format!("joints {first} and {j} are both '{joint}'"))));
        }
    }
    let parents = skeleton.joint_parent_indices().map_err(|e| at(path, e))?;
    let matrices = |attribute: &str, attr: Attribute| -> Result<Vec<DMat4>, InputError> {
        let list = match attr.get::<Value>().map_err(|e| at(path, e))? {
            Some(Value::Matrix4dVec(list)) => list,
            None => Vec::new(),
            Some(_) => return Err(bad(named(&format!("{attribute} is not a matrix4d[]")))),
        };
        if !list.is_empty() && list.len() != joints.len() {
            return Err(bad(named(&format!("{attribute} has {} matrices for {} joints", list.len(), joints.len()))));
        }
        if let Some(j) = list.iter().position(|m| m.0.iter().any(|x| !x.is_finite())) {
            return Err(bad(named(&format!("{attribute}[{j}] ('{}') is not finite", joints[j]))));
        }
        Ok(list.iter().map(columns).collect())
    };
    let bind = matrices("bindTransforms", skeleton.bind_transforms_attr())?;
    let mut rest = matrices("restTransforms", skeleton.rest_transforms_attr())?;
    if rest.is_empty() {
        if bind.is_empty() {
            return Err(bad(named("neither restTransforms nor bindTransforms is authored")));
        }
        rest = (0..joints.len()).map(|j| parents[j].map_or(bind[j], |p| bind[p].inverse() * bind[j])).collect();
    }
    let bind = if bind.is_empty() {
        let mut world = rest.clone();
        for j in 0..joints.len() {
            if let Some(p) = parents[j] {
                world[j] = world[p] * rest[j];
            }
        }
        world
    } else {
        bind
    };
    // The skeleton's place: its own transform and its ancestors', to the first that resets
    // the stack.
    let mut place = DMat4::IDENTITY;
    let mut prim = Some(path.clone());
    while let Some(p) = prim.filter(|p| !p.is_abs_root()) {
        let placed = Placed(stage.prim(p.clone()));
        place = columns(&placed.local_to_parent_transform(TimeCode::EARLIEST).map_err(|e| at(&p, e))?) * place;
        if placed.resets_xform_stack().map_err(|e| at(&p, e))? {
            break;
        }
        prim = p.parent();
    }
    nodes.push(node(path.name().unwrap_or("Skeleton"), &(*space * place)));
    let own = nodes.len() - 1;
    roots.push(own);
    let first = nodes.len();
    let mut children = vec![Vec::new(); joints.len()];
    for (j, joint) in joints.iter().enumerate() {
        let short = joint.rsplit_once('/').map_or(joint.as_str(), |(_, n)| n);
        nodes.push(node(short, &rest[j]));
        match parents[j] {
            Some(p) => children[p].push(first + j),
            None => {
                let list = nodes[own].as_object_mut().expect("a node is an object");
                list.entry("children")
                    .or_insert_with(|| json!([]))
                    .as_array_mut()
                    .expect("an array")
                    .push(json!(first + j));
            }
        }
    }
    for (j, list) in children.into_iter().enumerate().filter(|(_, l)| !l.is_empty()) {
        nodes[first + j]["children"] = json!(list);
    }
    let animation = SkelBindingAPI::get(stage, path.clone())
        .map_err(|e| at(path, e))?
        .map(|b| b.inherited_animation_source())
        .transpose()
        .map_err(|e| at(path, e))?
        .flatten();
    Ok(Skel { path: path.clone(), joints, bind, first, animation })
}

/// The mesh at `path`, bound to `skel`, as one glTF mesh of triangles: its points (and its
/// normals, where given a vertex each) in the skeleton's space, its faces as fans of
/// triangles, each vertex's heaviest four joints.
fn mesh(
    stage: &Stage,
    path: &sdf::Path,
    binding: &SkelBindingAPI,
    skel: &Skel,
    buffer: &mut Buffer,
) -> Result<Json, InputError> {
    let named = |what: String| bad(format!("mesh <{}>: {what}", path.as_str()));
    let prim = stage.prim(path.clone());
    let get = |name: &str| prim.attribute(name).get::<Value>().map_err(|e| at(path, e));
    let vectors = |value: Option<Value>| -> Option<Vec<DVec3>> {
        Some(match value? {
            Value::Vec3fVec(v) => v.iter().map(|p| DVec3::new(p.x.into(), p.y.into(), p.z.into())).collect(),
            Value::Vec3dVec(v) => v.iter().map(|p| DVec3::new(p.x, p.y, p.z)).collect(),
            _ => return None,
        })
    };
    let points = vectors(get("points")?).ok_or_else(|| named("points is not authored as point3f[]".into()))?;
    let ints = |name: &str| -> Result<Vec<i32>, InputError> {
        match get(name)? {
            Some(Value::IntVec(v)) => Ok(v),
            _ => Err(named(format!("{name} is not authored as int[]"))),
        }
    };
    let (counts, corners) = (ints("faceVertexCounts")?, ints("faceVertexIndices")?);
    let mut triangles = Vec::new();
    let mut next = 0usize;
    for (f, &count) in counts.iter().enumerate() {
        let count = usize::try_from(count)
            .ok()
            .filter(|&c| c >= 3)
            .ok_or_else(|| named(format!("face {f} has {count} vertices; a face has 3 or more")))?;
        let face = corners.get(next..next + count).ok_or_else(|| {
            named(format!("faceVertexCounts needs more than the {} faceVertexIndices", corners.len()))
        })?;
        for &v in face {
            if usize::try_from(v).map_or(true, |v| v >= points.len()) {
                return Err(named(format!("face {f}: vertex {v} is not one of the {} points", points.len())));
            }
        }
        for k in 1..count - 1 {
            triangles.extend([face[0], face[k], face[k + 1]].map(|v| v as u32));
        }
        next += count;
    }
    if next != corners.len() {
        return Err(named(format!("faceVertexCounts covers {next} of the {} faceVertexIndices", corners.len())));
    }
    let geom = binding.geom_bind_transform().map_err(|e| at(path, e))?.map_or(DMat4::IDENTITY, |m| columns(&m));
    let bound: Vec<f32> = points.iter().flat_map(|&p| geom.transform_point3(p).as_vec3().to_array()).collect();
    if bound.iter().any(|x| !x.is_finite()) {
        return Err(named("a point is not finite in the skeleton's space".into()));
    }
    let mut attributes = json!({"POSITION": buffer.attribute(&bound, 3, "VEC3", true)});
    let normal_attribute = prim.attribute("normals");
    let per_vertex = !matches!(
        normal_attribute.get_metadata::<Value>("interpolation"),
        Ok(Some(Value::Token(t))) if t.as_str() != "vertex" && t.as_str() != "varying"
    );
    if let Some(normals) = vectors(get("normals")?).filter(|n| per_vertex && n.len() == points.len()) {
        let turn = glam::DMat3::from_mat4(geom).inverse().transpose();
        let values: Vec<f32> =
            normals.iter().flat_map(|&n| (turn * n).normalize_or_zero().as_vec3().to_array()).collect();
        attributes["NORMAL"] = json!(buffer.attribute(&values, 3, "VEC3", false));
    }
    let indices = binding.joint_indices().map_err(|e| at(path, e))?;
    let weights = binding.joint_weights().map_err(|e| at(path, e))?;
    let per = usize::try_from(binding.elements_per_element().map_err(|e| at(path, e))?)
        .ok()
        .filter(|&n| n > 0)
        .ok_or_else(|| named("primvars:skel:jointIndices has an elementSize below 1".into()))?;
    let rigid = binding.interpolation().map_err(|e| at(path, e))? == InfluenceInterpolation::Constant;
    let expected = if rigid { per } else { per * points.len() };
    if indices.len() != expected || weights.len() != expected {
        let over =
            if rigid { "the whole mesh (constant)".to_string() } else { format!("each of {} points", points.len()) };
        return Err(named(format!(
            "primvars:skel:jointIndices and jointWeights hold {} and {} values; {per} influences for {over} are {expected}",
            indices.len(),
            weights.len(),
        )));
    }
    // The mesh's joints (skel:joints, else the skeleton's) as the skeleton's.
    let subset = binding.joint_subset().map_err(|e| at(path, e))?;
    let to_skeleton: Vec<u32> = if subset.is_empty() {
        (0..skel.joints.len() as u32).collect()
    } else {
        subset
            .iter()
            .map(|name| {
                skel.joints.iter().position(|j| j == name).map(|j| j as u32).ok_or_else(|| {
                    named(format!("skel:joints names '{name}', not a joint of <{}>", skel.path.as_str()))
                })
            })
            .collect::<Result<_, _>>()?
    };
    if skel.joints.len() > usize::from(u16::MAX) {
        return Err(named(format!("its skeleton has {} joints; glTF binds at most 65535", skel.joints.len())));
    }
    let influences: Vec<_> = (0..points.len())
        .map(|v| {
            let first = if rigid { 0 } else { v * per };
            (first..first + per)
                .map(|k| {
                    let joint = usize::try_from(indices[k]).ok().and_then(|i| to_skeleton.get(i)).ok_or_else(|| {
                        named(format!(
                            "jointIndices[{k}] {} is not one of its {} joints",
                            indices[k],
                            to_skeleton.len()
                        ))
                    })?;
                    let weight = f64::from(weights[k]);
                    if !(weight.is_finite() && weight >= 0.0) {
                        return Err(named(format!("jointWeights[{k}] {weight} is not a weight")));
                    }
                    Ok((*joint, weight))
                })
                .collect::<Result<Vec<_>, _>>()
                .map(heaviest)
        })
        .collect::<Result<_, _>>()?;
    let (joints, weights) = buffer.influences(&influences);
    attributes["JOINTS_0"] = json!(joints);
    attributes["WEIGHTS_0"] = json!(weights);
    let indices = buffer.indices(&triangles);
    Ok(
        json!({"name": path.name().unwrap_or_default(), "primitives": [{"attributes": attributes, "indices": indices, "mode": 4}]}),
    )
}

/// The animation at `path` as a glTF animation of the skeleton it animates (the one that
/// binds it as `skel:animationSource`, else the one sharing the most of its joints; `None`
/// where no skeleton shares one): a sampler per animated component of each joint, its times
/// in seconds from the animation's first sample.
fn animation(
    stage: &Stage,
    path: &sdf::Path,
    skeletons: &[Skel],
    seconds: f64,
    step: bool,
    buffer: &mut Buffer,
) -> Result<Option<Json>, InputError> {
    let named = |what: String| bad(format!("SkelAnimation <{}>: {what}", path.as_str()));
    let Some(anim) = SkelAnimation::get(stage, path.clone()).map_err(|e| at(path, e))? else { return Ok(None) };
    let joints = anim.joints().map_err(|e| at(path, e))?;
    let shared = |s: &Skel| joints.iter().filter(|j| s.joints.contains(j)).count();
    let skel = skeletons
        .iter()
        .find(|s| s.animation.as_ref() == Some(path))
        .or_else(|| skeletons.iter().filter(|s| shared(s) > 0).max_by_key(|s| (shared(s), std::cmp::Reverse(s.first))));
    let Some(skel) = skel else { return Ok(None) };
    let targets: Vec<Option<usize>> =
        joints.iter().map(|j| skel.joints.iter().position(|s| s == j).map(|k| skel.first + k)).collect();
    let components = [
        ("rotations", "rotation", 4, "VEC4"),
        ("translations", "translation", 3, "VEC3"),
        ("scales", "scale", 3, "VEC3"),
    ];
    let mut read = Vec::new();
    let mut start = f64::INFINITY;
    for (attribute, gltf_path, width, kind) in components {
        let attr = anim.prim().attribute(attribute);
        let mut times = attr.time_sample_times().map_err(|e| at(path, e))?;
        let default = times.is_empty();
        if default {
            if attr.get::<Value>().map_err(|e| at(path, e))?.is_none() {
                continue;
            }
            times.push(f64::NAN);
        }
        let mut values = Vec::with_capacity(times.len());
        for &t in &times {
            let time = (!default).then(|| TimeCode::new(t));
            let value = attr.get_at::<Value>(time).map_err(|e| at(path, e))?;
            let at_time = || if default { String::new() } else { format!(" at time {t}") };
            let floats = flatten(value, width).ok_or_else(|| {
                named(format!(
                    "{attribute}{} is not an array of {}",
                    at_time(),
                    if width == 4 { "quaternions" } else { "vectors" }
                ))
            })?;
            if floats.len() != joints.len() * width {
                return Err(named(format!(
                    "{attribute}{} holds {} values for {} joints",
                    at_time(),
                    floats.len() / width,
                    joints.len()
                )));
            }
            if let Some(k) = floats.iter().position(|x| !x.is_finite()) {
                return Err(named(format!("{attribute}{}: joint '{}' is not finite", at_time(), joints[k / width])));
            }
            values.push(floats);
        }
        if !default {
            start = start.min(times[0]);
        }
        read.push((gltf_path, width, kind, times, default, values));
    }
    if read.is_empty() {
        return Ok(None);
    }
    let start = if start.is_finite() { start } else { 0.0 };
    let interpolation = if step { "STEP" } else { "LINEAR" };
    let (mut samplers, mut channels) = (Vec::new(), Vec::new());
    for (gltf_path, width, kind, times, default, values) in read {
        let times: Vec<f32> =
            if default { vec![0.0] } else { times.iter().map(|t| ((t - start) / seconds) as f32).collect() };
        let input = buffer.floats(&times, 1, "SCALAR", true);
        for (k, target) in targets.iter().enumerate() {
            let Some(target) = target else { continue };
            let output: Vec<f32> = values.iter().flat_map(|v| v[k * width..(k + 1) * width].iter().copied()).collect();
            let output = buffer.floats(&output, width, kind, false);
            samplers.push(json!({"input": input, "output": output, "interpolation": interpolation}));
            channels.push(json!({"sampler": samplers.len() - 1, "target": {"node": target, "path": gltf_path}}));
        }
    }
    if channels.is_empty() {
        return Ok(None);
    }
    Ok(Some(json!({"name": path.name().unwrap_or_default(), "samplers": samplers, "channels": channels})))
}

/// An array of quaternions (`width` 4, as glTF's x, y, z, w) or of vectors (`width` 3) as
/// floats; `None` for any other value.
fn flatten(value: Option<Value>, width: usize) -> Option<Vec<f32>> {
    Some(match (value?, width) {
        (Value::QuatfVec(v), 4) => v.iter().flat_map(|q| [q.x, q.y, q.z, q.w]).collect(),
        (Value::QuathVec(v), 4) => v.iter().flat_map(|q| [q.x, q.y, q.z, q.w].map(|h| h.to_f32())).collect(),
        (Value::QuatdVec(v), 4) => v.iter().flat_map(|q| [q.x, q.y, q.z, q.w].map(|d| d as f32)).collect(),
        (Value::Vec3fVec(v), 3) => v.iter().flat_map(|p| [p.x, p.y, p.z]).collect(),
        (Value::Vec3hVec(v), 3) => v.iter().flat_map(|p| [p.x, p.y, p.z].map(|h| h.to_f32())).collect(),
        (Value::Vec3dVec(v), 3) => v.iter().flat_map(|p| [p.x, p.y, p.z].map(|d| d as f32)).collect(),
        _ => return None,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use quatcurve_anim::{ChannelCurve, Property};

    /// A leg of two joints, +Z up in centimetres, its knee bent over a second by an
    /// animation the skeleton binds, and a quad skinned to it.
    const LEG: &str = r#"#usda 1.0
(
    metersPerUnit = 0.01
    upAxis = "Z"
    timeCodesPerSecond = 24
)
def SkelRoot "Rig"
{
    def Skeleton "Skel" (
        prepend apiSchemas = ["SkelBindingAPI"]
    )
    {
        uniform token[] joints = ["Hip", "Hip/Knee"]
        uniform matrix4d[] bindTransforms = [((1, 0, 0, 0), (0, 1, 0, 0), (0, 0, 1, 0), (0, 0, 0, 1)), ((1, 0, 0, 0), (0, 1, 0, 0), (0, 0, 1, 0), (0, 0, 10, 1))]
        uniform matrix4d[] restTransforms = [((1, 0, 0, 0), (0, 1, 0, 0), (0, 0, 1, 0), (0, 0, 0, 1)), ((1, 0, 0, 0), (0, 1, 0, 0), (0, 0, 1, 0), (0, 0, 10, 1))]
        rel skel:animationSource = </Rig/Bend>
    }

    def SkelAnimation "Bend"
    {
        uniform token[] joints = ["Hip/Knee"]
        quatf[] rotations.timeSamples = {
            12: [(1, 0, 0, 0)],
            36: [(0.70710677, 0.70710677, 0, 0)],
        }
        float3[] translations = [(0, 0, 10)]
        half3[] scales = [(1, 1, 1)]
    }

    def Mesh "Leg" (
        prepend apiSchemas = ["SkelBindingAPI"]
    )
    {
        point3f[] points = [(0, 0, 0), (1, 0, 0), (1, 0, 10), (0, 0, 10)]
        int[] faceVertexCounts = [4]
        int[] faceVertexIndices = [0, 1, 2, 3]
        int[] primvars:skel:jointIndices = [0, 0, 1, 1] (
            elementSize = 1
            interpolation = "vertex"
        )
        float[] primvars:skel:jointWeights = [1, 1, 1, 1] (
            elementSize = 1
            interpolation = "vertex"
        )
        rel skel:skeleton = </Rig/Skel>
    }
}
"#;

    fn read_text(dir: &Path, name: &str, text: &str) -> Result<UsdFile, InputError> {
        let path = dir.join(name);
        std::fs::write(&path, text).unwrap();
        read(&path)
    }

    fn close(a: &[f64], b: &[f64]) -> bool {
        a.iter().zip(b).all(|(x, y)| (x - y).abs() < 1e-6)
    }

    #[test]
    fn a_stage_reads_as_its_skeleton_in_gltf_s_space_its_animation_and_its_skinned_mesh() {
        let dir = tempfile::tempdir().unwrap();
        let file = read_text(dir.path(), "leg.usda", LEG).unwrap();
        assert_eq!((file.source_unit_metres, file.source_up), (0.01, "+Z"));
        let animation = &file.gltf.animation;
        let names: Vec<&str> = animation.joints.iter().map(|j| j.name.as_str()).collect();
        assert_eq!(names, ["Skel", "Hip", "Knee", "Leg"]);
        // The skeleton's node: centimetres to metres, +Z up turned to +Y up.
        let skel = &animation.joints[0];
        assert!(close(&skel.scale, &[0.01; 3]), "{:?}", skel.scale);
        let half = std::f64::consts::FRAC_1_SQRT_2;
        assert!(close(&skel.rotation, &[-half, 0.0, 0.0, half]), "{:?}", skel.rotation);
        assert_eq!((animation.joints[1].parent, animation.joints[2].parent), (Some(0), Some(1)));
        assert!(close(&animation.joints[2].translation, &[0.0, 0.0, 10.0]));
        let clip = &animation.clips[0];
        assert_eq!((animation.clips.len(), clip.name.as_str()), (1, "Bend"));
        let rotation = clip.channels.iter().find(|c| c.property == Property::Rotation).unwrap();
        assert_eq!(rotation.joint, 2);
        let ChannelCurve::Keys { times, .. } = &rotation.curve else { panic!("keys") };
        // Time codes 12 and 36 at 24 a second, from the animation's first sample.
        assert!(close(times, &[0.0, 1.0]), "{times:?}");
        let primitives = crate::mesh::skinned_primitives(&file.gltf).unwrap().primitives;
        assert_eq!(primitives.len(), 1);
        assert_eq!(primitives[0].indices.as_deref(), Some(&[0, 1, 2, 0, 2, 3][..]), "a quad as a fan");
    }

    /// The `.usdc` here is openusd's own (usd-core 26.11 refuses openusd 0.6's crate files:
    /// "invalid children in primChildren"); `python/tests/test_usd.py` reads one usd-core writes.
    #[test]
    fn the_binary_form_reads_as_the_text_form() {
        let dir = tempfile::tempdir().unwrap();
        let text = read_text(dir.path(), "leg.usda", LEG).unwrap();
        let stage = Stage::open(dir.path().join("leg.usda").to_str().unwrap()).unwrap();
        let binary = dir.path().join("leg.usdc");
        stage.root_layer().export(binary.to_str().unwrap()).unwrap();
        let read_back = read(&binary).unwrap();
        assert_eq!(format!("{:?}", read_back.gltf.animation), format!("{:?}", text.gltf.animation));
        let bytes = std::fs::read(&binary).unwrap();
        for cut in [16, bytes.len() / 2, bytes.len() - 8] {
            let cut_file = dir.path().join(format!("cut{cut}.usdc"));
            std::fs::write(&cut_file, &bytes[..cut]).unwrap();
            let error = read(&cut_file).unwrap_err().to_string();
            assert!(error.contains("not a readable USD stage"), "{cut}: {error}");
        }
    }

    #[test]
    fn a_stage_breaking_a_rule_of_usdskel_is_refused_naming_the_prim_and_the_rule() {
        let dir = tempfile::tempdir().unwrap();
        let cases = [
            ("\"Hip\", \"Hip/Knee\"]", "\"Hip\", \"Hip\"]", "Skeleton </Rig/Skel>: joints 0 and 1 are both 'Hip'"),
            (
                "36: [(0.70710677, 0.70710677, 0, 0)]",
                "36: []",
                "SkelAnimation </Rig/Bend>: rotations at time 36 holds 0 values for 1 joints",
            ),
            ("[0, 0, 1, 1] (", "[0, 0, 1, 7] (", "mesh </Rig/Leg>: jointIndices[3] 7 is not one of its 2 joints"),
            (
                "faceVertexIndices = [0, 1, 2, 3]",
                "faceVertexIndices = [0, 1, 2, 9]",
                "mesh </Rig/Leg>: face 0: vertex 9 is not one of the 4 points",
            ),
            ("faceVertexCounts = [4]", "faceVertexCounts = [2]", "mesh </Rig/Leg>: face 0 has 2 vertices"),
            (
                "float[] primvars:skel:jointWeights = [1, 1, 1, 1]",
                "float[] primvars:skel:jointWeights = [1, 1, 1]",
                "jointWeights hold 4 and 3 values",
            ),
            (
                "uniform matrix4d[] restTransforms",
                "uniform double[] restTransforms = [1, 2]\n        uniform matrix4d[] unused",
                "Skeleton </Rig/Skel>: restTransforms is not a matrix4d[]",
            ),
            (
                "rel skel:skeleton = </Rig/Skel>",
                "rel skel:skeleton = </Rig/Bend>",
                "mesh </Rig/Leg>: skel:skeleton </Rig/Bend> is not a Skeleton",
            ),
            ("def Skeleton \"Skel\"", "def Xform \"Skel\"", "no Skeleton prim"),
            (
                "(0, 0, 10)]\n        half3",
                "(0, 0, inf)]\n        half3",
                "translations: joint 'Hip/Knee' is not finite",
            ),
            ("#usda 1.0", "#usda 1.0\ndef", "not a readable USD stage"),
        ];
        for (k, (from, to, expected)) in cases.into_iter().enumerate() {
            assert!(LEG.contains(from), "{from}");
            let error = read_text(dir.path(), &format!("bad{k}.usda"), &LEG.replacen(from, to, 1)).unwrap_err();
            assert!(matches!(error, InputError::Usd(_)), "{k}: {error:?}");
            assert!(error.to_string().contains(expected), "{k}: {error}");
        }
    }

    #[test]
    fn a_panic_inside_openusd_is_the_file_s_error_and_prints_nothing() {
        let error = guarded::<()>(|| panic!("index out of bounds: the len is 84 but the index is 165")).unwrap_err();
        assert_eq!(
            error.to_string(),
            "not a readable USD stage: openusd failed on it (index out of bounds: the len is 84 but the index is 165)"
        );
        // The hook is quiet only inside openusd: a panic elsewhere still reports (and fails).
        assert!(!IN_OPENUSD.with(Cell::get));
    }
}
