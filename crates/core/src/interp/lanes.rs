//! Four tracks of one shape (key count and loop mode) solved at once, one per `f64` lane
//! ([`Lanes64`]): the first guess, Newton iteration and sign chain of [`super::solve_in`] with
//! every branch taken per lane, each function here the lane twin of the one named in its doc.
//! A lane that has converged (or failed) stops changing while the others go on; each lane's
//! line search halves its own step; nothing a lane computes reads another lane.
//!
//! Built twice, like the CPU evaluator's kernels: inside a `#[target_feature(enable =
//! "avx2,fma")]` function on CPUs that have AVX2 ([`Isa::Avx2`]), else at the build's
//! baseline. Both give the same bits ([`super::f64x4`]).

#[cfg(target_arch = "x86_64")]
use super::f64x4::Avx2;
use super::f64x4::{relative_log, Lanes64, Portable, Select, M4, Q4, V4};
use super::tridiagonal::{solve, Scratch};
use super::{
    keys_as_points, Condition, NoConvergence, Solved, System, END_TARGET, END_TOLERANCE, KEY_TARGET, KEY_TOLERANCE,
    MAX_ITERATIONS, MAX_MOVE,
};
use crate::isa::Isa;
use crate::quat::{QuatF64, Vec3F64};
use std::cell::RefCell;
use std::f64::consts::PI;
use std::rc::Rc;

/// Tracks solved together.
pub(super) const LANES: usize = 4;

/// A row's condition with each lane's basis constants (the lanes' key times may differ).
#[derive(Clone, Copy, Debug)]
enum Row<L> {
    Key { a: L, b: L, key: usize },
    End { c1: L, c2: L, k: L },
}

/// [`super::KeyPoint`] per lane.
#[derive(Clone, Copy, Debug)]
struct KeyPoint<L> {
    q: Q4<L>,
    e2: Q4<L>,
    c: Q4<L>,
    jr: [[L; 2]; 2],
}

impl<L: Lanes64> KeyPoint<L> {
    #[inline(always)]
    fn none() -> Self {
        let one = Q4::identity();
        Self { q: one, e2: one, c: one, jr: [[L::zero(); 2]; 2] }
    }

    #[inline(always)]
    fn new(p0: Q4<L>, w: [V4<L>; 2], a: L, b: L) -> Self {
        let (e1, j1) = exp_jr(w[0] * a);
        let (e2, j2) = exp_jr(w[1] * b);
        let c = e1 * e2;
        Self { q: p0 * c, e2, c, jr: [j1, j2] }
    }
}

impl<L: Lanes64> Select<L> for KeyPoint<L> {
    #[inline(always)]
    fn select(m: L, t: Self, f: Self) -> Self {
        let (a, b) = (t.jr, f.jr);
        let jr = [
            [m.blend(a[0][0], b[0][0]), m.blend(a[0][1], b[0][1])],
            [m.blend(a[1][0], b[1][0]), m.blend(a[1][1], b[1][1])],
        ];
        Self { q: m.pick(t.q, f.q), e2: m.pick(t.e2, f.e2), c: m.pick(t.c, f.c), jr }
    }
}

/// [`super::jacobian::exp_jr`] per lane: `exp(v)` and its Jacobian's coefficients from one
/// `sin_cos`, with the same series below `|v| = 1e-4`.
#[inline(always)]
fn exp_jr<L: Lanes64>(v: V4<L>) -> (Q4<L>, [L; 2]) {
    let h2 = v.length_squared();
    let h = h2.sqrt();
    let (s, c) = h.sin_cos();
    let small = h.lt(L::splat(1e-4));
    let zero = h.le(L::zero());
    // One division: sin^2 h / h^2 = sinc^2 and (2h - sin 2h) / 2h^3 = (1 - sinc cos h) / h^2.
    let inverse = L::splat(1.0) / zero.pick(L::splat(1.0), h);
    let sinc = zero.pick(L::splat(1.0), s * inverse);
    let series = [L::splat(1.0) - h2 * (1.0 / 3.0), L::splat(2.0 / 3.0) - h2 * (2.0 / 15.0)];
    let closed = [sinc * sinc, (L::splat(1.0) - sinc * c) * inverse * inverse];
    let jr = [small.pick(series[0], closed[0]), small.pick(series[1], closed[1])];
    (Q4 { x: v.x * sinc, y: v.y * sinc, z: v.z * sinc, w: c }, jr)
}

/// [`super::jacobian::step_log_coef`] per lane.
#[inline(always)]
fn step_log_coef<L: Lanes64>(v: V4<L>, rel: Q4<L>) -> L {
    let h2 = v.length_squared();
    let along = rel.x * v.x + rel.y * v.y + rel.z * v.z;
    let series = L::splat(1.0 / 3.0) + h2 * (1.0 / 45.0);
    h2.lt(L::splat(1e-6)).pick(series, (L::splat(1.0) - h2 * rel.w / along) / h2)
}

/// [`super::jacobian::log_coef`] per lane.
#[inline(always)]
fn log_coef<L: Lanes64>(v: V4<L>) -> L {
    let h = v.length();
    let (s, c) = h.sin_cos();
    let h2 = h * h;
    let series = L::splat(1.0 / 3.0) + h2 * (1.0 / 45.0);
    h.lt(L::splat(1e-4)).blend(series, (L::splat(1.0) - h * c / s) / h2)
}

/// [`super::jacobian::AxisPoly`] per lane.
#[derive(Clone, Copy)]
struct AxisPoly<L> {
    v: V4<L>,
    c: [L; 3],
}

impl<L: Lanes64> AxisPoly<L> {
    #[inline(always)]
    fn exp_jacobian(v: V4<L>, s: L, c: [L; 2]) -> Self {
        Self { v, c: [s, -(s * s * c[0]), s * s * s * c[1]] }
    }

    #[inline(always)]
    fn log_jacobians(v: V4<L>, c: L) -> (Self, Self) {
        let one = L::splat(1.0);
        (Self { v, c: [one, one, c] }, Self { v, c: [one, -one, c] })
    }

    #[inline(always)]
    fn times(self, o: Self) -> Self {
        let ([a0, a1, a2], [b0, b1, b2]) = (self.c, o.c);
        let h2 = self.v.length_squared();
        let c = [a0 * b0, a0 * b1 + a1 * b0 - h2 * (a1 * b2 + a2 * b1), a0 * b2 + a1 * b1 + a2 * b0 - h2 * a2 * b2];
        Self { v: self.v, c }
    }

    #[inline(always)]
    fn apply(self, x: V4<L>) -> V4<L> {
        let vx = self.v.cross(x);
        x * self.c[0] + vx * self.c[1] + self.v.cross(vx) * self.c[2]
    }

    #[inline(always)]
    fn matrix(self) -> M4<L> {
        let ([c0, c1, c2], v) = (self.c, self.v);
        let diagonal = c0 - c2 * v.length_squared();
        let z = L::zero();
        let units =
            [V4 { x: L::splat(1.0), y: z, z }, V4 { x: z, y: L::splat(1.0), z }, V4 { x: z, y: z, z: L::splat(1.0) }];
        let along = [v.x, v.y, v.z];
        // No closures here or below in the iteration: one not inlined into the AVX2 entry
        // point turns each AVX instruction in it into a call.
        let [ex, ey, ez] = units;
        M4 {
            cols: [
                v * (c2 * along[0]) + v.cross(ex) * c1 + ex * diagonal,
                v * (c2 * along[1]) + v.cross(ey) * c1 + ey * diagonal,
                v * (c2 * along[2]) + v.cross(ez) * c1 + ez * diagonal,
            ],
        }
    }
}

/// [`super::residual`] per lane.
#[inline(always)]
fn residual<L: Lanes64>(row: Row<L>, p: [Q4<L>; 3], w: [V4<L>; 2], keys: &[Q4<L>]) -> (V4<L>, KeyPoint<L>) {
    match row {
        Row::Key { a, b, key } => {
            let point = KeyPoint::new(p[0], w, a, b);
            (relative_log(keys[key], point.q), point)
        }
        Row::End { c1, c2, k } => (w[0] * c1 + w[1] * c2 + w[0].cross(w[1]) * k, KeyPoint::none()),
    }
}

/// [`super::row_jacobian`] per lane.
#[inline(always)]
fn row_jacobian<L: Lanes64>(row: Row<L>, point: &KeyPoint<L>, w: [V4<L>; 2], jc: [L; 2]) -> [M4<L>; 3] {
    let (v1, v2) = (w[0], w[1]);
    let [(r1, l1), (r2, l2)] = [AxisPoly::log_jacobians(v1, jc[0]), AxisPoly::log_jacobians(v2, jc[1])];
    match row {
        Row::Key { a, b, .. } => {
            let KeyPoint { e2, c, jr: [j1, j2], .. } = *point;
            let (k1, k2) = (AxisPoly::exp_jacobian(v1, a, j1), AxisPoly::exp_jacobian(v2, b, j2));
            let e = M4::from_quat(e2.conjugate());
            [
                M4::from_quat(c.conjugate()) - e * k1.times(l1).matrix(),
                e * k1.times(r1).matrix() - k2.times(l2).matrix(),
                k2.times(r2).matrix(),
            ]
        }
        Row::End { c1, c2, k } => {
            let f1 = M4::diagonal(c1) - M4::skew(v2) * k;
            let f2 = M4::diagonal(c2) + M4::skew(v1) * k;
            let [r1, l1, r2, l2] = [r1.matrix(), l1.matrix(), r2.matrix(), l2.matrix()];
            [-(f1 * l1), f1 * r1 - f2 * l2, f2 * r2]
        }
    }
}

/// [`super::Health`] per lane (indices as `f64`, so they select with the values).
#[derive(Clone, Copy)]
struct Health<L> {
    key: L,
    key_at: L,
    end: L,
    end_at: L,
    norm: L,
}

impl<L: Lanes64> Health<L> {
    #[inline(always)]
    fn converged(&self) -> L {
        self.key.le(L::splat(KEY_TARGET)) & self.end.le(L::splat(END_TARGET))
    }
}

impl<L: Lanes64> Select<L> for Health<L> {
    #[inline(always)]
    fn select(m: L, t: Self, f: Self) -> Self {
        Self {
            key: m.pick(t.key, f.key),
            key_at: m.pick(t.key_at, f.key_at),
            end: m.pick(t.end, f.end),
            end_at: m.pick(t.end_at, f.end_at),
            norm: m.pick(t.norm, f.norm),
        }
    }
}

/// [`super::State`] per lane.
struct State<L> {
    points: Vec<Q4<L>>,
    steps: Vec<V4<L>>,
    step_coefs: Vec<L>,
    key_points: Vec<KeyPoint<L>>,
    blocks: Vec<[M4<L>; 3]>,
    rhs: Vec<V4<L>>,
}

impl<L: Lanes64> Default for State<L> {
    fn default() -> Self {
        Self {
            points: Vec::new(),
            steps: Vec::new(),
            step_coefs: Vec::new(),
            key_points: Vec::new(),
            blocks: Vec::new(),
            rhs: Vec::new(),
        }
    }
}

impl<L: Lanes64> State<L> {
    fn resize(&mut self, count: usize, unknowns: usize) {
        self.points.resize(count, Q4::identity());
        self.steps.resize(count, V4::zero());
        self.step_coefs.resize(count, L::zero());
        self.key_points.resize(unknowns, KeyPoint::none());
        self.blocks.resize(unknowns, [M4::zero(); 3]);
        self.rhs.resize(unknowns, V4::zero());
    }

    /// Takes `o`'s points and steps in the lanes of `m`.
    #[inline(always)]
    fn keep(&mut self, m: L, o: &Self) {
        if !m.any() {
            return;
        }
        blend(m, &mut self.points, &o.points);
        blend(m, &mut self.steps, &o.steps);
    }

    /// Takes `o`'s points, steps and row values in the lanes of `m`.
    #[inline(always)]
    fn take(&mut self, m: L, o: &Self) {
        blend(m, &mut self.points, &o.points);
        blend(m, &mut self.steps, &o.steps);
        blend(m, &mut self.rhs, &o.rhs);
        blend(m, &mut self.key_points, &o.key_points);
    }
}

/// `to` takes `from`'s values in the lanes of `m`.
#[inline(always)]
fn blend<L: Lanes64, T: Select<L>>(m: L, to: &mut [T], from: &[T]) {
    for (t, f) in to.iter_mut().zip(from) {
        *t = m.pick(*f, *t);
    }
}

/// The shape the lanes share, with each lane's rows.
struct Shape<'a, L> {
    system: &'a System,
    rows: &'a [Row<L>],
    keys: &'a [Q4<L>],
}

/// [`super::assess`] per lane.
#[inline(always)]
fn assess<L: Lanes64>(shape: &Shape<L>, state: &mut State<L>) -> Health<L> {
    let zero = L::zero();
    let mut health = Health { key: zero, key_at: zero, end: zero, end_at: zero, norm: zero };
    let last = L::splat((shape.keys.len() - 1) as f64);
    for (r, &row) in shape.rows.iter().enumerate() {
        let [i, j, k] = shape.system.triple(r);
        let (res, point) = residual(
            row,
            [state.points[i], state.points[j], state.points[k]],
            [state.steps[j], state.steps[k]],
            shape.keys,
        );
        state.key_points[r] = point;
        let size = res.length();
        match row {
            Row::Key { key, .. } => {
                let angle = size * 2.0;
                let worse = angle.gt(health.key);
                health.key = worse.pick(angle, health.key);
                health.key_at = worse.pick(L::splat(key as f64), health.key_at);
            }
            Row::End { .. } => {
                let worse = size.gt(health.end);
                health.end = worse.pick(size, health.end);
                health.end_at = worse.pick(if r == 0 { zero } else { last }, health.end_at);
            }
        }
        // A NaN anywhere must not pass for convergence.
        let bad = !size.is_finite();
        health.key = bad.pick(L::splat(f64::INFINITY), health.key);
        health.key_at = bad.pick(L::splat(r as f64), health.key_at);
        health.norm = health.norm + size * size;
        state.rhs[r] = -res;
    }
    health
}

/// [`super::linearize`] per lane.
#[inline(always)]
fn linearize<L: Lanes64>(shape: &Shape<L>, state: &mut State<L>) {
    let State { points, steps, step_coefs, key_points, blocks, .. } = state;
    let count = points.len();
    for (j, (coef, w)) in step_coefs.iter_mut().zip(steps.iter()).enumerate() {
        *coef = step_log_coef(*w, points[(j + count - 1) % count].conjugate() * points[j]);
    }
    for (r, &row) in shape.rows.iter().enumerate() {
        let [_, j, k] = shape.system.triple(r);
        blocks[r] = row_jacobian(row, &key_points[r], [steps[j], steps[k]], [step_coefs[j], step_coefs[k]]);
    }
}

/// [`super::nearest_log`] per lane.
#[inline(always)]
fn nearest_log<L: Lanes64>(r: Q4<L>, predicted: V4<L>) -> V4<L> {
    let short = r.aligned_with(Q4::identity()).log();
    let th = short.length();
    let has_angle = th.gt(L::zero());
    let one = L::splat(1.0);
    let mut axis = short * (one / has_angle.pick(th, one));
    let mut keep = has_angle;
    if !has_angle.all() {
        // The identity in some lane: whole turns about the prediction's axis there.
        let length = predicted.length();
        let has_prediction = length.gt(L::zero());
        axis = has_angle.pick(axis, predicted * (one / has_prediction.pick(length, one)));
        keep = has_angle | has_prediction;
    }
    let m = ((predicted.dot(axis) - th) * (1.0 / PI)).round();
    keep.pick(axis * (th + m * PI), short)
}

/// The thread's arrays for lane solves, kept across solves ([`super::Workspace`]).
struct Workspace<L: Lanes64> {
    state: State<L>,
    trial: State<L>,
    /// Each lane's points and steps once it stops.
    done: State<L>,
    scratch: Scratch<M4<L>>,
    delta: Vec<V4<L>>,
    step_change: Vec<V4<L>>,
    rows: Vec<Row<L>>,
    keys: Vec<Q4<L>>,
}

impl<L: Lanes64> Default for Workspace<L> {
    fn default() -> Self {
        Self {
            state: State::default(),
            trial: State::default(),
            done: State::default(),
            scratch: Scratch::default(),
            delta: Vec::new(),
            step_change: Vec::new(),
            rows: Vec::new(),
            keys: Vec::new(),
        }
    }
}

/// How each lane's iteration ended.
struct Outcome<L> {
    health: Health<L>,
    iterations: [usize; LANES],
    /// Lanes whose linear system was singular (they stopped there, as the scalar solve).
    singular: L,
}

/// [`super::first_guess`] per lane, into `state`'s points and steps (`moves` is scratch).
#[inline(always)]
fn first_guess<L: Lanes64>(shape: &Shape<L>, state: &mut State<L>, moves: &mut Vec<V4<L>>) {
    let (system, keys) = (shape.system, shape.keys);
    let n = keys.len() - 1;
    let points = &mut state.points;
    keys_as_points(keys, system.periodic, points);
    let count = points.len();
    let prev = |j: usize| (j + count - 1) % count;
    let steps = &mut state.steps;
    steps.clear();
    for j in 0..count {
        steps.push(relative_log(points[prev(j)], points[j]));
    }
    moves.clear();
    moves.resize(count, V4::zero());
    for (r, &row) in shape.rows.iter().enumerate() {
        if let Row::Key { a, b, .. } = row {
            let j = system.triple(r)[1];
            moves[j] = steps[j] * (L::splat(1.0) - a) - steps[(j + 1) % count] * b;
        }
    }
    if !system.periodic {
        for (row, j) in [(0, 1), (n, n + 1)] {
            if let Row::End { c1, c2, .. } = shape.rows[row] {
                let s = -c2 / (c1 - c2);
                let s = s.is_finite().blend(s.min(L::splat(1.0)).max(L::zero()), L::zero());
                let chord = steps[j] + steps[j + 1] + moves[j + 1] - moves[j - 1];
                moves[j] = chord * s - steps[j] + moves[j - 1];
            }
        }
    }
    for (p, m) in points.iter_mut().zip(moves.iter()) {
        *p = *p * Q4::exp(*m);
    }
    for j in 0..count {
        let (r, l) = AxisPoly::log_jacobians(steps[j], log_coef(steps[j]));
        let predicted = steps[j] + r.apply(moves[j]) - l.apply(moves[prev(j)]);
        steps[j] = nearest_log(points[prev(j)].conjugate() * points[j], predicted);
    }
}

/// [`super::finish`]'s order and sign chain per lane: one period of points (looping) and
/// the step into each, signs following the product chain; into `out`.
#[inline(always)]
fn chain<L: Lanes64>(state: &State<L>, n: usize, periodic: bool, out: &mut State<L>) {
    let (points, steps) = (&state.points, &state.steps);
    let count = if periodic { n + 3 } else { points.len() };
    let at = |j: usize| if periodic { (j + n - 1) % n } else { j };
    out.points.clear();
    out.steps.clear();
    out.points.push(points[at(0)]);
    for j in 1..count {
        let step = steps[at(j)];
        let chained = out.points[j - 1] * Q4::exp(step);
        out.points.push(points[at(j)].aligned_with(chained));
        out.steps.push(step);
    }
}

/// Point `p`'s move: its unknown's share of `delta` times `scale` (fixed points stay).
#[inline(always)]
fn moved<L: Lanes64>(system: &System, delta: &[V4<L>], p: usize, scale: L) -> V4<L> {
    match system.unknown(p) {
        Some(u) => delta[u] * scale,
        None => V4::zero(),
    }
}

/// The Newton iteration over the lanes of `ws.state`, from their first guess.
#[inline(always)]
fn newton<L: Lanes64>(ws: &mut Workspace<L>, system: &System) -> Outcome<L> {
    let Workspace { state, trial, done, scratch, delta, step_change, rows, keys } = ws;
    let shape = Shape { system, rows, keys };
    let periodic = system.periodic;
    let count = state.points.len();
    let prev = |j: usize| (j + count - 1) % count;
    let mut health = assess(&shape, state);
    let mut active = !health.converged();
    // Each lane's points and steps are kept in `done` when it stops; from then on its values
    // in `state` and `trial` are free, so a line search that all running lanes accept at
    // once swaps the two instead of blending them.
    done.points.resize(count, Q4::identity());
    done.steps.resize(count, V4::zero());
    done.keep(!active, state);
    let mut singular = L::none();
    let mut iterations = [0; LANES];
    let mut iteration = 0;
    while active.any() && iteration < MAX_ITERATIONS {
        iteration += 1;
        for (it, lane) in iterations.iter_mut().zip(active.to_array()) {
            *it += usize::from(lane.to_bits() != 0);
        }
        linearize(&shape, state);
        let stuck = solve(&system.columns, &state.blocks, &state.rhs, periodic, scratch, delta) & active;
        singular = singular | stuck;
        done.keep(stuck, state);
        active = active & !stuck;
        // Lanes that are done do not move.
        for d in delta.iter_mut() {
            *d = active.pick(*d, V4::zero());
        }
        let mut largest = L::zero();
        for v in delta.iter() {
            largest = largest.max(v.length());
        }
        step_change.clear();
        for j in 0..count {
            let (r, l) = AxisPoly::log_jacobians(state.steps[j], state.step_coefs[j]);
            step_change.push(
                r.apply(moved(system, delta, j, L::splat(1.0))) - l.apply(moved(system, delta, prev(j), L::splat(1.0))),
            );
        }
        let too_far = largest.gt(L::splat(MAX_MOVE));
        let mut scale = too_far.pick(L::splat(MAX_MOVE) / too_far.pick(largest, L::splat(1.0)), L::splat(1.0));
        let mut pending = active;
        for halving in 0..30 {
            for (p, q) in trial.points.iter_mut().enumerate() {
                *q = state.points[p] * Q4::exp(moved(system, delta, p, scale));
            }
            for (j, change) in step_change.iter().enumerate() {
                let predicted = state.steps[j] + *change * scale;
                trial.steps[j] = nearest_log(trial.points[prev(j)].conjugate() * trial.points[j], predicted);
            }
            let h = assess(&shape, trial);
            let accept = pending & (h.norm.lt(health.norm) | h.converged());
            if accept.any() {
                if halving == 0 && (accept | !active).all() {
                    std::mem::swap(state, trial);
                } else {
                    state.take(accept, trial);
                }
                health = accept.pick(h, health);
            }
            pending = pending & !accept;
            if !pending.any() {
                break;
            }
            scale = scale * 0.5;
        }
        // A lane whose line search found no decrease stops.
        let stopping = active & (pending | health.converged());
        done.keep(stopping, state);
        active = active & !stopping;
    }
    done.keep(active, state);
    Outcome { health, iterations, singular }
}

/// The lane type this CPU runs ([`Isa::detect`], once).
fn isa() -> Isa {
    static ISA: std::sync::OnceLock<Isa> = std::sync::OnceLock::new();
    *ISA.get_or_init(Isa::detect)
}

/// The keys of each lane: `LANES` tracks of one shape.
type Tracks<'a> = ([&'a [QuatF64]; LANES], [&'a [f64]; LANES]);

/// Solves `LANES` tracks of one shape: the same key count and loop mode (times may differ),
/// as [`super::solve_rotations`] solves each, with each lane's iteration count and result.
pub(super) fn solve_rotations_lanes(
    keys: [&[QuatF64]; LANES],
    times: [&[f64]; LANES],
    periodic: bool,
) -> [Result<Solved, NoConvergence>; LANES] {
    thread_local! {
        static PORTABLE: RefCell<Workspace<Portable>> = RefCell::new(Workspace::default());
        #[cfg(target_arch = "x86_64")]
        static AVX2: RefCell<Workspace<Avx2>> = RefCell::new(Workspace::default());
    }
    #[cfg(target_arch = "x86_64")]
    if isa() == Isa::Avx2 {
        // SAFETY (both calls): `Isa::Avx2` is chosen only where the CPU has AVX2 and FMA.
        return AVX2.with(|spare| match spare.try_borrow_mut() {
            Ok(mut ws) => unsafe { solve_avx2(&mut ws, (keys, times), periodic) },
            Err(_) => unsafe { solve_avx2(&mut Workspace::default(), (keys, times), periodic) },
        });
    }
    PORTABLE.with(|spare| match spare.try_borrow_mut() {
        Ok(mut ws) => solve_portable(&mut ws, (keys, times), periodic),
        Err(_) => solve_portable(&mut Workspace::default(), (keys, times), periodic),
    })
}

/// [`solve_in`] built for AVX2, with everything below it inlined.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
unsafe fn solve_avx2(
    ws: &mut Workspace<Avx2>,
    tracks: Tracks,
    periodic: bool,
) -> [Result<Solved, NoConvergence>; LANES] {
    solve_in(ws, tracks, periodic)
}

/// [`solve_in`] at the build's baseline.
fn solve_portable(
    ws: &mut Workspace<Portable>,
    tracks: Tracks,
    periodic: bool,
) -> [Result<Solved, NoConvergence>; LANES] {
    solve_in(ws, tracks, periodic)
}

/// [`solve_rotations_lanes`] in `ws`: the rows and keys gathered into lanes, the solve, each
/// lane's curve scattered back.
#[inline(always)]
fn solve_in<L: Lanes64>(
    ws: &mut Workspace<L>,
    (keys, times): Tracks,
    periodic: bool,
) -> [Result<Solved, NoConvergence>; LANES] {
    let n = keys[0].len() - 1;
    assert!(keys.iter().zip(&times).all(|(k, t)| k.len() == n + 1 && t.len() == n + 1), "lanes of one shape");
    let systems: [Rc<System>; LANES] = std::array::from_fn(|l| System::shared(times[l], periodic));
    let system = &systems[0];
    let (count, unknowns) = (if periodic { n } else { n + 3 }, system.unknowns());
    ws.state.resize(count, unknowns);
    ws.trial.resize(count, unknowns);
    // Rows with each lane's constants.
    ws.rows.clear();
    for (r, &row) in system.rows.iter().enumerate() {
        let rows: [Condition; LANES] = [0, 1, 2, 3].map(|l| systems[l].rows[r]);
        let [mut a, mut b, mut c1, mut c2, mut k] = [[0.0; LANES]; 5];
        for (l, lane_row) in rows.iter().enumerate() {
            match *lane_row {
                Condition::Key { a: la, b: lb, .. } => (a[l], b[l]) = (la, lb),
                Condition::End { c1: l1, c2: l2, k: lk } => (c1[l], c2[l], k[l]) = (l1, l2, lk),
            }
        }
        ws.rows.push(match row {
            Condition::Key { key, .. } => Row::Key { a: L::from_array(a), b: L::from_array(b), key },
            Condition::End { .. } => Row::End { c1: L::from_array(c1), c2: L::from_array(c2), k: L::from_array(k) },
        });
    }
    // Keys gathered a point at a time.
    ws.keys.clear();
    let [k0, k1, k2, k3] = keys;
    for (((a, b), c), d) in k0.iter().zip(k1).zip(k2).zip(k3) {
        let q = [a, b, c, d].map(|k| k.to_array());
        ws.keys.push(Q4 {
            x: L::from_array([q[0][0], q[1][0], q[2][0], q[3][0]]),
            y: L::from_array([q[0][1], q[1][1], q[2][1], q[3][1]]),
            z: L::from_array([q[0][2], q[1][2], q[2][2], q[3][2]]),
            w: L::from_array([q[0][3], q[1][3], q[2][3], q[3][3]]),
        });
    }
    {
        let Workspace { state, rows, keys, step_change, .. } = ws;
        first_guess(&Shape { system, rows, keys }, state, step_change);
    }
    let outcome = newton(ws, system);
    chain(&ws.done, n, periodic, &mut ws.trial);
    // Each lane's points and steps, scattered back a point at a time.
    let mut points: [Vec<QuatF64>; LANES] = std::array::from_fn(|_| Vec::with_capacity(ws.trial.points.len()));
    let mut coefs: [Vec<Vec3F64>; LANES] = std::array::from_fn(|_| Vec::with_capacity(ws.trial.steps.len()));
    for p in &ws.trial.points {
        let [x, y, z, w] = [p.x, p.y, p.z, p.w].map(L::to_array);
        for (l, lane) in points.iter_mut().enumerate() {
            lane.push(QuatF64::from_xyzw(x[l], y[l], z[l], w[l]));
        }
    }
    for v in &ws.trial.steps {
        let [x, y, z] = [v.x, v.y, v.z].map(L::to_array);
        for (l, lane) in coefs.iter_mut().enumerate() {
            lane.push(Vec3F64::new(x[l], y[l], z[l]));
        }
    }
    let h = &outcome.health;
    let [key, key_at, end, end_at] = [h.key, h.key_at, h.end, h.end_at].map(L::to_array);
    let singular = outcome.singular.to_array();
    let mut lanes = points.into_iter().zip(coefs);
    std::array::from_fn(|l| {
        let (points, coefs) = lanes.next().expect("one per lane");
        let iterations = outcome.iterations[l];
        let (key, key_at, end, end_at) = (key[l], key_at[l] as usize, end[l], end_at[l] as usize);
        if singular[l].to_bits() != 0 {
            return Err(NoConvergence { worst_key: key_at, error: key, iterations });
        }
        if !(key <= KEY_TOLERANCE && end <= END_TOLERANCE) {
            let (worst_key, error) = if key > KEY_TOLERANCE { (key_at, key) } else { (end_at, end) };
            return Err(NoConvergence { worst_key, error, iterations });
        }
        Ok(Solved { points, coefs, knots: systems[l].knots.clone(), iterations, key_error: key })
    })
}

#[cfg(test)]
mod tests {
    use super::super::{solve_rotations, solve_rotations_batch, Problem};
    use crate::quat::{relative_log, QuatF64, Vec3F64};

    /// xorshift64 in [0, 1).
    fn uniform(seed: &mut u64) -> f64 {
        *seed ^= *seed << 13;
        *seed ^= *seed >> 7;
        *seed ^= *seed << 17;
        (*seed >> 11) as f64 / (1u64 << 53) as f64
    }

    /// Keys stepping by random rotations of up to `max_degrees` at random spacings in
    /// [0.1, 1] s (the hard cases of `examples/interp_convergence`); a loop closes on its
    /// first key.
    pub(super) fn track(seed: &mut u64, keys: usize, max_degrees: f64, periodic: bool) -> (Vec<QuatF64>, Vec<f64>) {
        let mut q = vec![QuatF64::exp(Vec3F64::new(uniform(seed), -uniform(seed), 0.3))];
        let mut t = vec![uniform(seed)];
        for _ in 1..keys {
            let axis = Vec3F64::new(uniform(seed) - 0.5, uniform(seed) - 0.5, uniform(seed) - 0.5);
            let half = 0.5 * uniform(seed) * max_degrees.to_radians();
            let last = *q.last().unwrap();
            q.push(last * QuatF64::exp(axis.scale(half / axis.length())));
            t.push(t.last().unwrap() + 0.1 + 0.9 * uniform(seed));
        }
        if periodic {
            let n = keys - 1;
            q[n] = q[0].aligned_with(q[n - 1]);
        }
        (q, t)
    }

    /// The largest difference between two solutions: control points by angle, steps (the
    /// curve's coefficients) by length.
    fn difference(a: &super::Solved, b: &super::Solved) -> f64 {
        let points = a.points.iter().zip(&b.points).map(|(p, q)| 2.0 * relative_log(*p, *q).length());
        let coefs = a.coefs.iter().zip(&b.coefs).map(|(v, w)| 2.0 * (*v - *w).length());
        assert_eq!(a.knots, b.knots);
        points.chain(coefs).fold(0.0, f64::max)
    }

    /// A batch mixing shapes (key counts, open and looping, groups of one to many, full and
    /// short lane groups) against the scalar solve of each track: the same outcome, the same
    /// curve to `AGREE` rad, and every key hit to the solve's tolerance.
    #[test]
    fn lanes_agree_with_the_scalar_solve_on_mixed_batches() {
        // Both stop once every key is within KEY_TARGET; the control points that give that
        // agree to a few times it (measured worst 2.1e-13 rad on the 170-degree steps).
        const AGREE: f64 = super::KEY_TOLERANCE;
        let mut seed = 0x9E37_79B9_7F4A_7C15;
        let mut tracks = Vec::new();
        for i in 0..240 {
            let keys = [2, 3, 4, 5, 13, 32, 13, 13][i % 8];
            let periodic = i % 3 == 0 && keys >= 3;
            let degrees = [20.0, 90.0, 170.0][i % 3];
            tracks.push((track(&mut seed, keys, degrees, periodic), periodic));
        }
        // A shape met once.
        tracks.push((track(&mut seed, 7, 60.0, false), false));
        // A lane that cannot converge (a NaN key) beside three that do: it fails as the scalar
        // solve does, and the others are untouched.
        for i in 0..4 {
            let (mut keys, times) = track(&mut seed, 9, 45.0, false);
            if i == 2 {
                keys[4] = QuatF64::from_xyzw(f64::NAN, 0.0, 0.0, 1.0);
            }
            tracks.push(((keys, times), false));
        }
        let problems: Vec<Problem> =
            tracks.iter().map(|((k, t), periodic)| Problem { keys: k, times: t, periodic: *periodic }).collect();
        let batch = solve_rotations_batch(&problems);
        let (mut worst, mut solved, mut failed) = (0.0f64, 0, 0);
        for (i, (p, lanes)) in problems.iter().zip(&batch).enumerate() {
            match (solve_rotations(p.keys, p.times, p.periodic), lanes) {
                (Ok(a), Ok(b)) => {
                    let d = difference(&a, b);
                    assert!(
                        d <= AGREE,
                        "track {i} ({} keys, loop {}): lanes differ by {d:e} rad",
                        p.keys.len(),
                        p.periodic
                    );
                    assert!(b.key_error <= super::KEY_TOLERANCE);
                    worst = worst.max(d);
                    solved += 1;
                }
                (Err(a), Err(b)) => {
                    assert_eq!(a.worst_key, b.worst_key, "track {i}");
                    failed += 1;
                }
                (a, b) => panic!(
                    "track {i}: scalar {:?}, lanes {:?}",
                    a.map(|s| s.key_error),
                    b.as_ref().map(|s| s.key_error)
                ),
            }
        }
        assert!(solved > 200 && failed >= 1, "{solved} solved, {failed} failed");
        eprintln!("lanes against scalar: {solved} solved (worst difference {worst:e} rad), {failed} failed alike");
    }
}

/// A track's curve is the same bits whichever tracks share its lane group (easy ones, hard
/// ones that take the general paths of log and sin/cos, or copies of itself): a batch's
/// result never depends on how it is grouped or sliced.
#[cfg(test)]
mod mates_tests {
    use super::super::{solve_rotations_batch, Problem};
    use super::tests::track;

    #[test]
    fn a_track_solves_to_the_same_bits_beside_any_lane_mates() {
        let mut seed = 0x1234_5678_9abc_def1u64;
        for periodic in [false, true] {
            let subject = track(&mut seed, 11, 30.0, periodic);
            let easy: Vec<_> = (0..3).map(|_| track(&mut seed, 11, 5.0, periodic)).collect();
            let hard: Vec<_> = (0..3).map(|_| track(&mut seed, 11, 170.0, periodic)).collect();
            let solve = |mates: &[(Vec<crate::quat::QuatF64>, Vec<f64>)]| {
                let mut problems = vec![Problem { keys: &subject.0, times: &subject.1, periodic }];
                problems.extend(mates.iter().map(|(k, t)| Problem { keys: k, times: t, periodic }));
                solve_rotations_batch(&problems).swap_remove(0)
            };
            let alone = solve(&[]);
            assert!(alone.is_ok());
            assert_eq!(solve(&easy), alone, "beside easy tracks");
            assert_eq!(solve(&hard), alone, "beside hard tracks");
        }
    }
}

/// The AVX2 build of the lane solve gives the portable build's bits (no fused operations;
/// the same formulas), on the hard cases, open and looping.
#[cfg(all(test, target_arch = "x86_64"))]
mod isa_tests {
    use super::tests::track;
    use super::{solve_avx2, solve_portable, Isa, Workspace};

    #[test]
    fn avx2_lanes_give_the_portable_bits() {
        if !Isa::Avx2.available() {
            eprintln!("no AVX2 on this CPU: nothing to compare");
            return;
        }
        let mut seed = 0x2545_f491_4f6c_dd1du64;
        for periodic in [false, true] {
            for _ in 0..20 {
                let tracks: Vec<_> = (0..4).map(|_| track(&mut seed, 13, 170.0, periodic)).collect();
                let keys = std::array::from_fn(|l| tracks[l].0.as_slice());
                let times = std::array::from_fn(|l| tracks[l].1.as_slice());
                let portable = solve_portable(&mut Workspace::default(), (keys, times), periodic);
                // SAFETY: AVX2 and FMA are present (checked above).
                let avx2 = unsafe { solve_avx2(&mut Workspace::default(), (keys, times), periodic) };
                assert_eq!(portable, avx2);
            }
        }
    }
}
