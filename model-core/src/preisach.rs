//! Preisach hysteresis: a population of relays, each switching up when the deflection rises to
//! its threshold α and down when it falls to its threshold β ≤ α, with a non-negative density
//! over the (α, β) plane. Unlike the Masing kinds (micro-slip, genetic), a loop's shape depends
//! on where it sits: a density that varies along the diagonal gives minor loops that are not
//! congruent, biased loops unlike centred ones, and small-amplitude stiffness that the large
//! loops do not imply. Return-point memory and wiping-out hold by construction (Madelung's
//! rules, [`Madelung`]).
//!
//! ```text
//! H(x) = −P(x),   P = Σ_cells w_c · (fraction of cell c switched up − at rest)
//! ```
//!
//! **Sign.** A relay switches up late on the way up and down late on the way down, so P alone
//! runs its loops the way that delivers energy. A gear's friction dissipates it: its torque
//! is the spring S minus what the relays have let go, T = S(x) − P(x). The Maxwell-slip
//! element is exactly that: its torque k·(x − p_d) is a spring k·x less k times a play
//! operator p_d, which is the relays on the line α − β = 2d (see below). So H = −P, and S
//! carries the elastic stiffness that the relays soften: T's stiffness just after a reversal
//! is S′, and falls along the branch as the relays switch.
//!
//! **The density** is piecewise constant on a grid: the thresholds' span [−R, R] of
//! x = θ − θ0 ([`Preisach::reach`]) in [`INTERVALS`] equal intervals of width h = 2R/INTERVALS,
//! cell (i, j) the relays with α in interval i and β in interval j ≤ i (the cells on the
//! diagonal are half squares, β ≤ α), each of total weight w_c ≥ 0 (N·m: what P gains when the
//! whole cell switches up). [`CELLS`] = 36 weights: linear in them, one non-negative
//! least-squares solve identifies the density (the host's fit).
//!
//! **Rest** is the demagnetised state, every relay up whose centre (α + β)/2 lies below 0 (the
//! micro-slip kind's rest: each element at the middle of its play). The first loading from rest
//! follows the virgin curve, P = V(x) (x ≥ 0) or −W(x) (x ≤ 0), Rayleigh's parabola x² for a
//! uniform density.
//!
//! **Evaluation through the turning points.** Along a branch from a turning point x_a with
//! H_a, the relays that switch are those of one triangle of the plane, and the Everett function
//! E(α, β) = Σ_c w_c · (fraction of cell c inside {β ≤ b ≤ a ≤ α}) gives
//!
//! ```text
//! rising from a minimum x_a:   H(x) = H_a − E(x, x_a)
//! falling from a maximum x_a:  H(x) = H_a + E(x_a, x)
//! ```
//!
//! E is tabulated at the grid's nodes when a set is prepared ([`PreparedPreisach`]); between
//! them it is the bilinear interpolation of the four nodes around (α, β) less the diagonal
//! cells' curvature (exact: the density is constant per cell), so a tick costs the same
//! whatever the grid and the stack hold: no sum over cells, no walk down the stack.
//!
//! **Beyond the grid** there are no relays: past ±R every relay has switched, H holds its
//! value and the stiffness is the spring's.
//!
//! **The micro-slip kind is the special case** of a density that depends on α − β only,
//! concentrated on the lines α − β = 2·d_i (Prandtl–Ishlinskii, Mayergoyz): the relays on one
//! line are the play operator of half-width d_i. On this kind's grid that family is the uniform
//! density, a continuum of elements with slip deflections spread evenly from 0 to R; the tests
//! compare the two there.
//!
//! Like the rest of the crate: `no_std`, no allocation, never panics, f32 and f64.
use crate::memory::{Alone, Finish, Hysteretic, Madelung, Shape, TurningPoint};
use crate::{Elementary, Error, Evaluation, Libm, Real};

/// The equal intervals of the thresholds' span [−R, R] (even: x = 0 is a node).
pub const INTERVALS: usize = 8;
/// Cells of the density: (i, j) with j ≤ i < [`INTERVALS`], stored at i(i+1)/2 + j.
pub const CELLS: usize = INTERVALS * (INTERVALS + 1) / 2;
/// Nodes (P, Q) with Q ≤ P ≤ [`INTERVALS`] where the Everett function is tabulated.
const NODES: usize = (INTERVALS + 1) * (INTERVALS + 2) / 2;
/// The node at x = 0.
const MIDDLE: usize = INTERVALS / 2;

/// The index of cell (i, j), j ≤ i, in [`Preisach::weights`].
pub const fn cell(i: usize, j: usize) -> usize {
    i * (i + 1) / 2 + j
}

/// The index of node (P, Q), Q ≤ P, in the Everett table.
const fn node(p: usize, q: usize) -> usize {
    p * (p + 1) / 2 + q
}

/// The Preisach kind's parameters.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Preisach<F> {
    /// R, rad: the thresholds' grid spans x ∈ [−R, R].
    pub reach: F,
    /// w of each cell (i, j) at [`cell`]`(i, j)`, N·m, ≥ 0: what P gains when the whole cell
    /// switches up.
    pub weights: [F; CELLS],
}

impl<F: Copy + Default> Default for Preisach<F> {
    fn default() -> Self {
        Preisach { reach: F::default(), weights: [F::default(); CELLS] }
    }
}

impl<F: Real> Preisach<F> {
    /// Whether R > 0 and every weight is ≥ 0, all finite ([`Error::InvalidPreisach`]).
    pub fn check(&self) -> Result<(), Error> {
        let valid = self.reach.is_finite()
            && self.reach > F::zero()
            && self.weights.iter().all(|w| w.is_finite() && *w >= F::zero());
        if valid {
            Ok(())
        } else {
            Err(Error::InvalidPreisach)
        }
    }

    /// Σ w_c, N·m: the most P can move, the hysteresis' largest |H|.
    pub fn total(&self) -> F {
        self.weights.iter().fold(F::zero(), |sum, w| sum + *w)
    }
}

// ---------------------------------------------------------------------------------------------
// The one copy of the density's geometry: each cell's share of a triangle and of the virgin
// regions, in node coordinates (u = (α + R)/h, v = (β + R)/h; node k at k). The evaluator's
// tables sum it at the nodes; the fit's columns ([`PreisachCells`]) evaluate it cell by cell.
// ---------------------------------------------------------------------------------------------

fn clamp01<F: Real>(t: F) -> F {
    if t < F::zero() {
        F::zero()
    } else if t > F::one() {
        F::one()
    } else {
        t
    }
}

fn weight<F: Real>(weights: &[F; CELLS], c: usize) -> F {
    weights.get(c).copied().unwrap_or(F::zero())
}

fn index<F: Real>(k: usize) -> F {
    F::from(k).unwrap_or(F::zero())
}

/// x in node coordinates, u = (x + R)/h with 1/h = `inv_h`, clamped to [0, INTERVALS], and
/// du/dx there (0 beyond the grid, where no relay is left to switch).
#[inline(always)]
fn coordinate<F: Real>(x: F, reach: F, inv_h: F) -> (F, F) {
    let u = (x + reach) * inv_h;
    let top = index::<F>(INTERVALS);
    if u >= top {
        (top, F::zero())
    } else if u <= F::zero() {
        (F::zero(), F::zero())
    } else {
        (u, inv_h)
    }
}

/// Whether node coordinate `t` lies in interval k, [k, k + 1): where a cell's share moves.
fn within<F: Real>(t: F, k: usize) -> bool {
    let low = index::<F>(k);
    t >= low && t < low + F::one()
}

/// The share of cell (i, j) inside the Everett triangle {v ≤ b ≤ a ≤ u} and its derivatives
/// in u and in v (right-continuous: a coordinate on a node counts in the interval above it).
fn triangle_share<F: Real>(i: usize, j: usize, u: F, v: F) -> (F, F, F) {
    let (zero, one) = (F::zero(), F::one());
    let (row, column) = (index::<F>(i), index::<F>(j));
    if i == j {
        // Half a square: the triangle {max(i, v) ≤ b ≤ a ≤ min(i + 1, u)}, side s.
        let top = if u < row + one { u } else { row + one };
        let bottom = if v > row { v } else { row };
        let s = top - bottom;
        if s <= zero {
            return (zero, zero, zero);
        }
        let s = if s > one { one } else { s };
        let two_s = s + s;
        let du = if within(u, i) { two_s } else { zero };
        let dv = if within(v, j) { -two_s } else { zero };
        (s * s, du, dv)
    } else {
        let across = clamp01(u - row);
        let down = clamp01(column + one - v);
        let du = if within(u, i) { down } else { zero };
        let dv = if within(v, j) { -across } else { zero };
        (across * down, du, dv)
    }
}

/// The share of cell (i, j) in the region the first loading from rest to u ≥ [`MIDDLE`]
/// switches up, {MIDDLE ≤ a ≤ u, a + b ≥ 2·MIDDLE, b ≤ a}, and its derivative in u.
fn virgin_up_share<F: Real>(i: usize, j: usize, u: F) -> (F, F) {
    let zero = F::zero();
    if i < MIDDLE {
        return (zero, zero);
    }
    let f = clamp01(u - index::<F>(i));
    let moving = within(u, i);
    let anti = INTERVALS - 1 - i;
    if j == i {
        (f * f, if moving { f + f } else { zero })
    } else if j == anti {
        // The square the line a + b = 2·MIDDLE halves: a triangle of legs f.
        let half = F::from(0.5).unwrap_or(zero);
        (half * f * f, if moving { f } else { zero })
    } else if j > anti {
        (f, if moving { F::one() } else { zero })
    } else {
        (zero, zero)
    }
}

/// The share of cell (i, j) in the region the first unloading from rest to v ≤ [`MIDDLE`]
/// switches down, {v ≤ b ≤ MIDDLE, a + b < 2·MIDDLE, b ≤ a}, and its derivative in v.
fn virgin_down_share<F: Real>(i: usize, j: usize, v: F) -> (F, F) {
    let zero = F::zero();
    if j >= MIDDLE {
        return (zero, zero);
    }
    let g = clamp01(index::<F>(j) + F::one() - v);
    let moving = within(v, j);
    let anti = INTERVALS - 1 - j;
    if i == j {
        (g * g, if moving { -(g + g) } else { zero })
    } else if i == anti {
        let half = F::from(0.5).unwrap_or(zero);
        (half * g * g, if moving { -g } else { zero })
    } else if i < anti {
        (g, if moving { -F::one() } else { zero })
    } else {
        (zero, zero)
    }
}

/// Every cell (i, j), in storage order.
fn cells() -> impl Iterator<Item = (usize, usize, usize)> {
    (0..INTERVALS).flat_map(|i| (0..=i).map(move |j| (cell(i, j), i, j)))
}

// ---------------------------------------------------------------------------------------------
// The evaluator: the Everett function tabulated, a branch by its fixed end
// ---------------------------------------------------------------------------------------------

/// A set prepared for evaluation: the Everett function at the grid's nodes, the diagonal cells'
/// weights (their curvature between nodes) and the virgin curves' coefficients per interval.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PreparedPreisach<F> {
    /// R, rad.
    reach: F,
    /// 1/h, rad⁻¹.
    inv_h: F,
    /// E at node (P, Q), Q ≤ P, at [`node`]`(P, Q)`.
    everett: [F; NODES],
    /// w of the diagonal cell (k, k).
    diagonal: [F; INTERVALS],
    /// V on row p ≥ MIDDLE (index p − MIDDLE) as V_p + a·f + b·f², f = u − p: [V_p, a, b].
    up: [[F; 3]; MIDDLE],
    /// W on column q < MIDDLE as W_q + a·g + b·g², g = q + 1 − v: [W_q, a, b].
    down: [[F; 3]; MIDDLE],
}

impl<F: Real> PreparedPreisach<F> {
    /// The tables of `preisach` (checked first).
    pub fn new(preisach: &Preisach<F>) -> Result<Self, Error> {
        preisach.check()?;
        let w = |i: usize, j: usize| weight(&preisach.weights, cell(i, j));
        let zero = F::zero();
        let inv_h = index::<F>(INTERVALS) / (preisach.reach + preisach.reach);
        // At the nodes every cell is in the triangle or out of it: E(P, Q) sums the cells
        // (i, j) with Q ≤ j ≤ i < P, row by row. (The cells' shares, which the fit's columns
        // use, give the same at the nodes: tested.)
        let mut everett = [zero; NODES];
        for p in 1..=INTERVALS {
            let row = p - 1;
            let mut along = zero;
            for q in (0..p).rev() {
                along = along + w(row, q);
                let below = if q < row { everett.get(node(row, q)).copied().unwrap_or(zero) } else { zero };
                if let Some(slot) = everett.get_mut(node(p, q)) {
                    *slot = below + along;
                }
            }
        }
        let mut diagonal = [zero; INTERVALS];
        for (k, slot) in diagonal.iter_mut().enumerate() {
            *slot = w(k, k);
        }
        // Each virgin curve, per interval: its value at the interval's start, then f (or g)
        // times the cells between the line a + b = 0 and the diagonal, and f² times the
        // diagonal cell and half the cell that line halves.
        let half = F::from(0.5).unwrap_or(zero);
        let mut up = [[zero; 3]; MIDDLE];
        let mut start = zero;
        for (k, slot) in up.iter_mut().enumerate() {
            let p = MIDDLE + k;
            let anti = INTERVALS - 1 - p;
            let between = (anti + 1..p).fold(zero, |sum, j| sum + w(p, j));
            let square = w(p, p) + half * w(p, anti);
            *slot = [start, between, square];
            start = start + between + square;
        }
        let mut down = [[zero; 3]; MIDDLE];
        let mut start = zero;
        for (q, slot) in down.iter_mut().enumerate().rev() {
            let anti = INTERVALS - 1 - q;
            let between = (q + 1..anti).fold(zero, |sum, i| sum + w(i, q));
            let square = w(q, q) + half * w(anti, q);
            *slot = [start, between, square];
            start = start + between + square;
        }
        Ok(PreparedPreisach { reach: preisach.reach, inv_h, everett, diagonal, up, down })
    }

    /// R, rad.
    pub fn reach(&self) -> F {
        self.reach
    }

    /// Σ w_c, N·m: the largest |H| (the Everett function over the whole grid).
    pub fn total(&self) -> F {
        self.at(INTERVALS, 0)
    }

    #[inline(always)]
    fn coordinate(&self, x: F) -> (F, F) {
        coordinate(x, self.reach, self.inv_h)
    }

    /// The interval of node coordinate t ∈ [0, INTERVALS] (the last for t = INTERVALS) and t's
    /// place in it, from 0 to 1.
    #[inline(always)]
    fn interval(t: F) -> (usize, F) {
        let end = End::of(t);
        (end.interval, end.place)
    }

    #[inline(always)]
    fn at(&self, p: usize, q: usize) -> F {
        self.everett.get(node(p, q)).copied().unwrap_or(F::zero())
    }

    /// E(u, v) and its derivatives in u and v, node coordinates within the grid, each end with
    /// its interval ([`End::of`]: a branch finds its fixed end's once).
    #[inline(always)]
    fn everett_at(&self, up: End<F>, down: End<F>) -> (F, F, F) {
        let zero = F::zero();
        let (u, v) = (up.at, down.at);
        if u <= v {
            return (zero, zero, zero);
        }
        let (p, f) = (up.interval, up.place);
        let (q, rest) = (down.interval, down.place);
        let w_pp = self.diagonal.get(p).copied().unwrap_or(zero);
        if p == q {
            // Within one diagonal cell: a triangle of side u − v.
            let s = u - v;
            return (w_pp * s * s, w_pp * (s + s), -(w_pp * (s + s)));
        }
        let g = F::one() - rest;
        let w_qq = self.diagonal.get(q).copied().unwrap_or(zero);
        let (n00, n10) = (self.at(p, q + 1), self.at(p + 1, q + 1));
        let (n01, n11) = (self.at(p, q), self.at(p + 1, q));
        let (along, down) = (n10 - n00, n01 - n00);
        let twist = n11 - n10 - down;
        let (one_f, one_g) = (F::one() - f, F::one() - g);
        let value = n00 + f * along + g * down + f * g * twist - w_pp * f * one_f - w_qq * g * one_g;
        let du = along + g * twist - w_pp * (one_f - f);
        // g falls as v rises.
        let dv = -(down + f * twist - w_qq * (one_g - g));
        (value, du, dv)
    }
}

/// A node coordinate with its interval (the last for t = INTERVALS) and its place in it, from
/// 0 to 1.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct End<F> {
    at: F,
    interval: usize,
    place: F,
}

impl<F: Real> End<F> {
    /// Node coordinate `t` ∈ [0, INTERVALS].
    #[inline(always)]
    fn of(t: F) -> Self {
        // t ≥ 0: truncation is the floor (a libm call less on the joint).
        let interval = t.to_usize().unwrap_or(0).min(INTERVALS - 1);
        End { at: t, interval, place: t - index::<F>(interval) }
    }
}

/// A branch of the Preisach kind: the turning point it starts from (its H and its node
/// coordinate) and which way it runs; or the virgin curve at rest.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum PreisachBranch<F> {
    /// From rest: the virgin curve.
    Virgin,
    /// From a minimum at `from` (β fixed, α = x).
    Rising { hysteresis: F, from: End<F> },
    /// From a maximum at `from` (α fixed, β = x).
    Falling { hysteresis: F, from: End<F> },
    /// A branch of zero width: H holds.
    Flat { hysteresis: F },
}

impl<F: Real> Shape<F> for PreparedPreisach<F> {
    type Value = F;
    type Output = Evaluation<F>;
    type Branch = PreisachBranch<F>;

    fn zero(&self) -> F {
        F::zero()
    }

    fn rest(&self) -> PreisachBranch<F> {
        PreisachBranch::Virgin
    }

    #[inline(always)]
    fn branch<E: Elementary<F>>(&self, from: TurningPoint<F>, to: TurningPoint<F>) -> PreisachBranch<F> {
        let at = End::of(self.coordinate(from.theta).0);
        let hysteresis = from.hysteresis;
        if to.theta > from.theta {
            PreisachBranch::Rising { hysteresis, from: at }
        } else if to.theta < from.theta {
            PreisachBranch::Falling { hysteresis, from: at }
        } else {
            PreisachBranch::Flat { hysteresis }
        }
    }

    /// Out of line: the memory's step evaluates in two places (on the branch, and after a
    /// change of it), and a copy in each was 1,016 B of the joint's flash; the call costs the
    /// tick up to 16 instructions (`bench/firmware.sh`: 372 → 388 at most, of 400).
    #[inline(never)]
    fn evaluate<E: Elementary<F>>(&self, branch: &PreisachBranch<F>, theta: F) -> Evaluation<F> {
        let (u, du_dx) = self.coordinate(theta);
        let at = End::of(u);
        // Rising: H_a − E(x, x_a), falling: H_a + E(x_a, x); one evaluation of E for both (a copy
        // of it per direction was 268 B of the joint's flash more).
        let (hysteresis, up, down, rising) = match *branch {
            PreisachBranch::Rising { hysteresis, from } => (hysteresis, at, from, true),
            PreisachBranch::Falling { hysteresis, from } => (hysteresis, from, at, false),
            PreisachBranch::Flat { hysteresis } => {
                return Evaluation { torque: hysteresis, stiffness: F::zero() };
            }
            PreisachBranch::Virgin => return self.virgin(u, du_dx),
        };
        let (e, de_up, de_down) = self.everett_at(up, down);
        if rising {
            Evaluation { torque: hysteresis - e, stiffness: -(de_up * du_dx) }
        } else {
            Evaluation { torque: hysteresis + e, stiffness: de_down * du_dx }
        }
    }

    #[inline(always)]
    fn value(output: &Evaluation<F>) -> F {
        output.torque
    }

    /// (−θ_a, H_a): the branch reads only its start's H; its target's is where the branch
    /// arrives, the virgin curve's value there.
    #[inline(always)]
    fn mirror(from: TurningPoint<F>) -> TurningPoint<F> {
        TurningPoint { theta: -from.theta, hysteresis: from.hysteresis }
    }
}

impl<F: Real> PreparedPreisach<F> {
    /// H on the virgin curve at node coordinate `u`: −V above the middle, W below.
    #[inline(always)]
    fn virgin(&self, u: F, du_dx: F) -> Evaluation<F> {
        let middle = index::<F>(MIDDLE);
        let zero = [F::zero(); 3];
        if u >= middle {
            let (p, f) = Self::interval(u);
            let [start, a, b] = self.up.get(p.saturating_sub(MIDDLE)).copied().unwrap_or(zero);
            let value = start + (a + b * f) * f;
            Evaluation { torque: -value, stiffness: -((a + (b + b) * f) * du_dx) }
        } else {
            let (q, rest) = Self::interval(u);
            let g = F::one() - rest;
            let [start, a, b] = self.down.get(q).copied().unwrap_or(zero);
            let value = start + (a + b * g) * g;
            // g falls as u rises.
            Evaluation { torque: value, stiffness: -((a + (b + b) * g) * du_dx) }
        }
    }
}

/// The Preisach kind's hysteresis with its memory: at most `N` turning points.
pub type PreisachMemory<F, const N: usize> = Madelung<F, PreparedPreisach<F>, N>;

impl<F: Real, const N: usize> Hysteretic<F> for Madelung<F, PreparedPreisach<F>, N> {
    fn reset(&mut self) {
        *self = Self::new(*self.shape(), self.band());
    }

    fn step(&mut self, theta: F) -> Result<Evaluation<F>, Error> {
        self.step_finishing::<Libm>(theta, Alone)
    }
}

// ---------------------------------------------------------------------------------------------
// The fit's columns: each cell's H at unit weight, along the same turning points
// ---------------------------------------------------------------------------------------------

/// Every cell's contribution to H at unit weight, h_c (so H = Σ w_c·h_c), and its slope in x:
/// the columns of a fit linear in the weights.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CellColumns<F> {
    pub value: [F; CELLS],
    pub slope: [F; CELLS],
}

/// The grid of a fit's columns: R and 1/h.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PreisachCells<F> {
    reach: F,
    inv_h: F,
}

impl<F: Real> PreisachCells<F> {
    /// The columns of a density on [−`reach`, `reach`] (R > 0, finite).
    pub fn new(reach: F) -> Result<Self, Error> {
        if !(reach.is_finite() && reach > F::zero()) {
            return Err(Error::InvalidPreisach);
        }
        Ok(PreisachCells { reach, inv_h: index::<F>(INTERVALS) / (reach + reach) })
    }

    fn coordinate(&self, x: F) -> (F, F) {
        coordinate(x, self.reach, self.inv_h)
    }
}

/// A branch of the columns: the start's columns and coordinate, and which way it runs.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CellBranch<F> {
    kind: PreisachBranch<F>,
    start: [F; CELLS],
}

impl<F: Real> Shape<F> for PreisachCells<F> {
    type Value = [F; CELLS];
    type Output = CellColumns<F>;
    type Branch = CellBranch<F>;

    fn zero(&self) -> [F; CELLS] {
        [F::zero(); CELLS]
    }

    fn rest(&self) -> CellBranch<F> {
        CellBranch { kind: PreisachBranch::Virgin, start: [F::zero(); CELLS] }
    }

    fn branch<E: Elementary<F>>(
        &self,
        from: TurningPoint<F, [F; CELLS]>,
        to: TurningPoint<F, [F; CELLS]>,
    ) -> CellBranch<F> {
        let at = End::of(self.coordinate(from.theta).0);
        let zero = F::zero();
        let kind = if to.theta > from.theta {
            PreisachBranch::Rising { hysteresis: zero, from: at }
        } else if to.theta < from.theta {
            PreisachBranch::Falling { hysteresis: zero, from: at }
        } else {
            PreisachBranch::Flat { hysteresis: zero }
        };
        CellBranch { kind, start: from.hysteresis }
    }

    fn evaluate<E: Elementary<F>>(&self, branch: &CellBranch<F>, theta: F) -> CellColumns<F> {
        let (u, du_dx) = self.coordinate(theta);
        let mut columns = CellColumns { value: branch.start, slope: [F::zero(); CELLS] };
        for (c, i, j) in cells() {
            let (value, slope) = match branch.kind {
                PreisachBranch::Rising { from, .. } => {
                    let (e, de, _) = triangle_share(i, j, u, from.at);
                    (-e, -de)
                }
                PreisachBranch::Falling { from, .. } => {
                    let (e, _, de) = triangle_share(i, j, from.at, u);
                    (e, de)
                }
                PreisachBranch::Flat { .. } => continue,
                PreisachBranch::Virgin => {
                    let (up, d_up) = virgin_up_share(i, j, u);
                    let (down, d_down) = virgin_down_share(i, j, u);
                    (down - up, d_down - d_up)
                }
            };
            if let (Some(v), Some(s)) = (columns.value.get_mut(c), columns.slope.get_mut(c)) {
                *v = *v + value;
                *s = slope * du_dx;
            }
        }
        columns
    }

    fn value(output: &CellColumns<F>) -> [F; CELLS] {
        output.value
    }

    fn mirror(from: TurningPoint<F, [F; CELLS]>) -> TurningPoint<F, [F; CELLS]> {
        TurningPoint { theta: -from.theta, hysteresis: from.hysteresis }
    }
}

impl<F: Real> Finish<CellColumns<F>> for Alone {
    fn finish(self, columns: CellColumns<F>) -> Result<CellColumns<F>, Error> {
        if columns.value.iter().chain(&columns.slope).all(|v| v.is_finite()) {
            Ok(columns)
        } else {
            Err(Error::Overflow)
        }
    }
}

/// Every cell's column along a motion from rest, by Madelung's rules with at most `N` turning
/// points: what the fit solves for the weights, stepped by the same rules as the evaluator.
pub type CellMemory<F, const N: usize> = Madelung<F, PreisachCells<F>, N>;

impl<F: Real, const N: usize> Madelung<F, PreisachCells<F>, N> {
    /// Moves to x (rad, from θ0): each cell's h_c and its slope there.
    pub fn columns(&mut self, x: F) -> Result<CellColumns<F>, Error> {
        self.step_finishing::<Libm>(x, Alone)
    }
}

#[cfg(test)]
mod tests;
