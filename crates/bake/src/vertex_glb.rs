//! The mesh a vertex texture plays (DESIGN section 8): each skinned primitive as a plain
//! mesh at the scene root, without skin, joints, weights or animation, its bind-space
//! positions and normals kept (what an engine draws when no texture is bound) and a
//! `TEXCOORD_0` that addresses each vertex's texel within a frame.

use super::image::Grid;
use super::texture::TextureKind;
use crate::error::{BakeError, Refusal};
use quatcurve_formats::mesh::SkinnedPrimitive;
use serde_json::{json, Value};

/// glTF's `ARRAY_BUFFER` and `ELEMENT_ARRAY_BUFFER` buffer-view targets.
const ARRAY_BUFFER: u32 = 34962;
const ELEMENT_ARRAY_BUFFER: u32 = 34963;
/// glTF's component types.
const UNSIGNED_SHORT: u32 = 5123;
const UNSIGNED_INT: u32 = 5125;
const FLOAT: u32 = 5126;
/// glTF's default primitive mode (triangles), written only when a primitive has another.
const TRIANGLES: u32 = 4;

/// Vertex `v`'s texel within a frame of a texture `frame_width` texels wide: `(v mod
/// frame_width, v div frame_width)`, the `TEXCOORD_0` written here.
#[must_use]
pub fn address(v: usize, frame_width: usize) -> [f32; 2] {
    [(v % frame_width) as f32, (v / frame_width) as f32]
}

/// The GLB of `primitives` as plain meshes, each vertex addressed for images of at most
/// `max_size` texels a side.
///
/// # Errors
/// [`InputError::Animation`] naming a primitive whose frame cannot fit that side, or a GLB
/// over 4 GiB.
pub fn write(primitives: &[SkinnedPrimitive], max_size: usize) -> Result<Vec<u8>, BakeError> {
    let mut bin: Vec<u8> = Vec::new();
    let (mut views, mut accessors, mut meshes, mut nodes) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    // One buffer view and accessor of `bytes` (already little-endian), 4-byte aligned.
    let mut push = |bin: &mut Vec<u8>, bytes: Vec<u8>, target: u32, accessor: Value| -> usize {
        views.push(json!({"buffer": 0, "byteOffset": bin.len(), "byteLength": bytes.len(), "target": target}));
        bin.extend(bytes);
        bin.resize(bin.len().next_multiple_of(4), 0);
        let mut accessor = accessor;
        accessor["bufferView"] = json!(views.len() - 1);
        accessors.push(accessor);
        accessors.len() - 1
    };
    for (k, p) in primitives.iter().enumerate() {
        let frame_width = Grid::new(TextureKind::Vertex, p.vertices(), 1, max_size)
            .map_err(|error| Refusal::Image { texture: p.name.clone(), error })?
            .frame_width;
        let count = p.vertices();
        let positions: Vec<[f32; 3]> = p.bind.positions.iter().map(|v| v.map(|c| c as f32)).collect();
        let (mut min, mut max) = ([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]);
        for v in &positions {
            for c in 0..3 {
                min[c] = min[c].min(v[c]);
                max[c] = max[c].max(v[c]);
            }
        }
        let floats = |values: &mut dyn Iterator<Item = f32>| values.flat_map(f32::to_le_bytes).collect::<Vec<u8>>();
        let position = push(
            &mut bin,
            floats(&mut positions.iter().flatten().copied()),
            ARRAY_BUFFER,
            json!({"componentType": FLOAT, "count": count, "type": "VEC3", "min": min, "max": max}),
        );
        let mut attributes = json!({"POSITION": position});
        if let Some(normals) = &p.bind.normals {
            let normal = push(
                &mut bin,
                floats(&mut normals.iter().flatten().map(|&c| c as f32)),
                ARRAY_BUFFER,
                json!({"componentType": FLOAT, "count": count, "type": "VEC3"}),
            );
            attributes["NORMAL"] = json!(normal);
        }
        let texel = push(
            &mut bin,
            floats(&mut (0..count).flat_map(|v| address(v, frame_width))),
            ARRAY_BUFFER,
            json!({"componentType": FLOAT, "count": count, "type": "VEC2"}),
        );
        attributes["TEXCOORD_0"] = json!(texel);
        let mut primitive = json!({"attributes": attributes});
        if let Some(indices) = &p.indices {
            // 16 bits while every index fits below the primitive-restart value 65535.
            let (bytes, component) = if count <= 0xFFFF {
                (indices.iter().flat_map(|&i| (i as u16).to_le_bytes()).collect(), UNSIGNED_SHORT)
            } else {
                (indices.iter().flat_map(|&i| i.to_le_bytes()).collect(), UNSIGNED_INT)
            };
            let accessor = json!({"componentType": component, "count": indices.len(), "type": "SCALAR"});
            primitive["indices"] = json!(push(&mut bin, bytes, ELEMENT_ARRAY_BUFFER, accessor));
        }
        if p.mode != TRIANGLES {
            primitive["mode"] = json!(p.mode);
        }
        meshes.push(json!({"name": p.name, "primitives": [primitive]}));
        nodes.push(json!({"name": format!("{}{}", p.name, super::vertex_texture::suffix(k)), "mesh": k}));
    }
    let document = json!({
        "asset": {"version": "2.0", "generator": format!("quatcurve {}", env!("CARGO_PKG_VERSION"))},
        "scene": 0,
        "scenes": [{"nodes": (0..nodes.len()).collect::<Vec<_>>()}],
        "nodes": nodes,
        "meshes": meshes,
        "accessors": accessors,
        "bufferViews": views,
        "buffers": [{"byteLength": bin.len()}],
    });
    Ok(quatcurve_formats::glb::assemble(&document, bin, "the mesh GLB would exceed 4 GiB, the most a GLB can hold")?)
}
