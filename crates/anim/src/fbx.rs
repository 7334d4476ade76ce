//! FBX in, through ufbx (its C loader, built by the crate): every node but the scene root as a
//! joint with its rest transform, every skin deformer as a skin (its clusters' bones, each
//! cluster's geometry-to-bone matrix as the inverse bind matrix), every animation stack as a
//! clip (ufbx's baked keys of each animated node).
//!
//! ufbx converts the scene to glTF's space as it loads: metres and +Y up, right-handed, by
//! adjusting the nodes' transforms (`SpaceConversion::AdjustTransforms`), so that the
//! geometry is untouched and the inverse bind matrices stay the file's. The file's own unit
//! and up axis are kept ([`FbxFile::source_unit_metres`], [`FbxFile::source_up`]).

use crate::error::InputError;
use crate::{Animation, Channel, Clip, Joint, Property, Skin};
use std::collections::HashMap;
use std::path::Path;

/// The extension of FBX files.
pub const EXTENSION: &str = "fbx";

/// An FBX file read for baking.
#[derive(Clone, Debug, PartialEq)]
pub struct FbxFile {
    /// The model, in metres and +Y up.
    pub animation: Animation,
    /// The length of the file's unit in metres (Blender writes 0.01).
    pub source_unit_metres: f64,
    /// The file's up axis (`+Y`, `+Z`, ...).
    pub source_up: &'static str,
}

fn bad(reason: impl std::fmt::Display) -> InputError {
    InputError::Fbx(reason.to_string())
}

/// Reads an FBX file (binary or ASCII).
///
/// # Errors
/// [`InputError::Read`] for an unreadable file; [`InputError::Fbx`] with ufbx's description
/// for a file it cannot load, or a stack it cannot bake.
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
        // No file beside it is opened: an FBX's external references are not followed.
        load_external_files: false,
        ..Default::default()
    };
    let scene =
        ufbx::load_memory(bytes, options).map_err(|e| bad(format!("not a readable FBX file: {}", &*e.description)))?;
    // Joints: every node but the scene root, parents before children as ufbx lists them.
    let mut index = HashMap::new();
    let mut joints = Vec::new();
    for node in scene.nodes.iter().filter(|n| !n.is_root) {
        index.insert(node.element.typed_id, joints.len());
        let t = &node.local_transform;
        let parent = node.parent.as_ref().filter(|p| !p.is_root).map(|p| p.element.typed_id);
        joints.push((node.element.name.to_string(), parent, *t));
    }
    let joint_of = |typed_id: u32| index.get(&typed_id).copied();
    let joints: Vec<Joint> = joints
        .into_iter()
        .map(|(name, parent, t)| Joint {
            name,
            parent: parent.and_then(joint_of),
            rotation: [t.rotation.x, t.rotation.y, t.rotation.z, t.rotation.w],
            translation: [t.translation.x, t.translation.y, t.translation.z],
            scale: [t.scale.x, t.scale.y, t.scale.z],
        })
        .collect();
    let mut skins = Vec::new();
    for deformer in scene.skin_deformers.iter() {
        let mut skin = Skin {
            name: deformer.element.name.to_string(),
            joints: Vec::new(),
            inverse_bind: Vec::new(),
            skeleton: None,
        };
        for cluster in deformer.clusters.iter() {
            let Some(joint) = cluster.bone_node.as_ref().and_then(|b| joint_of(b.element.typed_id)) else {
                return Err(bad(format!("skin '{}': cluster '{}' has no bone", skin.name, &*cluster.element.name)));
            };
            let m = &cluster.geometry_to_bone;
            skin.joints.push(joint);
            skin.inverse_bind
                .push([m.m00, m.m01, m.m02, m.m03, m.m10, m.m11, m.m12, m.m13, m.m20, m.m21, m.m22, m.m23]);
        }
        skins.push(skin);
    }
    let names = clip_names(&scene);
    let mut clips = Vec::new();
    for (stack, name) in scene.anim_stacks.iter().zip(names) {
        let baked = ufbx::bake_anim(&scene, &stack.anim, ufbx::BakeOpts::default())
            .map_err(|e| bad(format!("animation stack '{}': {}", &*stack.element.name, &*e.description)))?;
        let mut channels = Vec::new();
        for node in baked.nodes.iter() {
            let Some(joint) = joint_of(node.typed_id) else { continue };
            if !node.constant_rotation {
                let (times, values) =
                    node.rotation_keys.iter().map(|k| (k.time, [k.value.x, k.value.y, k.value.z, k.value.w])).unzip();
                channels.push(Channel::keys(joint, Property::Rotation, times, values));
            }
            for (constant, keys, property) in [
                (node.constant_translation, &node.translation_keys, Property::Translation),
                (node.constant_scale, &node.scale_keys, Property::Scale),
            ] {
                if !constant {
                    let (times, values) = keys.iter().map(|k| (k.time, [k.value.x, k.value.y, k.value.z, 0.0])).unzip();
                    channels.push(Channel::keys(joint, property, times, values));
                }
            }
        }
        if !channels.is_empty() {
            clips.push(Clip { name, channels });
        }
    }
    let settings = &scene.settings;
    Ok(FbxFile {
        animation: Animation { joints, clips, skins },
        source_unit_metres: settings.unit_meters,
        source_up: axis_name(settings.axes.up),
    })
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
