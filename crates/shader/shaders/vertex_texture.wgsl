// Vertex textures (DESIGN section 5d), composed after bone_texture.wgsl (whose BoneClip and
// bone_frames choose the frames, the one rule for both kinds of texture): what a renderer's
// vertex shader reads from a `--texture vertex` bake of `--format exr|png16`. A vertex's
// position and normal at any time of a clip: the two baked frames around it, positions
// lerped and normals nlerped. The mesh is the bake's `<stem>.mesh.glb`, whose TEXCOORD_0 is
// each vertex's texel within a frame; the rest of the address is bake::image::Grid's.

// The most clips one texture's layout describes (a uniform array has a fixed size).
const VERTEX_MAX_CLIPS: u32 = 64u;

// The sidecar's numbers for one primitive's .pos and .nrm files.
struct VertexLayout {
    // The files' grid (the sidecar's textures[k]): texels per row of a frame, image rows per
    // frame, frames down a column.
    frame_width: u32,
    rows_per_frame: u32,
    frames_per_column: u32,
    // 1 when the primitive has normals (a .nrm file is bound), else 0.
    has_normals: u32,
    // position = low + texel.xyz * span: the .pos file's low and span.
    low: vec4f,
    span: vec4f,
    clips: array<BoneClip, VERTEX_MAX_CLIPS>,
}

// rgba32float, rgba16float (EXR) or rgba16unorm (PNG16); read texel by texel, never filtered.
@group(2) @binding(0) var vertex_positions: texture_2d<f32>;
@group(2) @binding(1) var vertex_normals: texture_2d<f32>;
@group(2) @binding(2) var<uniform> vertex_layout: VertexLayout;

// The texel of the vertex at `address` (its TEXCOORD_0) in frame row `row` of a file.
fn vertex_texel(texture: texture_2d<f32>, address: vec2u, row: u32) -> vec4f {
    let x = (row / vertex_layout.frames_per_column) * vertex_layout.frame_width + address.x;
    let y = (row % vertex_layout.frames_per_column) * vertex_layout.rows_per_frame + address.y;
    return textureLoad(texture, vec2u(x, y), 0);
}

// The unit normal of an octahedral texel (bake::vertex_encoding::decode_normal).
fn vertex_decode_normal(texel: vec2f) -> vec3f {
    let uv = 2.0 * texel - 1.0;
    let z = 1.0 - abs(uv.x) - abs(uv.y);
    let fold = max(-z, 0.0);
    let xy = uv - fold * select(vec2f(-1.0), vec2f(1.0), uv >= vec2f(0.0));
    return normalize(vec3f(xy, z));
}

// The position of the vertex at `address` at `time` seconds into clip `clip`.
fn vertex_position(clip: u32, address: vec2u, time: f32) -> vec3f {
    let f = bone_frames(vertex_layout.clips[clip], time);
    let a = vertex_texel(vertex_positions, address, f.first).xyz;
    let b = vertex_texel(vertex_positions, address, f.second).xyz;
    return vertex_layout.low.xyz + mix(a, b, f.blend) * vertex_layout.span.xyz;
}

// The unit normal of the vertex at `address` at `time` seconds into clip `clip` (zero when
// the primitive has none: a fragment shader lights its faces, as viewer_fragment.wgsl does).
fn vertex_normal(clip: u32, address: vec2u, time: f32) -> vec3f {
    if vertex_layout.has_normals == 0u {
        return vec3f(0.0);
    }
    let f = bone_frames(vertex_layout.clips[clip], time);
    let a = vertex_decode_normal(vertex_texel(vertex_normals, address, f.first).xy);
    let b = vertex_decode_normal(vertex_texel(vertex_normals, address, f.second).xy);
    return normalize(mix(a, b, f.blend));
}
