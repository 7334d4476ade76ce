//! glTF 2.0 (`.gltf`, `.glb`) in and GLB out.
//!
//! Reading goes through the `gltf` crate (validation, accessor decoding). Writing edits the
//! file's own JSON rather than re-serializing the crate's model, so everything bake does not
//! touch (materials, skins, extensions the crate does not know, extras) is preserved as it
//! was: all buffers are gathered into the GLB's one BIN buffer (buffer views re-pointed), the
//! resampled keys are appended as new accessors, and each baked sampler is pointed at them
//! with LINEAR interpolation. Morph-target weight channels are left as they were.

use super::{Animation, Baked, Channel, Clip, Joint, Property};
use crate::device::DeviceError;
use base64::Engine;
use serde_json::{json, Value};
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

fn input(msg: String) -> DeviceError {
    DeviceError::Input(msg)
}

/// Reads a `.gltf` (buffers embedded as data URIs or in files beside it) or `.glb` file.
///
/// # Errors
/// [`DeviceError::Input`] for an unreadable or corrupt file, a missing buffer, or a channel
/// whose key and value counts differ, naming the clip and channel.
pub fn read(path: &Path) -> Result<GltfFile, DeviceError> {
    let bytes = std::fs::read(path).map_err(|e| input(format!("cannot read: {e}")))?;
    let gltf = match gltf::Gltf::from_slice(&bytes) {
        Ok(gltf) => gltf,
        // Accessors without buffer views (Draco-compressed meshes) and extensions the crate
        // does not know are flagged by its validation but do not concern animation, which we
        // read defensively; indices out of range and invalid values are real corruption.
        Err(gltf::Error::Validation(errors))
            if errors.iter().all(|(_, e)| matches!(e, gltf::json::validation::Error::Missing | gltf::json::validation::Error::Unsupported)) =>
        {
            gltf::Gltf::from_slice_without_validation(&bytes).map_err(|e| input(format!("not a valid glTF file: {e}")))?
        }
        Err(gltf::Error::Validation(errors)) => {
            let shown: Vec<String> = errors.iter().take(3).map(|(path, e)| format!("{path}: {e}")).collect();
            return Err(input(format!("not a valid glTF file: {} ({} problems)", shown.join("; "), errors.len())));
        }
        Err(e) => return Err(input(format!("not a valid glTF file: {e}"))),
    };
    let json: Value = if bytes.starts_with(b"glTF") {
        let glb = gltf::binary::Glb::from_slice(&bytes).map_err(|e| input(format!("not a valid GLB file: {e}")))?;
        serde_json::from_slice(&glb.json)
    } else {
        serde_json::from_slice(&bytes)
    }
    .map_err(|e| input(format!("not valid glTF JSON: {e}")))?;
    let mut buffers = Vec::new();
    for buffer in gltf.buffers() {
        let data = match buffer.source() {
            gltf::buffer::Source::Bin => gltf.blob.clone().ok_or_else(|| input(format!("buffer {} refers to a missing BIN chunk", buffer.index())))?,
            gltf::buffer::Source::Uri(uri) => load_uri(path, uri).map_err(|e| input(format!("buffer {} ({uri:.40}): {e}", buffer.index())))?,
        };
        if data.len() < buffer.length() {
            return Err(input(format!("buffer {} holds {} bytes but declares {}", buffer.index(), data.len(), buffer.length())));
        }
        buffers.push(data);
    }
    let joints = gltf
        .nodes()
        .map(|node| {
            let (translation, rotation, _) = node.transform().decomposed();
            Joint {
                name: node.name().map_or_else(|| format!("node{}", node.index()), str::to_string),
                rotation: rotation.map(f64::from),
                translation: translation.map(f64::from),
            }
        })
        .collect();
    let mut animation = Animation { joints, clips: Vec::new() };
    let mut samplers = Vec::new();
    for anim in gltf.animations() {
        let name = anim.name().map_or_else(|| format!("animation{}", anim.index()), str::to_string);
        let mut clip = Clip { name, channels: Vec::new() };
        let mut sources = Vec::new();
        for channel in anim.channels() {
            let property = match channel.target().property() {
                gltf::animation::Property::Rotation => Property::Rotation,
                gltf::animation::Property::Translation => Property::Translation,
                gltf::animation::Property::Scale => Property::Scale,
                gltf::animation::Property::MorphTargetWeights => continue,
            };
            let joint = channel.target().node().index();
            let mut keyed = Channel { joint, property, times: Vec::new(), values: Vec::new() };
            let label = animation.label(&clip, &keyed);
            let reader = channel.reader(|b| buffers.get(b.index()).map(Vec::as_slice));
            keyed.times = reader.read_inputs().ok_or_else(|| input(format!("{label}: key times cannot be read")))?.map(f64::from).collect();
            let values: Vec<[f64; 4]> = match reader.read_outputs().ok_or_else(|| input(format!("{label}: key values cannot be read")))? {
                gltf::animation::util::ReadOutputs::Rotations(r) => r.into_f32().map(|v| v.map(f64::from)).collect(),
                gltf::animation::util::ReadOutputs::Translations(v) | gltf::animation::util::ReadOutputs::Scales(v) => {
                    v.map(|[x, y, z]| [x, y, z, 0.0].map(f64::from)).collect()
                }
                gltf::animation::util::ReadOutputs::MorphTargetWeights(_) => continue,
            };
            // CUBICSPLINE stores (in-tangent, value, out-tangent) per key: the keys are the values.
            keyed.values = if channel.sampler().interpolation() == gltf::animation::Interpolation::CubicSpline {
                values.chunks(3).filter(|c| c.len() == 3).map(|c| c[1]).collect()
            } else {
                values
            };
            if keyed.values.len() != keyed.times.len() || keyed.times.is_empty() {
                return Err(input(format!("{label}: {} key times but {} key values", keyed.times.len(), keyed.values.len())));
            }
            clip.channels.push(keyed);
            sources.push((anim.index(), channel.sampler().index()));
        }
        if !clip.channels.is_empty() {
            animation.clips.push(clip);
            samplers.push(sources);
        }
    }
    Ok(GltfFile { animation, json, buffers, samplers })
}

/// A buffer URI: base64 `data:` or a file relative to the glTF file.
fn load_uri(path: &Path, uri: &str) -> Result<Vec<u8>, String> {
    if let Some(rest) = uri.strip_prefix("data:") {
        let (_, data) = rest.split_once(";base64,").ok_or("only base64 data URIs are supported")?;
        return base64::engine::general_purpose::STANDARD.decode(data).map_err(|e| format!("bad base64: {e}"));
    }
    let file = path.parent().unwrap_or(Path::new(".")).join(uri);
    std::fs::read(&file).map_err(|e| format!("{}: {e}", file.display()))
}

impl GltfFile {
    /// The GLB bytes with every baked sampler replaced by LINEAR keys at the baked frames.
    ///
    /// # Errors
    /// [`DeviceError::Device`] if the GLB cannot be assembled (over 4 GiB).
    pub fn to_glb(&self, baked: &Baked) -> Result<Vec<u8>, DeviceError> {
        let mut json = self.json.clone();
        let mut bin: Vec<u8> = Vec::new();
        let pad = |bin: &mut Vec<u8>, to: usize| bin.resize(bin.len().div_ceil(to) * to, 0);
        // All buffers become ranges of the one BIN buffer.
        let mut base = Vec::with_capacity(self.buffers.len());
        for data in &self.buffers {
            pad(&mut bin, 16);
            base.push(bin.len() as u64);
            bin.extend_from_slice(data);
        }
        let mut views: Vec<Value> = json["bufferViews"].as_array().cloned().unwrap_or_default();
        for view in &mut views {
            let buffer = view["buffer"].as_u64().unwrap_or(0) as usize;
            let offset = view["byteOffset"].as_u64().unwrap_or(0) + base.get(buffer).copied().unwrap_or(0);
            view["buffer"] = json!(0);
            view["byteOffset"] = json!(offset);
        }
        let mut accessors: Vec<Value> = json["accessors"].as_array().cloned().unwrap_or_default();
        let mut push = |bin: &mut Vec<u8>, data: &[f32], kind: &str, count: usize, bounds: Option<(f32, f32)>| -> usize {
            pad(bin, 4);
            views.push(json!({"buffer": 0, "byteOffset": bin.len(), "byteLength": data.len() * 4}));
            bin.extend(data.iter().flat_map(|v| v.to_le_bytes()));
            let mut accessor = json!({"bufferView": views.len() - 1, "componentType": 5126, "count": count, "type": kind});
            if let Some((min, max)) = bounds {
                accessor["min"] = json!([min]);
                accessor["max"] = json!([max]);
            }
            accessors.push(accessor);
            accessors.len() - 1
        };
        for ((clip, sources), result) in self.animation.clips.iter().zip(&self.samplers).zip(&baked.clips) {
            let times: Vec<f32> = result.times.iter().map(|&t| t as f32).collect();
            let bounds = (times[0], times[times.len() - 1]);
            let input_accessor = push(&mut bin, &times, "SCALAR", times.len(), Some(bounds));
            for ((channel, &(anim, sampler)), values) in clip.channels.iter().zip(sources).zip(&result.values) {
                let (data, kind): (Vec<f32>, _) = match channel.property {
                    Property::Rotation => (values.iter().flatten().copied().collect(), "VEC4"),
                    _ => (values.iter().flat_map(|v| [v[0], v[1], v[2]]).collect(), "VEC3"),
                };
                let output_accessor = push(&mut bin, &data, kind, values.len(), None);
                let target = &mut json["animations"][anim]["samplers"][sampler];
                target["input"] = json!(input_accessor);
                target["output"] = json!(output_accessor);
                target["interpolation"] = json!("LINEAR");
            }
        }
        pad(&mut bin, 4);
        json["bufferViews"] = Value::Array(views);
        json["accessors"] = Value::Array(accessors);
        json["buffers"] = json!([{"byteLength": bin.len()}]);
        if u32::try_from(bin.len() + (1 << 20)).is_err() {
            return Err(DeviceError::Device("the baked GLB would exceed 4 GiB".into()));
        }
        let text = serde_json::to_vec(&json).map_err(|e| DeviceError::Device(e.to_string()))?;
        let glb = gltf::binary::Glb {
            header: gltf::binary::Header { magic: *b"glTF", version: 2, length: 0 },
            json: text.into(),
            bin: Some(bin.into()),
        };
        glb.to_vec().map_err(|e| DeviceError::Device(format!("cannot assemble GLB: {e}")))
    }
}
