//! Babylon.js's baked vertex animation (`bake --format babylon`, DESIGN section 10): the JSON
//! object `VertexAnimationBaker.serializeBakedVertexDataToObject` writes, which Babylon's
//! `BakedVertexAnimationManager` plays with no shader code of the user's.
//!
//! Per frame (a row of the texture), per bone of the skin in joint order, the 4x4 matrix
//! Babylon's `Skeleton.getTransformMatrices(mesh)` returns, as Babylon stores it (column-major
//! in glTF's sense), then one identity matrix (Babylon's array has a slot past the last bone).
//! Babylon's glTF loader parents a skinned mesh to the parent of the skin's skeleton root
//! ([`mesh_parent`]) and draws its vertices through that node's world matrix, so each bone's
//! matrix is the skin matrix in that node's space: `world(parent at rest)^-1 * model(joint) *
//! inverseBindMatrix(joint)`. The node at rest is what the mesh hangs from while the manager
//! plays (the glTF's animation groups stopped), so its animation, if any, is in the bones.

pub use crate::error::{BabylonTooLarge, SingularWorld};
use quatcurve_anim::{Animation, Skin};
use quatcurve_eval::skeleton::{compose, inverse, trs, Affine};
use quatcurve_formats::gltf::IDENTITY_3X4 as IDENTITY;
use quatcurve_formats::mesh::DeclaredPrimitive;

/// The manager's settings that play a clip of `frames` rows from `first_row` at `rate` on the
/// source's clock: `(from, to, offset, speed)`. Babylon's manager (its `bakedVertexAnimation`
/// shader) plays rows `from..=to` in its first cycle and, assuming a loop's last row repeats
/// its first, `from + 1..=to` in every later one, each cycle `(to - from + 1) / speed` seconds
/// long and the row floored. A loop's period is `frames - 1` rows, so its speed is
/// `rate * frames / (frames - 1)` and its offset -1 row: every later cycle shows row
/// `floor(time * rate)` of the period exactly, the first a row late. An open clip plays its
/// rows at `rate`, offset 0.
#[must_use]
pub fn settings(first_row: usize, frames: usize, rate: f64, looping: bool) -> [f64; 4] {
    let (from, to) = (first_row as f64, (first_row + frames.max(1) - 1) as f64);
    if looping && frames > 1 {
        [from, to, -1.0, rate * frames as f64 / (frames - 1) as f64]
    } else {
        [from, to, 0.0, rate]
    }
}

/// Floats of one bone's matrix in Babylon's texture (four RGBA texels).
pub const MATRIX_FLOATS: usize = 16;

/// The node Babylon's glTF loader (`GLTFLoader._loadNodeAsync`) parents `skin`'s meshes to:
/// the parent of the skeleton root (the skin's `skeleton`, or when it names none the nearest
/// common ancestor of its joints), or that node's parent where it is a node drawing the skin
/// (`skinned_nodes`); `None` for the scene root (no common ancestor, or a root at the top).
#[must_use]
pub fn mesh_parent(animation: &Animation, skin: &Skin, skinned_nodes: &[usize]) -> Option<usize> {
    let parent = |node: usize| animation.joints.get(node).and_then(|j| j.parent);
    let root = skin.skeleton.or_else(|| nearest_common_ancestor(animation, &skin.joints))?;
    let above = parent(root)?;
    if skinned_nodes.contains(&above) {
        parent(above)
    } else {
        Some(above)
    }
}

/// [`mesh_parent`] of each skin of `animation`, whose meshes `skinned` lists.
#[must_use]
pub fn mesh_parents(animation: &Animation, skinned: &[DeclaredPrimitive]) -> Vec<Option<usize>> {
    let nodes = |k: usize| -> Vec<usize> { skinned.iter().filter(|p| p.skin == k).map(|p| p.node).collect() };
    animation.skins.iter().enumerate().map(|(k, skin)| mesh_parent(animation, skin, &nodes(k))).collect()
}

/// The deepest node that is `joints`' every joint or an ancestor of it (Babylon's
/// `_findSkeletonRootNode`); `None` when they share no node.
fn nearest_common_ancestor(animation: &Animation, joints: &[usize]) -> Option<usize> {
    let path = |joint: usize| {
        let mut path = vec![joint];
        // Parents were checked to form no cycle when the file was read.
        while let Some(p) = animation.joints[path[path.len() - 1]].parent {
            path.push(p);
        }
        path.reverse();
        path
    };
    let paths: Vec<Vec<usize>> = joints.iter().map(|&j| path(j)).collect();
    let first = paths.first()?;
    let shared = (0..first.len()).take_while(|&i| paths.iter().all(|p| p.get(i) == first.get(i))).count();
    shared.checked_sub(1).map(|i| first[i])
}

/// `world(node)^-1` at rest (the glTF's own transforms, no clip applied); the identity for the
/// scene root.
///
/// # Errors
/// The node's name when its rest world matrix is singular (a zero scale).
pub fn from_world(animation: &Animation, node: Option<usize>) -> Result<Affine, SingularWorld> {
    let Some(node) = node else { return Ok(IDENTITY) };
    let (mut world, mut at) = (IDENTITY, Some(node));
    // Parents were checked to form no cycle when the file was read.
    while let Some(joint) = at.map(|j| &animation.joints[j]) {
        world = compose(&trs(joint.rotation, joint.translation, joint.scale), &world);
        at = joint.parent;
    }
    inverse(&world).ok_or_else(|| SingularWorld { node: animation.joints[node].name.clone() })
}

/// Babylon's floats of `rows` (frame-major 3x4 row-major skin matrices of `bones` bones):
/// per frame `(bones + 1) * 16`, each bone's `from_world * skin` column-major, then identity.
#[must_use]
pub fn matrices(rows: &[f32], bones: usize, from_world: &Affine) -> Vec<f32> {
    let frames = rows.len() / (bones * 12).max(1);
    let mut out = Vec::with_capacity(frames * (bones + 1) * MATRIX_FLOATS);
    for frame in rows.chunks_exact(bones * 12) {
        for skin in frame.chunks_exact(12) {
            let m = compose(from_world, &std::array::from_fn(|i| f64::from(skin[i])));
            for column in 0..4 {
                out.extend((0..3).map(|row| m[4 * row + column] as f32));
                out.push(if column == 3 { 1.0 } else { 0.0 });
            }
        }
        out.extend((0..MATRIX_FLOATS).map(|i| if i % 5 == 0 { 1.0 } else { 0.0 }));
    }
    out
}

/// The JSON Babylon's `VertexAnimationBaker.loadBakedVertexDataFromJSON` reads:
/// `{"vertexData": base64 of the little-endian f32s, "width": (bones + 1) * 4, "height": frames}`.
#[must_use]
pub fn json(floats: &[f32], bones: usize) -> Vec<u8> {
    use base64::Engine as _;
    let bytes: Vec<u8> = floats.iter().flat_map(|f| f.to_le_bytes()).collect();
    let width = (bones + 1) * 4;
    let value = serde_json::json!({
        "vertexData": base64::engine::general_purpose::STANDARD.encode(bytes),
        "width": width,
        "height": floats.len() / (width * 4),
    });
    value.to_string().into_bytes()
}

/// Why `frames` frames of `bones` bones do not fit a texture of at most `max` texels a side
/// (Babylon's texture is one row per frame, `(bones + 1) * 4` texels wide, never wrapped).
#[must_use]
pub fn too_large(bones: usize, frames: usize, max: usize) -> Option<BabylonTooLarge> {
    let width = (bones + 1) * 4;
    if width > max {
        Some(BabylonTooLarge::Wide { width, max })
    } else if frames > max {
        Some(BabylonTooLarge::Tall { frames, max })
    } else {
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use quatcurve_anim::Joint;

    fn chain() -> Animation {
        // 0 scene root "Armature" (rotated, scaled) > 1 "hips" > 2 "spine"; 3 a second root.
        let mut armature = Joint::at("Armature".into(), None, [1.0, 2.0, 3.0]);
        armature.rotation = [0.0, 0.0, std::f64::consts::FRAC_1_SQRT_2, std::f64::consts::FRAC_1_SQRT_2];
        armature.scale = [2.0; 3];
        let joints = vec![
            armature,
            Joint::at("hips".into(), Some(0), [0.0, 1.0, 0.0]),
            Joint::at("spine".into(), Some(1), [0.0, 0.5, 0.0]),
            Joint::at("other".into(), None, [0.0; 3]),
        ];
        Animation { joints, clips: Vec::new(), skins: Vec::new() }
    }

    fn skin(joints: Vec<usize>, skeleton: Option<usize>) -> Skin {
        let inverse_bind = vec![IDENTITY; joints.len()];
        Skin { name: "skin".into(), joints, inverse_bind, skeleton }
    }

    #[test]
    fn the_mesh_hangs_from_the_skeleton_roots_parent_as_babylons_loader_places_it() {
        let animation = chain();
        // No `skeleton`: the nearest common ancestor of the joints (hips), whose parent is Armature.
        assert_eq!(mesh_parent(&animation, &skin(vec![1, 2], None), &[]), Some(0));
        // A named skeleton is taken as it is.
        assert_eq!(mesh_parent(&animation, &skin(vec![1, 2], Some(2)), &[]), Some(1));
        // The skeleton root's parent draws the skin: one node higher.
        assert_eq!(mesh_parent(&animation, &skin(vec![2], None), &[1]), Some(0));
        // Joints of two trees share no node, and a root skeleton has no parent: the scene root.
        assert_eq!(mesh_parent(&animation, &skin(vec![2, 3], None), &[]), None);
        assert_eq!(mesh_parent(&animation, &skin(vec![0, 1], None), &[]), None);
    }

    #[test]
    fn each_bone_is_the_skin_matrix_in_the_parents_space_column_major_then_identity() {
        let animation = chain();
        let to_armature = from_world(&animation, Some(0)).unwrap();
        // The skin matrix of a bone at the Armature's own world transform is the identity there.
        let world: Vec<f32> = trs(animation.joints[0].rotation, animation.joints[0].translation, [2.0; 3])
            .iter()
            .map(|&v| v as f32)
            .collect();
        let floats = matrices(&[world.clone(), world].concat(), 1, &to_armature);
        assert_eq!(floats.len(), 2 * 2 * MATRIX_FLOATS);
        let identity: Vec<f32> = (0..16).map(|i| if i % 5 == 0 { 1.0 } else { 0.0 }).collect();
        for m in floats.chunks_exact(16) {
            for (a, b) in m.iter().zip(&identity) {
                assert!((a - b).abs() < 1e-6, "{m:?}");
            }
        }
        // A translation lands in floats 12..15, as glTF and Babylon store it.
        let moved = [1.0, 0.0, 0.0, 4.0, 0.0, 1.0, 0.0, 5.0, 0.0, 0.0, 1.0, 6.0];
        let floats = matrices(&moved, 1, &IDENTITY);
        assert_eq!(&floats[12..16], &[4.0, 5.0, 6.0, 1.0]);
        assert_eq!(&floats[..4], &[1.0, 0.0, 0.0, 0.0]);
    }

    #[test]
    fn the_json_is_babylons_object_and_too_large_textures_are_refused_by_their_side() {
        let floats = matrices(&[1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0], 1, &IDENTITY);
        let value: serde_json::Value = serde_json::from_slice(&json(&floats, 1)).unwrap();
        assert_eq!((value["width"].as_u64(), value["height"].as_u64()), (Some(8), Some(1)));
        use base64::Engine as _;
        let bytes = base64::engine::general_purpose::STANDARD.decode(value["vertexData"].as_str().unwrap()).unwrap();
        assert_eq!(bytes.len(), 32 * 4);
        assert!(too_large(1, 4096, 4096).is_none());
        assert!(too_large(1, 4097, 4096).unwrap().to_string().contains("4097 rows tall"));
        assert!(too_large(1024, 10, 4096).unwrap().to_string().contains("4100 texels wide"));
    }
}
