// The batch evaluation kernel: the twin of crates/eval/src/reference.rs. One invocation per sample.
// The packed batch is the reference's, converted to f32 (times and knots as 32.32 fixed
// point, see segment.wgsl).
//
// Written for SIMD hosts as well as GPUs. On a software adapter (lavapipe) both sides of every
// branch run, masked, and every storage load is a loop over the lanes; measured there, a
// sample's time went to loads (point, factors, table, knots: half), the exp products (a fifth)
// and the span lookup. So branches that a whole batch never takes are compiled out by the
// override constants below, records and tables are read as whole vec4s, and the polynomial
// table is a uniform, read at constant offsets once the order is fixed.

const WORKGROUP_SIZE: u32 = 64u;

// Curve codes (checked against the Rust side by a test).
const CURVE_SLERP: u32 = 0u;
const CURVE_SQUAD: u32 = 1u;
const CURVE_BEZIER: u32 = 2u;
const CURVE_HERMITE: u32 = 3u;
const CURVE_NAM_KIM: u32 = 4u;
const CURVE_BSPLINE: u32 = 5u;
const CURVE_NORMALIZED_BSPLINE: u32 = 6u;
const ANY_CURVE: u32 = 255u;
/// ONLY_CURVE's code for "either B-spline form, per track" (a fitted clip's rotations).
const BSPLINE_FORMS: u32 = 254u;
const BLEND_QUADRATIC: u32 = 1u;

// GpuTrack.flags bits.
const FLAG_EXPLICIT_TIMES: u32 = 1u;
const FLAG_HAS_LAST: u32 = 2u;
const FLAG_UNIFORM_KNOTS: u32 = 4u;

/// Specialization: evaluate only this curve (ANY_CURVE: switch per track; BSPLINE_FORMS: the
/// two B-spline forms alone, per track).
override ONLY_CURVE: u32 = 255u;
/// Specialization: every track's knots (or key times) are equally spaced (FLAG_UNIFORM_KNOTS),
/// so spans are found by arithmetic alone and the general Cox-de Boor path is left out.
override UNIFORM_KNOTS_ONLY: bool = false;
/// Specialization: every B-spline track has this order (0: read it per track), so the order
/// is a constant to the driver's compiler and the polynomial table is read at constant
/// offsets (uniform loads, not one per lane).
override ONLY_ORDER: u32 = 0u;
/// Whether to compute and write angular velocity and acceleration.
override DERIVATIVES: bool = true;
/// Whether to write the 3x3 rotation matrix.
override MATRIX: bool = false;

struct Params {
    sample_count: u32,
    track_count: u32,
    channels: u32,
    frame_major: u32,
    groups_x: u32,
    pad0: u32,
    pad1: u32,
    pad2: u32,
}

struct GpuTrack {
    curve: u32,
    order: u32,
    blend: u32,
    flags: u32,
    point_offset: u32,
    point_count: u32,
    coef_offset: u32,
    knot_offset: u32,
    knot_count: u32,
    sample_offset: u32,
    sample_count: u32,
    time_offset: u32,
    // Uniform sampling start and exact last sample, 32.32 fixed point (low word first).
    start_lo: u32,
    start_hi: u32,
    last_lo: u32,
    last_hi: u32,
    // The sample step in 32.64 fixed point.
    step_whole: u32,
    step_frac_hi: u32,
    step_frac_lo: u32,
    // Where this entry's samples start in the whole track (a piece of a long track).
    sample_base: u32,
}

@group(0) @binding(0) var<uniform> params: Params;
// Each GpuTrack as TRACK_WORDS vec4u (`load_track`): a few vector loads instead of one per field.
@group(0) @binding(1) var<storage, read> tracks: array<array<vec4u, TRACK_WORDS>>;
@group(0) @binding(2) var<storage, read> points: array<vec4f>;
@group(0) @binding(3) var<storage, read> coefs: array<vec4f>;
@group(0) @binding(4) var<storage, read> knots: array<vec2u>;
@group(0) @binding(5) var<storage, read> times: array<vec2u>;
@group(0) @binding(6) var<storage, read_write> out: array<f32>;
// Span bases as polynomials in u, two vec4f (8 coefficients, lowest first) per function:
// uniform B-splines of orders 2..8 (order k from function (k - 2)(k - 1) / 2), then the cubic
// Hermite basis from POLY_HERMITE. Fitted from the reference's bases on the host.
@group(0) @binding(7) var<uniform> poly: array<vec4f, POLY_ENTRIES>;

const POLY_HERMITE: u32 = 28u;
/// The table's length: two vec4f per function, the uniform B-splines' and Hermite's three.
const POLY_ENTRIES: u32 = 2u * (POLY_HERMITE + 3u);
/// GpuTrack's size in vec4u (checked against the host struct by a test).
const TRACK_WORDS: u32 = 5u;

/// Track i, from its words in the order of GpuTrack's fields.
fn load_track(i: u32) -> GpuTrack {
    let w = tracks[i];
    return GpuTrack(
        w[0].x, w[0].y, w[0].z, w[0].w, w[1].x, w[1].y, w[1].z, w[1].w, w[2].x, w[2].y,
        w[2].z, w[2].w, w[3].x, w[3].y, w[3].z, w[3].w, w[4].x, w[4].y, w[4].z, w[4].w,
    );
}

/// Track i's first sample (GpuTrack.sample_offset), the one field the track search reads.
fn track_sample_offset(i: u32) -> u32 {
    return tracks[i][2].y;
}

/// (p, p', p'') in u of polynomial basis function f, of degree `degree`.
fn poly_jet(f: u32, degree: u32, u: f32) -> vec3f {
    let lo = poly[2u * f];
    var acc = vec3f(0.0);
    if degree > 3u {
        let hi = poly[2u * f + 1u];
        acc = horner_step(acc, u, hi.w);
        acc = horner_step(acc, u, hi.z);
        acc = horner_step(acc, u, hi.y);
        acc = horner_step(acc, u, hi.x);
    }
    acc = horner_step(acc, u, lo.w);
    acc = horner_step(acc, u, lo.z);
    acc = horner_step(acc, u, lo.y);
    acc = horner_step(acc, u, lo.x);
    return vec3f(acc.x, acc.y, 2.0 * acc.z);
}

struct Sample {
    q: vec4f,
    omega: vec3f,
    alpha: vec3f,
}

/// Sample j's time: explicit, the exact domain end, or start + j * step (exact integers).
fn sample_time(tr: GpuTrack, j: u32) -> vec2u {
    if (tr.flags & FLAG_EXPLICIT_TIMES) != 0u {
        return times[tr.time_offset + j];
    }
    if (tr.flags & FLAG_HAS_LAST) != 0u && j + 1u == tr.sample_count {
        return vec2u(tr.last_lo, tr.last_hi);
    }
    return time_step(vec2u(tr.start_lo, tr.start_hi), tr.sample_base + j, tr.step_whole, tr.step_frac_hi, tr.step_frac_lo);
}

/// Running state of a cumulative product q_s prod exp(v_j b_j) with W = q^-1 q' and W'.
struct Product {
    q: vec4f,
    w: vec3f,
    w_dot: vec3f,
}

fn product_start(q: vec4f) -> Product {
    return Product(q, vec3f(0.0), vec3f(0.0));
}

/// One factor exp(v b): W_j = A^-1 W A + v b', W_j' = A^-1 W' A + 2 (A^-1 W A) x (v b') + v b''.
fn product_step(p: Product, v: vec3f, b: vec3f) -> Product {
    let a = quat_exp(v * b.x);
    if !DERIVATIVES {
        return Product(quat_mul(p.q, a), p.w, p.w_dot);
    }
    let a_inv = quat_conjugate(a);
    let carried = quat_rotate(a_inv, p.w);
    let spin = v * b.y;
    let w_dot = quat_rotate(a_inv, p.w_dot) + 2.0 * cross(carried, spin) + v * b.z;
    return Product(quat_mul(p.q, a), carried + spin, w_dot);
}

fn product_sample(p: Product) -> Sample {
    return Sample(p.q, 2.0 * p.w, 2.0 * p.w_dot);
}

fn sample_from_jets(q: JetQuat) -> Sample {
    let inv = quat_conjugate(q.v);
    let w = quat_mul(inv, q.d);
    let w_dot = quat_mul(inv, q.dd) - quat_mul(w, w);
    return Sample(q.v, 2.0 * w.xyz, 2.0 * w_dot.xyz);
}

/// Segment of a piecewise track: index, local parameter u, 1 / segment length.
struct KeySegment {
    i: u32,
    u: f32,
    inv_len: f32,
}

fn key_segment(tr: GpuTrack, t: vec2u) -> KeySegment {
    var loc: Located;
    // The per-track flag is not consulted: on a SIMD host both searches would then run.
    if UNIFORM_KNOTS_ONLY {
        loc = locate_uniform(tr.knot_offset, 0u, tr.knot_count - 2u, t);
    } else {
        loc = locate(tr.knot_offset, 0u, tr.knot_count - 2u, t);
    }
    let k0 = knot(tr.knot_offset, loc.span);
    let len = time_sub(knot(tr.knot_offset, loc.span + 1u), k0);
    return KeySegment(loc.span, time_sub(loc.t, k0) / len, 1.0 / len);
}

fn eval_slerp(tr: GpuTrack, t: vec2u) -> Sample {
    let s = key_segment(tr, t);
    let p = product_start(points[tr.point_offset + s.i]);
    return product_sample(product_step(p, coefs[tr.coef_offset + s.i].xyz, vec3f(s.u, s.inv_len, 0.0)));
}

fn eval_bezier(tr: GpuTrack, t: vec2u) -> Sample {
    let s = key_segment(tr, t);
    var basis: array<vec3f, 32>;
    bernstein_cumulative(tr.order, s.u, &basis);
    let scale = vec3f(1.0, s.inv_len, s.inv_len * s.inv_len);
    var p = product_start(points[tr.point_offset]);
    for (var i = 0u; i < tr.order; i++) {
        p = product_step(p, coefs[tr.coef_offset + i].xyz, basis[i] * scale);
    }
    return product_sample(p);
}

fn eval_hermite(tr: GpuTrack, t: vec2u) -> Sample {
    let s = key_segment(tr, t);
    let scale = vec3f(1.0, s.inv_len, s.inv_len * s.inv_len);
    let c = tr.coef_offset + 3u * s.i;
    let start_sign = coefs[c + 1u].w;
    var p = product_start(points[tr.point_offset + s.i] * start_sign);
    for (var j = 0u; j < 3u; j++) {
        p = product_step(p, coefs[c + j].xyz, poly_jet(POLY_HERMITE + j, 3u, s.u) * scale);
    }
    return product_sample(p);
}

/// The span of a B-spline of order k with equally spaced knots at t: by arithmetic, checked
/// against the exact knots (so long clips keep full precision); its basis is the same
/// polynomials of u on every span (`poly`, from `(k - 2)(k - 1) / 2`).
fn uniform_bspline_span(tr: GpuTrack, k: u32, t: vec2u) -> KeySegment {
    let loc = locate_uniform(tr.knot_offset, k - 1u, tr.point_count - 1u, t);
    let start = knot(tr.knot_offset, loc.span);
    let len = time_sub(knot(tr.knot_offset, loc.span + 1u), start);
    return KeySegment(loc.span, time_sub(loc.t, start) / len, 1.0 / len);
}

/// A B-spline track's span l at t, and its cumulative basis there (B~_(l-k+2..=l) with time
/// derivatives) into `basis`: equally spaced knots by arithmetic and the polynomial table,
/// others by the Cox-de Boor triangle. Both forms of B-spline read it.
fn bspline_span(tr: GpuTrack, k: u32, t: vec2u, basis: ptr<function, array<vec3f, MAX_FACTORS>>) -> u32 {
    if UNIFORM_KNOTS_ONLY || (tr.flags & FLAG_UNIFORM_KNOTS) != 0u {
        let s = uniform_bspline_span(tr, k, t);
        let scale = vec3f(1.0, s.inv_len, s.inv_len * s.inv_len);
        let base = (k - 2u) * (k - 1u) / 2u;
        for (var r = 0u; r + 1u < k; r++) {
            (*basis)[r] = poly_jet(base + r, k - 1u, s.u) * scale;
        }
        return s.i;
    }
    let loc = locate(tr.knot_offset, k - 1u, tr.point_count - 1u, t);
    bspline_cumulative(knot_window(tr.knot_offset, k, loc.span, loc.t), k, basis);
    return loc.span;
}

/// A B-spline of either form: the span and its cumulative basis found once, then the
/// cumulative form's product from the span's first control point, or the normalized form's
/// sum. The form is folded to a constant where the kernel is specialized to one.
fn eval_bspline(tr: GpuTrack, t: vec2u) -> Sample {
    let k = select(tr.order, ONLY_ORDER, ONLY_ORDER != 0u);
    var basis: array<vec3f, MAX_FACTORS>;
    let l = bspline_span(tr, k, t, &basis);
    let form = select(tr.curve, ONLY_CURVE, ONLY_CURVE != ANY_CURVE && ONLY_CURVE != BSPLINE_FORMS);
    if form == CURVE_NORMALIZED_BSPLINE {
        return normalized_sum(tr, k, l, &basis);
    }
    var p = product_start(points[tr.point_offset + l + 1u - k]);
    for (var r = 0u; r + 1u < k; r++) {
        p = product_step(p, coefs[tr.coef_offset + l + r + 1u - k].xyz, basis[r]);
    }
    return product_sample(p);
}

/// normalize(sum B_i c_i) on span l with its time derivatives: the span's cumulative basis
/// (B~, as the cumulative form takes it) differenced into the plain one, B_i = B~_i -
/// B~_(i+1), B~ being 1 below the window and 0 above it; then the sum of control points
/// normalized on jets.
fn normalized_sum(tr: GpuTrack, k: u32, l: u32, basis: ptr<function, array<vec3f, MAX_FACTORS>>) -> Sample {
    var sum = jet_quat_const(vec4f(0.0));
    var above = vec3f(1.0, 0.0, 0.0);
    for (var r = 0u; r < k; r++) {
        var below = vec3f(0.0);
        if r + 1u < k {
            below = (*basis)[r];
        }
        let b = above - below;
        let c = points[tr.point_offset + l + 1u + r - k];
        sum = JetQuat(sum.v + b.x * c, sum.d + b.y * c, sum.dd + b.z * c);
        above = below;
    }
    return sample_from_jets(jet_quat_normalize(sum));
}

fn eval_squad(tr: GpuTrack, t: vec2u) -> Sample {
    let s = key_segment(tr, t);
    let h = vec3f(s.u, s.inv_len, 0.0);
    let q0 = jet_quat_const(points[tr.point_offset + s.i]);
    let q1 = jet_quat_const(points[tr.point_offset + s.i + 1u]);
    let s0 = jet_quat_const(coefs[tr.coef_offset + s.i]);
    let s1 = jet_quat_const(coefs[tr.coef_offset + s.i + 1u]);
    let path = jet_quat_geodesic(q0, q1, h);
    let aux = jet_quat_geodesic(s0, s1, h);
    return sample_from_jets(jet_quat_geodesic(path, aux, 2.0 * (h - jet_mul(h, h))));
}

fn blend(kind: u32, s: vec3f) -> vec3f {
    if kind == BLEND_QUADRATIC {
        if s.x <= 0.5 {
            return 2.0 * jet_mul(s, s);
        }
        let r = s - jet_const(1.0);
        return jet_const(1.0) - 2.0 * jet_mul(r, r);
    }
    return jet_mul(jet_mul(s, s), jet_const(3.0) - 2.0 * s);
}

fn eval_nam_kim(tr: GpuTrack, t: vec2u) -> Sample {
    let seg = key_segment(tr, t);
    let s = vec3f(seg.u, seg.inv_len, 0.0);
    let a = coefs[tr.coef_offset + 2u * seg.i].xyz;
    let b = coefs[tr.coef_offset + 2u * seg.i + 1u].xyz;
    let c1 = jet_quat_mul(jet_quat_const(points[tr.point_offset + seg.i]), jet_quat_exp(jet_vec_from(a, s)));
    let c2 = jet_quat_mul(jet_quat_const(points[tr.point_offset + seg.i + 1u]), jet_quat_exp(jet_vec_from(b, s - jet_const(1.0))));
    return sample_from_jets(jet_quat_geodesic(c1, c2, blend(tr.blend, s)));
}

/// Track `tr` at time `t`, a loop's time already wrapped into its domain (by the host for
/// `evaluate`, by `play_curves` for playback).
fn evaluate_track(tr: GpuTrack, t: vec2u) -> Sample {
    switch select(tr.curve, ONLY_CURVE, ONLY_CURVE != ANY_CURVE) {
        case CURVE_SLERP: { return eval_slerp(tr, t); }
        case CURVE_SQUAD: { return eval_squad(tr, t); }
        case CURVE_BEZIER: { return eval_bezier(tr, t); }
        case CURVE_HERMITE: { return eval_hermite(tr, t); }
        case CURVE_NAM_KIM: { return eval_nam_kim(tr, t); }
        // Either B-spline form.
        default: { return eval_bspline(tr, t); }
    }
}

/// The track of the workgroup's first sample, found once per workgroup.
var<workgroup> group_track: u32;

/// The last track whose first sample is <= g, searching tracks[lo..=hi].
fn find_track(g: u32, lo: u32, hi: u32) -> u32 {
    var a = lo;
    var b = hi;
    while a < b {
        let mid = (a + b + 1u) / 2u;
        if track_sample_offset(mid) <= g {
            a = mid;
        } else {
            b = mid - 1u;
        }
    }
    return a;
}

@compute @workgroup_size(WORKGROUP_SIZE)
fn evaluate(@builtin(workgroup_id) group: vec3u, @builtin(local_invocation_index) local: u32) {
    let first = (group.y * params.groups_x + group.x) * WORKGROUP_SIZE;
    let last_track = params.track_count - 1u;
    // One binary search per workgroup (a per-sample search cost ~75% of the kernel's time on
    // lavapipe); each invocation then steps forward over the few tracks its group spans.
    if local == 0u {
        group_track = find_track(min(first, params.sample_count - 1u), 0u, last_track);
    }
    let g = first + local;
    var a = workgroupUniformLoad(&group_track);
    while a < last_track && track_sample_offset(a + 1u) <= g {
        a += 1u;
    }
    if g >= params.sample_count {
        return;
    }
    let tr = load_track(a);
    let j = g - tr.sample_offset;
    let t = sample_time(tr, j);
    let s = evaluate_track(tr, t);
    let slot = select(g, j * params.track_count + a, params.frame_major != 0u);
    var o = slot * params.channels;
    out[o] = s.q.x;
    out[o + 1u] = s.q.y;
    out[o + 2u] = s.q.z;
    out[o + 3u] = s.q.w;
    o += 4u;
    if DERIVATIVES {
        out[o] = s.omega.x;
        out[o + 1u] = s.omega.y;
        out[o + 2u] = s.omega.z;
        out[o + 3u] = s.alpha.x;
        out[o + 4u] = s.alpha.y;
        out[o + 5u] = s.alpha.z;
        o += 6u;
    }
    if MATRIX {
        let m = quat_to_mat3(s.q);
        for (var r = 0u; r < 3u; r++) {
            out[o + 3u * r] = m[r].x;
            out[o + 3u * r + 1u] = m[r].y;
            out[o + 3u * r + 2u] = m[r].z;
        }
    }
}

/// The write-only roofline (`quatcurve bench`, `roofline_samples_per_s`): the same dispatch,
/// bindings and bytes per sample as `evaluate`, with nothing computed, so the kernel's figures
/// read as a fraction of what the device can write.
@compute @workgroup_size(WORKGROUP_SIZE)
fn roofline(@builtin(workgroup_id) group: vec3u, @builtin(local_invocation_index) local: u32) {
    let g = (group.y * params.groups_x + group.x) * WORKGROUP_SIZE + local;
    if g >= params.sample_count {
        return;
    }
    let o = g * params.channels;
    let v = f32(g);
    for (var c = 0u; c < params.channels; c++) {
        out[o + c] = v;
    }
}
