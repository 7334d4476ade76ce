// Second-order jets: the twin of src/real.rs (`Jet`) and of the generic quaternion code of
// src/quat.rs evaluated on jets. A scalar jet is vec3f(value, d/dt, d2/dt2); a jet of a
// quaternion or vector carries the same three parts per component. Squad and Nam-Kim are
// differentiated exactly through these (chain rule), as in the reference.

struct JetVec {
    v: vec3f,
    d: vec3f,
    dd: vec3f,
}

struct JetQuat {
    v: vec4f,
    d: vec4f,
    dd: vec4f,
}

fn jet_mul(a: vec3f, b: vec3f) -> vec3f {
    return vec3f(a.x * b.x, a.y * b.x + a.x * b.y, a.z * b.x + 2.0 * a.y * b.y + a.x * b.z);
}

/// Applies a scalar function with value f and derivatives f1, f2 at a.x.
fn jet_chain(a: vec3f, f: f32, f1: f32, f2: f32) -> vec3f {
    return vec3f(f, f1 * a.y, f2 * a.y * a.y + f1 * a.z);
}

fn jet_div(a: vec3f, b: vec3f) -> vec3f {
    let r = 1.0 / b.x;
    return jet_mul(a, jet_chain(b, r, -r * r, 2.0 * r * r * r));
}

fn jet_sqrt(a: vec3f) -> vec3f {
    let s = sqrt(a.x);
    return jet_chain(a, s, 0.5 / s, -0.25 / (s * a.x));
}

fn jet_sin(a: vec3f) -> vec3f {
    let sc = sin_cos(a.x);
    return jet_chain(a, sc.x, sc.y, -sc.x);
}

fn jet_cos(a: vec3f) -> vec3f {
    let sc = sin_cos(a.x);
    return jet_chain(a, sc.y, -sc.x, -sc.y);
}

fn jet_atan2(y: vec3f, x: vec3f) -> vec3f {
    let r2 = x.x * x.x + y.x * y.x;
    let num = x.x * y.y - y.x * x.y;
    let num_d = x.x * y.z - y.x * x.z;
    let r2_d = 2.0 * (x.x * x.y + y.x * y.y);
    return vec3f(arctan2(y.x, x.x), num / r2, num_d / r2 - num * r2_d / (r2 * r2));
}

fn jet_const(x: f32) -> vec3f {
    return vec3f(x, 0.0, 0.0);
}

fn jet_vec_dot(a: JetVec, b: JetVec) -> vec3f {
    return vec3f(dot(a.v, b.v), dot(a.d, b.v) + dot(a.v, b.d), dot(a.dd, b.v) + 2.0 * dot(a.d, b.d) + dot(a.v, b.dd));
}

fn jet_vec_scale(a: JetVec, k: vec3f) -> JetVec {
    return JetVec(a.v * k.x, a.d * k.x + a.v * k.y, a.dd * k.x + 2.0 * a.d * k.y + a.v * k.z);
}

/// A constant vector times a scalar jet.
fn jet_vec_from(v: vec3f, k: vec3f) -> JetVec {
    return JetVec(v * k.x, v * k.y, v * k.z);
}

fn jet_quat_const(q: vec4f) -> JetQuat {
    return JetQuat(q, vec4f(0.0), vec4f(0.0));
}

fn jet_quat_mul(a: JetQuat, b: JetQuat) -> JetQuat {
    return JetQuat(
        quat_mul(a.v, b.v),
        quat_mul(a.d, b.v) + quat_mul(a.v, b.d),
        quat_mul(a.dd, b.v) + 2.0 * quat_mul(a.d, b.d) + quat_mul(a.v, b.dd),
    );
}

fn jet_quat_conjugate(q: JetQuat) -> JetQuat {
    return JetQuat(quat_conjugate(q.v), quat_conjugate(q.d), quat_conjugate(q.dd));
}

fn jet_quat_exp(v: JetVec) -> JetQuat {
    let th2 = jet_vec_dot(v, v);
    var c: vec3f;
    var sinc: vec3f;
    if th2.x < SERIES_THRESHOLD_SQ {
        c = jet_const(1.0) - jet_mul(th2, jet_const(0.5) - jet_mul(th2, jet_const(1.0 / 24.0) - th2 / 720.0));
        sinc = jet_const(1.0) - jet_mul(th2, jet_const(1.0 / 6.0) - jet_mul(th2, jet_const(1.0 / 120.0) - th2 / 5040.0));
    } else {
        let th = jet_sqrt(th2);
        c = jet_cos(th);
        sinc = jet_div(jet_sin(th), th);
    }
    let xyz = jet_vec_scale(v, sinc);
    return JetQuat(vec4f(xyz.v, c.x), vec4f(xyz.d, c.y), vec4f(xyz.dd, c.z));
}

fn jet_quat_log(q: JetQuat) -> JetVec {
    let v = JetVec(q.v.xyz, q.d.xyz, q.dd.xyz);
    let s2 = jet_vec_dot(v, v);
    let w = vec3f(q.v.w, q.d.w, q.dd.w);
    var factor: vec3f;
    if w.x > 0.0 && s2.x < SERIES_THRESHOLD_SQ * w.x * w.x {
        let x2 = jet_div(s2, jet_mul(w, w));
        let series = jet_const(1.0) - jet_mul(x2, jet_const(1.0 / 3.0) - jet_mul(x2, jet_const(1.0 / 5.0) - jet_mul(x2, jet_const(1.0 / 7.0) - x2 / 9.0)));
        factor = jet_div(series, w);
    } else if s2.x == 0.0 {
        return JetVec(vec3f(PI, 0.0, 0.0), vec3f(0.0), vec3f(0.0));
    } else {
        let s = jet_sqrt(s2);
        factor = jet_div(jet_atan2(s, w), s);
    }
    return jet_vec_scale(v, factor);
}

/// Unfolded geodesic a exp(h log(a^-1 b)) on jets.
fn jet_quat_geodesic(a: JetQuat, b: JetQuat, h: vec3f) -> JetQuat {
    let rel = jet_quat_log(jet_quat_mul(jet_quat_conjugate(a), b));
    return jet_quat_mul(a, jet_quat_exp(jet_vec_scale(rel, h)));
}
