//! How far a lossy motion is from its source, as ACL measures it (its default
//! `qvvf_transform_error_metric`): each joint carries virtual vertices at a distance `d` on its
//! own axes, `(d, 0, 0)` and `(0, d, 0)`, and `(0, 0, d)` too when the skeleton scales; both
//! poses are taken to object space (a parent's error moves its children's vertices), and a
//! joint's error is the largest distance between where its vertices land in the two. A clip's
//! error is the largest over joints and samples. ACL's default `d` is 3 cm and its threshold
//! 0.01 cm. Poses compose as matrices, so a non-uniform scale's shear counts (ACL's `qvvf`
//! composition drops it; without non-uniform scale the two agree).

use quatcurve_eval::skeleton::{self, Affine};

/// ACL's default virtual vertex distance, in cm.
pub const ACL_VERTEX_DISTANCE_CM: f64 = 3.0;

/// A joint's local transform: `T * R * S` (glTF and BVH order), rotation `x, y, z, w`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Transform {
    /// Rotation `x, y, z, w` (normalized here).
    pub rotation: [f64; 4],
    /// Translation.
    pub translation: [f64; 3],
    /// Scale per axis.
    pub scale: [f64; 3],
}

impl Transform {
    fn affine(&self) -> Affine {
        skeleton::trs(self.rotation, self.translation, self.scale)
    }

    /// Whether the scale is other than 1 on some axis.
    #[must_use]
    pub fn scales(&self) -> bool {
        self.scale != [1.0; 3]
    }
}

/// Object-space transforms of one pose: `parents[j]` is joint `j`'s parent, `order` lists
/// parents before children.
#[must_use]
pub fn object_space(parents: &[Option<usize>], order: &[usize], local: &[Transform]) -> Vec<Affine> {
    skeleton::pose(parents, order, |j| local[j].affine())
}

/// Per joint, the largest distance between its virtual vertices (at `distance` on its axes;
/// the third axis only when `scales`) in the two object-space poses.
#[must_use]
pub fn joint_errors(raw: &[Affine], lossy: &[Affine], distance: f64, scales: bool) -> Vec<f64> {
    let used = if scales { 3 } else { 2 };
    raw.iter()
        .zip(lossy)
        .map(|(r, l)| {
            (0..used)
                .map(|axis| {
                    let mut p = [0.0; 3];
                    p[axis] = distance;
                    let (a, b) = (skeleton::transform_point(r, p), skeleton::transform_point(l, p));
                    a.iter().zip(&b).map(|(a, b)| (a - b) * (a - b)).sum::<f64>().sqrt()
                })
                .fold(0.0, f64::max)
        })
        .collect()
}

/// [`joint_errors`] of two poses given as local transforms (see [`object_space`]); the third
/// vertex counts when either pose scales any joint, as ACL's metric with scale does.
#[must_use]
pub fn pose_errors(
    parents: &[Option<usize>],
    order: &[usize],
    raw: &[Transform],
    lossy: &[Transform],
    distance: f64,
) -> Vec<f64> {
    let scales = raw.iter().chain(lossy).any(Transform::scales);
    joint_errors(&object_space(parents, order, raw), &object_space(parents, order, lossy), distance, scales)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn at(translation: [f64; 3]) -> Transform {
        Transform { rotation: [0.0, 0.0, 0.0, 1.0], translation, scale: [1.0; 3] }
    }

    fn about_z(angle: f64, translation: [f64; 3]) -> Transform {
        Transform { rotation: [0.0, 0.0, (angle / 2.0).sin(), (angle / 2.0).cos()], ..at(translation) }
    }

    /// A two-joint chain (child 10 cm along x) with the root turned by `angle` about z in the
    /// lossy pose: by hand, the root's vertices move `2 d sin(angle / 2)` and the child's
    /// farthest vertex, `10 + d` from the pivot, `2 (10 + d) sin(angle / 2)`.
    #[test]
    fn a_parent_turn_moves_the_child_vertices_by_the_hand_computed_chord() {
        let (parents, order) = ([None, Some(0)], [0, 1]);
        let d = ACL_VERTEX_DISTANCE_CM;
        let raw = [at([0.0; 3]), at([10.0, 0.0, 0.0])];
        for angle in [1e-6, 1e-3, 0.3, 2.0] {
            let lossy = [about_z(angle, [0.0; 3]), at([10.0, 0.0, 0.0])];
            let errors = pose_errors(&parents, &order, &raw, &lossy, d);
            let chord = |r: f64| 2.0 * r * (angle / 2.0).sin();
            assert!((errors[0] - chord(d)).abs() <= 1e-12 * chord(d).max(1.0), "{angle}: {errors:?}");
            assert!((errors[1] - chord(10.0 + d)).abs() <= 1e-12 * chord(10.0 + d).max(1.0), "{angle}: {errors:?}");
        }
        // A translation error alone moves every vertex of the joint and its children by itself.
        let lossy = [at([0.0, 0.004, 0.0]), at([10.0, 0.0, 0.0])];
        let errors = pose_errors(&parents, &order, &raw, &lossy, d);
        assert!(errors.iter().all(|e| (e - 0.004).abs() < 1e-15), "{errors:?}");
        // The child's own turn about its x axis leaves its x vertex in place: the y vertex
        // moves by the chord.
        let lossy = [
            at([0.0; 3]),
            Transform { rotation: [(0.25f64).sin(), 0.0, 0.0, (0.25f64).cos()], ..at([10.0, 0.0, 0.0]) },
        ];
        let errors = pose_errors(&parents, &order, &raw, &lossy, d);
        assert_eq!(errors[0], 0.0);
        assert!((errors[1] - 2.0 * d * (0.25f64).sin()).abs() < 1e-14, "{errors:?}");
    }

    /// A turn about the joint's own z axis moves its x and y vertices but not a z vertex; a
    /// scale along z moves only the z vertex, which counts once the skeleton scales.
    #[test]
    fn the_third_vertex_counts_only_when_the_skeleton_scales() {
        let (parents, order) = ([None], [0]);
        let d = 3.0;
        let raw = [at([0.0; 3])];
        let stretched = [Transform { scale: [1.0, 1.0, 1.001], ..at([0.0; 3]) }];
        let errors = pose_errors(&parents, &order, &raw, &stretched, d);
        assert!((errors[0] - 0.003).abs() < 1e-15, "{errors:?}");
        let object = object_space(&parents, &order, &stretched);
        assert_eq!(joint_errors(&object_space(&parents, &order, &raw), &object, d, false), vec![0.0]);
    }
}
