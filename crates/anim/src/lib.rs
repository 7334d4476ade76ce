//! The animation model every source is read into and every product starts from: joints with
//! rest poses, skins, and clips of channels, each channel a joint's rotation, translation or
//! scale as keys or as a fitted B-spline ([`ChannelCurve`]); an animation's channels as curves
//! built once and evaluated at any times ([`curves`]), and whether a clip loops ([`loops`]).
//! The runtime's base: importers (`quatcurve_formats`) fill it, the fitted container
//! (`quatcurve_qcf`) decodes into it, the bake resamples it, playback plays it, and the formats
//! write baked frames back ([`ClipFrames`]); it reads no file and opens no device.

pub mod curves;
pub mod error;
pub mod loops;
pub mod spline;

use error::AnimationError;

/// One clip resampled on a uniform grid of frames: what the format writers write back
/// (`quatcurve_formats`: glTF, BVH, SMPL archives), as the bake leaves it.
#[derive(Clone, Debug, PartialEq)]
pub struct ClipFrames<'a> {
    /// The frames' times in seconds, uniform, from the clip's first key.
    pub times: &'a [f64],
    /// Frames per second of `times`.
    pub rate: f64,
    /// Per channel, in the clip's order: one value per frame (`x, y, z, w`; a vector's `w`
    /// unused).
    pub values: Vec<&'a [[f32; 4]]>,
}

/// Centimetres in a glTF unit: glTF lengths are metres.
pub const GLTF_UNIT_CM: f64 = 100.0;

/// What a channel animates.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Property {
    /// Unit quaternion `x, y, z, w`.
    Rotation,
    /// Vector `x, y, z` (the fourth value is unused).
    Translation,
    /// Vector `x, y, z` (the fourth value is unused).
    Scale,
}

/// One animated property of one joint.
#[derive(Clone, Debug, PartialEq)]
pub struct Channel {
    /// Index into [`Animation::joints`].
    pub joint: usize,
    /// What it animates.
    pub property: Property,
    /// Its keys or its fitted spline.
    pub curve: ChannelCurve,
}

/// How the source plays a channel's keys between them: glTF's sampler interpolation, the
/// others' frames linear (BVH, FBX as ufbx bakes it, SMPL poses, the crowd). A bake takes it
/// unless asked for a curve family.
#[derive(Clone, Debug, Default, PartialEq)]
pub enum Interpolation {
    /// Slerp between rotations, lerp between vectors (glTF's LINEAR).
    #[default]
    Linear,
    /// Each key held until the next one (glTF's STEP).
    Step,
    /// glTF's CUBICSPLINE: a cubic Hermite spline of the components through the keys with
    /// these in- and out-tangents (per second, one pair per key), a rotation normalized.
    CubicSpline {
        /// `[in, out]` per key, as `values`.
        tangents: Vec<[[f64; 4]; 2]>,
    },
}

impl Interpolation {
    /// glTF's name of it.
    #[must_use]
    pub fn gltf_name(&self) -> &'static str {
        match self {
            Interpolation::Linear => "LINEAR",
            Interpolation::Step => "STEP",
            Interpolation::CubicSpline { .. } => "CUBICSPLINE",
        }
    }
}

/// What a channel holds. Keys lie on the motion and are interpolated as the source declares
/// or by the job's curve family; a fitted spline's control points do not, and it is evaluated
/// as it is: the two are read differently, so every consumer says which it takes.
#[derive(Clone, Debug, PartialEq)]
pub enum ChannelCurve {
    /// Keys on the motion.
    Keys {
        /// Seconds, strictly increasing.
        times: Vec<f64>,
        /// One per time: `x, y, z, w` for rotations, `x, y, z, 0` for vectors.
        values: Vec<[f64; 4]>,
        /// How the source interpolates them.
        interpolation: Interpolation,
    },
    /// A fitted channel (`quatcurve::fit`): a clamped B-spline of the family
    /// [`spline::spline_spec`] gives its order (the knot count less the control point
    /// count): a rotation cubic normalized, keys slerped or lerped.
    Spline {
        /// Knots in seconds, ascending, each end repeated to the order.
        knots: Vec<f64>,
        /// Control points, as `values` of keys.
        controls: Vec<[f64; 4]>,
    },
}

impl Channel {
    /// A channel of keys the source interpolates linearly.
    #[must_use]
    pub fn keys(joint: usize, property: Property, times: Vec<f64>, values: Vec<[f64; 4]>) -> Self {
        Self { joint, property, curve: ChannelCurve::Keys { times, values, interpolation: Interpolation::Linear } }
    }

    /// Its key times and values; `None` for a fitted spline.
    #[must_use]
    pub fn keyed(&self) -> Option<(&[f64], &[[f64; 4]])> {
        match &self.curve {
            ChannelCurve::Keys { times, values, .. } => Some((times, values)),
            ChannelCurve::Spline { .. } => None,
        }
    }

    /// How the source interpolates its keys; `None` for a fitted spline.
    #[must_use]
    pub fn interpolation(&self) -> Option<&Interpolation> {
        match &self.curve {
            ChannelCurve::Keys { interpolation, .. } => Some(interpolation),
            ChannelCurve::Spline { .. } => None,
        }
    }

    /// Whether it is a fitted spline.
    #[must_use]
    pub fn is_spline(&self) -> bool {
        matches!(self.curve, ChannelCurve::Spline { .. })
    }

    /// `[start, end]` of its keys or of its spline's domain; `None` with no key.
    #[must_use]
    pub fn span(&self) -> Option<[f64; 2]> {
        let points = match &self.curve {
            ChannelCurve::Keys { times, .. } => times,
            ChannelCurve::Spline { knots, .. } => knots,
        };
        Some([*points.first()?, *points.last()?])
    }

    /// Its keys, or its spline's control points: what it stores.
    #[must_use]
    pub fn len(&self) -> usize {
        match &self.curve {
            ChannelCurve::Keys { values, .. } => values.len(),
            ChannelCurve::Spline { controls, .. } => controls.len(),
        }
    }

    /// Whether it stores nothing.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// One clip: channels sharing a time line.
#[derive(Clone, Debug, PartialEq)]
pub struct Clip {
    /// Name for messages and sidecars.
    pub name: String,
    /// Its channels.
    pub channels: Vec<Channel>,
}

impl Clip {
    /// `[first key, last key]` over every channel (a spline's domain for a fitted one).
    #[must_use]
    pub fn span(&self) -> [f64; 2] {
        let spans = || self.channels.iter().filter_map(Channel::span);
        let first = spans().map(|[s, _]| s).fold(f64::INFINITY, f64::min);
        let last = spans().map(|[_, e]| e).fold(f64::NEG_INFINITY, f64::max);
        if first <= last {
            [first, last]
        } else {
            [0.0, 0.0]
        }
    }
}

/// A joint (glTF node, BVH joint) and its rest pose, used where a clip does not animate it.
#[derive(Clone, Debug, PartialEq)]
pub struct Joint {
    /// Name (glTF node name or `node<i>`; BVH joint name).
    pub name: String,
    /// The parent joint, `None` for a root of the scene.
    pub parent: Option<usize>,
    /// Rest rotation `x, y, z, w`.
    pub rotation: [f64; 4],
    /// Rest translation.
    pub translation: [f64; 3],
    /// Rest scale.
    pub scale: [f64; 3],
}

impl Joint {
    /// A joint at rest with the identity rotation and unit scale.
    #[must_use]
    pub fn at(name: String, parent: Option<usize>, translation: [f64; 3]) -> Self {
        Self { name, parent, rotation: [0.0, 0.0, 0.0, 1.0], translation, scale: [1.0; 3] }
    }
}

/// A glTF skin: the joints a mesh is bound to and their inverse bind matrices.
#[derive(Clone, Debug, PartialEq)]
pub struct Skin {
    /// Name (the skin's, or `skeleton<k>`, as Babylon's glTF loader names a skeleton).
    pub name: String,
    /// Joint indices into [`Animation::joints`], in the skin's order.
    pub joints: Vec<usize>,
    /// One per joint: the inverse bind matrix as 3x4 row-major (its last row is `0 0 0 1`).
    pub inverse_bind: Vec<[f64; 12]>,
    /// glTF's `skeleton`: the joint named as the skeleton's root, where the file names one.
    pub skeleton: Option<usize>,
}

/// A source file read into the common model.
#[derive(Clone, Debug, PartialEq)]
pub struct Animation {
    /// The joints the clips refer to, each with its parent.
    pub joints: Vec<Joint>,
    /// The clips.
    pub clips: Vec<Clip>,
    /// glTF skins (none for BVH and the crowd).
    pub skins: Vec<Skin>,
}

impl Animation {
    /// Every joint's rest pose as one local row `[joints, 10]`: what a frame holds where its clip
    /// does not animate a joint.
    #[must_use]
    pub fn rest_row(&self) -> Vec<f32> {
        self.joints
            .iter()
            .flat_map(|j| {
                j.rotation.iter().chain(&j.translation).chain(&j.scale).map(|&v| v as f32).collect::<Vec<_>>()
            })
            .collect()
    }

    /// Whether any channel is a fitted spline ([`ChannelCurve::Spline`]).
    #[must_use]
    pub fn is_fitted(&self) -> bool {
        self.clips.iter().flat_map(|c| &c.channels).any(Channel::is_spline)
    }

    /// Each joint's parent, in joint order.
    #[must_use]
    pub fn parents(&self) -> Vec<Option<usize>> {
        self.joints.iter().map(|j| j.parent).collect()
    }

    /// Joint indices with every parent before its children (the order forward kinematics
    /// walks).
    ///
    /// # Errors
    /// [`AnimationError`] for a parent index out of range or a cycle, naming a joint on it.
    pub fn parents_first(&self) -> Result<Vec<usize>, AnimationError> {
        let n = self.joints.len();
        // Depth by walking up; a chain longer than the joint count is a cycle.
        let mut depth = vec![usize::MAX; n];
        for start in 0..n {
            let mut chain = Vec::new();
            let mut at = start;
            while depth[at] == usize::MAX {
                chain.push(at);
                match self.joints[at].parent {
                    None => break,
                    Some(p) if p >= n => {
                        let name = self.joints[at].name.clone();
                        return Err(AnimationError::MissingParent { joint: at, name, parent: p });
                    }
                    Some(_) if chain.len() > n => {
                        return Err(AnimationError::Cycle { joint: at, name: self.joints[at].name.clone() });
                    }
                    Some(p) => at = p,
                }
            }
            let mut d = if depth[at] == usize::MAX { 0 } else { depth[at] + 1 };
            for &j in chain.iter().rev() {
                if depth[j] == usize::MAX {
                    depth[j] = d;
                    d += 1;
                }
            }
        }
        let mut order: Vec<usize> = (0..n).collect();
        order.sort_by_key(|&j| depth[j]);
        Ok(order)
    }

    /// Total keys (and control points) over every channel of every clip.
    #[must_use]
    pub fn key_count(&self) -> usize {
        self.clips.iter().flat_map(|c| &c.channels).map(Channel::len).sum()
    }

    /// `clip '<clip>', <joint> <property>`, naming a channel in messages.
    #[must_use]
    pub fn label(&self, clip: &Clip, channel: &Channel) -> String {
        let property = match channel.property {
            Property::Rotation => "rotation",
            Property::Translation => "translation",
            Property::Scale => "scale",
        };
        format!("clip '{}', {} {property}", clip.name, self.joints[channel.joint].name)
    }
}
