// The test probe of bone_texture.wgsl (composed after it): the library's own functions
// evaluated at given (clip, joint, time) queries, so that the tests measure the shader a
// renderer runs, not a copy of its math.

struct BoneQuery {
    clip: u32,
    joint: u32,
    time: f32,
    // 0: bone_pose (rotation, translation, scale); 1: bone_matrix_lerp (3x4 rows);
    // 2: bone_skin_matrix of `joints` and `weights` (3x4 rows).
    mode: u32,
    joints: vec4u,
    weights: vec4f,
}

@group(0) @binding(0) var<storage, read> bone_queries: array<BoneQuery>;
// 12 floats per query: rotation, translation, scale (and two zeros), or the matrix's rows.
@group(0) @binding(1) var<storage, read_write> bone_answers: array<f32>;

const BONE_ANSWER_FLOATS: u32 = 12u;

@compute @workgroup_size(64)
fn bone_probe(@builtin(global_invocation_id) id: vec3u) {
    let i = id.x;
    if i >= arrayLength(&bone_queries) {
        return;
    }
    let q = bone_queries[i];
    var out = array<f32, 12>();
    if q.mode == 0u {
        let p = bone_pose(q.clip, q.joint, q.time);
        out = array<f32, 12>(
            p.rotation.x, p.rotation.y, p.rotation.z, p.rotation.w,
            p.translation.x, p.translation.y, p.translation.z,
            p.scale.x, p.scale.y, p.scale.z, 0.0, 0.0,
        );
    } else {
        var m = transpose(bone_matrix_lerp(q.clip, q.joint, q.time));
        if q.mode == 2u {
            m = transpose(bone_skin_matrix(q.clip, q.joints, q.weights, q.time));
        }
        out = array<f32, 12>(
            m[0].x, m[0].y, m[0].z, m[0].w, m[1].x, m[1].y, m[1].z, m[1].w, m[2].x, m[2].y, m[2].z, m[2].w,
        );
    }
    for (var k = 0u; k < BONE_ANSWER_FLOATS; k = k + 1u) {
        bone_answers[i * BONE_ANSWER_FLOATS + k] = out[k];
    }
}
