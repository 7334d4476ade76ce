// Bone textures (DESIGN section 5c): what a renderer's shader reads from a baked texture of
// `--format exr|png16`. A joint's pose at any time of a clip: the two baked frames around it,
// rotations blended by normalized lerp on the shorter arc, translation and scale by lerp.
// Self-contained (no other file of shaders/ needed), so an engine includes this file alone;
// `quatcurve shaders` writes it with GLSL and HLSL generated from it. The texel address is
// bake::image::Grid's, the one formula of the sidecar's `address`.

// One clip of the texture (the sidecar's clips[i]): rows first_row .. first_row + frames.
struct BoneClip {
    first_row: u32,
    frames: u32,
    // 1 for a loop: its period is frames - 1 rows (its last row is its first a period later).
    looping: u32,
    // The clip's own rate in Hz (clips[i].rate), not the requested one.
    rate: f32,
}

// The most clips one texture's layout describes (a uniform array has a fixed size).
const BONE_MAX_CLIPS: u32 = 64u;
// Texels per joint: rotation, translation, scale (or a matrix's three rows).
const BONE_TEXELS: u32 = 3u;

// The sidecar's grid, remap and clips for one texture.
struct BoneLayout {
    // The file's grid (the sidecar's textures[k]): texels per joint, texels per row of a
    // frame, image rows per frame, frames down a column.
    texels_per_joint: u32,
    frame_width: u32,
    rows_per_frame: u32,
    frames_per_column: u32,
    // value = low + texel * span per texel slot and channel: a PNG16's remap (min, max - min),
    // 0 and 1 for EXR.
    low: array<vec4f, BONE_TEXELS>,
    span: array<vec4f, BONE_TEXELS>,
    clips: array<BoneClip, BONE_MAX_CLIPS>,
}

// rgba32float, rgba16float (EXR) or rgba16unorm (PNG16); read texel by texel, never filtered.
@group(1) @binding(0) var bone_texture: texture_2d<f32>;
@group(1) @binding(1) var<uniform> bone_layout: BoneLayout;

// A joint's transform: T * R * S, rotation x, y, z, w.
struct BonePose {
    rotation: vec4f,
    translation: vec3f,
    scale: vec3f,
}

// The rows of the two frames around a time, and how far the time is from the first to the
// second.
struct BoneFrames {
    first: u32,
    second: u32,
    blend: f32,
}

// The frames around `time` seconds into `clip`: a loop wraps at its period (frames - 1 rows),
// an open clip holds its first and last frames outside its span.
fn bone_frames(clip: BoneClip, time: f32) -> BoneFrames {
    let last = max(clip.frames, 1u) - 1u;
    var at = time * clip.rate;
    if clip.looping != 0u && last > 0u {
        let period = f32(last);
        at = at - floor(at / period) * period;
    }
    at = clamp(at, 0.0, f32(last));
    let first = min(u32(floor(at)), max(last, 1u) - 1u);
    let second = min(first + 1u, last);
    return BoneFrames(clip.first_row + first, clip.first_row + second, at - f32(first));
}

// Texel `t` of `joint` in frame row `row` of the file (the sidecar's `address`), remapped to
// its value.
fn bone_texel(row: u32, joint: u32, t: u32) -> vec4f {
    let at = joint * bone_layout.texels_per_joint + t;
    let width = bone_layout.frame_width;
    let x = (row / bone_layout.frames_per_column) * width + at % width;
    let y = (row % bone_layout.frames_per_column) * bone_layout.rows_per_frame + at / width;
    return bone_layout.low[t] + textureLoad(bone_texture, vec2u(x, y), 0) * bone_layout.span[t];
}

// The pose of `joint` at `time` seconds into clip `clip` of a local, model-trs or skin-trs
// texture: nlerp of the two frames' rotations (the second's sign turned to the first's side),
// lerp of their translations and scales.
fn bone_pose(clip: u32, joint: u32, time: f32) -> BonePose {
    let f = bone_frames(bone_layout.clips[clip], time);
    let q0 = bone_texel(f.first, joint, 0u);
    let q1 = bone_texel(f.second, joint, 0u);
    let q = normalize(mix(q0, select(q1, -q1, dot(q0, q1) < 0.0), f.blend));
    let t = mix(bone_texel(f.first, joint, 1u).xyz, bone_texel(f.second, joint, 1u).xyz, f.blend);
    let s = mix(bone_texel(f.first, joint, 2u).xyz, bone_texel(f.second, joint, 2u).xyz, f.blend);
    return BonePose(q, t, s);
}

// T * R * S as a column-major 4x4 matrix.
fn bone_pose_matrix(p: BonePose) -> mat4x4f {
    let x = p.rotation.x;
    let y = p.rotation.y;
    let z = p.rotation.z;
    let w = p.rotation.w;
    return mat4x4f(
        vec4f(1.0 - 2.0 * (y * y + z * z), 2.0 * (x * y + w * z), 2.0 * (x * z - w * y), 0.0) * p.scale.x,
        vec4f(2.0 * (x * y - w * z), 1.0 - 2.0 * (x * x + z * z), 2.0 * (y * z + w * x), 0.0) * p.scale.y,
        vec4f(2.0 * (x * z + w * y), 2.0 * (y * z - w * x), 1.0 - 2.0 * (x * x + y * y), 0.0) * p.scale.z,
        vec4f(p.translation, 1.0),
    );
}

// glTF skinning's matrix for a vertex bound to `joints` (JOINTS_0, indices into the skin's
// joints: the rows of a skin-trs texture) with `weights` (WEIGHTS_0), at `time` in `clip`:
// the weighted sum of the joints' skinning matrices, which takes the vertex from bind space.
fn bone_skin_matrix(clip: u32, joints: vec4u, weights: vec4f, time: f32) -> mat4x4f {
    var skin = mat4x4f(vec4f(0.0), vec4f(0.0), vec4f(0.0), vec4f(0.0));
    for (var i = 0u; i < 4u; i = i + 1u) {
        skin = skin + bone_pose_matrix(bone_pose(clip, joints[i], time)) * weights[i];
    }
    return skin;
}

// The 3x4 matrix of `joint` at `time` in a model or skin (matrix) texture, its rows lerped
// between the two frames: cheap, but a rotating joint shrinks and shears between frames
// (prefer the -trs textures and bone_pose).
fn bone_matrix_lerp(clip: u32, joint: u32, time: f32) -> mat4x4f {
    let f = bone_frames(bone_layout.clips[clip], time);
    let r0 = mix(bone_texel(f.first, joint, 0u), bone_texel(f.second, joint, 0u), f.blend);
    let r1 = mix(bone_texel(f.first, joint, 1u), bone_texel(f.second, joint, 1u), f.blend);
    let r2 = mix(bone_texel(f.first, joint, 2u), bone_texel(f.second, joint, 2u), f.blend);
    return transpose(mat4x4f(r0, r1, r2, vec4f(0.0, 0.0, 0.0, 1.0)));
}
