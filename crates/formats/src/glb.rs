//! GLB out: the glTF file's own JSON, edited. Each baked sampler is pointed at new LINEAR keys;
//! accessors and buffer views that only the replaced keys used are removed and every index
//! that refers to the rest is renumbered; every buffer becomes a range of the one BIN chunk,
//! which holds only bytes a kept buffer view covers. A file that uses an extension this writer
//! does not know might refer to anything by index, so there nothing is removed or renumbered.

use quatcurve_anim::{Clip, ClipFrames, Property};

use quatcurve_anim::error::{AnimationError, InputError, InternalError};

use serde_json::{json, Value};

/// The first bytes of a GLB file.
pub(super) const GLB_MAGIC: &[u8; 4] = b"glTF";

/// Extensions known to hold no index of an accessor, buffer view or buffer (they refer to
/// textures, images, materials, nodes, or nothing).
const INDEX_FREE_EXTENSIONS: &[&str] = &[
    "KHR_animation_pointer",
    "KHR_lights_punctual",
    "KHR_materials_anisotropy",
    "KHR_materials_clearcoat",
    "KHR_materials_diffuse_transmission",
    "KHR_materials_dispersion",
    "KHR_materials_emissive_strength",
    "KHR_materials_ior",
    "KHR_materials_iridescence",
    "KHR_materials_pbrSpecularGlossiness",
    "KHR_materials_sheen",
    "KHR_materials_specular",
    "KHR_materials_transmission",
    "KHR_materials_unlit",
    "KHR_materials_variants",
    "KHR_materials_volume",
    "KHR_mesh_quantization",
    "KHR_node_visibility",
    "KHR_texture_basisu",
    "KHR_texture_transform",
    "KHR_xmp_json_ld",
    "EXT_texture_avif",
    "EXT_texture_webp",
];

/// Where indices of accessors are: paths from the root, `*` for every element or value.
/// Extensions whose indices are followed here (`KHR_draco_mesh_compression`'s attributes are
/// ids inside its compressed data, not accessors).
const ACCESSOR_INDICES: &[&[&str]] = &[
    &["meshes", "*", "primitives", "*", "attributes", "*"],
    &["meshes", "*", "primitives", "*", "indices"],
    &["meshes", "*", "primitives", "*", "targets", "*", "*"],
    &["skins", "*", "inverseBindMatrices"],
    &["animations", "*", "samplers", "*", "input"],
    &["animations", "*", "samplers", "*", "output"],
    &["nodes", "*", "extensions", "EXT_mesh_gpu_instancing", "attributes", "*"],
];

/// Where indices of buffer views are, outside the accessors.
const VIEW_INDICES: &[&[&str]] = &[
    &["images", "*", "bufferView"],
    &["meshes", "*", "primitives", "*", "extensions", "KHR_draco_mesh_compression", "bufferView"],
];

/// Where an accessor holds indices of buffer views, from the accessor.
const ACCESSOR_VIEWS: &[&[&str]] =
    &[&["bufferView"], &["sparse", "indices", "bufferView"], &["sparse", "values", "bufferView"]];

/// Extensions whose indices [`ACCESSOR_INDICES`] and [`VIEW_INDICES`] follow.
const FOLLOWED_EXTENSIONS: &[&str] = &["KHR_draco_mesh_compression", "EXT_mesh_gpu_instancing"];

/// Calls `f` on every value at `path` under `value` (`*`: each element or value).
fn walk(value: &mut Value, path: &[&str], f: &mut dyn FnMut(&mut Value)) {
    let Some((first, rest)) = path.split_first() else { return f(value) };
    match (*first, value) {
        ("*", Value::Array(items)) => items.iter_mut().for_each(|v| walk(v, rest, f)),
        ("*", Value::Object(map)) => map.values_mut().for_each(|v| walk(v, rest, f)),
        (key, Value::Object(map)) => {
            if let Some(v) = map.get_mut(key) {
                walk(v, rest, f);
            }
        }
        _ => {}
    }
}

/// Every index at `paths` under `value` (nulls, taken out of the document, skipped), each
/// `None` where the value is not an index.
fn indices(value: &mut Value, paths: &[&[&str]]) -> Vec<Option<usize>> {
    let mut found = Vec::new();
    for path in paths {
        walk(value, path, &mut |v| {
            if !v.is_null() {
                found.push(v.as_u64().and_then(|i| usize::try_from(i).ok()));
            }
        });
    }
    found
}

/// Every extension name the document uses or declares.
fn extensions(value: &Value, names: &mut Vec<String>) {
    match value {
        Value::Object(map) => {
            for (key, v) in map {
                match (key.as_str(), v) {
                    ("extensions", Value::Object(used)) => names.extend(used.keys().cloned()),
                    ("extensionsUsed" | "extensionsRequired", Value::Array(used)) => {
                        names.extend(used.iter().filter_map(Value::as_str).map(str::to_string))
                    }
                    _ => {}
                }
                extensions(v, names);
            }
        }
        Value::Array(items) => items.iter().for_each(|v| extensions(v, names)),
        _ => {}
    }
}

/// Old index to new (`None`: removed), for accessors and buffer views.
struct Renumbering {
    accessors: Vec<Option<usize>>,
    views: Vec<Option<usize>>,
}

impl Renumbering {
    /// Nothing removed.
    fn identity(accessors: usize, views: usize) -> Self {
        Self { accessors: (0..accessors).map(Some).collect(), views: (0..views).map(Some).collect() }
    }

    /// Keeps what anything but the `replaced` samplers refers to, and everything an
    /// accessor or view that nothing refers to in the file itself (the file's own affair).
    /// `None` when the file uses an extension outside [`INDEX_FREE_EXTENSIONS`] and
    /// [`FOLLOWED_EXTENSIONS`], or an index is out of range: then nothing is removed.
    fn without(json: &Value, replaced: &[(usize, usize)]) -> Option<Self> {
        let mut names = Vec::new();
        extensions(json, &mut names);
        if names
            .iter()
            .any(|n| !INDEX_FREE_EXTENSIONS.contains(&n.as_str()) && !FOLLOWED_EXTENSIONS.contains(&n.as_str()))
        {
            return None;
        }
        let mut doc = json.clone();
        let count = |key: &str| doc[key].as_array().map_or(0, Vec::len);
        let (accessor_count, view_count) = (count("accessors"), count("bufferViews"));
        // The replaced samplers' accessors, taken out of the document before counting what
        // else refers to them.
        let mut candidate = vec![false; accessor_count];
        for &(anim, sampler) in replaced {
            let sampler = &mut doc["animations"][anim]["samplers"][sampler];
            for key in ["input", "output"] {
                if let Some(i) = sampler.get_mut(key).map(Value::take).and_then(|v| v.as_u64()) {
                    *candidate.get_mut(usize::try_from(i).ok()?)? = true;
                }
            }
        }
        let mut keep_accessor: Vec<bool> = candidate.iter().map(|c| !c).collect();
        for index in indices(&mut doc, ACCESSOR_INDICES) {
            *keep_accessor.get_mut(index?)? = true;
        }
        // A view stays unless only removed accessors referred to it.
        let (mut referenced, mut used_by_removed) = (vec![false; view_count], vec![false; view_count]);
        for index in indices(&mut doc, VIEW_INDICES) {
            *referenced.get_mut(index?)? = true;
        }
        let accessors = doc["accessors"].as_array_mut().map(std::mem::take).unwrap_or_default();
        for (mut accessor, &kept) in accessors.into_iter().zip(&keep_accessor) {
            for index in indices(&mut accessor, ACCESSOR_VIEWS) {
                let marks = if kept { &mut referenced } else { &mut used_by_removed };
                *marks.get_mut(index?)? = true;
            }
        }
        let keep_view: Vec<bool> = referenced.iter().zip(&used_by_removed).map(|(&r, &u)| r || !u).collect();
        let numbered = |keep: &[bool]| -> Vec<Option<usize>> {
            let mut next = 0;
            keep.iter()
                .map(|&k| {
                    let index = k.then_some(next);
                    next += usize::from(k);
                    index
                })
                .collect()
        };
        Some(Self { accessors: numbered(&keep_accessor), views: numbered(&keep_view) })
    }

    /// Renumbers every index at `paths` under `value` by `map`; an index that is removed is
    /// left as it is (only the replaced samplers' keys are, and they are pointed anew).
    fn apply(value: &mut Value, paths: &[&[&str]], map: &[Option<usize>]) {
        for path in paths {
            walk(value, path, &mut |v| {
                if let Some(new) = v.as_u64().and_then(|i| map.get(usize::try_from(i).ok()?).copied().flatten()) {
                    *v = json!(new);
                }
            });
        }
    }
}

/// A range of an input buffer copied into the BIN chunk.
struct Range {
    buffer: usize,
    start: u64,
    end: u64,
    /// Where it starts in the BIN chunk (congruent to `start` modulo 16, so every offset
    /// inside keeps its alignment).
    at: u64,
}

/// Pads `bin` with zeros to a multiple of `to` bytes.
fn pad(bin: &mut Vec<u8>, to: usize) {
    bin.resize(bin.len().div_ceil(to) * to, 0);
}

/// The GLB bytes of `json` (its `buffers` given) with each clip's channels, baked, in place of
/// the samplers `samplers[clip][channel]` (animation, sampler) names.
///
/// # Errors
/// [`InputError::Animation`] if the GLB would exceed 4 GiB.
pub(super) fn write(
    json: &Value,
    buffers: &[Vec<u8>],
    clips: &[Clip],
    samplers: &[Vec<(usize, usize)>],
    frames: &[ClipFrames<'_>],
) -> Result<Vec<u8>, InputError> {
    let mut json = json.clone();
    let old_views: Vec<Value> = json["bufferViews"].as_array().cloned().unwrap_or_default();
    let old_accessors: Vec<Value> = json["accessors"].as_array().cloned().unwrap_or_default();
    let replaced: Vec<(usize, usize)> = samplers.iter().flatten().copied().collect();
    let renumbering = Renumbering::without(&json, &replaced);
    // Every byte of every buffer when nothing is removed; else the ranges kept views cover.
    let mut ranges: Vec<Range> = match &renumbering {
        None => buffers
            .iter()
            .enumerate()
            .map(|(buffer, data)| Range { buffer, start: 0, end: data.len() as u64, at: 0 })
            .collect(),
        Some(r) => {
            let mut spans: Vec<(usize, u64, u64)> = old_views
                .iter()
                .zip(&r.views)
                .filter(|(_, new)| new.is_some())
                .map(|(v, _)| {
                    let start = v["byteOffset"].as_u64().unwrap_or(0);
                    (
                        v["buffer"].as_u64().unwrap_or(0) as usize,
                        start,
                        start.saturating_add(v["byteLength"].as_u64().unwrap_or(0)),
                    )
                })
                .collect();
            spans.sort_unstable();
            let mut merged: Vec<Range> = Vec::new();
            for (buffer, start, end) in spans {
                match merged.last_mut() {
                    Some(last) if last.buffer == buffer && start <= last.end => last.end = last.end.max(end),
                    _ => merged.push(Range { buffer, start, end, at: 0 }),
                }
            }
            merged
        }
    };
    let mut bin: Vec<u8> = Vec::new();
    for range in &mut ranges {
        // In range: the reader checked every view against its buffer.
        let data = buffers
            .get(range.buffer)
            .map_or(&[][..], |d| &d[d.len().min(range.start as usize)..d.len().min(range.end as usize)]);
        pad(&mut bin, 16);
        bin.resize(bin.len() + (range.start % 16) as usize, 0);
        range.at = bin.len() as u64;
        bin.extend_from_slice(data);
    }
    let renumbering = renumbering.unwrap_or_else(|| Renumbering::identity(old_accessors.len(), old_views.len()));
    let mut views: Vec<Value> = Vec::new();
    for (mut view, new) in old_views.into_iter().zip(&renumbering.views) {
        if new.is_none() {
            continue;
        }
        let (buffer, offset) =
            (view["buffer"].as_u64().unwrap_or(0) as usize, view["byteOffset"].as_u64().unwrap_or(0));
        let at = ranges
            .iter()
            .find(|r| r.buffer == buffer && r.start <= offset && offset <= r.end)
            .map_or(0, |r| r.at + (offset - r.start));
        view["buffer"] = json!(0);
        view["byteOffset"] = json!(at);
        views.push(view);
    }
    let mut accessors: Vec<Value> = Vec::new();
    for (mut accessor, new) in old_accessors.into_iter().zip(&renumbering.accessors) {
        if new.is_some() {
            Renumbering::apply(&mut accessor, ACCESSOR_VIEWS, &renumbering.views);
            accessors.push(accessor);
        }
    }
    Renumbering::apply(&mut json, ACCESSOR_INDICES, &renumbering.accessors);
    Renumbering::apply(&mut json, VIEW_INDICES, &renumbering.views);
    // Every new key in one buffer view after the kept bytes (accessors at their offsets in
    // it): a view per accessor would grow the JSON by more than the keys it replaced.
    pad(&mut bin, 4);
    let (keys_view, keys_start) = (views.len(), bin.len());
    let mut push = |bin: &mut Vec<u8>, data: &[f32], kind: &str, count: usize, bounds: Option<(f32, f32)>| -> usize {
        let mut accessor = json!({
            "bufferView": keys_view, "byteOffset": bin.len() - keys_start,
            "componentType": 5126, "count": count, "type": kind,
        });
        bin.extend(data.iter().flat_map(|v| v.to_le_bytes()));
        if let Some((min, max)) = bounds {
            accessor["min"] = json!([min]);
            accessor["max"] = json!([max]);
        }
        accessors.push(accessor);
        accessors.len() - 1
    };
    for ((clip, sources), frames) in clips.iter().zip(samplers).zip(frames) {
        let times: Vec<f32> = frames.times.iter().map(|&t| t as f32).collect();
        let bounds = (times[0], times[times.len() - 1]);
        let input_accessor = push(&mut bin, &times, "SCALAR", times.len(), Some(bounds));
        for ((channel, &(anim, sampler)), values) in clip.channels.iter().zip(sources).zip(&frames.values) {
            let (data, kind): (Vec<f32>, _) = match channel.property {
                Property::Rotation => (values.iter().flatten().copied().collect(), "VEC4"),
                _ => (values.iter().flat_map(|v| [v[0], v[1], v[2]]).collect(), "VEC3"),
            };
            let output_accessor = push(&mut bin, &data, kind, values.len(), None);
            let target = &mut json["animations"][anim]["samplers"][sampler];
            target["input"] = json!(input_accessor);
            target["output"] = json!(output_accessor);
            // LINEAR, glTF's default: no field (it would grow the JSON past what it replaced).
            if let Some(sampler) = target.as_object_mut() {
                sampler.remove("interpolation");
            }
        }
    }
    views.push(json!({"buffer": 0, "byteOffset": keys_start, "byteLength": bin.len() - keys_start}));
    pad(&mut bin, 4);
    json["bufferViews"] = Value::Array(views);
    json["accessors"] = Value::Array(accessors);
    json["buffers"] = json!([{"byteLength": bin.len()}]);
    assemble(&json, bin, "the baked GLB would exceed 4 GiB, the most a GLB can hold; bake at a lower rate")
}

/// The GLB of `json` and its BIN chunk `bin` (`json`'s one buffer); `too_large` is the message
/// when the file would exceed the 4 GiB a GLB can hold.
///
/// # Errors
/// [`AnimationError::GlbTooLarge`] saying `too_large`.
pub fn assemble(json: &Value, bin: Vec<u8>, too_large: &'static str) -> Result<Vec<u8>, InputError> {
    if u32::try_from(bin.len() + (1 << 20)).is_err() {
        return Err(AnimationError::GlbTooLarge(too_large).into());
    }
    let encode = |error| InternalError::Encode { what: "the GLB".into(), error };
    let text = serde_json::to_vec(json).map_err(|e| encode(e.into()))?;
    let glb = gltf::binary::Glb {
        header: gltf::binary::Header { magic: *GLB_MAGIC, version: 2, length: 0 },
        json: text.into(),
        bin: Some(bin.into()),
    };
    Ok(glb.to_vec().map_err(|e| encode(e.into()))?)
}
