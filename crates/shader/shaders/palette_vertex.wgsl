// A skinned vertex from skin palettes left on the device by crowd playback (DESIGN section 11:
// `[instances, skin joints, 12]`, each a 3x4 row-major skin matrix): the WebGPU viewer's
// vertex shader, one character per instance. Its vertex inputs are skin_vertex.wgsl's (the
// same names and locations), so the viewer's mesh attributes feed either; the instance's
// clip and time are the palette's, not inputs. Its outputs are what viewer_fragment.wgsl
// reads.

struct PaletteCamera {
    view_projection: mat4x4f,
}

struct PaletteLayout {
    // Matrices per palette: the skin's joints.
    joints: u32,
    pad0: u32,
    pad1: u32,
    pad2: u32,
}

@group(0) @binding(0) var<uniform> palette_camera: PaletteCamera;
@group(0) @binding(1) var<storage, read> palette_matrices: array<vec4f>;
@group(0) @binding(2) var<uniform> palette_layout: PaletteLayout;

struct PaletteVertex {
    @location(0) position: vec3f,
    @location(1) normal: vec3f,
    @location(2) joints: vec4u,
    @location(3) weights: vec4f,
    @location(4) instance_offset: vec3f,
}

struct PaletteOut {
    @builtin(position) position: vec4f,
    @location(0) normal: vec3f,
    @location(1) world: vec3f,
}

/// The 3x4 rows of instance `instance`'s skin matrix of joint `joint`, as a mat4 (columns).
fn palette_matrix(instance: u32, joint: u32) -> mat4x4f {
    let at = 3u * (instance * palette_layout.joints + joint);
    let r0 = palette_matrices[at];
    let r1 = palette_matrices[at + 1u];
    let r2 = palette_matrices[at + 2u];
    return mat4x4f(
        vec4f(r0.x, r1.x, r2.x, 0.0),
        vec4f(r0.y, r1.y, r2.y, 0.0),
        vec4f(r0.z, r1.z, r2.z, 0.0),
        vec4f(r0.w, r1.w, r2.w, 1.0),
    );
}

@vertex
fn palette_vertex(v: PaletteVertex, @builtin(instance_index) instance: u32) -> PaletteOut {
    var skin = mat4x4f();
    for (var k = 0u; k < 4u; k++) {
        skin += palette_matrix(instance, v.joints[k]) * v.weights[k];
    }
    let world = (skin * vec4f(v.position, 1.0)).xyz + v.instance_offset;
    var out: PaletteOut;
    out.position = palette_camera.view_projection * vec4f(world, 1.0);
    out.normal = (skin * vec4f(v.normal, 0.0)).xyz;
    out.world = world;
    return out;
}
