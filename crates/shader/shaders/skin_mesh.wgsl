// Linear blend skinning of a mesh primitive at every frame of a skin texture, for vertex
// textures (DESIGN section 5d): one invocation per (frame, vertex). A vertex's matrix is the
// weighted sum of its joints' skinning matrices; its normal is turned by that matrix and
// renormalized (as skin_vertex.wgsl does). Self-contained; the CPU twin is
// `bake::skinning::skin` (f64).

struct SkinMeshJob {
    vertices: u32,
    frames: u32,
    // Influences per vertex (four per JOINTS_n/WEIGHTS_n set) and joints of the skin.
    influences: u32,
    joints: u32,
    // Invocations per row of the dispatch grid (x groups times the workgroup size).
    row: u32,
    pad0: u32,
    pad1: u32,
    pad2: u32,
}

// Skinning matrices [frames, joints, 12]: 3x4 row-major, model * inverse bind.
@group(0) @binding(0) var<storage, read> skin_matrices: array<f32>;
// Bind-space vertices [vertices, 6]: position, normal (zero when the mesh has none).
@group(0) @binding(1) var<storage, read> skin_bind: array<f32>;
// Per vertex, `influences` pairs: joint index (as the bits of a u32), weight.
@group(0) @binding(2) var<storage, read> skin_influences: array<u32>;
// Skinned vertices [frames, vertices, 6].
@group(0) @binding(3) var<storage, read_write> skin_out: array<f32>;
@group(0) @binding(4) var<uniform> skin_job: SkinMeshJob;

const SKIN_VERTEX_CHANNELS: u32 = 6u;
const SKIN_MATRIX_CHANNELS: u32 = 12u;

@compute @workgroup_size(64)
fn skin_mesh(@builtin(global_invocation_id) id: vec3u) {
    let i = id.x + id.y * skin_job.row;
    if (i >= skin_job.vertices * skin_job.frames) {
        return;
    }
    let frame = i / skin_job.vertices;
    let vertex = i % skin_job.vertices;
    var m0 = vec4f(0.0);
    var m1 = vec4f(0.0);
    var m2 = vec4f(0.0);
    for (var k = 0u; k < skin_job.influences; k++) {
        let at = 2u * (vertex * skin_job.influences + k);
        let weight = bitcast<f32>(skin_influences[at + 1u]);
        if (weight == 0.0) {
            continue;
        }
        let m = (frame * skin_job.joints + skin_influences[at]) * SKIN_MATRIX_CHANNELS;
        m0 += weight * vec4f(skin_matrices[m], skin_matrices[m + 1u], skin_matrices[m + 2u], skin_matrices[m + 3u]);
        m1 += weight * vec4f(skin_matrices[m + 4u], skin_matrices[m + 5u], skin_matrices[m + 6u], skin_matrices[m + 7u]);
        m2 += weight * vec4f(skin_matrices[m + 8u], skin_matrices[m + 9u], skin_matrices[m + 10u], skin_matrices[m + 11u]);
    }
    let b = vertex * SKIN_VERTEX_CHANNELS;
    let p = vec4f(skin_bind[b], skin_bind[b + 1u], skin_bind[b + 2u], 1.0);
    let n = vec4f(skin_bind[b + 3u], skin_bind[b + 4u], skin_bind[b + 5u], 0.0);
    var turned = vec3f(dot(m0, n), dot(m1, n), dot(m2, n));
    let length = sqrt(dot(turned, turned));
    turned = select(vec3f(0.0), turned / length, length > 0.0);
    let out = i * SKIN_VERTEX_CHANNELS;
    skin_out[out] = dot(m0, p);
    skin_out[out + 1u] = dot(m1, p);
    skin_out[out + 2u] = dot(m2, p);
    skin_out[out + 3u] = turned.x;
    skin_out[out + 4u] = turned.y;
    skin_out[out + 5u] = turned.z;
}
