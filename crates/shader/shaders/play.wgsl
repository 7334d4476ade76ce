// Crowd playback's pose blend and skin palettes (DESIGN section 11), recorded in one
// submission with fk.wgsl's forward kinematics between them: each instance's two local poses
// blended (`play_blend`), forward kinematics over the blended rows (the instances as its
// frames), then every skin joint's model matrix times its inverse bind (`play_palette`).
// Composed after real.wgsl, quat.wgsl and fk.wgsl; the CPU twins are
// `quatcurve_eval::skeleton::blend_poses` and `skeleton::palettes` (f64).

struct PlayParams {
    instances: u32,
    // Joints of the animation, per pose.
    joints: u32,
    // The skin's joints: matrices per palette.
    skin_joints: u32,
    // Invocations per row of the dispatch grid (x groups times the workgroup size).
    row: u32,
}

// Two local poses per instance, [instances, 2, joints, 10]: rotation x, y, z, w, translation,
// scale.
@group(0) @binding(13) var<storage, read> play_poses: array<f32>;
// Per instance, the second pose's weight (0: the first pose alone).
@group(0) @binding(14) var<storage, read> play_weights: array<f32>;
// The blended local rows, [instances, joints, 10]: forward kinematics' input.
@group(0) @binding(15) var<storage, read_write> play_local: array<f32>;
// The skin's joints (indices into the animation's), in the skin's order.
@group(0) @binding(16) var<storage, read> play_skin_joints: array<u32>;
// Per skin joint, its inverse bind matrix, 3x4 row-major.
@group(0) @binding(17) var<storage, read> play_inverse_binds: array<f32>;
// The palettes, [instances, skin joints, 12]: 3x4 row-major skin matrices.
@group(0) @binding(18) var<storage, read_write> play_palettes: array<f32>;
@group(0) @binding(19) var<uniform> play_params: PlayParams;

const PLAY_POSE_CHANNELS: u32 = 10u;
const PLAY_MATRIX_CHANNELS: u32 = 12u;

/// One joint's local pose.
struct JointPose {
    rotation: vec4f,
    translation: vec3f,
    scale: vec3f,
}

/// The pose at `at` in `play_poses`.
fn play_read_pose(at: u32) -> JointPose {
    return JointPose(
        vec4f(play_poses[at], play_poses[at + 1u], play_poses[at + 2u], play_poses[at + 3u]),
        vec3f(play_poses[at + 4u], play_poses[at + 5u], play_poses[at + 6u]),
        vec3f(play_poses[at + 7u], play_poses[at + 8u], play_poses[at + 9u]),
    );
}

/// `a` blended towards `b` by `w`: the rotations by slerp on the shorter arc,
/// a * exp(w log(a^-1 b)) with b turned to a's side; translation and scale by lerp.
fn play_mix(a: JointPose, b: JointPose, w: f32) -> JointPose {
    let qa = normalize(a.rotation);
    let qb = normalize(b.rotation);
    let turned = select(qb, -qb, dot(qa, qb) < 0.0);
    let q = quat_mul(qa, quat_exp(quat_log(quat_mul(quat_conjugate(qa), turned)) * w));
    return JointPose(q, mix(a.translation, b.translation, w), mix(a.scale, b.scale, w));
}

/// Row `i` of `play_local` (instance-major, then joint).
fn play_write_local(i: u32, pose: JointPose) {
    let out = i * PLAY_POSE_CHANNELS;
    let values = array<f32, 10>(
        pose.rotation.x, pose.rotation.y, pose.rotation.z, pose.rotation.w,
        pose.translation.x, pose.translation.y, pose.translation.z,
        pose.scale.x, pose.scale.y, pose.scale.z,
    );
    for (var c = 0u; c < PLAY_POSE_CHANNELS; c++) {
        play_local[out + c] = values[c];
    }
}

// One invocation per instance and joint: the two poses given in `play_poses`, blended.
@compute @workgroup_size(64)
fn play_blend(@builtin(global_invocation_id) id: vec3u) {
    let i = id.x + id.y * play_params.row;
    let joints = play_params.joints;
    if (i >= play_params.instances * joints) {
        return;
    }
    let instance = i / joints;
    let joint = i % joints;
    let a = ((2u * instance) * joints + joint) * PLAY_POSE_CHANNELS;
    let b = ((2u * instance + 1u) * joints + joint) * PLAY_POSE_CHANNELS;
    play_write_local(i, play_mix(play_read_pose(a), play_read_pose(b), play_weights[instance]));
}

// One invocation per instance and skin joint: model(joint) * inverseBind, both 3x4 with an
// implicit last row 0 0 0 1.
@compute @workgroup_size(64)
fn play_palette(@builtin(global_invocation_id) id: vec3u) {
    let i = id.x + id.y * play_params.row;
    let skin_joints = play_params.skin_joints;
    if (i >= play_params.instances * skin_joints) {
        return;
    }
    let instance = i / skin_joints;
    let k = i % skin_joints;
    let m = (instance * play_params.joints + play_skin_joints[k]) * PLAY_MATRIX_CHANNELS;
    let ib = k * PLAY_MATRIX_CHANNELS;
    let out = i * PLAY_MATRIX_CHANNELS;
    for (var r = 0u; r < 3u; r++) {
        for (var c = 0u; c < 4u; c++) {
            var v = select(0.0, fk_model[m + 4u * r + 3u], c == 3u);
            for (var j = 0u; j < 3u; j++) {
                v += fk_model[m + 4u * r + j] * play_inverse_binds[ib + 4u * j + c];
            }
            play_palettes[out + 4u * r + c] = v;
        }
    }
}
