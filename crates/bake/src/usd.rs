//! OpenUSD's skeletal animation as text (`bake --usd`, DESIGN section 7): one stage per
//! input, its joints a `Skeleton` and each baked clip a `SkelAnimation` of the joints' local
//! frames at their times, chosen on the skeleton by a variant set (`clip`), as USD picks one
//! animation of several; and a crowd (`play --usd`, DESIGN section 17): the character once,
//! each instance an instanced reference to it playing its own `SkelAnimation`.

use super::texture::{self, LOCAL_CHANNELS};
use super::Baked;
use quatcurve_anim::error::InputError;
use quatcurve_anim::Animation;
use quatcurve_eval::skeleton::{self, Affine};
use quatcurve_formats::mesh::SkinnedPrimitive;
use std::collections::HashSet;
use std::fmt::Write;

/// glTF's `mode` of a primitive of triangles.
const TRIANGLES: u32 = 4;

/// The stage of one input's bake, `name` its root prim: the skeleton at rest and bound as
/// `animation`'s skins bind it, its joints in `order` (parents first, as UsdSkel wants them:
/// [`Animation::parents_first`]), the triangle primitives of `meshes` bound to it, every clip
/// of `baked` sampled at its frames, time codes `time_codes` a second and lengths in metres
/// `metres_per_unit`.
#[must_use]
pub fn stage(
    animation: &Animation,
    order: &[usize],
    meshes: &[SkinnedPrimitive],
    baked: &Baked,
    name: &str,
    metres_per_unit: f64,
    time_codes: f64,
) -> String {
    let root = identifier(name, &mut HashSet::new());
    let character = Character::new(animation, order);
    let mut clip_names = HashSet::new();
    let clips: Vec<String> = animation.clips.iter().map(|c| identifier(&c.name, &mut clip_names)).collect();
    let last_code = baked
        .clips
        .iter()
        .map(|c| (c.times.last().unwrap_or(&0.0) - c.times.first().unwrap_or(&0.0)) * time_codes)
        .fold(0.0, f64::max);
    let mut s = String::new();
    let doc = "quatcurve bake: each clip a SkelAnimation, chosen by the skeleton's variant set 'clip'";
    header(&mut s, &root, doc, metres_per_unit, time_codes, last_code);
    let _ = writeln!(s, "def SkelRoot \"{root}\"\n{{");
    character.write(&mut s, &root, meshes, &clips);
    let _ = writeln!(s, "    def Scope \"Animations\"\n    {{");
    for (c, clip) in clips.iter().enumerate() {
        let times = &baked.clips[c].times;
        let frames: Vec<usize> = (0..times.len()).collect();
        let rows = texture::local_rows(animation, baked, c, &frames);
        let codes: Vec<f64> = times.iter().map(|t| (t - times[0]) * time_codes).collect();
        character.animation(&mut s, clip, &rows, &codes);
    }
    let _ = writeln!(s, "    }}\n}}");
    s
}

/// How far apart a crowd stage sets its instances, in rest skeletons' largest sides.
pub const CROWD_SPACING: f64 = 1.5;

/// One instance of a crowd stage ([`crowd_stage`]): the clip it plays and from where, for
/// the reader (its pose is its own animation's).
#[derive(Clone, Debug, PartialEq)]
pub struct CrowdInstance {
    /// The clip it plays.
    pub clip: String,
    /// Where in the clip it starts, in seconds.
    pub phase: f64,
    /// The clip it blends towards and the weight, if any.
    pub blend: Option<(String, f32)>,
}

/// A crowd as one stage: the character of `animation` (its skeleton and the meshes bound to
/// it, as [`stage`] writes them) once, as the class prim `name`, and each of `instances` an
/// instanceable `SkelRoot` referencing it, set out on a grid [`CROWD_SPACING`] rest skeletons'
/// largest sides apart (the joints' box at rest), bound
/// (`skel:animationSource` on the instance, which UsdSkel inherits into the shared skeleton)
/// to its own `SkelAnimation` of `poses`: `[frames, instances, joints, 10]` local rows (the
/// animation's joint order), frame `k` at time code `k`, `rate` time codes a second. Each
/// instance's clip, phase and blend are in its `customData`.
///
/// # Errors
/// [`InputError::Animation`] for joints whose parents do not form a tree.
pub fn crowd_stage(
    animation: &Animation,
    meshes: &[SkinnedPrimitive],
    name: &str,
    instances: &[CrowdInstance],
    poses: &[f32],
    rate: f64,
    metres_per_unit: f64,
) -> Result<String, InputError> {
    let order = animation.parents_first()?;
    let side = super::texture::rig_extent(animation)?.into_iter().fold(0.0, f64::max);
    let spacing = CROWD_SPACING * if side > 0.0 { side } else { 1.0 };
    let root = identifier(name, &mut ["Crowd".to_string()].into());
    let character = Character::new(animation, &order);
    let row = animation.joints.len() * LOCAL_CHANNELS;
    let frames = poses.len() / (row * instances.len()).max(1);
    let mut s = String::new();
    let doc = "quatcurve play: each instance references the character and plays its own SkelAnimation";
    header(&mut s, "Crowd", doc, metres_per_unit, rate, frames.saturating_sub(1) as f64);
    let _ = writeln!(s, "class SkelRoot \"{root}\"\n{{");
    character.write(&mut s, &root, meshes, &[]);
    let _ = writeln!(s, "}}\n\ndef Xform \"Crowd\"\n{{");
    let columns = (instances.len() as f64).sqrt().ceil().max(1.0) as usize;
    for (i, instance) in instances.iter().enumerate() {
        let (x, z) = ((i % columns) as f64 * spacing, (i / columns) as f64 * spacing);
        let blend = instance.blend.as_ref().map_or(String::new(), |(clip, weight)| {
            format!("\n            string blendClip = {}\n            double blendWeight = {weight}", quoted(clip))
        });
        let _ = writeln!(
            s,
            "    def SkelRoot \"Instance_{i}\" (\n        prepend apiSchemas = [\"SkelBindingAPI\"]\n        customData = {{\n            string clip = {}\n            double phase = {}{blend}\n        }}\n        instanceable = true\n        prepend references = </{root}>\n    )\n    {{",
            quoted(&instance.clip),
            instance.phase
        );
        let _ = writeln!(s, "        rel skel:animationSource = </Crowd/Motion/Instance_{i}>");
        let _ = writeln!(s, "        double3 xformOp:translate = ({x}, 0, {z})\n        uniform token[] xformOpOrder = [\"xformOp:translate\"]\n    }}\n");
    }
    let _ = writeln!(s, "    def Scope \"Motion\"\n    {{");
    let codes: Vec<f64> = (0..frames).map(|k| k as f64).collect();
    for i in 0..instances.len() {
        let rows: Vec<f32> = (0..frames)
            .flat_map(|k| poses[(k * instances.len() + i) * row..(k * instances.len() + i + 1) * row].iter().copied())
            .collect();
        character.animation(&mut s, &format!("Instance_{i}"), &rows, &codes);
    }
    let _ = writeln!(s, "    }}\n}}");
    Ok(s)
}

/// `text` as a USD string literal: quoted, its backslashes, quotes and line breaks escaped.
fn quoted(text: &str) -> String {
    format!("\"{}\"", text.replace('\\', "\\\\").replace('"', "\\\"").replace('\n', "\\n"))
}

/// A stage's metadata: its default prim, what wrote it, its unit, +Y up and its time codes.
fn header(s: &mut String, default_prim: &str, doc: &str, metres_per_unit: f64, time_codes: f64, last_code: f64) {
    let _ = writeln!(s, "#usda 1.0\n(\n    defaultPrim = \"{default_prim}\"\n    doc = \"{doc}\"");
    let _ = writeln!(s, "    metersPerUnit = {metres_per_unit}\n    upAxis = \"Y\"");
    let _ =
        writeln!(s, "    timeCodesPerSecond = {time_codes}\n    startTimeCode = 0\n    endTimeCode = {last_code}\n)\n");
}

/// A character as UsdSkel holds it: its joints as paths, in `order`.
struct Character<'a> {
    animation: &'a Animation,
    order: &'a [usize],
    paths: Vec<String>,
    tokens: String,
}

impl<'a> Character<'a> {
    fn new(animation: &'a Animation, order: &'a [usize]) -> Self {
        let paths = joint_paths(animation, order);
        let tokens = order.iter().map(|&j| format!("\"{}\"", paths[j])).collect::<Vec<_>>().join(", ");
        Self { animation, order, paths, tokens }
    }

    /// The `Skeleton` (rest and bind transforms; with `clips`, the variant set `clip` choosing
    /// its animation among `</root/Animations/...>`) and the triangle primitives of `meshes`
    /// bound to it, inside the prim `root`.
    fn write(&self, s: &mut String, root: &str, meshes: &[SkinnedPrimitive], clips: &[String]) {
        let (animation, order) = (self.animation, self.order);
        let _ = writeln!(s, "    def Skeleton \"Skeleton\" (\n        prepend apiSchemas = [\"SkelBindingAPI\"]");
        if let Some(first) = clips.first() {
            let _ = writeln!(s, "        variants = {{\n            string clip = \"{first}\"\n        }}");
            let _ = writeln!(s, "        prepend variantSets = \"clip\"");
        }
        let _ = writeln!(s, "    )\n    {{\n        uniform token[] joints = [{}]", self.tokens);
        let matrices = |m: &[Affine]| m.iter().map(matrix).collect::<Vec<_>>().join(", ");
        let bind = bind_transforms(animation, order);
        let _ = writeln!(
            s,
            "        uniform matrix4d[] bindTransforms = [{}]",
            matrices(&order.iter().map(|&j| bind[j]).collect::<Vec<_>>())
        );
        let rest: Vec<Affine> = order
            .iter()
            .map(|&j| &animation.joints[j])
            .map(|j| skeleton::trs(j.rotation, j.translation, j.scale))
            .collect();
        let _ = writeln!(s, "        uniform matrix4d[] restTransforms = [{}]", matrices(&rest));
        if !clips.is_empty() {
            let _ = writeln!(s, "        variantSet \"clip\" = {{");
            for clip in clips {
                let _ = writeln!(s, "            \"{clip}\" {{\n                rel skel:animationSource = </{root}/Animations/{clip}>\n            }}");
            }
            let _ = writeln!(s, "        }}");
        }
        let _ = writeln!(s, "    }}\n");
        let mut taken: HashSet<String> = ["Skeleton", "Animations"].map(String::from).into();
        // glTF's triangles (mode 4); points, lines, strips and fans are not USD meshes.
        for primitive in meshes.iter().filter(|p| p.mode == TRIANGLES) {
            let skin_joints: Vec<&String> =
                animation.skins[primitive.skin].joints.iter().map(|&j| &self.paths[j]).collect();
            mesh(s, root, primitive, &skin_joints, &mut taken);
        }
    }

    /// A `SkelAnimation` `name` of the joints' local `rows` (a frame's every joint, the
    /// animation's order, [`LOCAL_CHANNELS`] each) at time codes `codes`. An attribute the same
    /// at every frame (every joint's scale, most often) is written once, as its value at all
    /// times, not once a frame.
    fn animation(&self, s: &mut String, name: &str, rows: &[f32], codes: &[f64]) {
        let attribute = |kind: &str, f: &dyn Fn(&[f32]) -> String| -> String {
            let frames: Vec<String> = rows
                .chunks_exact(self.animation.joints.len() * LOCAL_CHANNELS)
                .map(|frame| {
                    let values = self.order.iter().map(|&j| f(&frame[j * LOCAL_CHANNELS..(j + 1) * LOCAL_CHANNELS]));
                    values.collect::<Vec<_>>().join(", ")
                })
                .collect();
            if frames.windows(2).all(|w| w[0] == w[1]) {
                return format!("            {kind} = [{}]", frames.first().map_or("", String::as_str));
            }
            let samples: Vec<String> =
                frames.iter().zip(codes).map(|(values, code)| format!("                {code}: [{values}],")).collect();
            format!("            {kind}.timeSamples = {{\n{}\n            }}", samples.join("\n"))
        };
        let _ = writeln!(
            s,
            "        def SkelAnimation \"{name}\"\n        {{\n            uniform token[] joints = [{}]",
            self.tokens
        );
        let _ =
            writeln!(s, "{}", attribute("quatf[] rotations", &|r| format!("({}, {}, {}, {})", r[3], r[0], r[1], r[2])));
        let _ = writeln!(s, "{}", attribute("float3[] translations", &|r| format!("({}, {}, {})", r[4], r[5], r[6])));
        let _ = writeln!(s, "{}", attribute("half3[] scales", &|r| format!("({}, {}, {})", r[7], r[8], r[9])));
        let _ = writeln!(s, "        }}");
    }
}

/// One mesh primitive as a USD `Mesh` bound to the skeleton as glTF binds it: its bind-space
/// points and normals, triangles, and per vertex its joints (indices into `skin_joints`, the
/// skin's joints as the skeleton's paths) and weights; the geometry's bind transform the
/// identity, its points being in bind space already.
fn mesh(
    s: &mut String,
    root: &str,
    primitive: &SkinnedPrimitive,
    skin_joints: &[&String],
    taken: &mut HashSet<String>,
) {
    let bind = &primitive.bind;
    let name = identifier(&primitive.name, taken);
    let triangles: Vec<u32> = match &primitive.indices {
        Some(indices) => indices.clone(),
        None => (0..bind.vertices() as u32).collect(),
    };
    let list = |values: &mut dyn Iterator<Item = String>| values.collect::<Vec<_>>().join(", ");
    let point = |p: &[f64; 3]| format!("({}, {}, {})", p[0] as f32, p[1] as f32, p[2] as f32);
    let _ = writeln!(s, "    def Mesh \"{name}\" (\n        prepend apiSchemas = [\"SkelBindingAPI\"]\n    )\n    {{");
    let _ = writeln!(s, "        uniform token subdivisionScheme = \"none\"");
    let _ = writeln!(s, "        point3f[] points = [{}]", list(&mut bind.positions.iter().map(point)));
    if let Some(normals) = &bind.normals {
        let _ = writeln!(
            s,
            "        normal3f[] normals = [{}] (\n            interpolation = \"vertex\"\n        )",
            list(&mut normals.iter().map(point))
        );
    }
    let _ = writeln!(
        s,
        "        int[] faceVertexCounts = [{}]",
        list(&mut (0..triangles.len() / 3).map(|_| "3".to_string()))
    );
    let _ = writeln!(s, "        int[] faceVertexIndices = [{}]", list(&mut triangles.iter().map(u32::to_string)));
    let n = bind.influences;
    let _ = writeln!(
        s,
        "        int[] primvars:skel:jointIndices = [{}] (\n            elementSize = {n}\n            interpolation = \"vertex\"\n        )",
        list(&mut bind.joints.iter().map(u32::to_string))
    );
    let _ = writeln!(
        s,
        "        float[] primvars:skel:jointWeights = [{}] (\n            elementSize = {n}\n            interpolation = \"vertex\"\n        )",
        list(&mut bind.weights.iter().map(|&w| (w as f32).to_string()))
    );
    let identity = matrix(&[1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0]);
    let _ = writeln!(s, "        matrix4d primvars:skel:geomBindTransform = {identity}");
    let _ = writeln!(
        s,
        "        uniform token[] skel:joints = [{}]",
        list(&mut skin_joints.iter().map(|p| format!("\"{p}\"")))
    );
    let _ = writeln!(s, "        rel skel:skeleton = </{root}/Skeleton>\n    }}\n");
}

/// A 3x4 row-major matrix (column vectors) as USD's `matrix4d` (row vectors: the transpose,
/// its translation the last row).
fn matrix(m: &Affine) -> String {
    let row = |c: usize| format!("({}, {}, {}, {})", m[c], m[4 + c], m[8 + c], if c == 3 { 1 } else { 0 });
    format!("({}, {}, {}, {})", row(0), row(1), row(2), row(3))
}

/// Each joint's bind transform in the skeleton's space: the inverse of its inverse bind
/// matrix in the first skin that binds it, else its place at rest.
fn bind_transforms(animation: &Animation, order: &[usize]) -> Vec<Affine> {
    let rest = skeleton::pose(&animation.parents(), order, |j| {
        let joint = &animation.joints[j];
        skeleton::trs(joint.rotation, joint.translation, joint.scale)
    });
    let mut bind = rest;
    let mut bound = vec![false; animation.joints.len()];
    for skin in &animation.skins {
        for (&j, ibm) in skin.joints.iter().zip(&skin.inverse_bind) {
            if !bound[j] {
                if let Some(m) = skeleton::inverse(ibm) {
                    (bind[j], bound[j]) = (m, true);
                }
            }
        }
    }
    bind
}

/// Each joint's path from its root (`order`: parents first), names made identifiers and
/// unique among siblings.
fn joint_paths(animation: &Animation, order: &[usize]) -> Vec<String> {
    let mut paths = vec![String::new(); animation.joints.len()];
    let mut siblings: Vec<HashSet<String>> = vec![HashSet::new(); animation.joints.len() + 1];
    for &j in order {
        let joint = &animation.joints[j];
        let taken = &mut siblings[joint.parent.map_or(animation.joints.len(), |p| p)];
        let own = identifier(&joint.name, taken);
        paths[j] = match joint.parent {
            Some(p) => format!("{}/{own}", paths[p]),
            None => own,
        };
    }
    paths
}

/// `name` as a USD identifier (letters, digits and `_`, not starting with a digit), made
/// unique among `taken` with a number, and taken.
fn identifier(name: &str, taken: &mut HashSet<String>) -> String {
    let mut base: String = name.chars().map(|c| if c.is_ascii_alphanumeric() { c } else { '_' }).collect();
    if base.is_empty() || base.starts_with(|c: char| c.is_ascii_digit()) {
        base.insert(0, '_');
    }
    let mut unique = base.clone();
    let mut k = 2;
    while !taken.insert(unique.clone()) {
        unique = format!("{base}_{k}");
        k += 1;
    }
    unique
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_become_identifiers_unique_among_their_siblings() {
        let mut taken = HashSet::new();
        let names = ["mixamorig:Hips", "mixamorig_Hips", "3d", "", "Run"].map(|n| identifier(n, &mut taken));
        assert_eq!(names, ["mixamorig_Hips", "mixamorig_Hips_2", "_3d", "_", "Run"]);
    }

    #[test]
    fn a_name_is_a_string_literal_with_its_quotes_backslashes_and_line_breaks_escaped() {
        assert_eq!(quoted("Run"), "\"Run\"");
        assert_eq!(quoted("a \"b\"\\c\nd"), "\"a \\\"b\\\"\\\\c\\nd\"");
    }

    #[test]
    fn a_matrix_is_written_transposed_its_translation_the_last_row() {
        let m = [1.0, 2.0, 3.0, 10.0, 4.0, 5.0, 6.0, 20.0, 7.0, 8.0, 9.0, 30.0];
        assert_eq!(matrix(&m), "((1, 4, 7, 0), (2, 5, 8, 0), (3, 6, 9, 0), (10, 20, 30, 1))");
    }
}
