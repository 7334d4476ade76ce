// Scalars: the twin of src/real.rs. Accurate sin/cos/atan, the smooth functions of x that
// exp and log are written with, and second-order jets vec3f(value, d/dt, d2/dt2).
//
// sin, cos and atan are computed here rather than by the builtins: Vulkan lets builtin sin
// and cos err by 2^-11 absolute and atan by 4096 ulp, far above the 1e-5 rad accuracy bar.
// No f64 anywhere: naga's f64 transcendentals are invalid SPIR-V on lavapipe.

const PI: f32 = 3.14159265358979;
const HALF_PI: f32 = 1.57079632679490;
const QUARTER_PI: f32 = 0.785398163397448;
const TAN_EIGHTH_PI: f32 = 0.414213562373095;
// pi/2 split for Cody-Waite reduction: k * HALF_PI_1 is exact for |k| < 2^16 (HALF_PI_PARTS
// in crates/eval/src/cpu/simd.rs, tied by a test).
const TWO_OVER_PI: f32 = 0.636619772367581;
const HALF_PI_1: f32 = 1.5703125;
const HALF_PI_2: f32 = 4.837512969970703125e-4;
const HALF_PI_3: f32 = 7.54978995489188216e-8;
/// Below this argument the functions of x use their Taylor series (as SERIES_LIMIT in Rust).
const SERIES_LIMIT: f32 = 0.25;

/// (sin x, cos x) with absolute error ~1e-7 for |x| < 1e4.
fn sin_cos(x: f32) -> vec2f {
    let k = round(x * TWO_OVER_PI);
    let r = ((x - k * HALF_PI_1) - k * HALF_PI_2) - k * HALF_PI_3;
    let r2 = r * r;
    // Taylor series on [-pi/4, pi/4]: truncation below 1e-11. Written with the reciprocals of
    // the factorial ratios: a driver need not turn a division by a constant into a product.
    let s = r * (1.0 - r2 * (1.0 / 6.0) * (1.0 - r2 * (1.0 / 20.0) * (1.0 - r2 * (1.0 / 42.0) * (1.0 - r2 * (1.0 / 72.0) * (1.0 - r2 * (1.0 / 110.0))))));
    let c = 1.0 - r2 * 0.5 * (1.0 - r2 * (1.0 / 12.0) * (1.0 - r2 * (1.0 / 30.0) * (1.0 - r2 * (1.0 / 56.0) * (1.0 - r2 * (1.0 / 90.0) * (1.0 - r2 * (1.0 / 132.0))))));
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
    for (var k = 9; k >= 0; k--) {
        p = 1.0 / f32(2 * k + 1) - z2 * p;
    }
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

/// One Horner step for p, p' and p''/2 at once (coefficients highest first).
fn horner_step(acc: vec3f, x: f32, ck: f32) -> vec3f {
    // acc = (p, p', p''/2)
    return vec3f(acc.x * x + ck, acc.y * x + acc.x, acc.z * x + acc.y);
}

/// cos(sqrt x) with its first two derivatives in x. Series: sum (-1)^k x^k / (2k)!, 7 terms
/// (truncation below 1e-12 at x = 1/4; the f64 twin keeps 10).
fn cos_sqrt(x: f32) -> vec3f {
    if x < SERIES_LIMIT {
        var acc = vec3f(0.0);
        acc = horner_step(acc, x, 2.08767569878681e-09);
        acc = horner_step(acc, x, -2.755731922e-07);
        acc = horner_step(acc, x, 2.48015873e-05);
        acc = horner_step(acc, x, -0.001388888889);
        acc = horner_step(acc, x, 0.04166666667);
        acc = horner_step(acc, x, -0.5);
        acc = horner_step(acc, x, 1.0);
        return vec3f(acc.x, acc.y, 2.0 * acc.z);
    }
    let s = sinc_sqrt(x);
    return vec3f(sin_cos(sqrt(x)).y, -0.5 * s.x, -0.5 * s.y);
}

/// sin(sqrt x) / sqrt x with its first two derivatives: S' = (C - S) / 2x, S'' = (C' - 3 S') / 2x.
/// Series: sum (-1)^k x^k / (2k+1)!, 7 terms.
fn sinc_sqrt(x: f32) -> vec3f {
    if x < SERIES_LIMIT {
        var acc = vec3f(0.0);
        acc = horner_step(acc, x, 1.605904384e-10);
        acc = horner_step(acc, x, -2.505210839e-08);
        acc = horner_step(acc, x, 2.755731922e-06);
        acc = horner_step(acc, x, -0.0001984126984);
        acc = horner_step(acc, x, 0.008333333333);
        acc = horner_step(acc, x, -0.1666666667);
        acc = horner_step(acc, x, 1.0);
        return vec3f(acc.x, acc.y, 2.0 * acc.z);
    }
    let r = sqrt(x);
    let sc = sin_cos(r);
    let s = sc.x / r;
    let d1 = (sc.y - s) / (2.0 * x);
    let d2 = (-0.5 * s - 3.0 * d1) / (2.0 * x);
    return vec3f(s, d1, d2);
}

/// atan(sqrt x) / sqrt x with its first two derivatives: A' = (B - A) / 2x,
/// A'' = (-B^2 - 3 A') / 2x with B = 1 / (1 + x). Series: sum (-1)^k x^k / (2k+1), 13 terms
/// (truncation below 3e-9 at x = 1/4; the f64 twin keeps 30).
fn atanc_sqrt(x: f32) -> vec3f {
    if x < SERIES_LIMIT {
        var acc = vec3f(0.0);
        acc = horner_step(acc, x, 0.04);
        acc = horner_step(acc, x, -0.04347826087);
        acc = horner_step(acc, x, 0.04761904762);
        acc = horner_step(acc, x, -0.05263157895);
        acc = horner_step(acc, x, 0.05882352941);
        acc = horner_step(acc, x, -0.06666666667);
        acc = horner_step(acc, x, 0.07692307692);
        acc = horner_step(acc, x, -0.09090909091);
        acc = horner_step(acc, x, 0.1111111111);
        acc = horner_step(acc, x, -0.1428571429);
        acc = horner_step(acc, x, 0.2);
        acc = horner_step(acc, x, -0.3333333333);
        acc = horner_step(acc, x, 1.0);
        return vec3f(acc.x, acc.y, 2.0 * acc.z);
    }
    let r = sqrt(x);
    let a = arctan2(r, 1.0) / r;
    let b = 1.0 / (1.0 + x);
    let d1 = (b - a) / (2.0 * x);
    let d2 = (-b * b - 3.0 * d1) / (2.0 * x);
    return vec3f(a, d1, d2);
}

// Second-order jets vec3f(value, d/dt, d2/dt2): the twin of `Jet`.

fn jet_mul(a: vec3f, b: vec3f) -> vec3f {
    return vec3f(a.x * b.x, a.y * b.x + a.x * b.y, a.z * b.x + 2.0 * a.y * b.y + a.x * b.z);
}

/// Applies a scalar function given f = (value, f', f'') at a.x (the chain rule).
fn jet_apply(a: vec3f, f: vec3f) -> vec3f {
    return vec3f(f.x, f.y * a.y, f.z * a.y * a.y + f.y * a.z);
}

fn jet_div(a: vec3f, b: vec3f) -> vec3f {
    let r = 1.0 / b.x;
    return jet_mul(a, jet_apply(b, vec3f(r, -r * r, 2.0 * r * r * r)));
}

fn jet_sqrt(a: vec3f) -> vec3f {
    let s = sqrt(a.x);
    return jet_apply(a, vec3f(s, 0.5 / s, -0.25 / (s * a.x)));
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
