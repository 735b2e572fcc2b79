//! A gear's model of any kind: the one parameter set that the host fits and writes to files, that
//! the wire carries (in f32) and that the joint evaluates, and its one stateful evaluator.
//!
//! ```text
//! T(θ) = S(x) + H(x),   x = θ − θ0
//! ```
//!
//! θ0 is the deflection's zero (where the encoders read the gear unstressed), S the free-form
//! spring ([`Spring`]: memoryless, asymmetric, continued beyond its identified range with the
//! edge stiffness) and H the kind's hysteresis with its memory ([`Hysteresis`]).
//!
//! ```text
//! GearModel<f64> ── params file (serde: {"model": kind, "params": {zero, spring, …}}) ── fit, predict, simulate
//!      │ try_map(f64 → f32, naming the parameter that does not fit)
//!      ▼
//! GearModel<f32> ── the wire's JointParams.model (postcard) ── flash records
//!      │ evaluator(band)
//!      ▼
//! Evaluator<F>   ── step(θ) every sample: host (f64) and joint tick (f32)
//! ```
//!
//! **Adding a kind** is a variant of [`Hysteresis`] and of [`Evaluator`]'s hysteresis here
//! (with its parameters' names in [`ParamName`], its checks, its range bound in `range`, its f32
//! tolerance in `tolerance`, its serde names), its fit on the host, and one arm in the firmware's
//! budget, which bounds its per-tick cost. Nothing else branches on the kind.
use crate::bouc_wen::{BoucWen, BoucWenMemory, BoucWenTerm};
use crate::memory::{finite, Finish, GeneticMemory, Hysteretic, Madelung, MicroSlip, SlipElement};
use crate::preisach::{Preisach, PreisachMemory, PreparedPreisach, CELLS};
use crate::range::{self, Culprit};
use crate::spring::{PreparedSpring, Spring};
use crate::{Direction, Elementary, Error, Evaluation, Identifiable, Libm, Model, ParamName, Params, Real};

/// Turning points the genetic kind remembers, on the host as on the joint: deeper nested
/// excursions retrace reversibly.
pub const TURNING_POINTS: usize = 16;
/// Most elasto-slip elements of the micro-slip kind, on the host as on the joint.
pub const SLIP_ELEMENTS: usize = 16;

/// A model kind: what `fit --model` identifies and what a params file and the wire name.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Kind {
    /// The paper's genetic model, generalised to any motion by Madelung's rules.
    Genetic,
    /// Maxwell-slip (a discrete Iwan model): up to [`SLIP_ELEMENTS`] elasto-slip elements.
    MicroSlip,
    /// Bouc–Wen: smooth branches, no exact return-point memory ([`crate::bouc_wen`]).
    BoucWen,
    /// Preisach: a density of relays over their switching thresholds, loops that depend on where
    /// they sit ([`crate::preisach`]).
    Preisach,
}

impl Kind {
    /// Every kind, in the order reports list them.
    pub const ALL: [Kind; 4] = [Kind::Genetic, Kind::MicroSlip, Kind::BoucWen, Kind::Preisach];

    /// The kind's name in params files (their `model` field).
    pub const fn name(self) -> &'static str {
        match self {
            Kind::Genetic => crate::MODEL_NAME,
            Kind::MicroSlip => "micro-slip",
            Kind::BoucWen => "bouc-wen",
            Kind::Preisach => "preisach",
        }
    }

    /// The kind's short name on the command line and in tables.
    pub const fn label(self) -> &'static str {
        match self {
            Kind::Genetic => "genetic",
            Kind::MicroSlip => "micro-slip",
            Kind::BoucWen => "bouc-wen",
            Kind::Preisach => "preisach",
        }
    }

    /// What physics the kind stands for, in a line (command-line help).
    pub const fn description(self) -> &'static str {
        match self {
            Kind::Genetic => "The paper's genetic model, with Madelung's rules on a recording",
            Kind::MicroSlip => "Maxwell-slip: up to 16 elasto-slip elements, each its own slip deflection (recordings)",
            Kind::BoucWen => {
                "Bouc–Wen: smooth branches that saturate, minor loops that drift (no return-point memory; recordings)"
            }
            Kind::Preisach => {
                "Preisach: a density of relays on an 8×8 grid of thresholds, loops that depend on where they sit (recordings)"
            }
        }
    }

    /// What the kind's hysteresis is, for reports.
    pub const fn equation(self) -> &'static str {
        match self {
            Kind::Genetic => {
                "H = the paper's hysteresis z (α, β, ω) on every branch between turning points (Madelung's rules)"
            }
            Kind::MicroSlip => "H = Σ k_i·e_i, elasto-slip elements slipping at deflections d_i",
            Kind::BoucWen => "H = k_h·z, dz = dx·(A − |z|ⁿ·(β·sign(dx·z) + γ)) (Bouc–Wen)",
            Kind::Preisach => {
                "H = −Σ w_c·(share of cell c switched up − at rest), relays over thresholds β ≤ α in [−R, R]"
            }
        }
    }

    /// Whether the kind has a stateless form on a symmetric loop: the paper's genetic loop, which
    /// a loop table (one symmetric loop) identifies.
    pub const fn has_symmetric_loop(self) -> bool {
        matches!(self, Kind::Genetic)
    }

    /// The kind named `name` in a file ([`Kind::name`]) or on the command line ([`Kind::label`]).
    pub fn from_name(name: &str) -> Option<Kind> {
        Kind::ALL.into_iter().find(|kind| kind.name() == name || kind.label() == name)
    }
}

impl core::fmt::Display for Kind {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(self.label())
    }
}

/// What is wrong with a parameter.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ParamFault {
    NotFinite,
    OutOfRange,
}

/// The genetic kind's hysteresis: the paper's α (N·m/rad per unit of ω), β and ω (1/s). Only
/// h = A·α/(ω(1 + r²)) and r = β/ω are identifiable; fits write the point with ω = 1.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Genetic<F> {
    pub alpha: F,
    pub beta: F,
    pub omega: F,
}

impl<F: Real> Genetic<F> {
    /// The paper's parameters of this hysteresis with no spring.
    fn params(&self) -> Params<F> {
        let zero = F::zero();
        Params { c1: zero, c2: zero, c3: zero, alpha: self.alpha, beta: self.beta, omega: self.omega }
    }

    /// The paper's model of this hysteresis with no spring: what the memory evaluates.
    fn model(&self) -> Result<Model<F>, Error> {
        Model::new(self.params())
    }
}

/// A gear's hysteresis, of one kind.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Hysteresis<F> {
    Genetic(Genetic<F>),
    /// The elements, slip deflections increasing; the first `count` are used.
    MicroSlip(([SlipElement<F>; SLIP_ELEMENTS], u8)),
    BoucWen(BoucWenTerm<F>),
    Preisach(Preisach<F>),
}

/// A gear's model: its deflection zero, its spring and its hysteresis, in `F` (f64 on the host,
/// f32 on the joint).
///
/// In a human-readable serde format (a params file) it is `{"model": name, "params": {"zero",
/// "spring", …the kind's own}}`; in a compact one (postcard, on the wire and in flash) the
/// fields in order, the kind by its index.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct GearModel<F> {
    /// θ0, rad: the deflection at which the gear is unstressed.
    pub zero: F,
    pub spring: Spring<F>,
    pub hysteresis: Hysteresis<F>,
}

impl<F> GearModel<F> {
    /// The model's kind.
    pub const fn kind(&self) -> Kind {
        match self.hysteresis {
            Hysteresis::Genetic(_) => Kind::Genetic,
            Hysteresis::MicroSlip(_) => Kind::MicroSlip,
            Hysteresis::BoucWen(_) => Kind::BoucWen,
            Hysteresis::Preisach(_) => Kind::Preisach,
        }
    }
}

impl<F: Real> GearModel<F> {
    /// The paper's model: its six parameters, the odd polynomial spring unbounded, θ0 = 0.
    pub fn paper(params: Params<F>) -> Self {
        GearModel {
            zero: F::zero(),
            spring: Spring::polynomial(params.c1, params.c2, params.c3),
            hysteresis: Hysteresis::Genetic(Genetic { alpha: params.alpha, beta: params.beta, omega: params.omega }),
        }
    }

    /// A micro-slip model: θ0, the spring and up to [`SLIP_ELEMENTS`] elements.
    pub fn micro_slip(zero: F, spring: Spring<F>, elements: &[SlipElement<F>]) -> Result<Self, Error> {
        let mut all = [SlipElement::default(); SLIP_ELEMENTS];
        all.get_mut(..elements.len()).ok_or(Error::InvalidSlipRange)?.copy_from_slice(elements);
        Ok(GearModel { zero, spring, hysteresis: Hysteresis::MicroSlip((all, elements.len() as u8)) })
    }

    /// The paper's six parameters, where the model is the paper's: the genetic kind, the odd
    /// polynomial spring without knots, θ0 = 0 (the loop fit of a loop table, the diagnosis'
    /// baseline, today's symmetric loop).
    pub fn paper_params(&self) -> Option<Params<F>> {
        let Hysteresis::Genetic(g) = self.hysteresis else { return None };
        let s = &self.spring;
        (self.zero == F::zero() && s.knots().is_empty()).then_some(Params {
            c1: s.c1,
            c2: s.c2,
            c3: s.c3,
            alpha: g.alpha,
            beta: g.beta,
            omega: g.omega,
        })
    }

    /// The micro-slip kind's elements in use.
    pub fn slip_elements(&self) -> &[SlipElement<F>] {
        match &self.hysteresis {
            Hysteresis::MicroSlip((elements, count)) => elements.get(..usize::from(*count)).unwrap_or(&[]),
            Hysteresis::Genetic(_) | Hysteresis::BoucWen(_) | Hysteresis::Preisach(_) => &[],
        }
    }

    /// The first parameter that is not finite, or out of its range: the spring's
    /// ([`Spring::check`]), θ0, then the kind's (ω = 0; a slip deflection ≤ 0 or out of order, a
    /// negative element stiffness, too many elements): what a joint refuses a set for.
    pub fn check(&self) -> Result<(), (ParamName, ParamFault)> {
        if !self.zero.is_finite() {
            return Err((ParamName::Zero, ParamFault::NotFinite));
        }
        self.spring.check()?;
        let out_of_range = |name| Err((name, ParamFault::OutOfRange));
        match &self.hysteresis {
            Hysteresis::Genetic(g) => {
                let fields = [(ParamName::Alpha, g.alpha), (ParamName::Beta, g.beta), (ParamName::Omega, g.omega)];
                if let Some((name, _)) = fields.into_iter().find(|(_, value)| !value.is_finite()) {
                    return Err((name, ParamFault::NotFinite));
                }
                if g.omega == F::zero() {
                    return out_of_range(ParamName::Omega);
                }
                Ok(())
            }
            Hysteresis::MicroSlip((elements, count)) => {
                if usize::from(*count) > SLIP_ELEMENTS {
                    return out_of_range(ParamName::Slip(SLIP_ELEMENTS as u8));
                }
                let mut previous = F::zero();
                for (i, element) in (0u8..).zip(elements.iter().take(usize::from(*count))) {
                    if !element.slip.is_finite() {
                        return Err((ParamName::Slip(i), ParamFault::NotFinite));
                    }
                    if !element.stiffness.is_finite() {
                        return Err((ParamName::SlipStiffness(i), ParamFault::NotFinite));
                    }
                    if element.slip <= previous {
                        return out_of_range(ParamName::Slip(i));
                    }
                    if element.stiffness < F::zero() {
                        return out_of_range(ParamName::SlipStiffness(i));
                    }
                    previous = element.slip;
                }
                Ok(())
            }
            Hysteresis::BoucWen(term) => {
                let BoucWen { a, beta, gamma, n } = term.shape;
                let fields = [
                    (ParamName::HysteresisStiffness, term.stiffness),
                    (ParamName::BoucWenA, a),
                    (ParamName::BoucWenBeta, beta),
                    (ParamName::BoucWenGamma, gamma),
                    (ParamName::BoucWenN, n),
                ];
                if let Some((name, _)) = fields.into_iter().find(|(_, value)| !value.is_finite()) {
                    return Err((name, ParamFault::NotFinite));
                }
                if a <= F::zero() {
                    return out_of_range(ParamName::BoucWenA);
                }
                if beta <= F::zero() {
                    return out_of_range(ParamName::BoucWenBeta);
                }
                if gamma <= -beta {
                    return out_of_range(ParamName::BoucWenGamma);
                }
                if n < F::one() || n > F::from(crate::bouc_wen::MAX_N).unwrap_or(F::one()) {
                    return out_of_range(ParamName::BoucWenN);
                }
                Ok(())
            }
            Hysteresis::Preisach(preisach) => {
                if !preisach.reach.is_finite() {
                    return Err((ParamName::PreisachReach, ParamFault::NotFinite));
                }
                if preisach.reach <= F::zero() {
                    return out_of_range(ParamName::PreisachReach);
                }
                for (i, w) in (0u8..).zip(&preisach.weights) {
                    if !w.is_finite() {
                        return Err((ParamName::PreisachWeight(i), ParamFault::NotFinite));
                    }
                    if *w < F::zero() {
                        return out_of_range(ParamName::PreisachWeight(i));
                    }
                }
                Ok(())
            }
        }
    }

    /// Checks that the model can be evaluated (its evaluator can be built).
    pub fn validate(&self) -> Result<(), Error> {
        self.evaluator(F::zero()).map(|_| ())
    }

    /// The model's evaluator at rest. `band` is the smallest reversal the genetic kind follows
    /// (rad; negative or NaN counts as 0); the micro-slip kind needs none (noise only makes tiny
    /// reversible loops).
    pub fn evaluator(&self, band: F) -> Result<Evaluator<F>, Error> {
        let mut evaluator = Evaluator::idle();
        self.prepare(band, &mut evaluator)?;
        Ok(evaluator)
    }

    /// [`GearModel::evaluator`] written over `evaluator`, field by field in place: a joint
    /// prepares its next set in its slot, with no evaluator of 700 bytes put together on its
    /// stack and copied. Where the model is refused, `evaluator` is left in some state of no
    /// use (the caller keeps it out of service). Never inlined: its frame then does not sit
    /// under a caller's own deep calls, such as the range checks a joint runs first.
    #[inline(never)]
    pub fn prepare(&self, band: F, evaluator: &mut Evaluator<F>) -> Result<(), Error> {
        if let Err((name, fault)) = self.check() {
            return Err(Error::InvalidParameter(name, fault));
        }
        evaluator.zero = self.zero;
        match &self.hysteresis {
            Hysteresis::Genetic(g) => {
                evaluator.hysteresis = HysteresisState::Genetic(GeneticMemory::new(g.model()?, band));
            }
            Hysteresis::MicroSlip(_) => {
                evaluator.hysteresis = HysteresisState::MicroSlip(MicroSlip::new(self.slip_elements())?);
            }
            Hysteresis::BoucWen(term) => {
                evaluator.hysteresis = HysteresisState::BoucWen(BoucWenMemory::new(*term)?);
            }
            Hysteresis::Preisach(preisach) => {
                evaluator.hysteresis = HysteresisState::Preisach(Madelung::new(PreparedPreisach::new(preisach)?, band));
            }
        }
        self.spring.prepare_into(&mut evaluator.spring)
    }

    /// Whether the model can be evaluated in `F` for every |θ| ≤ `max_deflection` and every
    /// state its evaluator can reach (model-core's `range`); else the parameter at fault.
    pub fn evaluable_within(&self, max_deflection: F) -> Result<(), Culprit> {
        range::gear(self, max_deflection)
    }

    /// Whether the evaluator stays where elementary functions approximated for speed (the joint's
    /// fast path) hold: the genetic kind when it forms h·e^(−rφ) directly
    /// ([`Model::has_direct_decay`]); kinds without transcendental functions always.
    pub fn has_fast_path(&self) -> bool {
        match &self.hysteresis {
            Hysteresis::Genetic(g) => g.model().is_ok_and(|model| model.has_direct_decay()),
            Hysteresis::MicroSlip(_) | Hysteresis::BoucWen(_) | Hysteresis::Preisach(_) => true,
        }
    }

    /// The spring's stiffness at θ0, N·m/rad: the linear stiffness a controller falls back to.
    pub fn linear_stiffness(&self) -> F {
        self.spring.prepare().map_or(self.spring.c1, |mut spring| spring.evaluate(F::zero()).stiffness)
    }

    /// The identifiable part (h, r) of the hysteresis on a loop of amplitude `amplitude`, where the
    /// kind has one: only h and r of the genetic kind's (α, β, ω) are identifiable.
    pub fn identifiable(&self, amplitude: F) -> Option<Identifiable<F>> {
        match &self.hysteresis {
            Hysteresis::Genetic(g) => g.params().identifiable(amplitude).ok(),
            Hysteresis::MicroSlip(_) | Hysteresis::BoucWen(_) | Hysteresis::Preisach(_) => None,
        }
    }

    /// The deflections θ the spring was identified over, rad (its range from θ0).
    pub fn range(&self) -> [F; 2] {
        let [lo, hi] = self.spring.range;
        [self.zero + lo, self.zero + hi]
    }
}

impl<F: Copy + Default> GearModel<F> {
    /// Each parameter converted by `convert`, which may refuse one by its name (the first refusal
    /// wins): f64 → f32 for the joint, naming the parameter that does not fit.
    pub fn try_map<G: Copy + Default, E>(
        &self,
        mut convert: impl FnMut(ParamName, F) -> Result<G, E>,
    ) -> Result<GearModel<G>, E> {
        let zero = convert(ParamName::Zero, self.zero)?;
        let s = &self.spring;
        let (c1, c2, c3) =
            (convert(ParamName::C1, s.c1)?, convert(ParamName::C2, s.c2)?, convert(ParamName::C3, s.c3)?);
        let mut knots = [crate::spring::Knot::default(); crate::spring::MAX_KNOTS];
        for ((i, knot), slot) in (0u8..).zip(s.knots.0.iter().take(usize::from(s.knots.1))).zip(knots.iter_mut()) {
            *slot = crate::spring::Knot {
                x: convert(ParamName::Knot(i), knot.x)?,
                stiffness: convert(ParamName::KnotStiffness(i), knot.stiffness)?,
            };
        }
        let range = [convert(ParamName::RangeMin, s.range[0])?, convert(ParamName::RangeMax, s.range[1])?];
        let spring = Spring { c1, c2, c3, knots: (knots, s.knots.1), range };
        let hysteresis = match &self.hysteresis {
            Hysteresis::Genetic(g) => Hysteresis::Genetic(Genetic {
                alpha: convert(ParamName::Alpha, g.alpha)?,
                beta: convert(ParamName::Beta, g.beta)?,
                omega: convert(ParamName::Omega, g.omega)?,
            }),
            Hysteresis::MicroSlip((elements, count)) => {
                let mut converted = [SlipElement::default(); SLIP_ELEMENTS];
                for ((i, element), slot) in
                    (0u8..).zip(elements.iter().take(usize::from(*count))).zip(converted.iter_mut())
                {
                    *slot = SlipElement {
                        slip: convert(ParamName::Slip(i), element.slip)?,
                        stiffness: convert(ParamName::SlipStiffness(i), element.stiffness)?,
                    };
                }
                Hysteresis::MicroSlip((converted, *count))
            }
            Hysteresis::BoucWen(term) => Hysteresis::BoucWen(BoucWenTerm {
                stiffness: convert(ParamName::HysteresisStiffness, term.stiffness)?,
                shape: BoucWen {
                    a: convert(ParamName::BoucWenA, term.shape.a)?,
                    beta: convert(ParamName::BoucWenBeta, term.shape.beta)?,
                    gamma: convert(ParamName::BoucWenGamma, term.shape.gamma)?,
                    n: convert(ParamName::BoucWenN, term.shape.n)?,
                },
            }),
            Hysteresis::Preisach(preisach) => {
                let mut weights = [G::default(); CELLS];
                for ((i, w), slot) in (0u8..).zip(&preisach.weights).zip(weights.iter_mut()) {
                    *slot = convert(ParamName::PreisachWeight(i), *w)?;
                }
                Hysteresis::Preisach(Preisach { reach: convert(ParamName::PreisachReach, preisach.reach)?, weights })
            }
        };
        Ok(GearModel { zero, spring, hysteresis })
    }

    /// Each parameter converted by `convert`, which is given its name too.
    pub fn map<G: Copy + Default>(&self, mut convert: impl FnMut(ParamName, F) -> G) -> GearModel<G> {
        let converted: Result<GearModel<G>, core::convert::Infallible> =
            self.try_map(|name, value| Ok(convert(name, value)));
        match converted {
            Ok(model) => model,
            Err(never) => match never {},
        }
    }

    /// The model with parameter `name` set to `value` (a name the model does not have changes
    /// nothing).
    pub fn with(&self, name: ParamName, value: F) -> GearModel<F> {
        self.map(|each, old| if each == name { value } else { old })
    }
}

impl<F: Copy + Default + core::fmt::LowerExp> core::fmt::Display for GearModel<F> {
    /// The kind and every parameter by name: `genetic zero=0e0 c1=9.0e3 … omega=1e0`.
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(self.kind().label())?;
        self.try_map(|name, value| write!(f, " {name}={value:e}")).map(|_: GearModel<()>| ())
    }
}

/// What an evaluator remembers of the motion, as the joint reports it every tick.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Memory {
    /// The direction of motion the genetic, Bouc–Wen and Preisach kinds follow (`None` at rest
    /// and for the micro-slip kind, which needs none).
    pub direction: Option<Direction>,
    /// How much memory is in use: turning points stored (genetic, Preisach) or elements
    /// slipping (micro-slip); Bouc–Wen keeps one state, z, whatever the motion (0).
    pub depth: usize,
}

/// The kind's hysteresis with its memory, in x = θ − θ0. A tag of its own (`repr(u8)`): left to
/// the compiler, the tag went into a spare value of the Preisach kind's fields, and every kind's
/// tick read it from there (Bouc–Wen's tick 284 instructions against 279, Preisach's 409
/// against 405, `bench/firmware.sh`).
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(u8)]
pub enum HysteresisState<F: Real> {
    Genetic(GeneticMemory<F, TURNING_POINTS>),
    MicroSlip(MicroSlip<F, SLIP_ELEMENTS>),
    BoucWen(BoucWenMemory<F>),
    Preisach(PreisachMemory<F, TURNING_POINTS>),
}

impl<F: Real> HysteresisState<F> {
    /// No hysteresis: no elasto-slip elements.
    fn idle() -> Self {
        HysteresisState::MicroSlip(MicroSlip::none())
    }
}

/// The stateful evaluator of a [`GearModel`]: fed θ sample by sample from rest, it keeps what the
/// motion has left behind. The same on the host (f64, with libm) and on the joint (f32, with
/// libm or the firmware's fast elementary functions).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Evaluator<F: Real> {
    zero: F,
    spring: PreparedSpring<F>,
    hysteresis: HysteresisState<F>,
}

impl<F: Real> Evaluator<F> {
    /// An evaluator of no gear (T = 0 everywhere, no memory): what [`GearModel::prepare`]
    /// writes over.
    pub fn idle() -> Self {
        Evaluator { zero: F::zero(), spring: PreparedSpring::empty(), hysteresis: HysteresisState::idle() }
    }

    /// [`Hysteretic::step`] with the elementary functions of `E` where the kind uses any: the
    /// same state whichever `E` runs a sample.
    #[inline(always)]
    pub fn step_with<E: Elementary<F>>(&mut self, theta: F) -> Result<Evaluation<F>, Error> {
        self.step_reporting::<E>(theta).0
    }

    /// [`Evaluator::step_with`] and [`Evaluator::memory`] after it, in one dispatch on the kind
    /// (the joint's tick: a second dispatch cost instructions every tick).
    #[inline(always)]
    pub fn step_reporting<E: Elementary<F>>(&mut self, theta: F) -> (Result<Evaluation<F>, Error>, Memory) {
        self.step_reporting_either::<E, E>(theta, true)
    }

    /// [`Evaluator::step_reporting`] with the elementary functions of `A` where `first`, else
    /// of `B` (Bouc–Wen: `A`'s always): the joint's tick, which chooses its fast path or libm
    /// sample by sample, gets one copy of the kinds that use none.
    ///
    /// T = S(x) + H(x) is checked once, on the sum; the hysteresis' memory is written only if it
    /// is finite, so a step that fails leaves the memory as it was.
    #[inline(always)]
    pub fn step_reporting_either<A: Elementary<F>, B: Elementary<F>>(
        &mut self,
        theta: F,
        first: bool,
    ) -> (Result<Evaluation<F>, Error>, Memory) {
        let x = theta - self.zero;
        let finish = WithSpring { spring: &mut self.spring, x };
        match &mut self.hysteresis {
            HysteresisState::Genetic(memory) => {
                let evaluation =
                    if first { memory.step_finishing::<A>(x, finish) } else { memory.step_finishing::<B>(x, finish) };
                (evaluation, Memory { direction: memory.direction(), depth: memory.depth() })
            }
            HysteresisState::MicroSlip(slip) => {
                (slip.step_finishing(x, finish), Memory { direction: None, depth: slip.slipping() })
            }
            // One path, A's: on the joint a second copy of its step in libm's functions was
            // 2.2 KiB of the 48 KiB of flash, for the same z to f32 rounding.
            HysteresisState::BoucWen(bouc_wen) => (bouc_wen.step_finishing::<A>(x, finish), bouc_wen.memory()),
            // No elementary functions: one path.
            HysteresisState::Preisach(memory) => {
                (memory.step_finishing::<A>(x, finish), Memory { direction: memory.direction(), depth: memory.depth() })
            }
        }
    }

    /// What the evaluator remembers.
    #[inline(always)]
    pub fn memory(&self) -> Memory {
        match &self.hysteresis {
            HysteresisState::Genetic(memory) => Memory { direction: memory.direction(), depth: memory.depth() },
            HysteresisState::MicroSlip(slip) => Memory { direction: None, depth: slip.slipping() },
            HysteresisState::BoucWen(bouc_wen) => bouc_wen.memory(),
            HysteresisState::Preisach(memory) => Memory { direction: memory.direction(), depth: memory.depth() },
        }
    }

    /// How far θ (rad) lies beyond the spring's identified range (0 within it), rad.
    pub fn excess(&self, theta: F) -> F {
        self.spring.excess(theta - self.zero)
    }

    /// The kind's hysteresis with its memory.
    pub fn hysteresis(&self) -> &HysteresisState<F> {
        &self.hysteresis
    }

    /// The deflection's zero θ0, rad.
    pub fn zero(&self) -> F {
        self.zero
    }
}

/// The gear's spring at x added to the hysteresis, and the sum checked: what the evaluator's
/// step makes of H before the memory is written.
struct WithSpring<'a, F> {
    spring: &'a mut PreparedSpring<F>,
    x: F,
}

impl<F: Real> Finish<Evaluation<F>> for WithSpring<'_, F> {
    #[inline(always)]
    fn finish(self, hysteresis: Evaluation<F>) -> Result<Evaluation<F>, Error> {
        finite(self.spring.evaluate(self.x).plus(hysteresis))
    }
}

impl<F: Real> Hysteretic<F> for Evaluator<F> {
    fn reset(&mut self) {
        match &mut self.hysteresis {
            HysteresisState::Genetic(memory) => memory.reset(),
            HysteresisState::MicroSlip(slip) => slip.reset(),
            HysteresisState::BoucWen(bouc_wen) => bouc_wen.reset(),
            HysteresisState::Preisach(memory) => memory.reset(),
        }
    }

    fn step(&mut self, theta: F) -> Result<Evaluation<F>, Error> {
        self.step_with::<Libm>(theta)
    }
}

/// The two serde forms of [`GearModel`]: by name in files, by index on the wire.
#[cfg(feature = "serde")]
mod serde_forms {
    use super::*;
    use core::marker::PhantomData;
    use serde::de::{self, DeserializeSeed, EnumAccess, SeqAccess, VariantAccess, Visitor};
    use serde::{Deserialize, Deserializer, Serialize, Serializer};

    /// The genetic kind's parameters as a file and the wire write them.
    #[derive(Serialize, Deserialize)]
    #[serde(bound(deserialize = "F: Deserialize<'de> + Default + Copy"))]
    struct GeneticForm<F> {
        zero: F,
        spring: Spring<F>,
        alpha: F,
        beta: F,
        omega: F,
    }

    /// The micro-slip kind's parameters as a file and the wire write them.
    #[derive(Serialize, Deserialize)]
    #[serde(bound(deserialize = "F: Deserialize<'de> + Default + Copy"))]
    struct MicroSlipForm<F> {
        zero: F,
        spring: Spring<F>,
        #[serde(with = "crate::serde_array::prefix")]
        elements: ([SlipElement<F>; SLIP_ELEMENTS], u8),
    }

    /// The Bouc–Wen kind's parameters as a file and the wire write them.
    #[derive(Serialize, Deserialize)]
    #[serde(bound(deserialize = "F: Deserialize<'de> + Default + Copy"))]
    struct BoucWenForm<F> {
        zero: F,
        spring: Spring<F>,
        stiffness: F,
        a: F,
        beta: F,
        gamma: F,
        n: F,
    }

    /// The Preisach kind's parameters as a file and the wire write them.
    #[derive(Serialize, Deserialize)]
    #[serde(bound(deserialize = "F: Deserialize<'de> + Default + Copy"))]
    struct PreisachForm<F> {
        zero: F,
        spring: Spring<F>,
        reach: F,
        #[serde(with = "crate::serde_array")]
        weights: [F; CELLS],
    }

    /// `{"model": "genetic-hysteresis", "params": {…}}`. The names are [`Kind::name`] (tested).
    #[derive(Serialize)]
    #[cfg_attr(feature = "use-std", derive(Deserialize))]
    #[serde(tag = "model", content = "params")]
    #[serde(bound(deserialize = "F: Deserialize<'de> + Default + Copy"))]
    enum Named<F> {
        #[serde(rename = "genetic-hysteresis")]
        Genetic(GeneticForm<F>),
        #[serde(rename = "micro-slip")]
        MicroSlip(MicroSlipForm<F>),
        #[serde(rename = "bouc-wen")]
        BoucWen(BoucWenForm<F>),
        #[serde(rename = "preisach")]
        Preisach(PreisachForm<F>),
    }

    /// By index (on the wire, in flash); read by [`Compact`].
    #[derive(Serialize)]
    enum Indexed<F> {
        Genetic(GeneticForm<F>),
        MicroSlip(MicroSlipForm<F>),
        BoucWen(BoucWenForm<F>),
        Preisach(PreisachForm<F>),
    }

    /// The kind's parameters apart.
    enum Form<F> {
        Genetic(GeneticForm<F>),
        MicroSlip(MicroSlipForm<F>),
        BoucWen(BoucWenForm<F>),
        Preisach(PreisachForm<F>),
    }

    fn forms<F: Copy>(model: &GearModel<F>) -> Form<F> {
        let (zero, spring) = (model.zero, model.spring);
        match model.hysteresis {
            Hysteresis::Genetic(g) => {
                Form::Genetic(GeneticForm { zero, spring, alpha: g.alpha, beta: g.beta, omega: g.omega })
            }
            Hysteresis::MicroSlip(elements) => Form::MicroSlip(MicroSlipForm { zero, spring, elements }),
            Hysteresis::BoucWen(BoucWenTerm { stiffness, shape: BoucWen { a, beta, gamma, n } }) => {
                Form::BoucWen(BoucWenForm { zero, spring, stiffness, a, beta, gamma, n })
            }
            Hysteresis::Preisach(Preisach { reach, weights }) => {
                Form::Preisach(PreisachForm { zero, spring, reach, weights })
            }
        }
    }

    #[cfg(feature = "use-std")]
    fn preisach<F>(form: PreisachForm<F>) -> GearModel<F> {
        let PreisachForm { zero, spring, reach, weights } = form;
        GearModel { zero, spring, hysteresis: Hysteresis::Preisach(Preisach { reach, weights }) }
    }

    #[cfg(feature = "use-std")]
    fn bouc_wen<F>(form: BoucWenForm<F>) -> GearModel<F> {
        let BoucWenForm { zero, spring, stiffness, a, beta, gamma, n } = form;
        GearModel {
            zero,
            spring,
            hysteresis: Hysteresis::BoucWen(BoucWenTerm { stiffness, shape: BoucWen { a, beta, gamma, n } }),
        }
    }

    #[cfg(feature = "use-std")]
    fn genetic<F>(form: GeneticForm<F>) -> GearModel<F> {
        let GeneticForm { zero, spring, alpha, beta, omega } = form;
        GearModel { zero, spring, hysteresis: Hysteresis::Genetic(Genetic { alpha, beta, omega }) }
    }

    #[cfg(feature = "use-std")]
    fn micro_slip<F>(form: MicroSlipForm<F>) -> GearModel<F> {
        GearModel { zero: form.zero, spring: form.spring, hysteresis: Hysteresis::MicroSlip(form.elements) }
    }

    impl<F: Serialize + Copy> Serialize for GearModel<F> {
        fn serialize<S: Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
            match (forms(self), serializer.is_human_readable()) {
                (Form::Genetic(g), true) => Named::Genetic(g).serialize(serializer),
                (Form::MicroSlip(m), true) => Named::MicroSlip(m).serialize(serializer),
                (Form::BoucWen(b), true) => Named::BoucWen(b).serialize(serializer),
                (Form::Preisach(p), true) => Named::Preisach(p).serialize(serializer),
                (Form::Genetic(g), false) => Indexed::Genetic(g).serialize(serializer),
                (Form::MicroSlip(m), false) => Indexed::MicroSlip(m).serialize(serializer),
                (Form::BoucWen(b), false) => Indexed::BoucWen(b).serialize(serializer),
                (Form::Preisach(p), false) => Indexed::Preisach(p).serialize(serializer),
            }
        }
    }

    impl<'de, F: Deserialize<'de> + Default + Copy> Deserialize<'de> for GearModel<F> {
        fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
            // Adjacent tagging reads the two fields in any order, buffering in serde's
            // `Content`, which needs an allocator: files are read on the host only.
            #[cfg(feature = "use-std")]
            if deserializer.is_human_readable() {
                return Ok(match Named::deserialize(deserializer)? {
                    Named::Genetic(g) => genetic(g),
                    Named::MicroSlip(m) => micro_slip(m),
                    Named::BoucWen(b) => bouc_wen(b),
                    Named::Preisach(p) => preisach(p),
                });
            }
            deserializer.deserialize_enum(
                "Indexed",
                &["Genetic", "MicroSlip", "BoucWen", "Preisach"],
                Compact(PhantomData),
            )
        }
    }

    /// [`Indexed`]'s deserialization, the bytes read in the same order, the model made of them
    /// directly: through `Indexed` and the kind's form, a model (300 bytes on the joint) was
    /// made three times in the frame that decodes a set, the link's deepest stack.
    struct Compact<F>(PhantomData<F>);

    impl<'de, F: Deserialize<'de> + Default + Copy> Visitor<'de> for Compact<F> {
        type Value = GearModel<F>;

        fn expecting(&self, formatter: &mut core::fmt::Formatter) -> core::fmt::Result {
            formatter.write_str("enum Indexed")
        }

        fn visit_enum<A: EnumAccess<'de>>(self, data: A) -> Result<GearModel<F>, A::Error> {
            let (KindIndex(kind), variant) = data.variant()?;
            variant.newtype_variant_seed(Fields(kind, PhantomData))
        }
    }

    /// The index of [`Indexed`]'s variant: a kind.
    struct KindIndex(Kind);

    impl<'de> Deserialize<'de> for KindIndex {
        fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<KindIndex, D::Error> {
            struct Index;
            impl Visitor<'_> for Index {
                type Value = KindIndex;
                fn expecting(&self, formatter: &mut core::fmt::Formatter) -> core::fmt::Result {
                    formatter.write_str("variant index 0 <= i < 4")
                }
                fn visit_u64<E: de::Error>(self, index: u64) -> Result<KindIndex, E> {
                    match index {
                        0 => Ok(KindIndex(Kind::Genetic)),
                        1 => Ok(KindIndex(Kind::MicroSlip)),
                        2 => Ok(KindIndex(Kind::BoucWen)),
                        3 => Ok(KindIndex(Kind::Preisach)),
                        _ => Err(E::invalid_value(de::Unexpected::Unsigned(index), &self)),
                    }
                }
            }
            deserializer.deserialize_identifier(Index)
        }
    }

    /// The fields of the kind's form ([`GeneticForm`], [`MicroSlipForm`], [`BoucWenForm`],
    /// [`PreisachForm`]) in their order.
    struct Fields<F>(Kind, PhantomData<F>);

    impl<'de, F: Deserialize<'de> + Default + Copy> DeserializeSeed<'de> for Fields<F> {
        type Value = GearModel<F>;

        fn deserialize<D: Deserializer<'de>>(self, deserializer: D) -> Result<GearModel<F>, D::Error> {
            let (name, fields): (_, &[&str]) = match self.0 {
                Kind::Genetic => ("GeneticForm", &["zero", "spring", "alpha", "beta", "omega"]),
                Kind::MicroSlip => ("MicroSlipForm", &["zero", "spring", "elements"]),
                Kind::BoucWen => ("BoucWenForm", &["zero", "spring", "stiffness", "a", "beta", "gamma", "n"]),
                Kind::Preisach => ("PreisachForm", &["zero", "spring", "reach", "weights"]),
            };
            deserializer.deserialize_struct(name, fields, self)
        }
    }

    impl<'de, F: Deserialize<'de> + Default + Copy> Visitor<'de> for Fields<F> {
        type Value = GearModel<F>;

        fn expecting(&self, formatter: &mut core::fmt::Formatter) -> core::fmt::Result {
            write!(formatter, "the {} kind's parameters", self.0.name())
        }

        fn visit_seq<A: SeqAccess<'de>>(self, mut seq: A) -> Result<GearModel<F>, A::Error> {
            let zero = field(&mut seq, 0, &self)?;
            let spring = field(&mut seq, 1, &self)?;
            let hysteresis = match self.0 {
                Kind::Genetic => {
                    let (alpha, beta) = (field(&mut seq, 2, &self)?, field(&mut seq, 3, &self)?);
                    Hysteresis::Genetic(Genetic { alpha, beta, omega: field(&mut seq, 4, &self)? })
                }
                Kind::MicroSlip => {
                    let Elements(elements) = field(&mut seq, 2, &self)?;
                    Hysteresis::MicroSlip(elements)
                }
                Kind::BoucWen => {
                    let (stiffness, a) = (field(&mut seq, 2, &self)?, field(&mut seq, 3, &self)?);
                    let (beta, gamma) = (field(&mut seq, 4, &self)?, field(&mut seq, 5, &self)?);
                    let shape = BoucWen { a, beta, gamma, n: field(&mut seq, 6, &self)? };
                    Hysteresis::BoucWen(BoucWenTerm { stiffness, shape })
                }
                Kind::Preisach => {
                    let reach = field(&mut seq, 2, &self)?;
                    let Weights(weights) = field(&mut seq, 3, &self)?;
                    Hysteresis::Preisach(Preisach { reach, weights })
                }
            };
            Ok(GearModel { zero, spring, hysteresis })
        }
    }

    /// The next field, the `index`th, of a form.
    fn field<'de, T: Deserialize<'de>, A: SeqAccess<'de>>(
        seq: &mut A,
        index: usize,
        form: &dyn de::Expected,
    ) -> Result<T, A::Error> {
        seq.next_element()?.ok_or_else(|| de::Error::invalid_length(index, form))
    }

    /// [`PreisachForm::weights`] alone.
    struct Weights<F>([F; CELLS]);

    impl<'de, F: Deserialize<'de> + Default + Copy> Deserialize<'de> for Weights<F> {
        fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
            crate::serde_array::deserialize(deserializer).map(Weights)
        }
    }

    /// [`MicroSlipForm::elements`] alone.
    struct Elements<F>(([SlipElement<F>; SLIP_ELEMENTS], u8));

    impl<'de, F: Deserialize<'de> + Default + Copy> Deserialize<'de> for Elements<F> {
        fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
            crate::serde_array::prefix::deserialize(deserializer).map(Elements)
        }
    }

    impl<F: Serialize + Copy> GearModel<F> {
        /// The parameters alone, by name (a params file's `params`), for a report that writes
        /// the kind's name in a field of its own.
        pub fn serialize_params<S: Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
            match forms(self) {
                Form::Genetic(g) => g.serialize(serializer),
                Form::MicroSlip(m) => m.serialize(serializer),
                Form::BoucWen(b) => b.serialize(serializer),
                Form::Preisach(p) => p.serialize(serializer),
            }
        }
    }
}

#[cfg(test)]
mod tests;
