//! `bspline-interp`: the C2 cubic KKS B-spline through every key (KKS section 6.2, Fig. 10;
//! DESIGN section 3). The builder solves its control points here, once, in f64; afterwards
//! the curve is an ordinary cubic B-spline on explicit knots, which every evaluator already
//! runs.
//!
//! **Open curves.** Knots `tau_0 x4, tau_1, ..., tau_{n-1}, tau_n x4`, control points
//! `P_0..P_{n+2}` with `P_0 = q_0`, `P_{n+2} = q_n`. Unknowns `P_1..P_{n+1}`; conditions
//! `q(tau_0)'' = 0` (natural start), `q(tau_i) = q_i` for `0 < i < n`, natural end. At a knot
//! `tau_i` only three control points act, `q(tau_i) = P_i exp(a w_{i+1}) exp(b w_{i+2})`, and at
//! each end the body acceleration is `w_1 b_1'' + w_2 b_2'' + 2 b_1' b_2' (w_1 x w_2)` (the
//! derivative recursion of DESIGN section 2 with every factor at the identity, or, at the right
//! end, conjugated by one): so row `r` of the system involves unknowns `r - 1, r, r + 1` and the
//! Jacobian is block tridiagonal with 3x3 blocks.
//!
//! **Loops.** Knots extended by the period, control points `P_0..P_{n-1}` repeating with
//! period `n`, conditions `q(tau_i) = q_i` for `0 <= i < n`: a cyclic block tridiagonal system.
//!
//! **Newton.** Control points move by body rotations `P_j <- P_j exp(d_j)`; the blocks are the
//! exact derivatives of each row (right and left Jacobians of the half-angle exp and log, below),
//! so convergence is quadratic (one step when all keys share an axis, where the problem is
//! linear). Each step is damped by halving until the residual decreases. The vector analogue
//! (natural or periodic cubic spline of translations and scales) is the same system with scalar
//! blocks, solved once.

mod f64x4;
mod jacobian;
mod lanes;
mod tridiagonal;

use crate::basis::bspline_cumulative;
use crate::quat::{relative_log, QuatF64, Vec3F64};
use glam::{DMat3, DVec3 as V3};
use jacobian::{d, exp_jr, g, log_coef, skew, step_log_coef, AxisPoly};
use std::cell::RefCell;
use std::f64::consts::PI;
use std::rc::Rc;
use tridiagonal::{solve, Scratch};

/// Largest angle (rad) a solved curve may miss a key by (DESIGN section 3).
pub const KEY_TOLERANCE: f64 = 1e-12;
/// Newton iterations before giving up.
pub const MAX_ITERATIONS: usize = 100;
/// Newton stops once every key is within this (rad): well inside [`KEY_TOLERANCE`], at the
/// level of f64 rounding in the row evaluation.
const KEY_TARGET: f64 = 1e-13;
/// Natural-end residual (body acceleration times the end segment's squared length, so in
/// half-angle units per squared segment parameter) at which Newton stops.
const END_TARGET: f64 = 1e-10;
/// Largest body move of a control point in one Newton step (half-angle rad).
const MAX_MOVE: f64 = 0.25;
/// Natural-end residual accepted when the iteration cap is reached.
const END_TOLERANCE: f64 = 1e-9;

/// A solve that did not reach [`KEY_TOLERANCE`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NoConvergence {
    /// Index of the key with the largest error (for an end condition: 0 or n).
    pub worst_key: usize,
    /// That key's error in rad (or, for an end condition, the residual acceleration).
    pub error: f64,
    /// Newton iterations run.
    pub iterations: usize,
}

/// Solved control points and how the solve went.
#[derive(Clone, Debug, PartialEq)]
pub struct Solved {
    /// Sign-continuous control points: `P_0..P_{n+2}` (open) or `P_{n-1}, P_0, ..., P_{n-1},
    /// P_0, P_1` (loop: one period of the repeating sequence, ready for [`Self::knots`]).
    pub points: Vec<QuatF64>,
    /// The step into each point after the first, `w_j` with `P_j = P_{j-1} exp(w_j)`: the
    /// curve's coefficients, not folded (they may exceed a half turn).
    pub coefs: Vec<Vec3F64>,
    /// The knot vector the points belong to (`n + 7` entries either way).
    pub knots: Vec<f64>,
    /// Newton iterations used.
    pub iterations: usize,
    /// Largest angle between a key and the curve at its time, rad.
    pub key_error: f64,
}

/// The open knot vector `tau_0 x4, tau_1..tau_{n-1}, tau_n x4`.
#[must_use]
pub fn open_knots(times: &[f64]) -> Vec<f64> {
    let n = times.len() - 1;
    let mut knots = vec![times[0]; 4];
    knots.extend_from_slice(&times[1..n]);
    knots.extend(std::iter::repeat(times[n]).take(4));
    knots
}

/// The periodic knot vector over one period: `t_j = tau_{j-3}` for `j = 0..n+7`, key times
/// extended by `tau_{j+n} = tau_j + T`.
#[must_use]
pub fn periodic_knots(times: &[f64]) -> Vec<f64> {
    let n = times.len() - 1;
    let period = times[n] - times[0];
    (0..n + 7)
        .map(|j| {
            let i = j as isize - 3;
            let (cycle, r) = (i.div_euclid(n as isize), i.rem_euclid(n as isize) as usize);
            // The key times themselves inside the period (so the domain ends are exact);
            // extended ones carry the period.
            if (0..=n as isize).contains(&i) {
                times[i as usize]
            } else {
                times[r] + cycle as f64 * period
            }
        })
        .collect()
}

/// What one row of the system asks (a key hit, or a natural end), with its basis constants
/// from the knot vector (computed once per track).
#[derive(Clone, Copy, Debug)]
enum Condition {
    /// `q(tau) = P_a exp(a w) exp(b w')`, to equal key `key`.
    Key { a: f64, b: f64, key: usize },
    /// Natural end: `c1 w + c2 w' + k (w x w') = 0` (times the squared end segment length).
    End { c1: f64, c2: f64, k: f64 },
}

/// The rows of a system: open (`n + 1` rows over unknowns `P_1..P_{n+1}`) or periodic (`n`
/// rows over `P_0..P_{n-1}`), one [`Condition`] each. Row `r` reads three consecutive control points; see
/// [`System::triple`].
struct System {
    periodic: bool,
    rows: Vec<Condition>,
    knots: Vec<f64>,
    /// The unknown each row's three points are ([`System::triple`], [`System::unknown`]).
    columns: Vec<[Option<usize>; 3]>,
}

impl System {
    /// The system for `times`, shared with the previous solve on this thread when that had
    /// the same times: the tracks of a clip share their key times, and the basis values at
    /// every knot were a measured part of each solve.
    fn shared(times: &[f64], periodic: bool) -> Rc<Self> {
        thread_local! {
            static LAST: RefCell<Option<(Vec<f64>, Rc<System>)>> = const { RefCell::new(None) };
        }
        LAST.with_borrow_mut(|last| {
            if let Some((last_times, system)) = last {
                if system.periodic == periodic && last_times.as_slice() == times {
                    return Rc::clone(system);
                }
            }
            let system = Rc::new(Self::new(times, periodic));
            *last = Some((times.to_vec(), Rc::clone(&system)));
            system
        })
    }

    fn new(times: &[f64], periodic: bool) -> Self {
        let n = times.len() - 1;
        let key_row = |knots: &[f64], i: usize| {
            let b = bspline_cumulative(knots, 4, 3 + i, knots[3 + i]);
            Condition::Key { a: b[0][0], b: b[1][0], key: i }
        };
        if periodic {
            let knots = periodic_knots(times);
            let rows = (0..n).map(|i| key_row(&knots, i)).collect();
            return Self { periodic, rows, knots, columns: Vec::new() }.with_columns();
        }
        let knots = open_knots(times);
        let end = |b1: [f64; 3], b2: [f64; 3], d: f64| Condition::End {
            c1: b1[2] * d * d,
            c2: b2[2] * d * d,
            k: 2.0 * b1[1] * b2[1] * d * d,
        };
        let start = bspline_cumulative(&knots, 4, 3, times[0]);
        let finish = bspline_cumulative(&knots, 4, n + 2, times[n]);
        let mut rows = vec![end(start[0], start[1], times[1] - times[0])];
        rows.extend((1..n).map(|i| key_row(&knots, i)));
        rows.push(end(finish[1], finish[2], times[n] - times[n - 1]));
        Self { periodic, rows, knots, columns: Vec::new() }.with_columns()
    }

    fn with_columns(mut self) -> Self {
        self.columns = (0..self.unknowns()).map(|r| self.triple(r).map(|p| self.unknown(p))).collect();
        self
    }

    /// Number of unknown control points.
    fn unknowns(&self) -> usize {
        self.rows.len()
    }

    /// Indices into the control points of row `r`'s three points. Open: `P_r, P_{r+1},
    /// P_{r+2}` of `P_0..P_{n+2}` (unknown `j` is point `j + 1`). Periodic: `P_{r-1}, P_r,
    /// P_{r+1}` modulo `n` (unknown `j` is point `j`).
    fn triple(&self, r: usize) -> [usize; 3] {
        if self.periodic {
            let n = self.rows.len();
            [(r + n - 1) % n, r, (r + 1) % n]
        } else {
            [r, r + 1, r + 2]
        }
    }

    /// The unknown each of row `r`'s points is, if any (open ends are fixed).
    fn unknown(&self, point: usize) -> Option<usize> {
        if self.periodic {
            Some(point)
        } else if point == 0 || point == self.rows.len() + 1 {
            None
        } else {
            Some(point - 1)
        }
    }
}

/// The rotation matrix of `q^-1`: `rot_inv(q) v = q^-1 v q`.
fn rot_inv(q: QuatF64) -> DMat3 {
    DMat3::from_quat(glam::DQuat::from(q.conjugate()))
}

/// A key row's curve point `P_0 exp(a w) exp(b w')`, with what its Jacobian reuses: the
/// second factor, the product of both, and both factors' Jacobian coefficients
/// ([`AxisPoly::exp_jacobian`]).
#[derive(Clone, Copy, Debug)]
struct KeyPoint {
    q: QuatF64,
    e2: QuatF64,
    c: QuatF64,
    jr: [[f64; 2]; 2],
}

impl KeyPoint {
    /// What end rows carry (nothing reads it).
    const NONE: Self = {
        let one = QuatF64 { x: 0.0, y: 0.0, z: 0.0, w: 1.0 };
        Self { q: one, e2: one, c: one, jr: [[0.0; 2]; 2] }
    };

    fn new(p0: QuatF64, w: [Vec3F64; 2], a: f64, b: f64) -> Self {
        let (e1, j1) = exp_jr(g(w[0]) * a);
        let (e2, j2) = exp_jr(g(w[1]) * b);
        let c = e1 * e2;
        Self { q: p0 * c, e2, c, jr: [j1, j2] }
    }
}

/// One row's residual at control points `p` whose steps are `w` (`p[1] = p[0] exp(w[0])`,
/// `p[2] = p[1] exp(w[1])`, not folded): the key error as a body rotation vector, or the
/// natural-end condition; with the key row's point for [`row_jacobian`].
fn residual(row: Condition, p: [QuatF64; 3], w: [Vec3F64; 2], keys: &[QuatF64]) -> (V3, KeyPoint) {
    match row {
        Condition::Key { a, b, key } => {
            let point = KeyPoint::new(p[0], w, a, b);
            (g(relative_log(keys[key], point.q)), point)
        }
        Condition::End { c1, c2, k } => {
            let (v1, v2) = (g(w[0]), g(w[1]));
            (v1 * c1 + v2 * c2 + v1.cross(v2) * k, KeyPoint::NONE)
        }
    }
}

/// The derivatives of a row's residual with respect to body moves of its three points, given
/// the row's [`KeyPoint`] and the coefficients `jc` of its two steps' log Jacobians
/// ([`AxisPoly::log_jacobians`], shared by the two rows each step enters).
///
/// A key row's residual is `r = log(key^-1 q)`, whose exact derivative is `jr_inv(r) B` with
/// `B` the derivative of `q`'s body move returned here. The factor is left out on purpose:
/// `jr_inv(r) r = r` (`[r]x r = 0`), so the Newton step `J^-1 (-R)` with `J = diag(jr_inv(r_k))
/// B` equals `B^-1 (-R)` exactly, and the factor would cost a `sin_cos` and three products per
/// row.
fn row_jacobian(row: Condition, point: &KeyPoint, w: [Vec3F64; 2], jc: [f64; 2]) -> [DMat3; 3] {
    let (v1, v2) = (g(w[0]), g(w[1]));
    let [(r1, l1), (r2, l2)] = [AxisPoly::log_jacobians(v1, jc[0]), AxisPoly::log_jacobians(v2, jc[1])];
    match row {
        Condition::Key { a, b, .. } => {
            let KeyPoint { e2, c, jr: [j1, j2], .. } = *point;
            // q exp(eps): eps from P_0 carried through c, from w1 through exp(b w2), from w2.
            let (k1, k2) = (AxisPoly::exp_jacobian(v1, a, j1), AxisPoly::exp_jacobian(v2, b, j2));
            let e = rot_inv(e2);
            [
                rot_inv(c) - e * k1.times(l1).matrix(),
                e * k1.times(r1).matrix() - k2.times(l2).matrix(),
                k2.times(r2).matrix(),
            ]
        }
        Condition::End { c1, c2, k } => {
            let f1 = DMat3::from_diagonal(V3::splat(c1)) - skew(v2) * k;
            let f2 = DMat3::from_diagonal(V3::splat(c2)) + skew(v1) * k;
            let [r1, l1, r2, l2] = [r1, l1, r2, l2].map(AxisPoly::matrix);
            [-(f1 * l1), f1 * r1 - f2 * l2, f2 * r2]
        }
    }
}

/// How far a set of control points is from solving the system.
#[derive(Clone, Copy, Debug)]
struct Health {
    /// Largest key error (physical angle, rad) and its key.
    key: (f64, usize),
    /// Largest end residual and its key (0 or n).
    end: (f64, usize),
    /// Sum of squared residuals, for the line search.
    norm: f64,
}

impl Health {
    fn converged(&self) -> bool {
        self.key.0 <= KEY_TARGET && self.end.0 <= END_TARGET
    }

    fn acceptable(&self) -> bool {
        self.key.0 <= KEY_TOLERANCE && self.end.0 <= END_TOLERANCE
    }
}

/// A candidate solution and its linearization: control points, the step into each, the
/// steps' inverse Jacobians, and every row's Jacobian blocks and negated residual.
#[derive(Clone, Default)]
struct State {
    points: Vec<QuatF64>,
    steps: Vec<Vec3F64>,
    /// Each step's [`AxisPoly::log_jacobians`] coefficient.
    step_coefs: Vec<f64>,
    key_points: Vec<KeyPoint>,
    blocks: Vec<[DMat3; 3]>,
    rhs: Vec<V3>,
}

/// Fills `state`'s right-hand sides (negated residuals) from its points and steps.
fn assess(system: &System, state: &mut State, keys: &[QuatF64]) -> Health {
    let mut health = Health { key: (0.0, 0), end: (0.0, 0), norm: 0.0 };
    let last = keys.len() - 1;
    for (r, &row) in system.rows.iter().enumerate() {
        let [i, j, k] = system.triple(r);
        let (res, point) =
            residual(row, [state.points[i], state.points[j], state.points[k]], [state.steps[j], state.steps[k]], keys);
        state.key_points[r] = point;
        let size = res.length();
        match row {
            Condition::Key { key, .. } if 2.0 * size > health.key.0 => health.key = (2.0 * size, key),
            Condition::End { .. } if size > health.end.0 => health.end = (size, if r == 0 { 0 } else { last }),
            _ => {}
        }
        // A NaN anywhere must not pass for convergence.
        if !size.is_finite() {
            health.key = (f64::INFINITY, r);
        }
        health.norm += size * size;
        state.rhs[r] = -res;
    }
    health
}

/// Fills `state`'s step Jacobians and Jacobian blocks (after [`assess`], whose residuals the
/// key rows' blocks read). Only states that Newton steps from need them.
fn linearize(system: &System, state: &mut State) {
    let State { points, steps, step_coefs, key_points, blocks, .. } = state;
    let count = points.len();
    for (j, (coef, w)) in step_coefs.iter_mut().zip(steps.iter()).enumerate() {
        *coef = step_log_coef(g(*w), points[(j + count - 1) % count].conjugate() * points[j]);
    }
    for (r, &row) in system.rows.iter().enumerate() {
        let [_, j, k] = system.triple(r);
        blocks[r] = row_jacobian(row, &key_points[r], [steps[j], steps[k]], [step_coefs[j], step_coefs[k]]);
    }
}

/// The keys laid out as control points, where Newton's first guess moves them from: one period
/// (`P_0..P_{n-1}`) of a loop, an open curve's keys with each end key twice more (`P_0 = q_0`,
/// `P_{n+2} = q_n`).
#[inline(always)]
fn keys_as_points<T: Copy>(keys: &[T], periodic: bool, points: &mut Vec<T>) {
    let n = keys.len() - 1;
    points.clear();
    if periodic {
        points.extend_from_slice(&keys[..n]);
    } else {
        points.push(keys[0]);
        points.extend_from_slice(keys);
        points.push(keys[n]);
    }
}

/// Newton's starting control points and the step into each. Each key row's point is its key
/// moved against the row's residual at the keys (one Richardson step on `A P = q`: exact for
/// the row's linear part on keys along one axis at constant speed, and it leaves only the
/// high-frequency part of the error); an open curve's two points next to the ends go on the
/// chord that solves the natural-end rows' linear part (`c1 w + c2 w' = 0`). Starting from the
/// keys themselves cost most tracks one more iteration. The steps follow the moves to first
/// order and take the nearest branch, as in a Newton update.
fn first_guess(
    system: &System,
    keys: &[QuatF64],
    points: &mut Vec<QuatF64>,
    steps: &mut Vec<Vec3F64>,
    moves: &mut Vec<V3>,
) {
    let n = keys.len() - 1;
    keys_as_points(keys, system.periodic, points);
    let count = points.len();
    let prev = |j: usize| (j + count - 1) % count;
    // Steps between keys are short (the keys are sign-continuous), so folding is right here.
    steps.clear();
    steps.extend((0..count).map(|j| relative_log(points[prev(j)], points[j])));
    moves.clear();
    moves.resize(count, V3::ZERO);
    for (r, &row) in system.rows.iter().enumerate() {
        if let Condition::Key { a, b, .. } = row {
            // Residual at the keys: (1 - a) back along the step in, b along the step out.
            let j = system.triple(r)[1];
            moves[j] = g(steps[j]) * (1.0 - a) - g(steps[(j + 1) % count]) * b;
        }
    }
    if !system.periodic {
        for (row, j) in [(0, 1), (n, n + 1)] {
            if let Condition::End { c1, c2, .. } = system.rows[row] {
                let s = -c2 / (c1 - c2);
                let s = if s.is_finite() { s.clamp(0.0, 1.0) } else { 0.0 };
                let chord = g(steps[j]) + g(steps[j + 1]) + moves[j + 1] - moves[j - 1];
                moves[j] = chord * s - g(steps[j]) + moves[j - 1];
            }
        }
    }
    for (p, m) in points.iter_mut().zip(moves.iter()) {
        *p = *p * QuatF64::exp(d(*m));
    }
    // Each step from its own value before the moves (read before it is overwritten).
    for j in 0..count {
        let (r, l) = AxisPoly::log_jacobians(g(steps[j]), log_coef(g(steps[j])));
        let predicted = d(g(steps[j]) + r.apply(moves[j]) - l.apply(moves[prev(j)]));
        steps[j] = nearest_log(points[prev(j)].conjugate() * points[j], predicted);
    }
}

/// What a solve allocates, kept per thread across solves: a bake solves tens of thousands of
/// tracks, and fresh vectors per solve (with the allocator handing their pages back to the
/// system in between) were a measured part of each.
#[derive(Default)]
struct Workspace {
    state: State,
    trial: State,
    scratch: Scratch<DMat3>,
    delta: Vec<V3>,
    /// The moves of the first guess, then each Newton step's first-order change of the steps.
    step_change: Vec<V3>,
}

impl Workspace {
    /// Runs `f` with this thread's workspace (a fresh one if a solve on this thread is already
    /// running it, which does not happen today).
    fn with<R>(f: impl FnOnce(&mut Workspace) -> R) -> R {
        thread_local! {
            static SPARE: RefCell<Workspace> = RefCell::new(Workspace::default());
        }
        SPARE.with(|spare| match spare.try_borrow_mut() {
            Ok(mut workspace) => f(&mut workspace),
            Err(_) => f(&mut Workspace::default()),
        })
    }
}

impl State {
    /// Room for `count` control points and `unknowns` rows (values are filled before read).
    fn resize(&mut self, count: usize, unknowns: usize) {
        self.points.resize(count, QuatF64::identity());
        self.steps.resize(count, Vec3F64::zero());
        self.step_coefs.resize(count, 0.0);
        self.key_points.resize(unknowns, KeyPoint::NONE);
        self.blocks.resize(unknowns, [DMat3::ZERO; 3]);
        self.rhs.resize(unknowns, V3::ZERO);
    }
}

/// Solves the control points of the curve through `keys` (sign-continuous, normalized) at
/// `times`, open with natural ends or periodic, one track at a time in scalar f64: the
/// formulas the lane solve ([`solve_rotations_batch`], the builder's) is tested against. A
/// periodic `keys` must close (`keys[n]` the same rotation as `keys[0]`; the builder checks
/// it).
///
/// # Errors
/// [`NoConvergence`] when Newton does not bring every key within [`KEY_TOLERANCE`] in
/// [`MAX_ITERATIONS`] (or meets a singular system), naming the worst key.
pub fn solve_rotations(keys: &[QuatF64], times: &[f64], periodic: bool) -> Result<Solved, NoConvergence> {
    Workspace::with(|workspace| solve_in(workspace, keys, times, periodic))
}

/// One track's keys for [`solve_rotations_batch`]: as [`solve_rotations`] takes them.
#[derive(Clone, Copy, Debug)]
pub struct Problem<'a> {
    /// Sign-continuous, normalized keys.
    pub keys: &'a [QuatF64],
    /// Their times, strictly increasing.
    pub times: &'a [f64],
    /// A loop (the keys close) rather than an open curve with natural ends.
    pub periodic: bool,
}

/// [`solve_rotations`] for every problem, in order, four tracks of one shape (the same key
/// count and loop mode: every channel of a clip) at a time in `f64` SIMD lanes (`lanes`); a
/// group left short fills its spare lanes with copies of its first track. Each track's curve
/// depends on that track alone, bit for bit (never on its lane mates, on how a batch is
/// sliced or on the CPU's instruction set), and agrees with [`solve_rotations`]'s to the
/// solve's own tolerance, [`KEY_TOLERANCE`] (measured worst 2.1e-13 rad).
#[must_use]
pub fn solve_rotations_batch(problems: &[Problem]) -> Vec<Result<Solved, NoConvergence>> {
    let mut out: Vec<Option<Result<Solved, NoConvergence>>> = vec![None; problems.len()];
    let mut waiting: Vec<((usize, bool), Vec<usize>)> = Vec::new();
    let run = |group: &[usize], out: &mut Vec<Option<_>>| {
        let pick = |l: usize| problems[group.get(l).copied().unwrap_or(group[0])];
        let solved = lanes::solve_rotations_lanes(
            std::array::from_fn(|l| pick(l).keys),
            std::array::from_fn(|l| pick(l).times),
            problems[group[0]].periodic,
        );
        for (&i, result) in group.iter().zip(solved) {
            out[i] = Some(result);
        }
    };
    for (i, p) in problems.iter().enumerate() {
        let shape = (p.keys.len(), p.periodic);
        let slot = match waiting.iter().position(|(s, _)| *s == shape) {
            Some(slot) => slot,
            None => {
                waiting.push((shape, Vec::with_capacity(lanes::LANES)));
                waiting.len() - 1
            }
        };
        waiting[slot].1.push(i);
        if waiting[slot].1.len() == lanes::LANES {
            let (_, group) = waiting.swap_remove(slot);
            run(&group, &mut out);
        }
    }
    for (_, group) in waiting {
        run(&group, &mut out);
    }
    out.into_iter().map(|r| r.expect("every problem is solved")).collect()
}

/// [`solve_rotations`] in `workspace`'s arrays.
fn solve_in(
    workspace: &mut Workspace,
    keys: &[QuatF64],
    times: &[f64],
    periodic: bool,
) -> Result<Solved, NoConvergence> {
    let n = keys.len() - 1;
    let system = System::shared(times, periodic);
    let Workspace { state, trial, scratch, delta, step_change } = workspace;
    first_guess(&system, keys, &mut state.points, &mut state.steps, step_change);
    let unknowns = system.unknowns();
    let count = state.points.len();
    // The step into each point (`steps[j]`: P_{j-1} to P_j, cyclic when periodic; unused
    // `steps[0]` when open). Steps are never folded: an interpolating spline's control polygon
    // overshoots its keys (about 3x on alternating keys), so its steps can pass a half turn.
    let prev = |j: usize| (j + count - 1) % count;
    state.resize(count, unknowns);
    trial.resize(count, unknowns);
    let mut health = assess(&system, state, keys);
    let mut iterations = 0;
    while !health.converged() && iterations < MAX_ITERATIONS {
        iterations += 1;
        let fail = |h: &Health| NoConvergence { worst_key: h.key.1, error: h.key.0, iterations };
        linearize(&system, state);
        if solve(&system.columns, &state.blocks, &state.rhs, periodic, scratch, delta) {
            return Err(fail(&health));
        }
        let moved = |p: usize, scale: f64| system.unknown(p).map_or(V3::ZERO, |u| delta[u] * scale);
        // Damped update: no control point turns by more than MAX_MOVE at once (a far jump
        // lands in another basin), then halve the step until the residual decreases.
        let largest = delta.iter().map(|v| v.length()).fold(0.0, f64::max);
        // First-order change of each step for the full move (the line search scales it).
        step_change.clear();
        step_change.extend((0..count).map(|j| {
            let (r, l) = AxisPoly::log_jacobians(g(state.steps[j]), state.step_coefs[j]);
            r.apply(moved(j, 1.0)) - l.apply(moved(prev(j), 1.0))
        }));
        let mut scale = if largest > MAX_MOVE { MAX_MOVE / largest } else { 1.0 };
        let mut accepted = None;
        for _ in 0..30 {
            for (p, q) in trial.points.iter_mut().enumerate() {
                *q = state.points[p] * QuatF64::exp(d(moved(p, scale)));
            }
            // Each new step is the log of the new relative rotation on the branch nearest
            // its first-order prediction.
            for (j, change) in step_change.iter().enumerate() {
                let predicted = state.steps[j] + d(*change * scale);
                trial.steps[j] = nearest_log(trial.points[prev(j)].conjugate() * trial.points[j], predicted);
            }
            let h = assess(&system, trial, keys);
            if h.norm < health.norm || h.converged() {
                accepted = Some(h);
                break;
            }
            scale *= 0.5;
        }
        let Some(h) = accepted else { break };
        std::mem::swap(state, trial);
        health = h;
    }
    if !health.acceptable() {
        let (worst_key, error) =
            if health.key.0 > KEY_TOLERANCE { (health.key.1, health.key.0) } else { (health.end.1, health.end.0) };
        return Err(NoConvergence { worst_key, error, iterations });
    }
    Ok(finish(&state.points, &state.steps, n, periodic, &system.knots, iterations, health.key.0))
}

/// The [`Solved`] curve from converged control points and the steps into them (one period
/// when `periodic`).
fn finish(
    points: &[QuatF64],
    steps: &[Vec3F64],
    n: usize,
    periodic: bool,
    knots: &[f64],
    iterations: usize,
    key_error: f64,
) -> Solved {
    // Open: P_0..P_{n+2}. Periodic: one period of the repeating sequence, P_{n-1}, P_0, ...,
    // P_{n-1}, P_0, P_1, with the step into each.
    let order: Vec<usize> =
        if periodic { (0..n + 3).map(|j| (j + n - 1) % n).collect() } else { (0..points.len()).collect() };
    let mut out_points: Vec<QuatF64> = order.iter().map(|&j| points[j]).collect();
    let coefs: Vec<Vec3F64> = order[1..].iter().map(|&j| steps[j]).collect();
    // Signs follow the product chain, so that P_j = P_{j-1} exp(w_j) exactly as evaluated.
    for j in 1..out_points.len() {
        let chained = out_points[j - 1] * QuatF64::exp(coefs[j - 1]);
        out_points[j] = out_points[j].aligned_with(chained);
    }
    Solved { points: out_points, coefs, knots: knots.to_vec(), iterations, key_error }
}

/// The log of `r` (up to sign) nearest to `predicted`: among `(th + pi m) u` (every `v` with
/// `exp v = +-r`, `th u` the short log), the one whose length along `u` is nearest
/// `predicted`'s.
fn nearest_log(r: QuatF64, predicted: Vec3F64) -> Vec3F64 {
    let short = r.aligned_with(QuatF64::identity()).log();
    let th = short.length();
    let axis = if th > 0.0 {
        short.scale(1.0 / th)
    } else if predicted.length() > 0.0 {
        // The identity: whole turns about any axis; take the prediction's.
        predicted.scale(1.0 / predicted.length())
    } else {
        return short;
    };
    let m = ((predicted.dot(axis) - th) / PI).round();
    axis.scale(th + PI * m)
}

/// The vector analogue: control points of the natural (open) or periodic cubic spline through
/// `values` at `times`, in the same B-spline form and on the same knots as
/// [`solve_rotations`]. A periodic `values` must close exactly (the caller removes any
/// per-cycle offset first).
///
/// Returns `(points, knots)`, or `None` for a singular system (not reached for strictly
/// increasing times).
#[must_use]
pub fn solve_vectors(values: &[Vec3F64], times: &[f64], periodic: bool) -> Option<(Vec<Vec3F64>, Vec<f64>)> {
    let n = values.len() - 1;
    let system = System::new(times, periodic);
    let unknowns = system.unknowns();
    let last_point = if periodic { n - 1 } else { n + 2 };
    let fixed = |p: usize| -> V3 {
        match (periodic, p) {
            (false, 0) => g(values[0]),
            (false, p) if p == last_point => g(values[n]),
            _ => V3::ZERO,
        }
    };
    let mut blocks = Vec::with_capacity(unknowns);
    let mut rhs = Vec::with_capacity(unknowns);
    for (r, &row) in system.rows.iter().enumerate() {
        // Linear rows: key `(1 - a) p0 + (a - b) p1 + b p2 = value`; end
        // `c1 (p1 - p0) + c2 (p2 - p1) = 0`.
        let (weights, target) = match row {
            Condition::Key { a, b, key } => ([1.0 - a, a - b, b], g(values[key])),
            Condition::End { c1, c2, .. } => ([-c1, c1 - c2, c2], V3::ZERO),
        };
        let mut target = target;
        for ((&p, column), &w) in system.triple(r).iter().zip(&system.columns[r]).zip(&weights) {
            if column.is_none() {
                target -= fixed(p) * w;
            }
        }
        blocks.push(weights.map(|w| DMat3::from_diagonal(V3::splat(w))));
        rhs.push(target);
    }
    let mut x = Vec::with_capacity(unknowns);
    if solve(&system.columns, &blocks, &rhs, periodic, &mut Scratch::default(), &mut x) {
        return None;
    }
    let d = |v: V3| Vec3F64::new(v.x, v.y, v.z);
    let points = if periodic {
        (0..n + 3).map(|j| d(x[(j + n - 1) % n])).collect()
    } else {
        let mut p = Vec::with_capacity(n + 3);
        p.push(values[0]);
        p.extend(x.into_iter().map(d));
        p.push(values[n]);
        p
    };
    Some((points, system.knots))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn q(v: [f64; 3]) -> QuatF64 {
        QuatF64::exp(Vec3F64::from_array(v))
    }

    /// Every row's Jacobian blocks against central differences of its residual (a key row's
    /// blocks times `jr_inv(r)`, the factor [`row_jacobian`] leaves out because it fixes `r`).
    #[test]
    fn row_jacobians_match_finite_differences() {
        let keys = [q([0.3, -0.2, 0.5]), q([0.9, 0.4, -0.3]), q([-0.2, 1.1, 0.2])];
        let p = [q([0.1, 0.2, 0.3]), q([0.7, -0.5, 0.2]), q([-0.4, 0.9, 1.0])];
        let rows = [Condition::Key { a: 0.8, b: 0.15, key: 1 }, Condition::End { c1: 1.7, c2: -0.6, k: 0.9 }];
        for row in rows {
            let w = |p: [QuatF64; 3]| [relative_log(p[0], p[1]), relative_log(p[1], p[2])];
            let jc = w(p).map(|v| log_coef(g(v)));
            let (r, point) = residual(row, p, w(p), &keys);
            let outer = match row {
                Condition::Key { .. } => AxisPoly::log_jacobians(r, log_coef(r)).0.matrix(),
                Condition::End { .. } => DMat3::IDENTITY,
            };
            // What makes leaving the factor out exact: it does not move the residual itself.
            assert!(
                (outer * r - r).length() < 1e-15 * (1.0 + r.length()),
                "{row:?}: jr_inv(r) r = {} for r = {r}",
                outer * r
            );
            let blocks = row_jacobian(row, &point, w(p), jc).map(|b| outer * b);
            for (which, block) in blocks.iter().enumerate() {
                for axis in 0..3 {
                    let h = 1e-6;
                    let mut e = V3::ZERO;
                    e[axis] = h;
                    let moved = |s: f64| {
                        let mut p = p;
                        let d = e * s;
                        p[which] = p[which] * QuatF64::exp(Vec3F64::new(d.x, d.y, d.z));
                        residual(row, p, w(p), &keys).0
                    };
                    let fd = (moved(1.0) - moved(-1.0)) / (2.0 * h);
                    let exact = block.col(axis);
                    assert!((fd - exact).length() < 1e-7, "{row:?} block {which} axis {axis}: fd {fd} exact {exact}");
                }
            }
        }
    }

    #[test]
    fn periodic_knots_extend_by_the_period() {
        assert_eq!(periodic_knots(&[0.0, 1.0, 3.0, 4.0]), vec![-4.0, -3.0, -1.0, 0.0, 1.0, 3.0, 4.0, 5.0, 7.0, 8.0]);
        assert_eq!(periodic_knots(&[0.5, 2.0]), vec![-4.0, -2.5, -1.0, 0.5, 2.0, 3.5, 5.0, 6.5]);
    }
}
