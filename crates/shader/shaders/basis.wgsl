// Cumulative basis functions B~_i with first and second derivatives: the twin of
// src/basis.rs. Each entry is vec3f(value, first derivative, second derivative).

/// Largest Bezier degree the GPU evaluates (private arrays are fixed-size).
const MAX_BEZIER_DEGREE: u32 = 32u;
/// Largest B-spline order.
const MAX_ORDER: u32 = 8u;
/// Factors of a B-spline span's product (cumulative basis functions): k - 1.
const MAX_FACTORS: u32 = MAX_ORDER - 1u;
/// Knots a span's basis reads (`KnotWindow`).
const KNOT_WINDOW: u32 = 2u * MAX_ORDER;

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
fn bspline_at(row: ptr<function, array<f32, MAX_ORDER>>, l: u32, m: u32, j: u32) -> f32 {
    let first = i32(l) - i32(m) + 1;
    let r = i32(j) - first;
    if m == 0u || r < 0 || r >= i32(m) {
        return 0.0;
    }
    return (*row)[r];
}

/// The knots the basis of span l reads, l - k + 1 ..= l + k, copied once from the fixed-point
/// knot vector at `base` (a storage load per knot, instead of one per knot difference), and
/// the (clamped) time `t`. Knot l sits at index k - 1.
struct KnotWindow {
    knots: array<vec2u, KNOT_WINDOW>,
    t: vec2u,
}

fn knot_window(base: u32, k: u32, l: u32, t: vec2u) -> KnotWindow {
    var w: KnotWindow;
    w.t = t;
    for (var i = 0u; i < 2u * k; i++) {
        w.knots[i] = knot(base, l + 1u + i - k);
    }
    return w;
}

/// t - knot j (window index), in seconds.
fn t_minus_knot(w: ptr<function, KnotWindow>, j: u32) -> f32 {
    return time_sub((*w).t, (*w).knots[j]);
}

/// knot a - knot b (window indices), in seconds.
fn knot_minus_knot(w: ptr<function, KnotWindow>, a: u32, b: u32) -> f32 {
    return time_sub((*w).knots[a], (*w).knots[b]);
}

/// Cumulative B-spline basis of order k on the span of `window` at its time: out[r] for
/// i = l-k+2+r, r = 0..k-2, derivatives in time. Indices below are window indices: the span
/// is l = k - 1. The triangle is de Boor's: the 2k - 2 distances from t to the knots are
/// formed once (exact fixed-point differences, then one rounding each) and every quotient of
/// the recurrence reads them, so each order costs additions and one division per term
/// instead of four fixed-point subtractions. A zero-length interval gives 0, as in the
/// reference: its distances cancel exactly.
fn bspline_cumulative(window: KnotWindow, k: u32, out: ptr<function, array<vec3f, MAX_FACTORS>>) {
    var w = window;
    let l = k - 1u;
    // left[j] = t - knot(l + 1 - j), right[j] = knot(l + j) - t.
    var left: array<f32, MAX_ORDER>;
    var right: array<f32, MAX_ORDER>;
    for (var j = 1u; j < k; j++) {
        left[j] = t_minus_knot(&w, l + 1u - j);
        right[j] = -t_minus_knot(&w, l + j);
    }
    // row[r] = B_{l-m+1+r, m}, the basis of order m (row_k1, row_k2: orders k - 1, k - 2).
    var row: array<f32, MAX_ORDER>;
    var row_k1: array<f32, MAX_ORDER>;
    var row_k2: array<f32, MAX_ORDER>;
    row[0] = 1.0;
    if k == 2u {
        row_k1 = row;
    }
    if k == 3u {
        row_k2 = row;
    }
    for (var m = 1u; m < k; m++) {
        var saved = 0.0;
        for (var r = 0u; r < m; r++) {
            let quotient = safe_div(row[r], right[r + 1u] + left[m - r]);
            row[r] = saved + right[r + 1u] * quotient;
            saved = left[m - r] * quotient;
        }
        row[m] = saved;
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
        let span1 = knot_minus_knot(&w, i + k - 1u, i);
        let d1 = (kf - 1.0) * safe_div(bspline_at(&row_k1, l, k - 1u, i), span1);
        var d2 = 0.0;
        if k >= 3u {
            let inner = safe_div(bspline_at(&row_k2, l, k - 2u, i), knot_minus_knot(&w, i + k - 2u, i))
                - safe_div(bspline_at(&row_k2, l, k - 2u, i + 1u), knot_minus_knot(&w, i + k - 1u, i + 1u));
            d2 = (kf - 1.0) * (kf - 2.0) * safe_div(inner, span1);
        }
        (*out)[i - first] = vec3f(tail, d1, d2);
        if i == 0u {
            break;
        }
    }
}
