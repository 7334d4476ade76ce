// Forward kinematics for bake's model textures (DESIGN section 5b): each joint's model
// matrix is its parent's times its own T * R * S. One dispatch per level of the hierarchy
// (the joints at one depth, for every frame of the chunk); WebGPU orders the dispatches of a
// pass, so a level reads its parents complete. Composed after real.wgsl and quat.wgsl
// (quat_to_mat3); the CPU twin is `bake::texture::model` (f64).

struct FkLevel {
    // This level's joints: `fk_level_joints[first .. first + count]`.
    first: u32,
    count: u32,
    // Frames in the chunk and joints per frame.
    frames: u32,
    joints: u32,
    // Invocations per row of the dispatch grid (x groups times the workgroup size).
    row: u32,
    pad0: u32,
    pad1: u32,
    pad2: u32,
}

// Bindings from 8 on: crowd playback composes this file with eval.wgsl's (0-7).

// Local rows [frames, joints, 10]: rotation x, y, z, w, translation, scale.
@group(0) @binding(8) var<storage, read> fk_local: array<f32>;
// Parent of each joint, -1 for a root.
@group(0) @binding(9) var<storage, read> fk_parents: array<i32>;
// Joint indices grouped by depth, roots first.
@group(0) @binding(10) var<storage, read> fk_level_joints: array<u32>;
// Model rows [frames, joints, 12]: 3x4 row-major.
@group(0) @binding(11) var<storage, read_write> fk_model: array<f32>;
@group(0) @binding(12) var<uniform> fk_level: FkLevel;

const FK_LOCAL_CHANNELS: u32 = 10u;
const FK_MATRIX_CHANNELS: u32 = 12u;

fn fk_model_row(at: u32) -> vec4f {
    return vec4f(fk_model[at], fk_model[at + 1u], fk_model[at + 2u], fk_model[at + 3u]);
}

@compute @workgroup_size(64)
fn forward_kinematics(@builtin(global_invocation_id) id: vec3u) {
    let i = id.x + id.y * fk_level.row;
    if (i >= fk_level.count * fk_level.frames) {
        return;
    }
    let frame = i / fk_level.count;
    let joint = fk_level_joints[fk_level.first + i % fk_level.count];
    let at = (frame * fk_level.joints + joint) * FK_LOCAL_CHANNELS;
    // f32 keys are unit only to ~1e-7: normalize, as the CPU twin does.
    let q = normalize(vec4f(fk_local[at], fk_local[at + 1u], fk_local[at + 2u], fk_local[at + 3u]));
    let t = vec3f(fk_local[at + 4u], fk_local[at + 5u], fk_local[at + 6u]);
    let s = vec3f(fk_local[at + 7u], fk_local[at + 8u], fk_local[at + 9u]);
    // quat_to_mat3 returns the rows; R * diag(s) scales each row by s componentwise.
    let r = quat_to_mat3(q);
    var m0 = vec4f(r[0] * s, t.x);
    var m1 = vec4f(r[1] * s, t.y);
    var m2 = vec4f(r[2] * s, t.z);
    let parent = fk_parents[joint];
    if (parent >= 0) {
        let p = (frame * fk_level.joints + u32(parent)) * FK_MATRIX_CHANNELS;
        let p0 = fk_model_row(p);
        let p1 = fk_model_row(p + 4u);
        let p2 = fk_model_row(p + 8u);
        // Row k of P * M: sum_j P[k][j] M[j], plus P's translation.
        let own0 = m0;
        let own1 = m1;
        let own2 = m2;
        m0 = p0.x * own0 + p0.y * own1 + p0.z * own2 + vec4f(0.0, 0.0, 0.0, p0.w);
        m1 = p1.x * own0 + p1.y * own1 + p1.z * own2 + vec4f(0.0, 0.0, 0.0, p1.w);
        m2 = p2.x * own0 + p2.y * own1 + p2.z * own2 + vec4f(0.0, 0.0, 0.0, p2.w);
    }
    let out = (frame * fk_level.joints + joint) * FK_MATRIX_CHANNELS;
    let rows = array<vec4f, 3>(m0, m1, m2);
    for (var k = 0u; k < 3u; k++) {
        fk_model[out + 4u * k] = rows[k].x;
        fk_model[out + 4u * k + 1u] = rows[k].y;
        fk_model[out + 4u * k + 2u] = rows[k].z;
        fk_model[out + 4u * k + 3u] = rows[k].w;
    }
}
