//! The gear's elastic (memoryless) torque S(x) as a function of x = θ − θ0, the deflection from
//! its zero: every kind adds its hysteresis to it.
//!
//! ```text
//! S(x) = c1·x + c2·x³ + c3·x⁵ + P(x),   P(x) = ∫₀ˣ k(u) du
//! k(u) = the stiffness at the knots x_0 < … < x_(n−1), linear between them, constant beyond
//! ```
//!
//! - **Free form, linear in its parameters.** With the knots fixed, S is linear in c1, c2, c3 and
//!   the knots' stiffnesses K_j: P = Σ K_j·B_j(x), B_j the integral from 0 of the hat function of
//!   knot j ([`basis`]), so a fit solves for them exactly. K_j ≥ 0 makes P monotone (the stiffness
//!   between knots interpolates non-negative values); the fit asks that, as the physics does.
//! - **Asymmetric.** The knots and their stiffnesses on the + and − sides are independent.
//! - **Special cases.** The paper's odd polynomial is the spring without knots; the catalogue's
//!   three-segment curve (stiffness K1, K2, K3 with steps at two torques) is knots in pairs close
//!   around each step.
//! - **Beyond the identified range** [`Spring::range`] it continues with its stiffness at the
//!   range's edge: a straight line, never the polynomial's runaway. Host and joint alike.
use crate::{Error, Evaluation, ParamFault, ParamName, Polynomial, Real};

/// Most knots a spring has: 8 a side and the one at x = 0.
pub const MAX_KNOTS: usize = 17;

/// One knot of the stiffness curve.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Knot<F> {
    /// x, rad (from the deflection's zero).
    pub x: F,
    /// The stiffness there, N·m/rad.
    pub stiffness: F,
}

/// The spring: an odd polynomial plus a piecewise-linear stiffness on knots, within an identified
/// range of x. See the module's documentation.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(bound(deserialize = "F: serde::Deserialize<'de> + Default + Copy")))]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Spring<F> {
    /// N·m/rad.
    pub c1: F,
    /// N·m/rad³.
    pub c2: F,
    /// N·m/rad⁵.
    pub c3: F,
    /// The knots, x increasing; the first `knot_count` are used.
    #[cfg_attr(feature = "serde", serde(with = "crate::serde_array::prefix", rename = "knots"))]
    pub knots: ([Knot<F>; MAX_KNOTS], u8),
    /// The identified range of x, [lo, hi] rad, lo ≤ 0 ≤ hi: beyond it the spring continues with
    /// the stiffness at its edge.
    pub range: [F; 2],
}

/// x beyond which no gear deflects, rad: the range of a spring that was not fitted on a
/// recording (the paper's polynomial of a loop table, a params file of model version 1). The
/// readers refuse |θ| > 1 rad as a reading error.
pub const UNBOUNDED_RANGE: f64 = 1.0;

impl<F: Real> Spring<F> {
    /// The paper's odd polynomial c1·x + c2·x³ + c3·x⁵ alone, unbounded.
    pub fn polynomial(c1: F, c2: F, c3: F) -> Self {
        let edge = F::from(UNBOUNDED_RANGE).unwrap_or_else(F::one);
        Spring { c1, c2, c3, knots: ([Knot::default(); MAX_KNOTS], 0), range: [-edge, edge] }
    }

    /// A spring of knots only (no polynomial) over `range`: what a fit writes.
    pub fn of_knots(knots: &[Knot<F>], range: [F; 2]) -> Result<Self, Error> {
        let mut all = [Knot::default(); MAX_KNOTS];
        let count = knots.len();
        all.get_mut(..count).ok_or(Error::InvalidSpring)?.copy_from_slice(knots);
        let spring = Spring { c1: F::zero(), c2: F::zero(), c3: F::zero(), knots: (all, count as u8), range };
        spring.check().map_err(|_| Error::InvalidSpring)?;
        Ok(spring)
    }

    /// The knots in use.
    pub fn knots(&self) -> &[Knot<F>] {
        self.knots.0.get(..usize::from(self.knots.1)).unwrap_or(&[])
    }

    /// The first parameter that is not finite or out of its range: knots not increasing or beyond
    /// the range, a negative knot stiffness, a range that does not hold x = 0.
    pub fn check(&self) -> Result<(), (ParamName, ParamFault)> {
        for (name, value) in [(ParamName::C1, self.c1), (ParamName::C2, self.c2), (ParamName::C3, self.c3)] {
            if !value.is_finite() {
                return Err((name, ParamFault::NotFinite));
            }
        }
        if usize::from(self.knots.1) > MAX_KNOTS {
            return Err((ParamName::Knot(MAX_KNOTS as u8), ParamFault::OutOfRange));
        }
        let mut previous: Option<F> = None;
        for (i, knot) in (0u8..).zip(self.knots()) {
            if !knot.x.is_finite() {
                return Err((ParamName::Knot(i), ParamFault::NotFinite));
            }
            if !knot.stiffness.is_finite() {
                return Err((ParamName::KnotStiffness(i), ParamFault::NotFinite));
            }
            if previous.is_some_and(|p| knot.x <= p) {
                return Err((ParamName::Knot(i), ParamFault::OutOfRange));
            }
            if knot.stiffness < F::zero() {
                return Err((ParamName::KnotStiffness(i), ParamFault::OutOfRange));
            }
            previous = Some(knot.x);
        }
        let [lo, hi] = self.range;
        for (name, value) in [(ParamName::RangeMin, lo), (ParamName::RangeMax, hi)] {
            if !value.is_finite() {
                return Err((name, ParamFault::NotFinite));
            }
        }
        if lo > F::zero() {
            return Err((ParamName::RangeMin, ParamFault::OutOfRange));
        }
        if hi <= lo || hi < F::zero() {
            return Err((ParamName::RangeMax, ParamFault::OutOfRange));
        }
        // Knots beyond the range would shape a spring no sample identified: beyond it the spring
        // is its edge's line.
        if let Some(i) = (0u8..).zip(self.knots()).find_map(|(i, k)| (k.x < lo || k.x > hi).then_some(i)) {
            return Err((ParamName::Knot(i), ParamFault::OutOfRange));
        }
        Ok(())
    }

    /// The spring ready to evaluate: per segment of the knots' part its quadratic in x and where
    /// it starts and ends, and the polynomial's values at the range's edges.
    pub fn prepare(&self) -> Result<PreparedSpring<F>, Error> {
        let mut prepared = PreparedSpring::empty();
        self.prepare_into(&mut prepared)?;
        Ok(prepared)
    }

    /// [`Spring::prepare`] written over `prepared`, in place (unspecified where it fails).
    pub(crate) fn prepare_into(&self, prepared: &mut PreparedSpring<F>) -> Result<(), Error> {
        self.check().map_err(|_| Error::InvalidSpring)?;
        let polynomial = Polynomial::new(self.c1, self.c2, self.c3)?;
        let knots = self.knots();
        let half = F::one() / (F::one() + F::one());
        // From knot j the stiffness is K_j + slope_j·(x − x_j) and P = P_j + K_j·d + slope_j·d²/2
        // (P_j from knot 0, shifted below so that P(0) = 0); left of knot 0 and right of the last,
        // the end knot's stiffness. Each piece as a + b·x + c·x², from the previous knot (−∞
        // for the first) to the next (+∞ for the last). Without knots, one piece of 0 everywhere.
        prepared.clear();
        let segments = &mut prepared.segments;
        let mut torque = F::zero();
        for (j, knot) in knots.iter().enumerate() {
            let next = knots.get(j + 1);
            let slope = match next {
                Some(next) => (next.stiffness - knot.stiffness) / (next.x - knot.x),
                None => F::zero(),
            };
            if let Some(segment) = segments.get_mut(j + 1) {
                *segment = Segment::from_start(knot.x, torque, knot.stiffness, slope);
            }
            if j == 0 {
                if let Some(segment) = segments.first_mut() {
                    *segment = Segment::from_start(knot.x, F::zero(), knot.stiffness, F::zero());
                    segment.start = F::neg_infinity();
                }
            }
            if let Some(next) = next {
                torque = torque + (knot.stiffness + next.stiffness) * half * (next.x - knot.x);
            }
        }
        prepared.polynomial = self.has_polynomial().then_some(polynomial);
        prepared.range = self.range;
        // P(0) = 0. The cursor stays at x = 0, where an evaluator starts from rest.
        let at_zero = prepared.knots_part(F::zero());
        for segment in prepared.segments.iter_mut().take(knots.len() + 1) {
            segment.a = segment.a - at_zero.torque;
        }
        let [lo, hi] = self.range;
        prepared.at_range = [polynomial.evaluate(lo), polynomial.evaluate(hi)];
        let finite = |e: &Evaluation<F>| e.torque.is_finite() && e.stiffness.is_finite();
        let segments_finite = prepared.segments.iter().all(|s| s.a.is_finite() && s.b.is_finite() && s.c.is_finite());
        if !prepared.at_range.iter().all(finite) || !segments_finite {
            return Err(Error::Overflow);
        }
        Ok(())
    }

    /// Whether the odd polynomial is there (not c1 = c2 = c3 = 0).
    fn has_polynomial(&self) -> bool {
        [self.c1, self.c2, self.c3].iter().any(|c| *c != F::zero())
    }
}

/// One piece of the knots' part: from `start` to where the next piece starts, P = a + b·x + c·x²
/// and k = b + 2c·x.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct Segment<F> {
    start: F,
    a: F,
    b: F,
    c: F,
}

impl<F: Real> Segment<F> {
    /// The piece from `start` with P = `torque`, k = `stiffness` and dk/dx = `slope` there.
    fn from_start(start: F, torque: F, stiffness: F, slope: F) -> Self {
        let c = slope / (F::one() + F::one());
        Segment { start, a: torque - stiffness * start + c * start * start, b: stiffness - slope * start, c }
    }
}

/// A [`Spring`] ready to evaluate sample by sample; it remembers the last segment, so that a
/// tick finds the next one in a step or two (x moves little between ticks). Two are equal when
/// they evaluate alike: where the cursor stands is left out.
#[derive(Clone, Copy, Debug)]
pub struct PreparedSpring<F> {
    /// The odd polynomial, where it is there.
    polynomial: Option<Polynomial<F>>,
    /// The pieces in order of x, each ending where the next starts: the first from −∞, the
    /// last in use to +∞, where those not in use start (so the starts never decrease), and one
    /// more of those after the most pieces there can be, where the last one ends. (No end of
    /// its own: a tick compares x with the next piece's start, at the same address plus one
    /// piece, and the slot of each set is 20 % smaller.)
    segments: [Segment<F>; MAX_KNOTS + 2],
    range: [F; 2],
    /// The polynomial and its stiffness at the range's two edges.
    at_range: [Evaluation<F>; 2],
    cursor: usize,
}

impl<F: Real> PreparedSpring<F> {
    /// No knots, no polynomial: S = 0 everywhere (what [`Spring::prepare_into`] starts from).
    pub(crate) fn empty() -> Self {
        let unused = Segment { start: F::infinity(), ..Segment::default() };
        let mut segments = [unused; MAX_KNOTS + 2];
        if let Some(only) = segments.first_mut() {
            *only = Segment { start: F::neg_infinity(), ..unused };
        }
        let zero = F::zero();
        PreparedSpring {
            polynomial: None,
            segments,
            range: [zero, zero],
            at_range: [Evaluation::default(); 2],
            cursor: 0,
        }
    }
}

impl<F: Real> PreparedSpring<F> {
    /// Back to [`PreparedSpring::empty`], in place (no spring of 400 bytes made on the stack
    /// and copied: the joint prepares its sets in place).
    fn clear(&mut self) {
        let unused = Segment { start: F::infinity(), ..Segment::default() };
        for segment in self.segments.iter_mut() {
            *segment = unused;
        }
        if let Some(only) = self.segments.first_mut() {
            only.start = F::neg_infinity();
        }
        self.polynomial = None;
        self.range = [F::zero(); 2];
        self.at_range = [Evaluation::default(); 2];
        self.cursor = 0;
    }
}

impl<F: PartialEq> PartialEq for PreparedSpring<F> {
    fn eq(&self, other: &Self) -> bool {
        let PreparedSpring { polynomial, segments, range, at_range, cursor: _ } = self;
        *polynomial == other.polynomial
            && *segments == other.segments
            && *range == other.range
            && *at_range == other.at_range
    }
}

impl<F: Real> PreparedSpring<F> {
    /// S(x) and dS/dx, x = θ − θ0 in rad; beyond the range, the line of the edge's stiffness.
    #[inline(always)]
    pub fn evaluate(&mut self, x: F) -> Evaluation<F> {
        let knots = self.knots_part(x);
        match &self.polynomial {
            None => knots,
            Some(polynomial) => {
                let [lo, hi] = self.range;
                let [at_lo, at_hi] = self.at_range;
                let polynomial = if x > hi {
                    Evaluation { torque: at_hi.torque + at_hi.stiffness * (x - hi), stiffness: at_hi.stiffness }
                } else if x < lo {
                    Evaluation { torque: at_lo.torque + at_lo.stiffness * (x - lo), stiffness: at_lo.stiffness }
                } else {
                    polynomial.evaluate(x)
                };
                polynomial.plus(knots)
            }
        }
    }

    /// Whether x lies beyond the identified range, and by how much (rad, ≥ 0).
    pub fn excess(&self, x: F) -> F {
        let [lo, hi] = self.range;
        if x > hi {
            x - hi
        } else if x < lo {
            lo - x
        } else {
            F::zero()
        }
    }

    /// The identified range of x, rad.
    pub fn range(&self) -> [F; 2] {
        self.range
    }

    /// P(x) and k(x), moving the cursor to x's segment (the knots' part is linear beyond the
    /// outer knots: no range to check): the cursor's own segment or its neighbour towards x (x
    /// moves little between ticks), else a binary search of five fixed steps (the same few
    /// instructions wherever x jumps to). NaN for an x that is not finite.
    #[inline(always)]
    fn knots_part(&mut self, x: F) -> Evaluation<F> {
        // Piece i ends where piece i + 1 starts. A neighbour starts (ends) where the cursor's
        // piece ends (starts), so x is on its side of that end already: only its far end is
        // compared.
        let piece = |i: usize| Some((self.segments.get(i)?, self.segments.get(i + 1)?.start));
        let cursor = self.cursor;
        let segment = match piece(cursor) {
            Some((_, end)) if x >= end => piece(cursor + 1).filter(|(_, end)| x < *end).map(|(s, _)| (cursor + 1, s)),
            Some((s, _)) if x < s.start => cursor
                .checked_sub(1)
                .and_then(|i| self.segments.get(i))
                .filter(|previous| x >= previous.start)
                .map(|s| (cursor - 1, s)),
            Some((s, _)) => Some((cursor, s)),
            None => None,
        };
        let segment = match segment {
            Some((index, segment)) => {
                self.cursor = index;
                segment
            }
            None => {
                // How many pieces end at or before x: the index of x's piece (the ends increase,
                // the last piece in use and those after it end at +∞).
                // Written out, not a loop over the steps: where the tick is compiled for size, the
                // loop is not unrolled (`bench/firmware.sh`).
                let past = |index: usize, step: usize| {
                    if self.segments.get(index + step).is_some_and(|s| x >= s.start) {
                        index + step
                    } else {
                        index
                    }
                };
                let index = past(past(past(past(past(0, 16), 8), 4), 2), 1);
                self.cursor = index;
                match self.segments.get(index) {
                    Some(segment) => segment,
                    None => return Evaluation { torque: F::nan(), stiffness: F::nan() },
                }
            }
        };
        let cx = segment.c * x;
        Evaluation { torque: segment.a + x * (segment.b + cx), stiffness: segment.b + cx + cx }
    }
}

/// The fit's columns of the knots' stiffnesses at x: `torque[j]` = B_j(x) = ∫₀ˣ h_j(u) du and
/// `stiffness[j]` = h_j(x), h_j the hat function of knot j (1 at knot j, 0 at its neighbours,
/// linear between; the end knots' hats stay 1 beyond them), for knots `knots` (x increasing).
/// So P(x) = Σ K_j·B_j(x) and k(x) = Σ K_j·h_j(x). Only the first `knots.len()` entries of the
/// outputs are written.
pub fn basis<F: Real>(knots: &[F], x: F, torque: &mut [F], stiffness: &mut [F]) {
    for (j, (t, k)) in torque.iter_mut().zip(stiffness.iter_mut()).enumerate().take(knots.len()) {
        *t = hat_integral(knots, j, x) - hat_integral(knots, j, F::zero());
        *k = hat(knots, j, x);
    }
}

/// Each knot's ∫ from knot 0 to x = 0 of h_j into `at_zero` (its first `knots.len()` entries):
/// what [`basis_from`] subtracts, the same at every x.
pub fn basis_origin<F: Real>(knots: &[F], at_zero: &mut [F]) {
    for (j, origin) in at_zero.iter_mut().enumerate().take(knots.len()) {
        *origin = hat_integral(knots, j, F::zero());
    }
}

/// [`basis`] with the integrals to x = 0 of [`basis_origin`] given: the same columns, for a fit
/// that evaluates them at every sample.
pub fn basis_from<F: Real>(knots: &[F], at_zero: &[F], x: F, torque: &mut [F], stiffness: &mut [F]) {
    let columns = torque.iter_mut().zip(stiffness.iter_mut()).zip(at_zero);
    for (j, ((t, k), &origin)) in columns.enumerate().take(knots.len()) {
        *t = hat_integral(knots, j, x) - origin;
        *k = hat(knots, j, x);
    }
}

/// h_j(x).
fn hat<F: Real>(knots: &[F], j: usize, x: F) -> F {
    let here = knots.get(j).copied().unwrap_or_else(F::zero);
    let rising = j.checked_sub(1).and_then(|i| knots.get(i)).map(|&left| (left, here));
    let falling = knots.get(j + 1).map(|&right| (here, right));
    if x <= here {
        match rising {
            None => F::one(),
            Some((left, _)) if x <= left => F::zero(),
            Some((left, right)) => (x - left) / (right - left),
        }
    } else {
        match falling {
            None => F::one(),
            Some((_, right)) if x >= right => F::zero(),
            Some((left, right)) => (right - x) / (right - left),
        }
    }
}

/// ∫ from knot 0 to x of h_j (negative for x left of knot 0).
fn hat_integral<F: Real>(knots: &[F], j: usize, x: F) -> F {
    let half = F::one() / (F::one() + F::one());
    let first = knots.first().copied().unwrap_or_else(F::zero);
    let here = knots.get(j).copied().unwrap_or_else(F::zero);
    let left = j.checked_sub(1).and_then(|i| knots.get(i)).copied();
    let right = knots.get(j + 1).copied();
    // The rising half, from the left neighbour (or, for knot 0, from knot 0 itself where the hat
    // has been 1 all along) to the knot.
    let rising = match left {
        None => (x.min(here) - first).min(F::zero()),
        Some(left) if x <= left => F::zero(),
        Some(left) => {
            let d = x.min(here) - left;
            d * d * half / (here - left)
        }
    };
    let falling = if x <= here {
        F::zero()
    } else {
        match right {
            None => x - here,
            Some(right) => {
                let width = right - here;
                let beyond = (right - x.min(right)) / width;
                width * half * (F::one() - beyond * beyond)
            }
        }
    };
    rising + falling
}

#[cfg(test)]
mod tests;
