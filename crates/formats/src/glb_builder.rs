//! A GLB built from a scene converted to glTF (FBX's through ufbx, USD's through openusd): its
//! BIN chunk and accessors written as the scene's parts are added, and each vertex's skin
//! influences cut to the four glTF holds.

use quatcurve_anim::error::InputError;
use serde_json::{json, Value};

/// Skin weights a glTF vertex holds (`JOINTS_0`, `WEIGHTS_0`); a converted vertex's heaviest
/// four are kept, renormalized ([`heaviest`]).
pub const WEIGHTS_PER_VERTEX: usize = 4;

/// A vertex's heaviest [`WEIGHTS_PER_VERTEX`] influences (joint, weight), renormalized to sum
/// to 1, padded with joint 0 at weight 0; a vertex without weight is bound wholly to joint 0.
/// A joint past glTF's `JOINTS_0` range (unsigned short) is the caller's to refuse first.
#[must_use]
pub fn heaviest(mut influences: Vec<(u32, f64)>) -> [(u16, f32); WEIGHTS_PER_VERTEX] {
    influences.sort_by(|a, b| b.1.total_cmp(&a.1));
    influences.truncate(WEIGHTS_PER_VERTEX);
    let total: f64 = influences.iter().map(|(_, w)| w).sum();
    std::array::from_fn(|k| {
        let (joint, weight) = influences.get(k).copied().unwrap_or((0, 0.0));
        let weight = if total > 0.0 {
            (weight / total) as f32
        } else if k == 0 {
            1.0
        } else {
            0.0
        };
        (u16::try_from(joint).unwrap_or(0), weight)
    })
}

/// glTF's buffer view target of vertex attributes.
const ARRAY_BUFFER: u32 = 34962;

/// glTF's buffer view target of vertex indices.
const ELEMENT_ARRAY_BUFFER: u32 = 34963;

/// The GLB's BIN chunk and its accessors, written as they are added.
#[derive(Default)]
pub struct Buffer {
    bin: Vec<u8>,
    views: Vec<Value>,
    accessors: Vec<Value>,
}

/// A converted scene's glTF parts, made one GLB by [`Buffer::glb`].
pub struct Scene {
    /// Who converted it: glTF's `asset.generator`.
    pub generator: &'static str,
    /// The nodes of glTF's one scene.
    pub roots: Vec<usize>,
    /// glTF's lists; meshes, skins and animations are left out when empty.
    pub nodes: Vec<Value>,
    pub meshes: Vec<Value>,
    pub skins: Vec<Value>,
    pub animations: Vec<Value>,
}

impl Buffer {
    /// The GLB of `scene` with this as its one buffer; `too_large` is the message past the
    /// 4 GiB a GLB holds.
    ///
    /// # Errors
    /// As [`crate::glb::assemble`].
    pub fn glb(self, scene: Scene, too_large: &'static str) -> Result<Vec<u8>, InputError> {
        let mut document = json!({
            "asset": {"version": "2.0", "generator": scene.generator},
            "scene": 0,
            "scenes": [{"nodes": scene.roots}],
            "nodes": scene.nodes,
            "accessors": self.accessors,
            "bufferViews": self.views,
            "buffers": [{"byteLength": self.bin.len()}],
        });
        // glTF forbids empty arrays.
        for (key, list) in [("meshes", scene.meshes), ("skins", scene.skins), ("animations", scene.animations)] {
            if !list.is_empty() {
                document[key] = Value::Array(list);
            }
        }
        crate::glb::assemble(&document, self.bin, too_large)
    }

    /// An accessor of `values` (`width` floats an element, glTF `kind`), with its bounds when
    /// glTF asks for them (`bounds`).
    pub fn floats(&mut self, values: &[f32], width: usize, kind: &str, bounds: bool) -> usize {
        let count = values.len() / width;
        let accessor = json!({"componentType": 5126, "count": count, "type": kind});
        self.floats_with(values, width, accessor, bounds)
    }

    /// A vertex attribute's accessor ([`Buffer::floats`] with its view marked as one).
    pub fn attribute(&mut self, values: &[f32], width: usize, kind: &str, bounds: bool) -> usize {
        let accessor =
            json!({"componentType": 5126, "count": values.len() / width, "type": kind, "target": ARRAY_BUFFER});
        self.floats_with(values, width, accessor, bounds)
    }

    fn floats_with(&mut self, values: &[f32], width: usize, mut accessor: Value, bounds: bool) -> usize {
        if bounds {
            let (mut lo, mut hi) = (vec![f32::MAX; width], vec![f32::MIN; width]);
            for element in values.chunks_exact(width) {
                for (c, &v) in element.iter().enumerate() {
                    lo[c] = lo[c].min(v);
                    hi[c] = hi[c].max(v);
                }
            }
            accessor["min"] = json!(lo);
            accessor["max"] = json!(hi);
        }
        self.add(values.iter().flat_map(|v| v.to_le_bytes()).collect(), accessor)
    }

    /// The `JOINTS_0` and `WEIGHTS_0` accessors of each vertex's influences ([`heaviest`]).
    pub fn influences(&mut self, influences: &[[(u16, f32); WEIGHTS_PER_VERTEX]]) -> (usize, usize) {
        let joints: Vec<u8> = influences.iter().flatten().flat_map(|(j, _)| j.to_le_bytes()).collect();
        let weights: Vec<f32> = influences.iter().flatten().map(|(_, w)| *w).collect();
        let accessor =
            json!({"componentType": 5123, "count": influences.len(), "type": "VEC4", "target": ARRAY_BUFFER});
        (self.add(joints, accessor), self.attribute(&weights, WEIGHTS_PER_VERTEX, "VEC4", false))
    }

    /// A primitive's triangle indices.
    pub fn indices(&mut self, values: &[u32]) -> usize {
        let accessor =
            json!({"componentType": 5125, "count": values.len(), "type": "SCALAR", "target": ELEMENT_ARRAY_BUFFER});
        self.add(values.iter().flat_map(|v| v.to_le_bytes()).collect(), accessor)
    }

    fn add(&mut self, bytes: Vec<u8>, mut accessor: Value) -> usize {
        self.bin.resize(self.bin.len().next_multiple_of(4), 0);
        let mut view = json!({"buffer": 0, "byteOffset": self.bin.len(), "byteLength": bytes.len()});
        if let Some(target) = accessor.as_object_mut().and_then(|a| a.remove("target")) {
            view["target"] = target;
        }
        self.views.push(view);
        self.bin.extend(bytes);
        accessor["bufferView"] = json!(self.views.len() - 1);
        self.accessors.push(accessor);
        self.accessors.len() - 1
    }
}
