// Crowd playback straight from the curves (DESIGN section 11): every instance's joints
// evaluated at that instance's own times, in up to two clips, and blended, into the local rows
// forward kinematics reads (`play_local`); then fk.wgsl and `play_palette` as for given poses,
// all in one submission. The clips stay on the device: rotations as the evaluator's tracks
// (eval.wgsl's records and functions), translations and scales as the Euclidean analogue on
// the same layout, one-key channels and rest values as constants. Per frame, only the
// instances change. Composed after eval.wgsl's files, fk.wgsl and play.wgsl; the CPU twin is
// `quatcurve_eval::euclidean::VectorCurve` with `quatcurve_play::Playback`'s host path.

/// An instance this frame: two (clip, time) pairs and the second's weight. Times are the
/// curves' own (a clip's start plus its time), 32.32 fixed point; a loop's may lie past its
/// end (each track wraps its own).
struct PlayInstance {
    first_clip: u32,
    second_clip: u32,
    weight: f32,
    pad: u32,
    first_time: vec2u,
    second_time: vec2u,
}

/// What a track needs beyond its evaluator record: a loop's domain start and period (period
/// 0: not a loop) in 32.32 fixed point, and a vector loop's per-cycle offset per second.
struct PlayTrack {
    start: vec2u,
    period: vec2u,
    drift: vec4f,
}

@group(0) @binding(20) var<storage, read> play_instances: array<PlayInstance>;
// Per clip, joint and property (rotation, translation, scale): a track index, or
// PLAY_SOURCE_VALUE | an index into play_values.
@group(0) @binding(21) var<storage, read> play_sources: array<u32>;
// Constant values: one-key channels and the rest pose's values.
@group(0) @binding(22) var<storage, read> play_values: array<vec4f>;
@group(0) @binding(23) var<storage, read> play_tracks: array<PlayTrack>;

/// Marks a source that is a constant value, not a track.
const PLAY_SOURCE_VALUE: u32 = 0x80000000u;
/// Sources per joint: rotation, translation, scale.
const PLAY_PROPERTIES: u32 = 3u;

/// -a in 64-bit two's complement.
fn time_negate(a: vec2u) -> vec2u {
    let lo = ~a.x + 1u;
    return vec2u(lo, ~a.y + select(0u, 1u, lo == 0u));
}

/// n * a for a non-negative period a (whole seconds below 2^31).
fn time_scale(n: u32, a: vec2u) -> vec2u {
    let low = mul_wide(n, a.x);
    return vec2u(low.x, low.y + n * a.y);
}

/// Time t on track `index`'s curve: a loop's wrapped into [start, start + period] (kept where
/// it lies inside), as `quatcurve_core::segment::wrap` does, in fixed point.
fn play_track_time(index: u32, t: vec2u) -> vec2u {
    let info = play_tracks[index];
    let end = time_add(info.start, info.period);
    if all(info.period == vec2u(0u)) || (time_le(info.start, t) && time_le(t, end)) {
        return t;
    }
    let cycles = floor(time_sub(t, info.start) / time_sub(info.period, vec2u(0u)));
    let n = u32(abs(cycles));
    var w = select(time_add(t, time_scale(n, info.period)), time_add(t, time_negate(time_scale(n, info.period))),
        cycles >= 0.0);
    // The f32 cycle count may be one off: step into the period.
    for (var k = 0; k < 2; k++) {
        if !time_le(info.start, w) {
            w = time_add(w, info.period);
        } else if !time_le(w, end) {
            w = time_add(w, time_negate(info.period));
        }
    }
    return w;
}

/// The Euclidean analogue of track `tr` at `t` (in its domain): euclidean.rs's `periodic`,
/// the cumulative sums p_0 + sum (p_i - p_{i-1}) B~_i on the rotation kernel's layout.
fn vector_at(tr: GpuTrack, t: vec2u) -> vec3f {
    let p = tr.point_offset;
    let c = tr.coef_offset;
    switch select(tr.curve, ONLY_CURVE, ONLY_CURVE != ANY_CURVE) {
        case CURVE_SLERP: {
            let s = key_segment(tr, t);
            return points[p + s.i].xyz + coefs[c + s.i].xyz * s.u;
        }
        case CURVE_BEZIER: {
            let s = key_segment(tr, t);
            var basis: array<vec3f, 32>;
            bernstein_cumulative(tr.order, s.u, &basis);
            var v = points[p].xyz;
            for (var i = 0u; i < tr.order; i++) {
                v += coefs[c + i].xyz * basis[i].x;
            }
            return v;
        }
        case CURVE_HERMITE: {
            let s = key_segment(tr, t);
            var v = points[p + s.i].xyz;
            for (var j = 0u; j < 3u; j++) {
                v += coefs[c + 3u * s.i + j].xyz * poly_jet(POLY_HERMITE + j, 3u, s.u).x;
            }
            return v;
        }
        case CURVE_SQUAD: {
            let s = key_segment(tr, t);
            let path = mix(points[p + s.i].xyz, points[p + s.i + 1u].xyz, s.u);
            let aux = mix(coefs[c + s.i].xyz, coefs[c + s.i + 1u].xyz, s.u);
            return mix(path, aux, 2.0 * s.u * (1.0 - s.u));
        }
        case CURVE_NAM_KIM: {
            let s = key_segment(tr, t);
            let c1 = points[p + s.i].xyz + coefs[c + 2u * s.i].xyz * s.u;
            let c2 = points[p + s.i + 1u].xyz + coefs[c + 2u * s.i + 1u].xyz * (s.u - 1.0);
            return mix(c1, c2, blend(tr.blend, vec3f(s.u, 0.0, 0.0)).x);
        }
        default: {
            let k = select(tr.order, ONLY_ORDER, ONLY_ORDER != 0u);
            if UNIFORM_KNOTS_ONLY || (tr.flags & FLAG_UNIFORM_KNOTS) != 0u {
                let s = uniform_bspline_span(tr, k, t);
                let base = (k - 2u) * (k - 1u) / 2u;
                var v = points[p + s.i + 1u - k].xyz;
                for (var r = 0u; r + 1u < k; r++) {
                    v += coefs[c + s.i + r + 1u - k].xyz * poly_jet(base + r, k - 1u, s.u).x;
                }
                return v;
            }
            let loc = locate(tr.knot_offset, k - 1u, tr.point_count - 1u, t);
            let l = loc.span;
            var basis: array<vec3f, MAX_FACTORS>;
            bspline_cumulative(knot_window(tr.knot_offset, k, l, loc.t), k, &basis);
            var v = points[p + l + 1u - k].xyz;
            for (var r = 0u; r + 1u < k; r++) {
                v += coefs[c + l + r + 1u - k].xyz * basis[r].x;
            }
            return v;
        }
    }
}

/// Joint `joint`'s local pose in clip `clip` at time `t`.
fn play_joint_pose(clip: u32, t: vec2u, joint: u32) -> JointPose {
    let at = (clip * play_params.joints + joint) * PLAY_PROPERTIES;
    var v: array<vec4f, 3>;
    for (var property = 0u; property < PLAY_PROPERTIES; property++) {
        let source = play_sources[at + property];
        if (source & PLAY_SOURCE_VALUE) != 0u {
            v[property] = play_values[source & ~PLAY_SOURCE_VALUE];
            continue;
        }
        let tr = load_track(source);
        let local = play_track_time(source, t);
        if property == 0u {
            v[0] = evaluate_track(tr, local).q;
        } else {
            let drift = play_tracks[source].drift.xyz * time_sub(t, play_tracks[source].start);
            v[property] = vec4f(vector_at(tr, local) + drift, 0.0);
        }
    }
    return JointPose(v[0], v[1].xyz, v[2].xyz);
}

// One invocation per instance and joint: both poses from the curves, blended into play_local.
@compute @workgroup_size(64)
fn play_curves(@builtin(global_invocation_id) id: vec3u) {
    let i = id.x + id.y * play_params.row;
    let joints = play_params.joints;
    if (i >= play_params.instances * joints) {
        return;
    }
    let instance = play_instances[i / joints];
    let joint = i % joints;
    let first = play_joint_pose(instance.first_clip, instance.first_time, joint);
    var pose = JointPose(normalize(first.rotation), first.translation, first.scale);
    if instance.weight != 0.0 {
        pose = play_mix(first, play_joint_pose(instance.second_clip, instance.second_time, joint), instance.weight);
    }
    play_write_local(i, pose);
}
