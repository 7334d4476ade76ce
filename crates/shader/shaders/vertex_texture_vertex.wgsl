// The minimal vertex shader of a crowd over a vertex texture (composed after
// bone_texture.wgsl and vertex_texture.wgsl): one character per instance, each with its own
// clip and time; no skinning, the vertex read from the texture. The camera is the engine's
// own (group 0).

struct VertexCamera {
    view_projection: mat4x4f,
}

@group(0) @binding(0) var<uniform> vertex_camera: VertexCamera;

struct TexturedVertex {
    // The mesh file's TEXCOORD_0: the vertex's texel within a frame.
    @location(0) address: vec2f,
    // Per instance: where the character stands, which clip it plays and how far into it (s).
    @location(1) instance_offset: vec3f,
    @location(2) instance_clip: u32,
    @location(3) instance_time: f32,
}

struct TexturedOut {
    @builtin(position) position: vec4f,
    // Zero for a primitive without normals, which the fragment shader lights by its faces.
    @location(0) normal: vec3f,
    // The position lit (scene space plus the instance's offset).
    @location(1) world: vec3f,
}

@vertex
fn vertex_texture_vertex(v: TexturedVertex) -> TexturedOut {
    let address = vec2u(v.address + 0.5);
    var out: TexturedOut;
    let world = vertex_position(v.instance_clip, address, v.instance_time) + v.instance_offset;
    out.position = vertex_camera.view_projection * vec4f(world, 1.0);
    out.normal = vertex_normal(v.instance_clip, address, v.instance_time);
    out.world = world;
    return out;
}
