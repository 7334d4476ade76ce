//! glTF 2.0 (`.gltf`, `.glb`) in and GLB out.
//!
//! Reading goes through the `gltf` crate (validation, accessor decoding). Writing edits the
//! file's own JSON rather than re-serializing the crate's model, so everything bake does not
//! touch (materials, skins, extensions the crate does not know, extras) is preserved as it
//! was: all buffers are gathered into the GLB's one BIN buffer (buffer views re-pointed), the
//! resampled keys are appended as new accessors, and each baked sampler is pointed at them
//! with LINEAR interpolation. Morph-target weight channels are left as they were.
use super::glb::GLB_MAGIC;
use base64::Engine;
use gltf::json::validation::Checked;
use quatcurve_anim::error::{FormatError, InputError};
use quatcurve_anim::{Animation, Channel, ChannelCurve, Clip, ClipFrames, Interpolation, Joint, Property, Skin};
use serde_json::Value;
use std::path::Path;

/// A glTF file read for baking.
#[derive(Clone, Debug)]
pub struct GltfFile {
    /// Joints (every node) and clips (every animation with rotation, translation or scale).
    pub animation: Animation,
    /// The document's JSON as written in the file.
    json: Value,
    /// Every buffer's bytes, in buffer order.
    buffers: Vec<Vec<u8>>,
    /// Per clip, per channel: the (animation, sampler) it came from.
    samplers: Vec<Vec<(usize, usize)>>,
}

/// A rule of the file broken, found here.
fn input(rule: String) -> InputError {
    InputError::Gltf(FormatError::rule(rule))
}

/// A rule of the file broken at `rule`, found by `error` (the parser's, or a check's here).
fn caused(rule: String, error: impl Into<Box<dyn std::error::Error + Send + Sync>>) -> InputError {
    InputError::Gltf(FormatError::caused(rule, error))
}

/// Why an accessor cannot be read as the element it is used for.
#[derive(Debug, thiserror::Error)]
pub enum AccessorError {
    /// No elements.
    #[error("count is 0")]
    Empty,
    /// A sparse accessor where keys are read.
    #[error("sparse accessors are not supported for animation")]
    Sparse,
    /// A component or element type the reader does not know.
    #[error("unknown component type or element type")]
    UnknownType,
    /// An element type glTF does not allow where it is used.
    #[error("{element} of {component} is not an element type glTF allows here")]
    NotAllowed {
        /// The element type (`Vec3`).
        element: String,
        /// The component type (`F32`).
        component: String,
    },
    /// No buffer view.
    #[error("no buffer view (an all-zero accessor cannot hold keys)")]
    NoView,
    /// A byte stride smaller than an element.
    #[error("byte stride {stride} is smaller than its {element}-byte element")]
    Stride {
        /// The view's stride.
        stride: usize,
        /// An element's bytes.
        element: usize,
    },
    /// Elements whose extent overflows.
    #[error("count {count} with stride {stride} overflows")]
    Overflow {
        /// Elements.
        count: usize,
        /// The view's stride.
        stride: usize,
    },
    /// Elements that overrun the buffer view.
    #[error("count {count} with stride {stride} needs {needs} bytes, its buffer view holds {holds}")]
    Overrun {
        /// Elements.
        count: usize,
        /// The view's stride.
        stride: usize,
        /// Bytes they need.
        needs: usize,
        /// Bytes the view holds.
        holds: usize,
    },
}

/// Why a buffer URI is not read.
#[derive(Debug, thiserror::Error)]
pub enum UriError {
    /// A data URI that is not base64.
    #[error("only base64 data URIs are supported")]
    NotBase64,
    /// Base64 that does not decode.
    #[error("bad base64: {0}")]
    Base64(#[from] base64::DecodeError),
    /// A scheme other than `data:` and `file:`.
    #[error("{0} URIs are not read")]
    Scheme(String),
    /// A path the policy refuses.
    #[error(
        "{0}; only data URIs and relative paths inside the file's directory are read (the bake option to allow \
         external URIs reads it anyway)"
    )]
    Refused(&'static str),
    /// A `%` escape that is not two hex digits.
    #[error("a % not followed by two hex digits")]
    Escape,
    /// A decoded path that is not UTF-8.
    #[error("the decoded path is not UTF-8")]
    NotUtf8,
    /// A NUL in the decoded path.
    #[error("a NUL in the path")]
    Nul,
    /// A file that cannot be read.
    #[error("{}: {error}", file.display())]
    Read {
        /// The file.
        file: std::path::PathBuf,
        /// Why.
        error: std::io::Error,
    },
}

/// Which buffer URIs a glTF file may name (DESIGN: files made by others are untrusted).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct UriPolicy {
    /// Also allow absolute paths, `..` leaving the file's directory, symlinks pointing out of
    /// it and `file:` URIs (the CLI's `--allow-external-uris`). Off by default: a crafted
    /// file could otherwise copy any readable file (`/etc/passwd`) into the baked GLB.
    pub allow_external: bool,
}

/// Reads a `.gltf` (buffers embedded as data URIs or in files beside it) or `.glb` file.
///
/// # Errors
/// [`InputError::Read`] for an unreadable file, [`InputError::Gltf`] for a corrupt one, a buffer URI the policy refuses
/// or that cannot be read, a missing buffer, an accessor whose declared count or stride needs
/// more bytes than its buffer holds, or a channel whose key and value counts differ, naming
/// the clip and channel.
pub fn read(path: &Path, uris: UriPolicy) -> Result<GltfFile, InputError> {
    let bytes = std::fs::read(path).map_err(InputError::Read)?;
    from_bytes(&bytes, path.parent().unwrap_or(Path::new(".")), uris)
}

/// Reads glTF or GLB `bytes` whose relative buffer URIs resolve against `dir` (see [`read`]).
///
/// # Errors
/// As [`read`].
pub fn from_bytes(bytes: &[u8], dir: &Path, uris: UriPolicy) -> Result<GltfFile, InputError> {
    check_magic(bytes)?;
    let gltf =
        gltf::Gltf::from_slice_without_validation(bytes).map_err(|e| caused("not a valid glTF file".into(), e))?;
    validate(gltf.document.as_json())?;
    let json: Value = if bytes.starts_with(GLB_MAGIC) {
        let glb = gltf::binary::Glb::from_slice(bytes).map_err(|e| caused("not a valid GLB file".into(), e))?;
        serde_json::from_slice(&glb.json)
    } else {
        serde_json::from_slice(bytes)
    }
    .map_err(|e| caused("not valid glTF JSON".into(), e))?;
    let buffers = read_buffers(&gltf, dir, uris)?;
    let joints = read_joints(&gltf)?;
    let skins = read_skins(&gltf, &buffers)?;
    let mut animation = Animation { joints, clips: Vec::new(), skins };
    animation.parents_first()?;
    let root = gltf.document.as_json();
    let mut samplers = Vec::new();
    for anim in gltf.animations() {
        let name = anim.name().map_or_else(|| format!("animation{}", anim.index()), str::to_string);
        let mut clip = Clip { name, channels: Vec::new() };
        let mut sources = Vec::new();
        for channel in anim.channels() {
            if let Some(keyed) = read_channel(root, &buffers, &animation, &clip, &channel)? {
                clip.channels.push(keyed);
                sources.push((anim.index(), channel.sampler().index()));
            }
        }
        if !clip.channels.is_empty() {
            animation.clips.push(clip);
            samplers.push(sources);
        }
    }
    Ok(GltfFile { animation, json, buffers, samplers })
}

/// A GLB starts with [`GLB_MAGIC`], glTF JSON with `{`: anything else (an image or archive
/// renamed `.glb`) is named as what it looks like, not reported as a JSON syntax error.
fn check_magic(bytes: &[u8]) -> Result<(), InputError> {
    let json =
        bytes.iter().find(|b| !b.is_ascii_whitespace() && **b != 0xEF && **b != 0xBB && **b != 0xBF) == Some(&b'{');
    if bytes.starts_with(GLB_MAGIC) || json {
        return Ok(());
    }
    let head: Vec<String> = bytes.iter().take(8).map(|b| format!("{b:02x}")).collect();
    let looks = [
        (&b"\x89PNG"[..], " (a PNG image)"),
        (b"\xff\xd8\xff", " (a JPEG image)"),
        (b"PK\x03\x04", " (a zip archive)"),
        (b"HIERARCHY", " (a BVH file)"),
    ]
    .iter()
    .find(|(magic, _)| bytes.starts_with(magic))
    .map_or("", |(_, what)| what);
    Err(input(format!(
        "not a glTF file: a GLB starts with the bytes '{}' and glTF JSON with '{{', but this file starts with \
            {}{looks}",
        String::from_utf8_lossy(GLB_MAGIC),
        if head.is_empty() { "nothing (it is empty)".to_string() } else { head.join(" ") }
    )))
}

/// Every buffer's bytes (the BIN chunk, data URIs, files the policy allows), each at least its
/// declared length, and every buffer view inside its buffer.
fn read_buffers(gltf: &gltf::Gltf, dir: &Path, uris: UriPolicy) -> Result<Vec<Vec<u8>>, InputError> {
    let mut buffers = Vec::new();
    for buffer in gltf.buffers() {
        let data = match buffer.source() {
            gltf::buffer::Source::Bin => gltf
                .blob
                .clone()
                .ok_or_else(|| input(format!("buffer {} refers to a missing BIN chunk", buffer.index())))?,
            gltf::buffer::Source::Uri(uri) => {
                load_uri(dir, uri, uris).map_err(|e| caused(format!("buffer {} (uri {uri:.60})", buffer.index()), e))?
            }
        };
        if data.len() < buffer.length() {
            return Err(input(format!(
                "buffer {} holds {} bytes but declares {}",
                buffer.index(),
                data.len(),
                buffer.length()
            )));
        }
        buffers.push(data);
    }
    // Every view inside its buffer (the GLB writer re-bases them all, used by animation or not).
    for view in gltf.views() {
        let end = view.offset().checked_add(view.length());
        if !end.is_some_and(|end| end <= buffers[view.buffer().index()].len()) {
            return Err(input(format!(
                "bufferViews[{}]: bytes {}+{} lie outside buffer {}",
                view.index(),
                view.offset(),
                view.length(),
                view.buffer().index()
            )));
        }
    }
    Ok(buffers)
}

/// The nodes as joints (at most one parent each; a `matrix` node by its TRS decomposition).
fn read_joints(gltf: &gltf::Gltf) -> Result<Vec<Joint>, InputError> {
    let mut parents: Vec<Option<usize>> = vec![None; gltf.nodes().len()];
    for node in gltf.nodes() {
        for child in node.children() {
            if let Some(first) = parents[child.index()].replace(node.index()) {
                return Err(input(format!(
                    "node {} is a child of both node {first} and node {}; a glTF node has at most one parent",
                    child.index(),
                    node.index()
                )));
            }
        }
    }
    Ok(gltf
        .nodes()
        .map(|node| {
            // A `matrix` node becomes its TRS decomposition (glTF requires matrices that have one).
            let (translation, rotation, scale) = node.transform().decomposed();
            Joint {
                name: node.name().map_or_else(|| format!("node{}", node.index()), str::to_string),
                parent: parents[node.index()],
                rotation: rotation.map(f64::from),
                translation: translation.map(f64::from),
                scale: scale.map(f64::from),
            }
        })
        .collect())
}

/// The skins with their inverse bind matrices (identity when absent), one per joint.
fn read_skins(gltf: &gltf::Gltf, buffers: &[Vec<u8>]) -> Result<Vec<Skin>, InputError> {
    let root = gltf.document.as_json();
    let mut skins = Vec::new();
    for skin in gltf.skins() {
        // An unnamed skin is `skeleton<k>`, the name Babylon's glTF loader gives its skeleton.
        let name = skin.name().map_or_else(|| format!("skeleton{}", skin.index()), str::to_string);
        let joints: Vec<usize> = skin.joints().map(|j| j.index()).collect();
        let inverse_bind = match skin.inverse_bind_matrices() {
            None => vec![IDENTITY_3X4; joints.len()],
            Some(accessor) => {
                check_accessor(&accessor, &root.accessors[accessor.index()], Element::Matrices).map_err(|e| {
                    caused(format!("skin '{name}': inverse bind matrices (accessor {})", accessor.index()), e)
                })?;
                let reader = skin.reader(|b| buffers.get(b.index()).map(Vec::as_slice));
                let matrices: Vec<[f64; 12]> =
                    reader.read_inverse_bind_matrices().into_iter().flatten().map(affine_rows).collect();
                if matrices.len() != joints.len() {
                    return Err(input(format!(
                        "skin '{name}': {} joints but {} inverse bind matrices",
                        joints.len(),
                        matrices.len()
                    )));
                }
                matrices
            }
        };
        skins.push(Skin { name, joints, inverse_bind, skeleton: skin.skeleton().map(|n| n.index()) });
    }
    Ok(skins)
}

/// One animation channel as keys, or `None` for morph target weights; every accessor checked
/// against the bytes present before the crate's readers (which trust the counts) run.
fn read_channel(
    root: &gltf::json::Root,
    buffers: &[Vec<u8>],
    animation: &Animation,
    clip: &Clip,
    channel: &gltf::animation::Channel<'_>,
) -> Result<Option<Channel>, InputError> {
    let anim = channel.animation();
    // The crate's accessors unwrap enum fields it could not parse (a panic on a
    // crafted file): read them checked.
    let unknown = |what: &str| input(format!("clip '{}', channel {}: unknown {what}", clip.name, channel.index()));
    let raw = &root.animations[anim.index()];
    let property = match &raw.channels[channel.index()].target.path {
        Checked::Valid(gltf::json::animation::Property::Rotation) => Property::Rotation,
        Checked::Valid(gltf::json::animation::Property::Translation) => Property::Translation,
        Checked::Valid(gltf::json::animation::Property::Scale) => Property::Scale,
        Checked::Valid(gltf::json::animation::Property::MorphTargetWeights) => return Ok(None),
        Checked::Invalid => return Err(unknown("target path")),
    };
    let declared = match &raw.samplers[channel.sampler().index()].interpolation {
        Checked::Valid(interpolation) => *interpolation,
        Checked::Invalid => return Err(unknown("interpolation")),
    };
    let joint = channel.target().node().index();
    let label = animation.label(clip, &Channel::keys(joint, property, Vec::new(), Vec::new()));
    // The crate's readers trust accessor counts (and allocate from them): check every
    // accessor against the bytes present first.
    let sampler = channel.sampler();
    let values_kind = if property == Property::Rotation { Element::Rotations } else { Element::Vectors };
    for (what, accessor, kind) in
        [("key times", sampler.input(), Element::Times), ("key values", sampler.output(), values_kind)]
    {
        check_accessor(&accessor, &root.accessors[accessor.index()], kind)
            .map_err(|e| caused(format!("{label}: {what} (accessor {})", accessor.index()), e))?;
    }
    let reader = channel.reader(|b| buffers.get(b.index()).map(Vec::as_slice));
    let times: Vec<f64> = reader
        .read_inputs()
        .ok_or_else(|| input(format!("{label}: key times cannot be read")))?
        .map(f64::from)
        .collect();
    let values: Vec<[f64; 4]> =
        match reader.read_outputs().ok_or_else(|| input(format!("{label}: key values cannot be read")))? {
            gltf::animation::util::ReadOutputs::Rotations(r) => r.into_f32().map(|v| v.map(f64::from)).collect(),
            gltf::animation::util::ReadOutputs::Translations(v) | gltf::animation::util::ReadOutputs::Scales(v) => {
                v.map(|[x, y, z]| [x, y, z, 0.0].map(f64::from)).collect()
            }
            gltf::animation::util::ReadOutputs::MorphTargetWeights(_) => return Ok(None),
        };
    // CUBICSPLINE stores (in-tangent, value, out-tangent) per key.
    let (values, interpolation) = match declared {
        gltf::json::animation::Interpolation::Linear => (values, Interpolation::Linear),
        gltf::json::animation::Interpolation::Step => (values, Interpolation::Step),
        gltf::json::animation::Interpolation::CubicSpline => {
            let triples = values.chunks_exact(3);
            let tangents = triples.clone().map(|c| [c[0], c[2]]).collect();
            (triples.map(|c| c[1]).collect(), Interpolation::CubicSpline { tangents })
        }
    };
    if values.len() != times.len() || times.is_empty() {
        return Err(input(format!("{label}: {} key times but {} key values", times.len(), values.len())));
    }
    Ok(Some(Channel { joint, property, curve: ChannelCurve::Keys { times, values, interpolation } }))
}

/// The crate's validation, run here so that a known panic in it is avoided first: its
/// POSITION hook indexes the accessors without a range check (found by the mutation run).
/// Accessors without buffer views (Draco-compressed meshes) and extensions the crate does not
/// know are flagged but do not concern animation, which is read defensively; indices out of
/// range and invalid values are real corruption.
fn validate(root: &gltf::json::Root) -> Result<(), InputError> {
    use gltf::json::validation::{Error, Validate};
    for (m, mesh) in root.meshes.iter().enumerate() {
        for (p, primitive) in mesh.primitives.iter().enumerate() {
            for (semantic, index) in &primitive.attributes {
                if index.value() >= root.accessors.len() {
                    let name = match semantic {
                        Checked::Valid(semantic) => semantic.to_string(),
                        Checked::Invalid => "?".into(),
                    };
                    return Err(input(format!(
                        "not a valid glTF file: meshes[{m}].primitives[{p}].attributes.{name}: \
                        accessor {} does not exist",
                        index.value()
                    )));
                }
            }
        }
    }
    // The indices this reader follows, checked here: the crate's accessors unwrap them.
    let bad_index =
        |what: String, index: usize| Err(input(format!("not a valid glTF file: {what}: index {index} does not exist")));
    for (a, anim) in root.animations.iter().enumerate() {
        for (c, channel) in anim.channels.iter().enumerate() {
            if channel.sampler.value() >= anim.samplers.len() {
                return bad_index(format!("animations[{a}].channels[{c}].sampler"), channel.sampler.value());
            }
            if channel.target.node.value() >= root.nodes.len() {
                return bad_index(format!("animations[{a}].channels[{c}].target.node"), channel.target.node.value());
            }
        }
        for (k, sampler) in anim.samplers.iter().enumerate() {
            for (field, index) in [("input", sampler.input.value()), ("output", sampler.output.value())] {
                if index >= root.accessors.len() {
                    return bad_index(format!("animations[{a}].samplers[{k}].{field}"), index);
                }
            }
        }
    }
    for (i, accessor) in root.accessors.iter().enumerate() {
        if let Some(view) = accessor.buffer_view.filter(|v| v.value() >= root.buffer_views.len()) {
            return bad_index(format!("accessors[{i}].bufferView"), view.value());
        }
    }
    for (i, view) in root.buffer_views.iter().enumerate() {
        if view.buffer.value() >= root.buffers.len() {
            return bad_index(format!("bufferViews[{i}].buffer"), view.buffer.value());
        }
    }
    let mut errors = Vec::new();
    root.validate(root, gltf::json::Path::new, &mut |path, error| errors.push((path(), error)));
    if errors.iter().any(|(_, e)| !matches!(e, Error::Missing | Error::Unsupported)) {
        let shown: Vec<String> = errors.iter().take(3).map(|(path, e)| format!("{path}: {e}")).collect();
        return Err(input(format!("not a valid glTF file: {} ({} problems)", shown.join("; "), errors.len())));
    }
    Ok(())
}

/// The 3x4 identity, row-major.
pub const IDENTITY_3X4: [f64; 12] = [1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0];

/// A glTF column-major 4x4 matrix as the first three rows, row-major (the affine part).
fn affine_rows(m: [[f32; 4]; 4]) -> [f64; 12] {
    std::array::from_fn(|i| f64::from(m[i % 4][i / 4]))
}

/// What an animation or skinned-mesh accessor holds.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Element {
    /// Key times: SCALAR float.
    Times,
    /// Rotation keys: VEC4 float or normalized integers.
    Rotations,
    /// Translation and scale keys: VEC3 float.
    Vectors,
    /// Inverse bind matrices: MAT4 float.
    Matrices,
    /// Skinned vertices' joint indices (JOINTS_n): VEC4 unsigned byte or short.
    Joints,
    /// Skinned vertices' weights (WEIGHTS_n): VEC4 float or normalized unsigned integers.
    Weights,
    /// A primitive's vertex indices: SCALAR unsigned byte, short or int.
    Indices,
}

/// Whether `accessor` holds `kind`'s element type and its elements lie inside its buffer
/// view. Accessors without a buffer view (all zeros, or sparse) are refused for animation.
pub(super) fn check_accessor(
    accessor: &gltf::Accessor,
    json: &gltf::json::Accessor,
    kind: Element,
) -> Result<(), AccessorError> {
    use gltf::json::accessor::{ComponentType as C, GenericComponentType, Type};
    let count = accessor.count();
    if count == 0 {
        return Err(AccessorError::Empty);
    }
    if accessor.sparse().is_some() {
        return Err(AccessorError::Sparse);
    }
    // The element types glTF allows for animation samplers (the readers assume them).
    let (Checked::Valid(GenericComponentType(component)), Checked::Valid(element_type)) =
        (&json.component_type, &json.type_)
    else {
        return Err(AccessorError::UnknownType);
    };
    let allowed = match kind {
        Element::Times => *element_type == Type::Scalar && *component == C::F32,
        Element::Vectors => *element_type == Type::Vec3 && *component == C::F32,
        Element::Matrices => *element_type == Type::Mat4 && *component == C::F32,
        Element::Rotations => {
            *element_type == Type::Vec4 && matches!(component, C::F32 | C::I8 | C::U8 | C::I16 | C::U16)
        }
        Element::Joints => *element_type == Type::Vec4 && matches!(component, C::U8 | C::U16),
        Element::Weights => {
            *element_type == Type::Vec4
                && (*component == C::F32 || (json.normalized && matches!(component, C::U8 | C::U16)))
        }
        Element::Indices => {
            *element_type == Type::Scalar && !json.normalized && matches!(component, C::U8 | C::U16 | C::U32)
        }
    };
    if !allowed {
        return Err(AccessorError::NotAllowed {
            element: format!("{element_type:?}"),
            component: format!("{component:?}"),
        });
    }
    let view = accessor.view().ok_or(AccessorError::NoView)?;
    let element = accessor.size();
    let stride = view.stride().unwrap_or(element);
    if stride < element {
        return Err(AccessorError::Stride { stride, element });
    }
    let needs = (count - 1)
        .checked_mul(stride)
        .and_then(|n| n.checked_add(element))
        .and_then(|n| n.checked_add(accessor.offset()))
        .ok_or(AccessorError::Overflow { count, stride })?;
    // (Every view lies inside its buffer: `from_bytes` checked them all.)
    if needs > view.length() {
        return Err(AccessorError::Overrun { count, stride, needs, holds: view.length() });
    }
    Ok(())
}

/// A buffer URI: base64 `data:`, or a relative path (percent-decoded) that stays inside `dir`
/// after resolving `..` and symlinks. Anything else (absolute paths, `file:` and other
/// schemes, escapes from `dir`) only with [`UriPolicy::allow_external`].
fn load_uri(dir: &Path, uri: &str, policy: UriPolicy) -> Result<Vec<u8>, UriError> {
    if let Some(rest) = uri.strip_prefix("data:") {
        let (_, data) = rest.split_once(";base64,").ok_or(UriError::NotBase64)?;
        return Ok(base64::engine::general_purpose::STANDARD.decode(data)?);
    }
    let (path, external) = match uri.strip_prefix("file://") {
        Some(rest) => (percent_decode(rest)?, true),
        None if has_scheme(uri) => return Err(UriError::Scheme(uri.split(':').next().unwrap_or_default().into())),
        None => (percent_decode(uri)?, false),
    };
    let file = dir.join(&path);
    if !policy.allow_external {
        if external || Path::new(&path).is_absolute() {
            return Err(UriError::Refused("an absolute path"));
        }
        let inside = match (std::fs::canonicalize(&file), std::fs::canonicalize(dir)) {
            (Ok(file), Ok(dir)) => file.starts_with(dir),
            (Err(error), _) | (_, Err(error)) => return Err(UriError::Read { file, error }),
        };
        if !inside {
            return Err(UriError::Refused("it leaves the file's directory"));
        }
    }
    std::fs::read(&file).map_err(|error| UriError::Read { file, error })
}

/// `scheme:` per RFC 3986 (a letter, then letters, digits, `+ - .`), as opposed to a path.
fn has_scheme(uri: &str) -> bool {
    let Some((scheme, _)) = uri.split_once(':') else { return false };
    let mut chars = scheme.chars();
    chars.next().is_some_and(|c| c.is_ascii_alphabetic())
        && chars.all(|c| c.is_ascii_alphanumeric() || "+-.".contains(c))
}

/// Decodes `%XX` escapes (glTF URIs are percent-encoded: `my%20file.bin`).
fn percent_decode(uri: &str) -> Result<String, UriError> {
    let bytes = uri.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        if bytes[i] == b'%' {
            let hex = bytes
                .get(i + 1..i + 3)
                .and_then(|h| std::str::from_utf8(h).ok())
                .and_then(|h| u8::from_str_radix(h, 16).ok());
            out.push(hex.ok_or(UriError::Escape)?);
            i += 3;
        } else {
            out.push(bytes[i]);
            i += 1;
        }
    }
    let path = String::from_utf8(out).map_err(|_| UriError::NotUtf8)?;
    if path.contains('\0') {
        return Err(UriError::Nul);
    }
    Ok(path)
}

impl GltfFile {
    /// Primitive `primitive` of mesh `mesh`'s object of glTF extension `name`, if it uses it
    /// (the crate's document keeps no unknown extensions).
    pub(super) fn primitive_extension(&self, mesh: usize, primitive: usize, name: &str) -> Option<&serde_json::Value> {
        self.json["meshes"][mesh]["primitives"][primitive]["extensions"].get(name)
    }

    /// The parsed document and the buffers' bytes: what the mesh readers take
    /// ([`super::mesh::skinned_primitives`]).
    pub(super) fn document(&self) -> Result<(gltf::Document, &[Vec<u8>]), InputError> {
        let root: gltf::json::Root =
            serde_json::from_value(self.json.clone()).map_err(|e| caused("not valid glTF JSON".into(), e))?;
        Ok((gltf::Document::from_json_without_validation(root), &self.buffers))
    }

    /// The GLB bytes with every baked sampler replaced by LINEAR keys at the baked frames, and
    /// nothing left that only the replaced keys used (DESIGN section 6, "Baked glTF").
    ///
    /// # Errors
    /// [`InputError::Animation`] if the GLB would exceed 4 GiB.
    pub fn to_glb(&self, frames: &[ClipFrames<'_>]) -> Result<Vec<u8>, InputError> {
        super::glb::write(&self.json, &self.buffers, &self.animation.clips, &self.samplers, frames)
    }
}
