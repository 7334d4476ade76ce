// Cumulative basis functions B~_i with first and second derivatives: the twin of
// src/basis.rs. Each entry is vec3f(value, first derivative, second derivative).

/// Largest Bezier degree the GPU evaluates (private arrays are fixed-size).
const MAX_BEZIER_DEGREE: u32 = 32u;
/// Largest B-spline order.
const MAX_ORDER: u32 = 8u;

fn bernstein_at(row: ptr<function, array<f32, 33>>, m: i32, j: i32) -> f32 {
    if m < 0 || j < 0 || j > m {
        return 0.0;
    }
    return (*row)[j];
}

/// Cumulative Bernstein basis of degree n at u: out[i - 1] for i = 1..=n, derivatives in u.
fn bernstein_cumulative(n: u32, u: f32, out: ptr<function, array<vec3f, 32>>) {
    var row: array<f32, 33>;
    var row1: array<f32, 33>; // degree n - 1
    var row2: array<f32, 33>; // degree n - 2
    row[0] = 1.0;
    let ni = i32(n);
    if ni == 1 {
        row1 = row;
    }
    if ni == 2 {
        row2 = row;
    }
    for (var m = 1; m <= ni; m++) {
        row[m] = u * row[m - 1];
        for (var j = m - 1; j >= 1; j--) {
            row[j] = (1.0 - u) * row[j] + u * row[j - 1];
        }
        row[0] = (1.0 - u) * row[0];
        if m == ni - 1 {
            row1 = row;
        }
        if m == ni - 2 {
            row2 = row;
        }
    }
    let nf = f32(n);
    var tail = 0.0;
    for (var i = ni; i >= 1; i--) {
        tail += row[i];
        let d1 = nf * bernstein_at(&row1, ni - 1, i - 1);
        let d2 = nf * (nf - 1.0) * (bernstein_at(&row2, ni - 2, i - 2) - bernstein_at(&row2, ni - 2, i - 1));
        (*out)[i - 1] = vec3f(tail, d1, d2);
    }
}

fn safe_div(a: f32, b: f32) -> f32 {
    return select(a / b, 0.0, b == 0.0);
}

/// B_{j,m}(t) from the triangle row of order m (row[r] = B_{l-m+1+r, m}); 0 outside it.
fn bspline_at(row: ptr<function, array<f32, 8>>, l: u32, m: u32, j: u32) -> f32 {
    let first = i32(l) - i32(m) + 1;
    let r = i32(j) - first;
    if m == 0u || r < 0 || r >= i32(m) {
        return 0.0;
    }
    return (*row)[r];
}

/// Where the basis takes knot differences from: the fixed-point knot vector at `base`, and
/// the (clamped) time `t`.
struct KnotSource {
    base: u32,
    t: vec2u,
}

/// t - knot j, in seconds.
fn t_minus_knot(src: KnotSource, j: u32) -> f32 {
    return time_sub(src.t, knot(src.base, j));
}

/// knot a - knot b, in seconds.
fn knot_minus_knot(src: KnotSource, a: u32, b: u32) -> f32 {
    return time_sub(knot(src.base, a), knot(src.base, b));
}

/// Cumulative B-spline basis of order k in span l at t (knot differences from `src`):
/// out[r] for i = l-k+2+r, r = 0..k-2, derivatives in time.
fn bspline_cumulative(src: KnotSource, k: u32, l: u32, out: ptr<function, array<vec3f, 7>>) {
    var row: array<f32, 8>;
    var row_k1: array<f32, 8>; // order k - 1
    var row_k2: array<f32, 8>; // order k - 2
    row[0] = 1.0;
    if k == 2u {
        row_k1 = row;
    }
    if k == 3u {
        row_k2 = row;
    }
    for (var m = 1u; m < k; m++) {
        var next: array<f32, 8>;
        for (var r = 0u; r <= m; r++) {
            let j = l - m + r;
            var left = 0.0;
            var right = 0.0;
            if r >= 1u {
                let den = knot_minus_knot(src, j + m, j);
                left = safe_div(t_minus_knot(src, j), den) * row[r - 1u];
            }
            if r < m {
                let den = knot_minus_knot(src, j + m + 1u, j + 1u);
                right = safe_div(-t_minus_knot(src, j + m + 1u), den) * row[r];
            }
            next[r] = left + right;
        }
        row = next;
        if m + 1u == k - 1u {
            row_k1 = row;
        }
        if m + 1u + 2u == k {
            row_k2 = row;
        }
    }
    let kf = f32(k);
    let first = l + 2u - k;
    var tail = 0.0;
    for (var i = l; i >= first; i--) {
        tail += bspline_at(&row, l, k, i);
        let span1 = knot_minus_knot(src, i + k - 1u, i);
        let d1 = (kf - 1.0) * safe_div(bspline_at(&row_k1, l, k - 1u, i), span1);
        var d2 = 0.0;
        if k >= 3u {
            let inner = safe_div(bspline_at(&row_k2, l, k - 2u, i), knot_minus_knot(src, i + k - 2u, i))
                - safe_div(bspline_at(&row_k2, l, k - 2u, i + 1u), knot_minus_knot(src, i + k - 1u, i + 1u));
            d2 = (kf - 1.0) * (kf - 2.0) * safe_div(inner, span1);
        }
        (*out)[i - first] = vec3f(tail, d1, d2);
        if i == 0u {
            break;
        }
    }
}
