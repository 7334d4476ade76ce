// The test probe of vertex_texture.wgsl (composed after bone_texture.wgsl and it): the
// library's own functions at given (clip, vertex address, time) queries, so that the tests
// measure the shader a renderer runs.

struct VertexQuery {
    clip: u32,
    time: f32,
    address: vec2u,
}

@group(0) @binding(0) var<storage, read> vertex_queries: array<VertexQuery>;
// Position and normal per query: six floats.
@group(0) @binding(1) var<storage, read_write> vertex_answers: array<f32>;

@compute @workgroup_size(64)
fn vertex_probe(@builtin(global_invocation_id) id: vec3u) {
    let i = id.x;
    if i >= arrayLength(&vertex_queries) {
        return;
    }
    let q = vertex_queries[i];
    let p = vertex_position(q.clip, q.address, q.time);
    let n = vertex_normal(q.clip, q.address, q.time);
    let out = array<f32, 6>(p.x, p.y, p.z, n.x, n.y, n.z);
    for (var k = 0u; k < 6u; k = k + 1u) {
        vertex_answers[i * 6u + k] = out[k];
    }
}
