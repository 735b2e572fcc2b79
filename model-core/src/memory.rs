//! Hysteresis with memory for arbitrary motion: biased oscillations, small reversals inside
//! big ones, holds with dither.
//!
//! [`Loop`](crate::Loop) evaluates the paper's model on one symmetric loop of amplitude A. The
//! evaluators here are fed θ sample by sample from rest and keep what the motion has left
//! behind, in memory bounded by a const generic; both implement [`Hysteretic`]:
//!
//! - [`GeneticMemory`]: the paper's genetic model generalised by Madelung's rules (a stack of
//!   turning points, each branch a scaled genetic loop between its two ends; see [`branch`]).
//!   On a symmetric zero-centred loop it is exactly [`Loop::evaluate`](crate::Loop::evaluate).
//! - [`MicroSlip`]: an odd polynomial spring in parallel with M elasto-slip elements
//!   (Maxwell-slip, a discrete Iwan model), linear in its parameters for a host-side
//!   non-negative least-squares fit ([`SlipElements`] gives the fit's columns).
//!
//! Like the rest of the crate: `no_std`, no allocation, never panics, f32 and f64. A step that
//! returns an error leaves the evaluator as it was (the sample is skipped).
use crate::{Direction, Elementary, Error, Evaluation, Libm, Model, Real, Scale};

/// A hysteretic element fed the deflection θ sample by sample.
pub trait Hysteretic<F> {
    /// Back to rest: no history (what a parameter change does on the joint).
    fn reset(&mut self);
    /// Moves to deflection θ (rad); T and K there. A non-finite θ is
    /// [`Error::NonFiniteDeflection`]; an error leaves the state unchanged.
    fn step(&mut self, theta: F) -> Result<Evaluation<F>, Error>;
}

fn two<F: Real>() -> F {
    F::one() + F::one()
}

fn opposite(direction: Direction) -> Direction {
    match direction {
        Direction::Rising => Direction::Falling,
        Direction::Falling => Direction::Rising,
    }
}

/// `e`, or [`Error::Overflow`] where T or K is not finite.
#[inline(always)]
#[allow(clippy::eq_op)]
pub(crate) fn finite<F: Real>(e: Evaluation<F>) -> Result<Evaluation<F>, Error> {
    // x − x is 0 for every finite x and NaN for ±∞ and NaN: one comparison for both, where
    // `is_finite` tests each one's bits (twice the M4F's instructions, every tick).
    if (e.torque - e.torque) + (e.stiffness - e.stiffness) == F::zero() {
        Ok(e)
    } else {
        Err(Error::Overflow)
    }
}

/// What a step does with the hysteresis' H and dH/dθ before it writes its new state: adds a
/// spring and checks the sum (a trait rather than a closure, so that the tick's one call of it
/// is inlined whatever its size).
pub(crate) trait Finish<O> {
    /// T and K from H and dH/dθ (or a fit's columns from the shape's), or why they cannot be
    /// used (the state is then not written).
    fn finish(self, hysteresis: O) -> Result<O, Error>;
}

/// H and dH/dθ alone, checked.
pub(crate) struct Alone;

impl<F: Real> Finish<Evaluation<F>> for Alone {
    #[inline(always)]
    fn finish(self, hysteresis: Evaluation<F>) -> Result<Evaluation<F>, Error> {
        finite(hysteresis)
    }
}

/// The memory's own polynomial spring at θ added, where it has one; checked.
struct WithPolynomial<F> {
    polynomial: Option<crate::Polynomial<F>>,
    theta: F,
}

impl<F: Real> Finish<Evaluation<F>> for WithPolynomial<F> {
    #[inline(always)]
    fn finish(self, hysteresis: Evaluation<F>) -> Result<Evaluation<F>, Error> {
        finite(match self.polynomial {
            Some(polynomial) => polynomial.evaluate(self.theta).plus(hysteresis),
            None => hysteresis,
        })
    }
}

/// A band in rad: negative or NaN counts as 0 (as the firmware's direction tracker).
fn sanitise_band<F: Real>(band: F) -> F {
    if band > F::zero() {
        band
    } else {
        F::zero()
    }
}

// ---------------------------------------------------------------------------------------------
// Madelung's rules: a stack of turning points, whatever the branches between them
// ---------------------------------------------------------------------------------------------

/// A turning point of the motion: the deflection where θ reversed and what the hysteresis kept
/// there, `V`: its part H of the torque (N·m), or for a fit's columns each column's value.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct TurningPoint<F, V = F> {
    /// θ, rad.
    pub theta: F,
    /// H there: for the genetic kind T − (c1·θ + c2·θ³ + c3·θ⁵), N·m.
    pub hysteresis: V,
}

/// How the hysteresis runs between turning points: the one thing in which the kinds that
/// follow Madelung's rules ([`Madelung`]) differ.
pub trait Shape<F> {
    /// What a turning point keeps of the hysteresis.
    type Value: Copy + PartialEq + core::fmt::Debug;
    /// The hysteresis and its slope at a deflection.
    type Output: Copy;
    /// What a branch keeps, made when the branch changes, so that a step on it evaluates only
    /// what depends on θ.
    type Branch: Copy + PartialEq + core::fmt::Debug;

    /// The value at rest (H = 0).
    fn zero(&self) -> Self::Value;
    /// The branch at rest: the virgin curve, before the first turning point and after the last
    /// is wiped out.
    fn rest(&self) -> Self::Branch;
    /// The branch from turning point `from` heading for `to` (with the elementary functions of
    /// `E`, where the shape uses any).
    fn branch<E: Elementary<F>>(
        &self,
        from: TurningPoint<F, Self::Value>,
        to: TurningPoint<F, Self::Value>,
    ) -> Self::Branch;
    /// The hysteresis and its slope at `theta` (finite) on `branch`; not checked for
    /// finiteness (a step's [`Finish`] checks what it makes of it).
    fn evaluate<E: Elementary<F>>(&self, branch: &Self::Branch, theta: F) -> Self::Output;
    /// What a turning point at an evaluation keeps.
    fn value(output: &Self::Output) -> Self::Value;
    /// The target of a branch that starts at `from` with no point under it: the mirror
    /// deflection −θ_a, where the motion has wiped out every turning point and rejoins the
    /// virgin curve.
    fn mirror(from: TurningPoint<F, Self::Value>) -> TurningPoint<F, Self::Value>;
}

/// Where θ leaves the branch from θ_a = `from` to θ_b = `to` without a reversal, (below,
/// above): beyond θ_b (Madelung's wipe-out) and, when `retracing`, back past θ_a; ±∞ where it
/// cannot (a branch of zero width).
fn exits<F: Real>(from: F, to: F, retracing: bool) -> (F, F) {
    let (below, above) = (F::neg_infinity(), F::infinity());
    if to > from {
        (if retracing { from } else { below }, to)
    } else if to < from {
        (to, if retracing { from } else { above })
    } else {
        (below, above)
    }
}

/// Hysteresis with Madelung's rules, branches of shape `S`, at most `N` turning points (N ≥ 3,
/// checked at compile time): the genetic kind ([`GeneticMemory`]) and the Preisach kind
/// ([`crate::preisach`]).
///
/// The state is a stack of turning points (θ_k, H_k):
///
/// - **Rest (virgin).** Empty stack, H = 0, on the shape's virgin curve ([`Shape::rest`]).
/// - **Reversal.** When θ moves back by more than `band` rad from its extreme since the last
///   reversal (band 0: every sign change of Δθ), the extreme sample (θ_r, H_r) is pushed.
/// - **Branch.** From the top point a toward its target b, the point below it (or, when the
///   stack holds one point, the mirror deflection −θ_a, [`Shape::mirror`]), of the shape's
///   form.
/// - **Wipe-out.** When θ passes the target b, a and b are popped and θ continues on the
///   branch below, which passes through b; repeated while θ is beyond the new target. Popping
///   the last point returns to the virgin curve, which a branch from the bottom point meets
///   at its mirror. A reversal exactly at the target closes the inner loop first (a and b
///   popped, then b pushed again), so a steady loop does not grow the stack.
/// - **Overflow.** A reversal that finds the stack full is not recorded: the innermost
///   excursion (the smallest, since the stack's loops nest) retraces the current branch
///   backward, reversibly. If θ moves back past that branch's start a, a is popped and θ
///   continues on the branch a lay on (which passes through a). T stays continuous everywhere
///   and every stored point keeps its return-point memory; only excursions nested deeper
///   than N have no hysteresis of their own.
///
///   Dropping the newest stored pair instead and pushing the new reversal is continuous at the
///   reversal, but not later: the new point lies on the dropped inner branch, not on the
///   branch below, so T would jump when a later motion wipes it out.
///
/// With a band, a reversal is recognised only once θ is more than the band back from θ_r, and
/// that sample changes branch there: T moves by about the loops' difference over one band, as
/// in the symmetric model with the firmware's direction tracker. Band 0 is continuous.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Madelung<F: Real, S: Shape<F>, const N: usize> {
    shape: S,
    band: F,
    stack: [TurningPoint<F, S::Value>; N],
    depth: usize,
    /// The direction of motion; `None` at rest until θ leaves ±band.
    direction: Option<Direction>,
    /// The extreme θ in `direction` since the last reversal, with its H.
    extreme: TurningPoint<F, S::Value>,
    /// A reversal found the stack full: θ moves against the current branch.
    retracing: bool,
    /// The current branch's constants ([`Shape::rest`] at rest), made with the elementary
    /// functions of the step that changed the branch: a step with other functions evaluates
    /// them, so a caller that changes `E` mid-branch gets that branch's constants in the form
    /// they were made in.
    branch: S::Branch,
    /// Where θ leaves the current branch without a reversal ([`exits`]).
    exits: (F, F),
}

impl<F: Real, S: Shape<F>, const N: usize> Madelung<F, S, N> {
    /// At rest (virgin), with a direction band of `band` rad (negative or NaN counts as 0).
    pub fn new(shape: S, band: F) -> Self {
        const { assert!(N >= 3, "Madelung's memory needs room for N >= 3 turning points") };
        let rest = TurningPoint { theta: F::zero(), hysteresis: shape.zero() };
        let branch = shape.rest();
        Madelung {
            shape,
            band: sanitise_band(band),
            stack: [rest; N],
            depth: 0,
            direction: None,
            extreme: rest,
            retracing: false,
            branch,
            exits: exits(F::zero(), F::zero(), false),
        }
    }

    /// The shape of its branches (for the genetic kind, the paper's model).
    pub fn shape(&self) -> &S {
        &self.shape
    }

    /// The direction band, rad.
    pub fn band(&self) -> F {
        self.band
    }

    /// The direction of motion (`None` at rest, before θ has left ±band).
    pub fn direction(&self) -> Option<Direction> {
        self.direction
    }

    /// The stored turning points, oldest first.
    pub fn turning_points(&self) -> &[TurningPoint<F, S::Value>] {
        self.stack.get(..self.depth).unwrap_or(&[])
    }

    /// How many turning points are stored (≤ N).
    pub fn depth(&self) -> usize {
        self.depth
    }

    /// Whether a reversal found the stack full and θ is retracing the current branch.
    pub fn is_retracing(&self) -> bool {
        self.retracing
    }

    /// Moves to `theta` by Madelung's rules, with the elementary functions of `E`; the
    /// result is what `finish` makes of the shape's output there (a caller's sum with its
    /// spring, checked there), and the state is written only if that succeeds.
    ///
    /// Most samples neither reverse nor leave the current branch: they are evaluated on the
    /// branch's kept constants. The others change the stack ([`Madelung::restack`]) and make
    /// the new branch's constants. Either way a failed step changes nothing.
    #[inline(always)]
    pub(crate) fn step_finishing<E: Elementary<F>>(
        &mut self,
        theta: F,
        finish: impl Finish<S::Output>,
    ) -> Result<S::Output, Error> {
        if !theta.is_finite() {
            return Err(Error::NonFiniteDeflection);
        }
        let (direction, new_extreme, turned) = self.motion(theta);
        let (below, above) = self.exits;
        let (evaluation, h) = if !(turned || theta < below || theta > above) {
            let h = self.shape.evaluate::<E>(&self.branch, theta);
            (finish.finish(h)?, S::value(&h))
        } else {
            let plan = self.restack(theta, turned);
            let (branch, exits) = match plan.current {
                Some((from, to, _)) => {
                    let exits = exits(from.theta, to.theta, plan.retracing);
                    if plan.changed {
                        (self.shape.branch::<E>(from, to), exits)
                    } else {
                        // A retrace that starts or ends: the same branch, left elsewhere.
                        (self.branch, exits)
                    }
                }
                None => (self.shape.rest(), exits(F::zero(), F::zero(), false)),
            };
            let h = self.shape.evaluate::<E>(&branch, theta);
            let evaluation = finish.finish(h)?;
            self.branch = branch;
            self.exits = exits;
            if let Some(point) = plan.pushed {
                if let Some(slot) = self.stack.get_mut(plan.depth) {
                    *slot = point;
                }
            }
            self.depth = plan.depth + usize::from(plan.pushed.is_some());
            self.retracing = plan.retracing;
            (evaluation, S::value(&h))
        };
        self.direction = direction;
        if new_extreme {
            self.extreme = TurningPoint { theta, hysteresis: h };
        }
        Ok(evaluation)
    }

    /// Where `theta` moves the direction tracker: the direction then, whether θ is the new
    /// extreme, and whether it reversed (more than the band back from the extreme).
    #[inline(always)]
    fn motion(&self, theta: F) -> (Option<Direction>, bool, bool) {
        match self.direction {
            None => {
                if theta > self.band {
                    (Some(Direction::Rising), true, false)
                } else if theta < -self.band {
                    (Some(Direction::Falling), true, false)
                } else {
                    (None, false, false)
                }
            }
            Some(direction) => {
                let extreme = self.extreme.theta;
                let (onward, turned) = match direction {
                    Direction::Rising => (theta > extreme, theta < extreme - self.band),
                    Direction::Falling => (theta < extreme, theta > extreme + self.band),
                };
                if turned {
                    (Some(opposite(direction)), true, true)
                } else {
                    (Some(direction), onward, false)
                }
            }
        }
    }

    /// The current branch's constants made afresh from the stack with the elementary
    /// functions of `E` ([`Shape::rest`] at rest), and where θ leaves it.
    #[inline(always)]
    fn fresh_branch<E: Elementary<F>>(&self) -> (S::Branch, (F, F)) {
        match self.current() {
            None => (self.shape.rest(), exits(F::zero(), F::zero(), false)),
            Some((from, to, _)) => (self.shape.branch::<E>(from, to), exits(from.theta, to.theta, self.retracing)),
        }
    }

    /// The current branch: its start, its target, and whether the target is stored (not the
    /// mirror of a single point).
    #[inline(always)]
    fn current(&self) -> Option<Current<F, S::Value>> {
        let below = self.depth.checked_sub(1)?;
        let from = *self.stack.get(below)?;
        let (to, stored) = self.target_of(from, below);
        Some((from, to, stored))
    }

    fn push(&mut self, point: TurningPoint<F, S::Value>) -> bool {
        match self.stack.get_mut(self.depth) {
            Some(slot) => {
                *slot = point;
                self.depth += 1;
                true
            }
            None => false,
        }
    }

    /// The target of a branch that starts at `from` with the points `stack[..below]` under it:
    /// the top of those (stored), or when there are none the mirror of `from` (not stored).
    #[inline(always)]
    fn target_of(&self, from: TurningPoint<F, S::Value>, below: usize) -> (TurningPoint<F, S::Value>, bool) {
        match below.checked_sub(1).and_then(|i| self.stack.get(i)) {
            Some(to) => (*to, true),
            None => (S::mirror(from), false),
        }
    }

    /// The stack after a sample that reversed (`turned`) or left the current branch, by
    /// Madelung's rules, worked out without writing anything:
    ///
    /// - a reversal records the extreme (rule 1), unless it ends a retrace; reaching the
    ///   target exactly and turning there closes the inner loop first (its start and target
    ///   are popped, then the target pushed again), so a steady loop does not grow the stack;
    ///   a full stack records nothing and θ retraces the current branch;
    /// - θ past the current branch's target pops its start and target (rules 2 and 3), and
    ///   retracing back past its start pops the start, as often as θ is past the next one.
    ///
    /// A sample that did not turn left the branch through its exits: if not retracing, past
    /// its target, which the first pass of the wipe-out would only find again.
    ///
    /// Written out case by case (the pushed point first, then the stored ones), each point
    /// read once: this runs on the ticks that change the branch, the joint's dearest.
    #[inline(always)]
    fn restack(&self, theta: F, turned: bool) -> Restack<F, S::Value> {
        let (mut depth, mut retracing, mut changed) = (self.depth, self.retracing, false);
        let mut pushed = None;
        if turned {
            if retracing {
                // Back onto the branch being retraced: nothing to record.
                retracing = false;
            } else {
                let point = self.extreme;
                // The current branch's target (the point under the top, or the top's mirror)
                // and how many points closing the loop there pops.
                let target = match depth {
                    0 => None,
                    1 => self.stack.first().map(|p| (-p.theta, 1)),
                    _ => self.stack.get(depth - 2).map(|p| (p.theta, 2)),
                };
                if let Some((to, closed)) = target {
                    if point.theta == to {
                        depth -= closed;
                    }
                }
                if depth < N {
                    pushed = Some(point);
                    changed = true;
                } else {
                    // The stack is full (so nothing was popped above).
                    retracing = true;
                }
            }
        } else if !retracing {
            // Past the target: the branch's start and, unless it is the mirror, its target go
            // (a branch at depth 1 heads for the start's mirror).
            depth = depth.saturating_sub(2);
            changed = true;
        }
        // θ past the target of the branch from a pushed point pops it, and the target too;
        // the push ended any retrace, so θ cannot be back past its start.
        if let Some(from) = pushed {
            let (to, stored) = self.target_of(from, depth);
            if !passes(from.theta, to.theta, theta) {
                return Restack { depth, pushed, retracing, current: Some((from, to, stored)), changed };
            }
            pushed = None;
            depth -= usize::from(stored);
        }
        // Each pass pops at least one point, so this ends.
        let mut points = self.stack.get(..depth).unwrap_or_default();
        let current = loop {
            let Some((&from, below)) = points.split_last() else { break None };
            let (to, stored) = match below.last() {
                Some(&to) => (to, true),
                None => (S::mirror(from), false),
            };
            let past_target = passes(from.theta, to.theta, theta);
            // Retraced back past the branch's start: θ continues on the branch it lay on.
            let back_past_start = retracing && passes(to.theta, from.theta, theta);
            if !(past_target || back_past_start) {
                break Some((from, to, stored));
            }
            // The start goes, and past the target the target too.
            points = below;
            if !past_target {
                retracing = false;
            } else if let Some((_, rest)) = below.split_last() {
                points = rest;
            }
            changed = true;
        };
        let depth = points.len();
        Restack { depth, pushed, retracing, current, changed }
    }
}

/// Whether θ has passed `to` on the way from `from` (beyond it, on the far side from `from`);
/// never when the two are equal.
#[inline(always)]
fn passes<F: Real>(from: F, to: F, theta: F) -> bool {
    (to > from && theta > to) || (to < from && theta < to)
}

/// The current branch: its start, its target, and whether the target is stored (not the mirror
/// of a single point).
type Current<F, V> = (TurningPoint<F, V>, TurningPoint<F, V>, bool);

/// The stack after a step that changes it ([`Madelung::restack`]): the points
/// `stack[..depth]` kept, `pushed` on top of them, the current branch there and whether it
/// differs from the one before.
struct Restack<F, V> {
    depth: usize,
    pushed: Option<TurningPoint<F, V>>,
    retracing: bool,
    current: Option<Current<F, V>>,
    changed: bool,
}

// ---------------------------------------------------------------------------------------------
// Kind 1: the genetic model with Madelung's rules
// ---------------------------------------------------------------------------------------------

/// The hysteretic part H (and dH/dθ, as an [`Evaluation`]) at `theta` on the branch that
/// starts at the turning point `from` = (θ_a, H_a) and heads for `to` = (θ_b, H_b):
///
/// ```text
/// H(θ) = H_a·(1 − s) + H_b·s + z(θ − c; w, direction)
/// s = (θ − θ_a)/(θ_b − θ_a),  c = (θ_a + θ_b)/2,  w = |θ_b − θ_a|/2,  direction = sign(θ_b − θ_a)
/// ```
///
/// with z the paper's hysteresis term on a symmetric loop of amplitude w (h = w·k, through
/// [`Model::scale_with`] and [`Model::hysteresis_with`], as [`Loop::evaluate_parts`](crate::Loop::evaluate_parts),
/// so the math is the crate's one copy). dH/dθ = (H_b − H_a)/(θ_b − θ_a) + dz/dθ.
///
/// Why this shape:
/// - **Exact on symmetric loops.** With the ends (∓A, 0) it is z of [`Loop`](crate::Loop) at
///   amplitude A, bit for bit (c = 0, w = A).
/// - **Continuity and return-point memory.** z vanishes at both ends of its loop, so the
///   branch starts exactly at `from` and ends exactly at `to` (at s = 0 and s = 1 the term is
///   evaluated at its clamped end, where it is 0).
/// - **Amplitude dependence as in the paper.** An inner branch is the paper's loop of the
///   inner excursion's own half-width: h ∝ w, so a small loop opens proportionally less, as
///   the paper's h = A·k does for a small symmetric loop.
///
/// Outside the branch (s < 0 or s > 1) the straight part holds its end value and z its edge
/// slope, as [`Loop`](crate::Loop) beyond ±A. A branch of zero width (or one so narrow that
/// 1/w overflows) is flat: H = H_a, no z.
pub fn branch<F: Real>(
    model: &Model<F>,
    from: TurningPoint<F>,
    to: TurningPoint<F>,
    theta: F,
) -> Result<Evaluation<F>, Error> {
    branch_with::<F, Libm>(model, from, to, theta)
}

/// [`branch`] with the elementary functions of `E` (ln, exp, asin, √): the firmware's fast
/// path runs this same formula with its polynomial approximations.
#[inline(always)]
pub fn branch_with<F: Real, E: Elementary<F>>(
    model: &Model<F>,
    from: TurningPoint<F>,
    to: TurningPoint<F>,
    theta: F,
) -> Result<Evaluation<F>, Error> {
    if !theta.is_finite() {
        return Err(Error::NonFiniteDeflection);
    }
    finite(model.evaluate::<E>(&model.branch::<E>(from, to), theta))
}

/// What [`branch`] computes from a branch's two ends before it looks at θ: the loop's centre,
/// half-span, direction and [`Scale`], the straight part's ends and slope. A
/// [`GeneticMemory`] keeps its current branch's, made when the branch changes (a reversal, a
/// wipe-out, the end of a retrace), so that a tick on the branch evaluates only what depends
/// on θ.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Branch<F> {
    /// H_a and H_b, the hysteretic part at the ends.
    from: F,
    to: F,
    /// θ_a/2.
    start: F,
    /// (θ_b − θ_a)/2, signed.
    span: F,
    /// c = θ_a/2 + θ_b/2.
    centre: F,
    /// (H_b − H_a)/(θ_b − θ_a).
    slope: F,
    direction: Direction,
    /// The loop's 1/w and h; `None` for a flat branch (zero width, or 1/w overflows).
    scale: Option<Scale<F>>,
}

impl<F: Real> Shape<F> for Model<F> {
    type Value = F;
    type Output = Evaluation<F>;
    type Branch = Branch<F>;

    fn zero(&self) -> F {
        F::zero()
    }

    /// At rest: H = 0 everywhere.
    #[inline(always)]
    fn rest(&self) -> Branch<F> {
        let zero = F::zero();
        Branch {
            from: zero,
            to: zero,
            start: zero,
            span: zero,
            centre: zero,
            slope: zero,
            direction: Direction::Rising,
            scale: None,
        }
    }

    /// The constants of the branch from `from` to `to`, with the elementary functions of `E`
    /// (h = w·k: see [`Model::scale_with`]). Not checked: where h overflows, no evaluation on
    /// the branch is finite.
    #[inline(always)]
    fn branch<E: Elementary<F>>(&self, from: TurningPoint<F>, to: TurningPoint<F>) -> Branch<F> {
        let half = two::<F>().recip();
        // Halves first: (θ_b − θ_a)/2 cannot overflow, and halving is exact.
        let (start, end) = (from.theta * half, to.theta * half);
        let span = end - start;
        let width = span.abs();
        let inv_width = width.recip();
        let (ends, zero) = ((from.hysteresis, to.hysteresis), F::zero());
        // 1/w ≥ 0 is never NaN: +∞ for w = 0 and for widths whose reciprocal overflows.
        if inv_width == F::infinity() {
            // Zero width, or one so narrow that 1/w overflows: flat.
            let direction = if span > zero { Direction::Rising } else { Direction::Falling };
            let (from, to) = ends;
            return Branch { from, to, start, span, centre: zero, slope: zero, direction, scale: None };
        }
        // The span is not 0, so its sign is that of θ_b − θ_a (halving keeps the order).
        let direction = if span > zero { Direction::Rising } else { Direction::Falling };
        let slope = (to.hysteresis * half - from.hysteresis * half) / span;
        let scale = Some(self.scale_of::<E>(width, inv_width));
        let (from, to) = ends;
        Branch { from, to, start, span, centre: start + end, slope, direction, scale }
    }

    /// H and dH/dθ at `theta` (finite), with the elementary functions of `E`; not checked for
    /// finiteness (a step adds them to the spring's T and K and checks the sums, which are
    /// not finite when they are not).
    #[inline(always)]
    fn evaluate<E: Elementary<F>>(&self, branch: &Branch<F>, theta: F) -> Evaluation<F> {
        let Some(scale) = &branch.scale else {
            return Evaluation { torque: branch.from, stiffness: F::zero() };
        };
        let half = two::<F>().recip();
        // s is exactly 0 at θ_a and exactly 1 at θ_b. At and past the ends s is clamped and
        // θ − c is beyond the loop's end (clamped there), where z = 0.
        let s = (theta * half - branch.start) / branch.span;
        // θ − c beyond the loop's end (clamped there) at and past the ends, where z = 0; ±∞
        // where 1.5·span overflows clamps to the end all the same. Made here, on the rare ticks
        // that need it, rather than kept with the branch.
        let beyond = || branch.span + branch.span * half;
        let (s, offset) = if s >= F::one() {
            (F::one(), beyond())
        } else if s <= F::zero() {
            (F::zero(), -beyond())
        } else {
            (s, theta - branch.centre)
        };
        let z = self.hysteresis_with::<E>(scale, offset, branch.direction);
        let line = branch.from * (F::one() - s) + branch.to * s;
        Evaluation { torque: line + z.torque, stiffness: branch.slope + z.stiffness }
    }

    #[inline(always)]
    fn value(output: &Evaluation<F>) -> F {
        output.torque
    }

    /// (−θ_a, −H_a): the genetic kind's virgin curve is H = 0, and a branch from the bottom
    /// point heads for the point opposite it.
    #[inline(always)]
    fn mirror(from: TurningPoint<F>) -> TurningPoint<F> {
        TurningPoint { theta: -from.theta, hysteresis: -from.hysteresis }
    }
}

/// The paper's genetic model for any motion, generalised by Madelung's rules ([`Madelung`]:
/// the stack, its wipe-outs, its overflow and the band), at most `N` turning points.
///
/// T = poly(θ) + H, poly the model's memoryless spring c1·θ + c2·θ³ + c3·θ⁵ and H the
/// hysteretic part, on each branch of the shape of [`branch`]. The virgin curve is H = 0: the
/// bottom point was pushed from rest (H = 0) or by [`GeneticMemory::on_loop`] (H = 0), and the
/// overflow rule never removes it, so the mirror target is on the virgin curve and the return
/// to H = 0 is continuous.
pub type GeneticMemory<F, const N: usize> = Madelung<F, Model<F>, N>;

impl<F: Real, const N: usize> Madelung<F, Model<F>, N> {
    /// At θ = 0 on the steady symmetric loop of amplitude `amplitude` (rad), moving in
    /// `direction`: stack [(A, 0), (−A, 0)] rising, [(−A, 0), (A, 0)] falling. A sine of
    /// amplitude A from θ = 0 then gives exactly [`Loop::evaluate`](crate::Loop::evaluate) from
    /// its first sample, turning points included, when its samples reach ±A (a peak sample
    /// short of A turns onto a branch narrower by that shortfall, by Madelung's rules).
    pub fn on_loop(model: Model<F>, band: F, amplitude: F, direction: Direction) -> Result<Self, Error> {
        if !(amplitude.is_finite() && amplitude > F::zero()) {
            return Err(Error::InvalidAmplitude);
        }
        let mut memory = Self::new(model, band);
        let (bottom, top) = match direction {
            Direction::Rising => (amplitude, -amplitude),
            Direction::Falling => (-amplitude, amplitude),
        };
        memory.push(TurningPoint { theta: bottom, hysteresis: F::zero() });
        memory.push(TurningPoint { theta: top, hysteresis: F::zero() });
        (memory.branch, memory.exits) = memory.fresh_branch::<Libm>();
        let at_rest = memory.hysteresis(F::zero())?;
        memory.direction = Some(direction);
        memory.extreme = TurningPoint { theta: F::zero(), hysteresis: at_rest.torque };
        Ok(memory)
    }

    /// The model's parameters.
    pub fn model(&self) -> &Model<F> {
        &self.shape
    }

    /// H and dH/dθ at `theta` on the current branch, without moving.
    pub fn hysteresis(&self, theta: F) -> Result<Evaluation<F>, Error> {
        self.hysteresis_with::<Libm>(theta)
    }

    /// [`GeneticMemory::hysteresis`] with the elementary functions of `E`.
    #[inline(always)]
    pub fn hysteresis_with<E: Elementary<F>>(&self, theta: F) -> Result<Evaluation<F>, Error> {
        match self.current() {
            None if theta.is_finite() => Ok(Evaluation { torque: F::zero(), stiffness: F::zero() }),
            None => Err(Error::NonFiniteDeflection),
            Some((from, to, _)) => branch_with::<F, E>(&self.shape, from, to, theta),
        }
    }

    /// [`Hysteretic::step`] with the elementary functions of `E` (the firmware's fast path):
    /// the same state, the same turning-point logic, so a caller may change `E` from one
    /// sample to the next.
    #[inline]
    pub fn step_with<E: Elementary<F>>(&mut self, theta: F) -> Result<Evaluation<F>, Error> {
        // A gear's model adds its spring itself: its hysteresis' model has none to evaluate.
        let polynomial = self.shape.has_spring().then_some(self.shape.polynomial);
        self.step_finishing::<E>(theta, WithPolynomial { polynomial, theta })
    }
}

impl<F: Real, const N: usize> Hysteretic<F> for Madelung<F, Model<F>, N> {
    fn reset(&mut self) {
        *self = Self::new(self.shape, self.band);
    }

    fn step(&mut self, theta: F) -> Result<Evaluation<F>, Error> {
        self.step_with::<Libm>(theta)
    }
}

// ---------------------------------------------------------------------------------------------
// Kind 2: Maxwell-slip / Iwan
// ---------------------------------------------------------------------------------------------

/// The slip deflections d_0 < … < d_(M−1) of the M elements: a log grid from `slip_min` to
/// `slip_max` (rad), d_i = d_min·(d_max/d_min)^(i/(M−1)), both ends exact; M = 1 gives
/// `[d_min]`. Needs 0 < d_min < d_max, both finite ([`Error::InvalidSlipRange`]).
pub fn slip_grid<F: Real, const M: usize>(slip_min: F, slip_max: F) -> Result<[F; M], Error> {
    if !(slip_min.is_finite() && slip_max.is_finite() && F::zero() < slip_min && slip_min < slip_max) {
        return Err(Error::InvalidSlipRange);
    }
    let (ln_min, ln_max) = (slip_min.ln(), slip_max.ln());
    let last = M.saturating_sub(1);
    let steps = F::from(last).ok_or(Error::Overflow)?;
    let mut grid = [slip_min; M];
    for (i, d) in grid.iter_mut().enumerate() {
        *d = if i == 0 {
            slip_min
        } else if i == last {
            slip_max
        } else {
            let fraction = F::from(i).ok_or(Error::Overflow)? / steps;
            (ln_min + fraction * (ln_max - ln_min)).exp()
        };
    }
    Ok(grid)
}

/// One elasto-slip element of the micro-slip kind: a spring of stiffness k in series with a
/// slider that slips when the spring's deflection reaches d.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct SlipElement<F> {
    /// d, rad (> 0).
    pub slip: F,
    /// k, N·m/rad (≥ 0).
    pub stiffness: F,
}

/// The M elasto-slip elements alone, each with unit stiffness: element i's elastic deflection
/// e_i (its spring's torque per N·m/rad of k_i). What a fit steps through a recording to build
/// its columns: T = c1·θ + c2·θ³ + c3·θ⁵ + Σ k_i·e_i is linear in (c1, c2, c3, k_1 … k_M),
/// with the columns θ, θ³, θ⁵, e_1 … e_M (and for the stiffness 1, 3θ², 5θ⁴ and 1 for each
/// element that sticks, 0 for one that slips), so non-negative least squares on the k_i
/// identifies them exactly, by the same code that [`MicroSlip`] runs.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SlipElements<F, const M: usize> {
    slip: [F; M],
    elastic: [F; M],
    theta: F,
}

impl<F: Real, const M: usize> SlipElements<F, M> {
    /// At rest (θ = 0, every e_i = 0), with slip deflections `slip` (each finite > 0, rad;
    /// otherwise [`Error::InvalidSlipRange`]).
    pub fn new(slip: [F; M]) -> Result<Self, Error> {
        if slip.iter().any(|d| !(d.is_finite() && *d > F::zero())) {
            return Err(Error::InvalidSlipRange);
        }
        Ok(SlipElements { slip, elastic: [F::zero(); M], theta: F::zero() })
    }

    /// The elements of the log grid [`slip_grid`]`(slip_min, slip_max)`, at rest.
    pub fn on_grid(slip_min: F, slip_max: F) -> Result<Self, Error> {
        Self::new(slip_grid(slip_min, slip_max)?)
    }

    /// Back to rest: θ = 0, every e_i = 0.
    pub fn reset(&mut self) {
        self.elastic = [F::zero(); M];
        self.theta = F::zero();
    }

    /// Moves to θ (rad): e_i ← clamp(e_i + Δθ, −d_i, d_i).
    pub fn step(&mut self, theta: F) -> Result<(), Error> {
        if !theta.is_finite() {
            return Err(Error::NonFiniteDeflection);
        }
        let delta = theta - self.theta;
        for (e, d) in self.elastic.iter_mut().zip(self.slip.iter()) {
            (*e, _) = slide::<F, { Heading::Either as u8 }>(*e, delta, *d);
        }
        self.theta = theta;
        Ok(())
    }

    /// The last θ, rad.
    pub fn theta(&self) -> F {
        self.theta
    }

    /// The slip deflections d_i, rad.
    pub fn slip(&self) -> &[F; M] {
        &self.slip
    }

    /// The elastic deflections e_i, rad: the torque of each element per unit stiffness.
    pub fn elastic(&self) -> &[F; M] {
        &self.elastic
    }

    /// Whether each element sticks (|e_i| < d_i: its spring adds to the stiffness) or slips
    /// (at its limit).
    pub fn sticking(&self) -> [bool; M] {
        let mut sticking = [false; M];
        for (s, (e, d)) in sticking.iter_mut().zip(self.elastic.iter().zip(self.slip.iter())) {
            *s = e.abs() < *d;
        }
        sticking
    }
}

/// Which way Δθ moves the elements: [`slide`]'s limits to test.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Heading {
    /// Δθ > 0: only +d can be reached.
    Up,
    /// Δθ < 0: only −d can be reached.
    Down,
    /// Δθ = 0: none; e stays.
    Still,
    /// Any Δθ: both.
    Either,
}

/// Element e moved by Δθ: clamp(e + Δθ, −d, d), and whether it sticks there (|e| < d) or slips
/// (at ±d). The one formula of [`SlipElements::step`] and [`MicroSlip`]'s step, so the fit's
/// columns are what the joint evaluates. Finite θs make Δθ finite or ±∞, never NaN, so
/// e + Δθ is never NaN and e stays finite; then this is exactly the clamp (e + Δθ = ±d gives
/// ±d either way).
///
/// `HEADING` says which limits Δθ can reach. An element lies within [−d, d], so one moved up
/// stays above −d (at most rounded to it: it left the limit, and sticks) and needs one
/// comparison, not two: on the M4F's tick that is 4 instructions an element that sticks.
#[inline(always)]
fn slide<F: Real, const HEADING: u8>(e: F, delta: F, d: F) -> (F, bool) {
    let moved = e + delta;
    if HEADING == Heading::Up as u8 {
        if moved >= d {
            return (d, false);
        }
    } else if HEADING == Heading::Down as u8 {
        if moved <= -d {
            return (-d, false);
        }
    } else if HEADING == Heading::Still as u8 {
        return (e, e.abs() < d);
    } else {
        if moved >= d {
            return (d, false);
        }
        if moved <= -d {
            return (-d, false);
        }
    }
    (moved, true)
}

/// Maxwell-slip (a discrete Iwan model): up to M elasto-slip elements, element i a spring k_i in
/// series with a slider that slips when the spring's deflection reaches d_i (each element its
/// own d_i); the gear's spring is added by its model ([`crate::GearModel`]).
///
/// H = Σ k_i·e_i; dH/dθ = Σ k_i over the sticking elements (|e_i| < d_i, or moved off its limit
/// by less than e_i's rounding). Madelung's rules hold exactly; the loops are rate-independent
/// and point-symmetric (Masing's rule).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MicroSlip<F, const M: usize> {
    /// Each element's d and k side by side: the tick loads the two of an element at once.
    elements: [SlipElement<F>; M],
    elastic: [F; M],
    theta: F,
    /// Elements in use: the first `count`.
    count: usize,
    /// How many elements slip (|e_i| = d_i), counted by the step that moved them.
    slipping: usize,
}

impl<F: Real, const M: usize> MicroSlip<F, M> {
    /// At rest, with `elements` (at most M; each d_i finite > 0 ([`Error::InvalidSlipRange`]),
    /// each k_i finite ≥ 0 ([`Error::InvalidSlipStiffness`])).
    pub fn new(elements: &[SlipElement<F>]) -> Result<Self, Error> {
        if elements.len() > M {
            return Err(Error::InvalidSlipRange);
        }
        let mut stored = [SlipElement { slip: F::one(), stiffness: F::zero() }; M];
        for (i, (element, slot)) in elements.iter().zip(stored.iter_mut()).enumerate() {
            if !(element.slip.is_finite() && element.slip > F::zero()) {
                return Err(Error::InvalidSlipRange);
            }
            if !(element.stiffness.is_finite() && element.stiffness >= F::zero()) {
                return Err(Error::InvalidSlipStiffness(i));
            }
            *slot = *element;
        }
        Ok(MicroSlip {
            elements: stored,
            elastic: [F::zero(); M],
            theta: F::zero(),
            count: elements.len(),
            slipping: 0,
        })
    }

    /// No elements (H = 0 everywhere).
    pub(crate) fn none() -> Self {
        let zero = F::zero();
        let unused = SlipElement { slip: F::one(), stiffness: zero };
        MicroSlip { elements: [unused; M], elastic: [zero; M], theta: zero, count: 0, slipping: 0 }
    }

    /// The elements in use: each d_i (rad) and k_i (N·m/rad).
    pub fn elements(&self) -> &[SlipElement<F>] {
        self.elements.get(..self.count).unwrap_or(&[])
    }

    /// The elements' elastic deflections e_i, rad.
    pub fn elastic(&self) -> &[F] {
        self.elastic.get(..self.count).unwrap_or(&[])
    }

    /// How many elements slip (|e_i| = d_i): none at rest (what the joint reports as the
    /// micro-slip kind's memory every tick, counted by the step rather than again here).
    pub fn slipping(&self) -> usize {
        self.slipping
    }
}

impl<F: Real, const M: usize> MicroSlip<F, M> {
    /// [`Hysteretic::step`] whose result is what `finish` makes of H and dH/dθ (a caller's sum
    /// with its spring, checked there): the new deflections are committed only if that succeeds.
    ///
    /// One pass over the elements moves each, sums H and dH/dθ and counts the slipping ones.
    /// (Stepping a copy of the elements, evaluating it in a second pass and counting in a third
    /// cost the M4F far more instructions per tick.)
    #[inline(always)]
    pub(crate) fn step_finishing(
        &mut self,
        theta: F,
        finish: impl Finish<Evaluation<F>>,
    ) -> Result<Evaluation<F>, Error> {
        if !theta.is_finite() {
            return Err(Error::NonFiniteDeflection);
        }
        let delta = theta - self.theta;
        let mut elastic = self.elastic;
        let (total, slipping) = if delta > F::zero() {
            self.slide_all::<{ Heading::Up as u8 }>(&mut elastic, delta)
        } else if delta < F::zero() {
            self.slide_all::<{ Heading::Down as u8 }>(&mut elastic, delta)
        } else {
            self.slide_all::<{ Heading::Still as u8 }>(&mut elastic, delta)
        };
        let evaluation = finish.finish(total)?;
        self.elastic = elastic;
        self.theta = theta;
        self.slipping = slipping;
        Ok(evaluation)
    }
}

impl<F: Real, const M: usize> MicroSlip<F, M> {
    /// `elastic` moved by Δθ = `delta`, element by element ([`slide`], testing the limit Δθ
    /// heads for): H, dH/dθ and how many elements slip.
    #[inline(always)]
    fn slide_all<const HEADING: u8>(&self, elastic: &mut [F; M], delta: F) -> (Evaluation<F>, usize) {
        let mut total = Evaluation { torque: F::zero(), stiffness: F::zero() };
        let mut slipping = 0;
        let elements = &self.elements;
        // Every slot, the unused too (k = 0, d = 1 rad: they never slip): the worst case, all M
        // in use, is what the tick is budgeted for. Four slots a pass, written out here: a loop
        // of one slot a pass is not unrolled where the tick is compiled for size, and zipped
        // iterators left `Zip::new` a call of its own (`bench/firmware.sh`).
        let mut at = 0;
        while at + 4 <= M {
            slide_slot::<F, HEADING, M>(elastic, elements, at, delta, &mut total, &mut slipping);
            slide_slot::<F, HEADING, M>(elastic, elements, at + 1, delta, &mut total, &mut slipping);
            slide_slot::<F, HEADING, M>(elastic, elements, at + 2, delta, &mut total, &mut slipping);
            slide_slot::<F, HEADING, M>(elastic, elements, at + 3, delta, &mut total, &mut slipping);
            at += 4;
        }
        while at < M {
            slide_slot::<F, HEADING, M>(elastic, elements, at, delta, &mut total, &mut slipping);
            at += 1;
        }
        (total, slipping)
    }
}

/// Slot `i` of the elements moved by Δθ = `delta` ([`slide`]), added to H and dH/dθ, counted
/// when it slips.
#[inline(always)]
fn slide_slot<F: Real, const HEADING: u8, const M: usize>(
    elastic: &mut [F; M],
    elements: &[SlipElement<F>; M],
    i: usize,
    delta: F,
    total: &mut Evaluation<F>,
    slipping: &mut usize,
) {
    if let (Some(e), Some(&SlipElement { slip: d, stiffness: k })) = (elastic.get_mut(i), elements.get(i)) {
        let sticks;
        (*e, sticks) = slide::<F, HEADING>(*e, delta, d);
        total.torque = total.torque + k * *e;
        if sticks {
            total.stiffness = total.stiffness + k;
        } else {
            *slipping += 1;
        }
    }
}

impl<F: Real, const M: usize> Hysteretic<F> for MicroSlip<F, M> {
    fn reset(&mut self) {
        self.elastic = [F::zero(); M];
        self.theta = F::zero();
        self.slipping = 0;
    }

    /// H and dH/dθ; the new deflections are committed only if both are finite.
    fn step(&mut self, theta: F) -> Result<Evaluation<F>, Error> {
        self.step_finishing(theta, Alone)
    }
}

#[cfg(test)]
mod tests;
