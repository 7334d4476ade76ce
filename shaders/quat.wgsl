// Quaternion algebra in f32: the twin of src/quat.rs (same names, same branches).
// Storage x, y, z, w. Half-angle exp/log: exp(th u) = (cos th, sin th u), a physical rotation
// by 2 th. No f64 anywhere: naga's f64 transcendentals are invalid SPIR-V on lavapipe.
//
// sin, cos and atan are computed here rather than by the builtins: Vulkan lets builtin sin
// and cos err by 2^-11 absolute and atan by 4096 ulp, far above the 1e-5 rad accuracy bar.

/// Below this squared half-angle exp and log use their Taylor series (same as the Rust twin).
const SERIES_THRESHOLD_SQ: f32 = 1e-4;
const PI: f32 = 3.14159265358979;
const HALF_PI: f32 = 1.57079632679490;
const QUARTER_PI: f32 = 0.785398163397448;
const TAN_EIGHTH_PI: f32 = 0.414213562373095;
// pi/2 split for Cody-Waite reduction: k * HALF_PI_1 is exact for |k| < 2^16.
const HALF_PI_1: f32 = 1.5703125;
const HALF_PI_2: f32 = 4.837512969970703125e-4;
const HALF_PI_3: f32 = 7.54978995489188216e-8;

/// (sin x, cos x) with absolute error ~1e-7 for |x| < 1e4.
fn sin_cos(x: f32) -> vec2f {
    let k = round(x * 0.636619772367581);
    let r = ((x - k * HALF_PI_1) - k * HALF_PI_2) - k * HALF_PI_3;
    let r2 = r * r;
    // Taylor series on [-pi/4, pi/4]: truncation below 1e-11.
    let s = r * (1.0 - r2 / 6.0 * (1.0 - r2 / 20.0 * (1.0 - r2 / 42.0 * (1.0 - r2 / 72.0 * (1.0 - r2 / 110.0)))));
    let c = 1.0 - r2 / 2.0 * (1.0 - r2 / 12.0 * (1.0 - r2 / 30.0 * (1.0 - r2 / 56.0 * (1.0 - r2 / 90.0 * (1.0 - r2 / 132.0)))));
    switch (i32(k) & 3) {
        case 0: { return vec2f(s, c); }
        case 1: { return vec2f(c, -s); }
        case 2: { return vec2f(-s, -c); }
        default: { return vec2f(-c, s); }
    }
}

/// atan(x) for |x| <= 1, via atan(x) = pi/4 + atan((x - 1) / (x + 1)) above tan(pi/8).
fn arctan_unit(x: f32) -> f32 {
    let a = abs(x);
    var z = a;
    var base = 0.0;
    if a > TAN_EIGHTH_PI {
        z = (a - 1.0) / (a + 1.0);
        base = QUARTER_PI;
    }
    let z2 = z * z;
    // Taylor series to z^21 on |z| <= tan(pi/8): truncation below 1e-9.
    var p = 1.0 / 21.0;
    p = 1.0 / 19.0 - z2 * p;
    p = 1.0 / 17.0 - z2 * p;
    p = 1.0 / 15.0 - z2 * p;
    p = 1.0 / 13.0 - z2 * p;
    p = 1.0 / 11.0 - z2 * p;
    p = 1.0 / 9.0 - z2 * p;
    p = 1.0 / 7.0 - z2 * p;
    p = 1.0 / 5.0 - z2 * p;
    p = 1.0 / 3.0 - z2 * p;
    p = 1.0 - z2 * p;
    return sign(x) * (base + z * p);
}

/// Four-quadrant arctangent of y / x.
fn arctan2(y: f32, x: f32) -> f32 {
    let ax = abs(x);
    let ay = abs(y);
    if ax == 0.0 && ay == 0.0 {
        return 0.0;
    }
    var a: f32;
    if ay <= ax {
        a = arctan_unit(ay / ax);
    } else {
        a = HALF_PI - arctan_unit(ax / ay);
    }
    if x < 0.0 {
        a = PI - a;
    }
    return select(a, -a, y < 0.0);
}

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

/// Half-angle exponential.
fn quat_exp(v: vec3f) -> vec4f {
    let th2 = dot(v, v);
    var c: f32;
    var sinc: f32;
    if th2 < SERIES_THRESHOLD_SQ {
        c = 1.0 - th2 * (0.5 - th2 * (1.0 / 24.0 - th2 / 720.0));
        sinc = 1.0 - th2 * (1.0 / 6.0 - th2 * (1.0 / 120.0 - th2 / 5040.0));
    } else {
        let th = sqrt(th2);
        let sc = sin_cos(th);
        c = sc.y;
        sinc = sc.x / th;
    }
    return vec4f(v * sinc, c);
}

/// Half-angle logarithm; (pi, 0, 0) at q = (0, 0, 0, -1).
fn quat_log(q: vec4f) -> vec3f {
    let s2 = dot(q.xyz, q.xyz);
    let w = q.w;
    if w > 0.0 && s2 < SERIES_THRESHOLD_SQ * w * w {
        let x2 = s2 / (w * w);
        let series = 1.0 - x2 * (1.0 / 3.0 - x2 * (1.0 / 5.0 - x2 * (1.0 / 7.0 - x2 / 9.0)));
        return q.xyz * (series / w);
    }
    if s2 == 0.0 {
        return vec3f(PI, 0.0, 0.0);
    }
    let s = sqrt(s2);
    return q.xyz * (arctan2(s, w) / s);
}

/// Unfolded geodesic a exp(h log(a^-1 b)).
fn quat_geodesic(a: vec4f, b: vec4f, h: f32) -> vec4f {
    return quat_mul(a, quat_exp(quat_log(quat_mul(quat_conjugate(a), b)) * h));
}

/// q v q^-1 for unit q.
fn quat_rotate(q: vec4f, v: vec3f) -> vec3f {
    return quat_mul(quat_mul(q, vec4f(v, 0.0)), quat_conjugate(q)).xyz;
}

/// Row-major 3x3 rotation matrix, rows as vectors.
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
