//! Linear blend skinning of a [`SkinnedPrimitive`] in f64: the CPU path of vertex textures and
//! the oracle the GPU's `shaders/skin_mesh.wgsl` is held to. A vertex's matrix is the weighted
//! sum of its joints' skinning matrices (`model * inverse_bind`, a skin texture's rows); its
//! normal is turned by that matrix and renormalized, as `shaders/skin_vertex.wgsl` does.
use super::mesh::SkinnedPrimitive;
use crate::output::{MATRIX_CHANNELS, VERTEX_CHANNELS};
use rayon::prelude::*;

/// Every vertex of `primitive` at every frame of `matrices` (`[frames, skin joints, 12]`, 3x4
/// row-major skinning matrices of the primitive's skin, as [`super::texture::skin`] makes them):
/// `[frames, vertices, VERTEX_CHANNELS]`. A primitive without normals gets zero normals.
///
/// # Panics
/// When `matrices` is not whole frames of the skin's joints, or a joint index is out of range
/// (both checked when the primitive was read).
#[must_use]
pub fn skin(primitive: &SkinnedPrimitive, skin_joints: usize, matrices: &[f32]) -> Vec<f64> {
    let frame = skin_joints * MATRIX_CHANNELS;
    assert!(frame > 0 && matrices.len() % frame == 0, "skinning matrices are whole frames of the skin's joints");
    let vertices = primitive.vertices();
    let mut out = vec![0.0; matrices.len() / frame * vertices * VERTEX_CHANNELS];
    out.par_chunks_mut((vertices * VERTEX_CHANNELS).max(1)).zip(matrices.par_chunks(frame)).for_each(|(out, m)| {
        for (v, o) in out.chunks_exact_mut(VERTEX_CHANNELS).enumerate() {
            let blended = blend(primitive, v, m);
            let [x, y, z] = primitive.positions[v];
            let row = |r: usize| &blended[4 * r..4 * r + 4];
            for (r, o) in o[..3].iter_mut().enumerate() {
                *o = row(r)[0] * x + row(r)[1] * y + row(r)[2] * z + row(r)[3];
            }
            if let Some(normals) = &primitive.normals {
                let [x, y, z] = normals[v];
                let n: [f64; 3] = std::array::from_fn(|r| row(r)[0] * x + row(r)[1] * y + row(r)[2] * z);
                let length = n.iter().map(|c| c * c).sum::<f64>().sqrt();
                for (o, n) in o[3..].iter_mut().zip(n) {
                    *o = if length > 0.0 { n / length } else { 0.0 };
                }
            }
        }
    });
    out
}

/// The weighted sum of vertex `v`'s joints' matrices in one frame's `matrices`.
fn blend(primitive: &SkinnedPrimitive, v: usize, matrices: &[f32]) -> [f64; MATRIX_CHANNELS] {
    let n = primitive.influences;
    let mut sum = [0.0; MATRIX_CHANNELS];
    for (&joint, &weight) in primitive.joints[v * n..(v + 1) * n].iter().zip(&primitive.weights[v * n..(v + 1) * n]) {
        if weight == 0.0 {
            continue;
        }
        let m = &matrices[joint as usize * MATRIX_CHANNELS..(joint as usize + 1) * MATRIX_CHANNELS];
        for (s, &c) in sum.iter_mut().zip(m) {
            *s += weight * f64::from(c);
        }
    }
    sum
}

/// `primitive` in the GPU kernel's layout.
#[cfg(feature = "gpu")]
#[must_use]
pub fn bind_mesh(primitive: &SkinnedPrimitive) -> crate::gpu::skinning::BindMesh {
    let normals = primitive.normals.as_deref();
    let vertices = (0..primitive.vertices())
        .flat_map(|v| {
            let n = normals.map_or([0.0; 3], |n| n[v]);
            let p = primitive.positions[v];
            [p[0], p[1], p[2], n[0], n[1], n[2]].map(|c| c as f32)
        })
        .collect();
    let pairs =
        primitive.joints.iter().zip(&primitive.weights).flat_map(|(&j, &w)| [j, (w as f32).to_bits()]).collect();
    crate::gpu::skinning::BindMesh { vertices, influences: primitive.influences, pairs }
}
