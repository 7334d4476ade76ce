// Quaternion algebra in f32: the twin of src/quat.rs (same names, same branches), for plain
// values and for jets (the Rust `Quat<Jet>`). Storage x, y, z, w. Half-angle exp/log:
// exp(th u) = (cos th, sin th u), a physical rotation by 2 th.

/// Hamilton product.
fn quat_mul(a: vec4f, b: vec4f) -> vec4f {
    return vec4f(
        a.w * b.x + a.x * b.w + a.y * b.z - a.z * b.y,
        a.w * b.y - a.x * b.z + a.y * b.w + a.z * b.x,
        a.w * b.z + a.x * b.y - a.y * b.x + a.z * b.w,
        a.w * b.w - a.x * b.x - a.y * b.y - a.z * b.z,
    );
}

fn quat_conjugate(q: vec4f) -> vec4f {
    return vec4f(-q.xyz, q.w);
}

/// Half-angle exponential `(sin|v| v / |v|, cos|v|)`, value only (jets take jet_quat_exp).
/// One sin_cos of |v|: the twin's cos_sqrt and sinc_sqrt, which carry derivatives and branch
/// on |v|^2, cost a quarter of the kernel's time on lavapipe. sin_cos is relative-accurate for
/// small arguments, so sin|v| / |v| keeps full precision down to |v| = 0.
fn quat_exp(v: vec3f) -> vec4f {
    let th = length(v);
    let sc = sin_cos(th);
    return vec4f(v * select(sc.x / th, 1.0, th == 0.0), sc.y);
}

/// Half-angle logarithm; (pi, 0, 0) at q = (0, 0, 0, -1).
fn quat_log(q: vec4f) -> vec3f {
    let s2 = dot(q.xyz, q.xyz);
    let w = q.w;
    if w > 0.0 && s2 < w * w {
        return q.xyz * (atanc_sqrt(s2 / (w * w)).x / w);
    }
    if s2 == 0.0 {
        return vec3f(PI, 0.0, 0.0);
    }
    let s = sqrt(s2);
    return q.xyz * (arctan2(s, w) / s);
}

/// q v q^-1 for unit q.
fn quat_rotate(q: vec4f, v: vec3f) -> vec3f {
    return quat_mul(quat_mul(q, vec4f(v, 0.0)), quat_conjugate(q)).xyz;
}

/// The rows of the rotation matrix R (`R p = q p q^-1`), row r as `m[r]`. WGSL's `mat3x3f`
/// constructor takes columns, so as a WGSL matrix this value is R transposed: read its
/// vectors as rows, never multiply it as R.
fn quat_to_mat3(q: vec4f) -> mat3x3f {
    let x = q.x;
    let y = q.y;
    let z = q.z;
    let w = q.w;
    return mat3x3f(
        vec3f(1.0 - 2.0 * (y * y + z * z), 2.0 * (x * y - w * z), 2.0 * (x * z + w * y)),
        vec3f(2.0 * (x * y + w * z), 1.0 - 2.0 * (x * x + z * z), 2.0 * (y * z - w * x)),
        vec3f(2.0 * (x * z - w * y), 2.0 * (y * z + w * x), 1.0 - 2.0 * (x * x + y * y)),
    );
}

// The same operations on jets (each component a value with two time derivatives).

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
    let c = jet_apply(th2, cos_sqrt(th2.x));
    let xyz = jet_vec_scale(v, jet_apply(th2, sinc_sqrt(th2.x)));
    return JetQuat(vec4f(xyz.v, c.x), vec4f(xyz.d, c.y), vec4f(xyz.dd, c.z));
}

fn jet_quat_log(q: JetQuat) -> JetVec {
    let v = JetVec(q.v.xyz, q.d.xyz, q.dd.xyz);
    let s2 = jet_vec_dot(v, v);
    let w = vec3f(q.v.w, q.d.w, q.dd.w);
    var factor: vec3f;
    if w.x > 0.0 && s2.x < w.x * w.x {
        let x = jet_div(s2, jet_mul(w, w));
        factor = jet_div(jet_apply(x, atanc_sqrt(x.x)), w);
    } else if s2.x == 0.0 {
        return JetVec(vec3f(PI, 0.0, 0.0), vec3f(0.0), vec3f(0.0));
    } else {
        let s = jet_sqrt(s2);
        factor = jet_div(jet_atan2(s, w), s);
    }
    return jet_vec_scale(v, factor);
}

/// q / |q| on jets: a normalized B-spline's sum of control points made a unit rotation.
fn jet_quat_normalize(q: JetQuat) -> JetQuat {
    let length2 = vec3f(dot(q.v, q.v), 2.0 * dot(q.v, q.d), 2.0 * dot(q.d, q.d) + 2.0 * dot(q.v, q.dd));
    let k = jet_div(jet_const(1.0), jet_sqrt(length2));
    return JetQuat(q.v * k.x, q.d * k.x + q.v * k.y, q.dd * k.x + 2.0 * q.d * k.y + q.v * k.z);
}

/// Unfolded geodesic a exp(h log(a^-1 b)) on jets, evaluated from the nearer end (as
/// Quat::geodesic): past the middle, b exp((1 - h) log(b^-1 a)).
fn jet_quat_geodesic(a: JetQuat, b: JetQuat, h: vec3f) -> JetQuat {
    if h.x <= 0.5 {
        let rel = jet_quat_log(jet_quat_mul(jet_quat_conjugate(a), b));
        return jet_quat_mul(a, jet_quat_exp(jet_vec_scale(rel, h)));
    }
    let rel = jet_quat_log(jet_quat_mul(jet_quat_conjugate(b), a));
    return jet_quat_mul(b, jet_quat_exp(jet_vec_scale(rel, jet_const(1.0) - h)));
}
