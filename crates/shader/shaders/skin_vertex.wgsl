// A skinned vertex from a skin-trs bone texture (composed after bone_texture.wgsl): the
// minimal vertex shader of a crowd, one character per instance, each with its own clip and
// time: the vertex in bind space times bone_skin_matrix. The camera is the engine's own
// (group 0).

struct Camera {
    view_projection: mat4x4f,
}

@group(0) @binding(0) var<uniform> camera: Camera;

struct SkinnedVertex {
    @location(0) position: vec3f,
    // glTF NORMAL; zeros for a mesh without normals (a host binds zeros; WebGL's unbound
    // attribute reads them), which the fragment shader then lights by its faces.
    @location(1) normal: vec3f,
    // glTF JOINTS_0 (indices into the skin's joints, as the skin texture's joints) and WEIGHTS_0.
    @location(2) joints: vec4u,
    @location(3) weights: vec4f,
    // Per instance: where the character stands, which clip it plays and how far into it (s).
    @location(4) instance_offset: vec3f,
    @location(5) instance_clip: u32,
    @location(6) instance_time: f32,
    // glTF TEXCOORD_0, passed through for the engine's own textures (zeros without one).
    @location(7) uv: vec2f,
}

struct SkinnedOut {
    @builtin(position) position: vec4f,
    // The skinned normal, not normalized: zero for a mesh without normals.
    @location(0) normal: vec3f,
    // The position lit (scene space plus the instance's offset).
    @location(1) world: vec3f,
    @location(2) uv: vec2f,
}

@vertex
fn skin_vertex(v: SkinnedVertex) -> SkinnedOut {
    let skin = bone_skin_matrix(v.instance_clip, v.joints, v.weights, v.instance_time);
    let world = (skin * vec4f(v.position, 1.0)).xyz + v.instance_offset;
    var out: SkinnedOut;
    out.position = camera.view_projection * vec4f(world, 1.0);
    out.normal = (skin * vec4f(v.normal, 0.0)).xyz;
    out.world = world;
    out.uv = v.uv;
    return out;
}
