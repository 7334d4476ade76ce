// Times and segment lookup: the twin of src/segment.rs.
//
// Times and knots are 32.32 fixed point, vec2<u32>(fraction, whole seconds as i32 bits):
// resolution 2.3e-10 s over +-68 years. An f32 time alone is off by up to 6e-5 s at
// t = 1000 s, which over a 27 ms key step of 55 degrees is 2e-3 rad; and double-float tricks
// are not safe, because drivers may reassociate float arithmetic (Mesa does, unless SPIR-V
// marks it NoContraction, which WGSL cannot ask for). Integer arithmetic is exact everywhere.
// Differences of nearby times then convert to f32 with full relative precision.

const TWO_POW_32: f32 = 4294967296.0;
const TWO_POW_MINUS_32: f32 = 2.3283064365386963e-10;

/// a - b in seconds.
fn time_sub(a: vec2u, b: vec2u) -> f32 {
    let borrow = select(0u, 1u, a.x < b.x);
    var lo = a.x - b.x;
    var hi = a.y - b.y - borrow;
    var sign = 1.0;
    if bitcast<i32>(hi) < 0 {
        // Negate the 64-bit two's complement value so small negatives convert precisely.
        lo = ~lo + 1u;
        hi = ~hi + select(0u, 1u, lo == 0u);
        sign = -1.0;
    }
    return sign * (f32(hi) * TWO_POW_32 + f32(lo)) * TWO_POW_MINUS_32;
}

/// a <= b.
fn time_le(a: vec2u, b: vec2u) -> bool {
    let ah = bitcast<i32>(a.y);
    let bh = bitcast<i32>(b.y);
    return ah < bh || (ah == bh && a.x <= b.x);
}

/// The 64-bit product of two u32 as vec2u(low word, high word), by 16-bit halves.
fn mul_wide(a: u32, b: u32) -> vec2u {
    let a0 = a & 0xffffu;
    let a1 = a >> 16u;
    let b0 = b & 0xffffu;
    let b1 = b >> 16u;
    let ll = a0 * b0;
    let lh = a0 * b1;
    let hl = a1 * b0;
    let mid = (ll >> 16u) + (lh & 0xffffu) + (hl & 0xffffu);
    return vec2u((ll & 0xffffu) | (mid << 16u), a1 * b1 + (lh >> 16u) + (hl >> 16u) + (mid >> 16u));
}

/// a + b with carry.
fn time_add(a: vec2u, b: vec2u) -> vec2u {
    let lo = a.x + b.x;
    return vec2u(lo, a.y + b.y + select(0u, 1u, lo < a.x));
}

/// start + j * step, with step in 32.64 fixed point (whole, fraction high, fraction low):
/// truncation below 5e-10 s for any j.
fn time_step(start: vec2u, j: u32, step_whole: u32, step_hi: u32, step_lo: u32) -> vec2u {
    let low = mul_wide(j, step_lo);
    let mid = mul_wide(j, step_hi);
    let frac = time_add(vec2u(mid.x, 0u), vec2u(low.y, 0u));
    let offset = vec2u(frac.x, mid.y + j * step_whole + frac.y);
    return time_add(start, offset);
}

fn knot(base: u32, j: u32) -> vec2u {
    return knots[base + j];
}

struct Located {
    span: u32,
    t: vec2u,
}

/// t clamped to [lo, hi].
fn time_clamp(t: vec2u, lo: vec2u, hi: vec2u) -> vec2u {
    let above = select(t, lo, !time_le(lo, t));
    return select(above, hi, !time_le(above, hi));
}

/// Clamps t to [knot first, knot last + 1] and finds the largest non-empty span in
/// first..=last with knot[span] <= t (the last span is closed).
fn locate(base: u32, first: u32, last: u32, t_in: vec2u) -> Located {
    let lo = knot(base, first);
    let t = time_clamp(t_in, lo, knot(base, last + 1u));
    var a = first;
    var b = last;
    while a < b {
        let mid = (a + b + 1u) / 2u;
        if time_le(knot(base, mid), t) {
            a = mid;
        } else {
            b = mid - 1u;
        }
    }
    while a > first && all(knot(base, a) == knot(base, a + 1u)) {
        a -= 1u;
    }
    return Located(a, t);
}

/// `locate` on equally spaced knots (no empty spans): the span by arithmetic, then stepped to
/// the exact knots' answer, so a time on a knot takes the span `locate` gives it.
fn locate_uniform(base: u32, first: u32, last: u32, t_in: vec2u) -> Located {
    let lo = knot(base, first);
    let t = time_clamp(t_in, lo, knot(base, last + 1u));
    let step = time_sub(knot(base, first + 1u), lo);
    // Bounded as an integer too: a NaN quotient (knots that collapse in fixed point) converts
    // to an indeterminate u32, and the steps below must stay within first..=last.
    var a = first + min(u32(clamp(floor(time_sub(t, lo) / step), 0.0, f32(last - first))), last - first);
    while a > first && !time_le(knot(base, a), t) {
        a -= 1u;
    }
    while a < last && time_le(knot(base, a + 1u), t) {
        a += 1u;
    }
    return Located(a, t);
}
