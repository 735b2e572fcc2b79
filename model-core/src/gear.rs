//! A gear's model of any kind: the one parameter set that the host fits and writes to files, that
//! the wire carries (in f32) and that the joint evaluates, and its one stateful evaluator.
//!
//! ```text
//! GearModel<f64> ── params file (serde: {"model": kind, "params": {…}}) ── fit, predict, simulate
//!      │ try_map(f64 → f32, naming the parameter that does not fit)
//!      ▼
//! GearModel<f32> ── the wire's JointParams.model (postcard) ── flash records
//!      │ evaluator(band)
//!      ▼
//! Evaluator<F>   ── step(θ) every sample: host (f64) and joint tick (f32)
//! ```
//!
//! **Adding a kind** is a variant here (with its parameters' names in [`ParamName`], its checks,
//! its evaluator in [`Evaluator`], its f32 range bound in `range`), its fit on the host, and one
//! arm in the firmware's fast-path dispatch, which budgets its per-tick cost. Nothing else
//! branches on the kind: every other use goes through the methods below.
use crate::memory::{GeneticMemory, Hysteretic, MicroSlip, SlipParams};
use crate::range::{self, Culprit};
use crate::{Direction, Elementary, Error, Evaluation, Identifiable, Libm, Model, ParamName, Params, Real};

/// Turning points the genetic kind remembers, on the host as on the joint: deeper nested
/// excursions retrace reversibly.
pub const TURNING_POINTS: usize = 16;
/// Elasto-slip elements of the micro-slip kind, on the host as on the joint.
pub const SLIP_ELEMENTS: usize = 16;

/// A model kind: what `fit --model` identifies and what a params file and the wire name.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Kind {
    /// The paper's genetic model, generalised to any motion by Madelung's rules.
    Genetic,
    /// Maxwell-slip (a discrete Iwan model): an odd polynomial spring with [`SLIP_ELEMENTS`]
    /// elasto-slip elements.
    MicroSlip,
}

impl Kind {
    /// Every kind, in the order reports list them.
    pub const ALL: [Kind; 2] = [Kind::Genetic, Kind::MicroSlip];

    /// The kind's name in params files (their `model` field).
    pub const fn name(self) -> &'static str {
        match self {
            Kind::Genetic => crate::MODEL_NAME,
            Kind::MicroSlip => "micro-slip",
        }
    }

    /// The kind's short name on the command line and in tables.
    pub const fn label(self) -> &'static str {
        match self {
            Kind::Genetic => "genetic",
            Kind::MicroSlip => "micro-slip",
        }
    }

    /// What physics the kind stands for, in a line (command-line help).
    pub const fn description(self) -> &'static str {
        match self {
            Kind::Genetic => "The paper's genetic model, with Madelung's rules on a recording",
            Kind::MicroSlip => "Maxwell-slip: an odd polynomial spring and 16 elasto-slip elements (recordings)",
        }
    }

    /// What the kind's torque is, for reports.
    pub const fn equation(self) -> &'static str {
        match self {
            Kind::Genetic => {
                "T = c1·θ + c2·θ³ + c3·θ⁵ + z(θ), z the paper's hysteresis (α, β, ω) on every branch between turning points (Madelung's rules)"
            }
            Kind::MicroSlip => {
                "T = c1·θ + c2·θ³ + c3·θ⁵ + Σ k_i·e_i, 16 elasto-slip elements slipping at deflections on the log grid slip_min … slip_max"
            }
        }
    }

    /// Whether the kind has a stateless form on a symmetric loop ([`GearModel::symmetric_model`]):
    /// the paper's genetic loop, which a loop table (one symmetric loop) identifies.
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

/// A gear's model: its kind and that kind's parameters, in `F` (f64 on the host, f32 on the
/// joint).
///
/// In a human-readable serde format (a params file) it is `{"model": name, "params": {…}}`,
/// the kind's [`Kind::name`] and its parameters by name; in a compact one (postcard, on the wire
/// and in flash) the variant's index and the parameters in order.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum GearModel<F> {
    /// T = c1·θ + c2·θ³ + c3·θ⁵ + the genetic hysteresis (α, β, ω) with Madelung's rules.
    Genetic(Params<F>),
    /// T = c1·θ + c2·θ³ + c3·θ⁵ + Σ k_i·e_i over [`SLIP_ELEMENTS`] elasto-slip elements.
    MicroSlip(SlipParams<F, SLIP_ELEMENTS>),
}

impl<F> GearModel<F> {
    /// The model's kind.
    pub const fn kind(&self) -> Kind {
        match self {
            GearModel::Genetic(_) => Kind::Genetic,
            GearModel::MicroSlip(_) => Kind::MicroSlip,
        }
    }
}

impl<F: Copy> GearModel<F> {
    /// Each parameter converted by `convert`, which may refuse one by its name (the first refusal
    /// wins): f64 → f32 for the joint, naming the parameter that does not fit.
    pub fn try_map<G: Default, E>(
        &self,
        mut convert: impl FnMut(ParamName, F) -> Result<G, E>,
    ) -> Result<GearModel<G>, E> {
        Ok(match self {
            GearModel::Genetic(params) => GearModel::Genetic(params.try_map(convert)?),
            GearModel::MicroSlip(params) => GearModel::MicroSlip(params.try_map(&mut convert)?),
        })
    }

    /// Each parameter converted by `convert`, which is given its name too.
    pub fn map<G: Default>(&self, mut convert: impl FnMut(ParamName, F) -> G) -> GearModel<G> {
        let converted: Result<GearModel<G>, core::convert::Infallible> =
            self.try_map(|name, value| Ok(convert(name, value)));
        match converted {
            Ok(model) => model,
            Err(never) => match never {},
        }
    }

    /// The model with parameter `name` set to `value` (a name the kind does not have changes
    /// nothing).
    pub fn with(&self, name: ParamName, value: F) -> GearModel<F>
    where
        F: Default,
    {
        self.map(|each, old| if each == name { value } else { old })
    }
}

impl<F: Real> GearModel<F> {
    /// The first parameter that is not finite, or out of its range (ω = 0; a negative element
    /// stiffness; slip deflections not 0 < d_min < d_max): what a joint refuses a set for.
    pub fn check(&self) -> Result<(), (ParamName, ParamFault)> {
        let mut not_finite = Ok(());
        let _ = self.try_map(|name, value| {
            if value.is_finite() {
                Ok(())
            } else {
                not_finite = Err((name, ParamFault::NotFinite));
                Err(())
            }
        });
        not_finite?;
        let out_of_range = |name| Err((name, ParamFault::OutOfRange));
        match self {
            GearModel::Genetic(params) if params.omega == F::zero() => out_of_range(ParamName::Omega),
            GearModel::Genetic(_) => Ok(()),
            GearModel::MicroSlip(params) => {
                if let Some(i) = (0u8..).zip(params.stiffness).find_map(|(i, k)| (k < F::zero()).then_some(i)) {
                    out_of_range(ParamName::SlipStiffness(i))
                } else if params.slip_min <= F::zero() {
                    out_of_range(ParamName::SlipMin)
                } else if params.slip_max <= params.slip_min {
                    out_of_range(ParamName::SlipMax)
                } else {
                    Ok(())
                }
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
        Ok(match self {
            GearModel::Genetic(params) => Evaluator::Genetic(GeneticMemory::new(Model::new(*params)?, band)),
            GearModel::MicroSlip(params) => Evaluator::MicroSlip(MicroSlip::new(*params)?),
        })
    }

    /// Whether the model can be evaluated in `F` for every |θ| ≤ `max_deflection` and every
    /// state its evaluator can reach (model-core's `range`); else the parameter at fault.
    pub fn evaluable_within(&self, max_deflection: F) -> Result<(), Culprit> {
        match self {
            GearModel::Genetic(params) => range::genetic(params, max_deflection, TURNING_POINTS),
            GearModel::MicroSlip(params) => range::micro_slip(params, max_deflection),
        }
    }

    /// Whether the evaluator stays where elementary functions approximated for speed (the joint's
    /// fast path) hold: the genetic kind when it forms h·e^(−rφ) directly
    /// ([`Model::has_direct_decay`]); kinds without transcendental functions always.
    pub fn has_fast_path(&self) -> bool {
        match self {
            GearModel::Genetic(params) => Model::new(*params).is_ok_and(|model| model.has_direct_decay()),
            GearModel::MicroSlip(_) => true,
        }
    }

    /// The spring's stiffness at θ = 0, N·m/rad: the linear stiffness a controller falls back to.
    pub fn linear_stiffness(&self) -> F {
        match self {
            GearModel::Genetic(params) => params.c1,
            GearModel::MicroSlip(params) => params.c1,
        }
    }

    /// The identifiable part (h, r) of the hysteresis on a loop of amplitude `amplitude`, where the
    /// kind has one: only h and r of the genetic kind's (α, β, ω) are identifiable.
    pub fn identifiable(&self, amplitude: F) -> Option<Identifiable<F>> {
        match self {
            GearModel::Genetic(params) => params.identifiable(amplitude).ok(),
            GearModel::MicroSlip(_) => None,
        }
    }

    /// The genetic kind's parameters, for what is defined on that kind alone (the loop fit of a
    /// loop table, the diagnosis' effect search).
    pub fn as_genetic(&self) -> Option<&Params<F>> {
        match self {
            GearModel::Genetic(params) => Some(params),
            GearModel::MicroSlip(_) => None,
        }
    }

    /// The stateless model of symmetric loops, where the kind has one
    /// ([`Kind::has_symmetric_loop`]): the paper's loop at any amplitude A, which a sine between
    /// ±A follows without memory and a loop table holds one of.
    pub fn symmetric_model(&self) -> Result<Option<Model<F>>, Error> {
        match self {
            GearModel::Genetic(params) => Model::new(*params).map(Some),
            GearModel::MicroSlip(_) => Ok(None),
        }
    }
}

impl<F: Copy + Default + core::fmt::LowerExp> core::fmt::Display for GearModel<F> {
    /// The kind and every parameter by name: `genetic c1=9.0e3 … omega=1e0`.
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(self.kind().label())?;
        self.try_map(|name, value| write!(f, " {name}={value:e}")).map(|_: GearModel<()>| ())
    }
}

/// What an evaluator remembers of the motion, as the joint reports it every tick.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Memory {
    /// The direction of motion the genetic kind follows (`None` at rest and for the micro-slip
    /// kind, which needs none).
    pub direction: Option<Direction>,
    /// How much memory is in use: turning points stored (genetic) or elements slipping
    /// (micro-slip).
    pub depth: usize,
}

/// The stateful evaluator of a [`GearModel`]: fed θ sample by sample from rest, it keeps what the
/// motion has left behind. The same on the host (f64, with libm) and on the joint (f32, with
/// libm or the firmware's fast elementary functions).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Evaluator<F> {
    Genetic(GeneticMemory<F, TURNING_POINTS>),
    MicroSlip(MicroSlip<F, SLIP_ELEMENTS>),
}

impl<F: Real> Evaluator<F> {
    /// [`Hysteretic::step`] with the elementary functions of `E` where the kind uses any: the
    /// same state whichever `E` runs a sample.
    #[inline(always)]
    pub fn step_with<E: Elementary<F>>(&mut self, theta: F) -> Result<Evaluation<F>, Error> {
        match self {
            Evaluator::Genetic(memory) => memory.step_with::<E>(theta),
            // No transcendental functions.
            Evaluator::MicroSlip(slip) => slip.step(theta),
        }
    }

    /// [`Evaluator::step_with`] and [`Evaluator::memory`] after it, in one dispatch on the kind
    /// (the joint's tick: a second dispatch cost instructions every tick).
    #[inline(always)]
    pub fn step_reporting<E: Elementary<F>>(&mut self, theta: F) -> (Result<Evaluation<F>, Error>, Memory) {
        match self {
            Evaluator::Genetic(memory) => {
                let evaluation = memory.step_with::<E>(theta);
                (evaluation, Memory { direction: memory.direction(), depth: memory.depth() })
            }
            Evaluator::MicroSlip(slip) => {
                let evaluation = slip.step(theta);
                (evaluation, Memory { direction: None, depth: slip.slipping() })
            }
        }
    }

    /// What the evaluator remembers.
    #[inline(always)]
    pub fn memory(&self) -> Memory {
        match self {
            Evaluator::Genetic(memory) => Memory { direction: memory.direction(), depth: memory.depth() },
            Evaluator::MicroSlip(slip) => Memory { direction: None, depth: slip.slipping() },
        }
    }
}

impl<F: Real> Hysteretic<F> for Evaluator<F> {
    fn reset(&mut self) {
        match self {
            Evaluator::Genetic(memory) => memory.reset(),
            Evaluator::MicroSlip(slip) => slip.reset(),
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
    use serde::{Deserialize, Deserializer, Serialize, Serializer};

    /// `{"model": "genetic-hysteresis", "params": {…}}`. The names are [`Kind::name`] (tested).
    #[derive(Serialize)]
    #[serde(tag = "model", content = "params")]
    enum Named<'a, F> {
        #[serde(rename = "genetic-hysteresis")]
        Genetic(&'a Params<F>),
        #[serde(rename = "micro-slip")]
        MicroSlip(&'a SlipParams<F, SLIP_ELEMENTS>),
    }

    // Adjacent tagging reads the two fields in any order, buffering in serde's `Content`, which
    // needs an allocator: files are read on the host only.
    #[cfg(feature = "use-std")]
    #[derive(Deserialize)]
    #[serde(tag = "model", content = "params")]
    #[serde(bound(deserialize = "F: Deserialize<'de> + Default"))]
    enum NamedOwned<F> {
        #[serde(rename = "genetic-hysteresis")]
        Genetic(Params<F>),
        #[serde(rename = "micro-slip")]
        MicroSlip(SlipParams<F, SLIP_ELEMENTS>),
    }

    #[derive(Serialize)]
    enum Indexed<'a, F> {
        Genetic(&'a Params<F>),
        MicroSlip(&'a SlipParams<F, SLIP_ELEMENTS>),
    }

    #[derive(Deserialize)]
    #[serde(bound(deserialize = "F: Deserialize<'de> + Default"))]
    enum IndexedOwned<F> {
        Genetic(Params<F>),
        MicroSlip(SlipParams<F, SLIP_ELEMENTS>),
    }

    impl<F: Serialize> Serialize for GearModel<F> {
        fn serialize<S: Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
            match (self, serializer.is_human_readable()) {
                (GearModel::Genetic(p), true) => Named::Genetic(p).serialize(serializer),
                (GearModel::MicroSlip(p), true) => Named::MicroSlip(p).serialize(serializer),
                (GearModel::Genetic(p), false) => Indexed::Genetic(p).serialize(serializer),
                (GearModel::MicroSlip(p), false) => Indexed::MicroSlip(p).serialize(serializer),
            }
        }
    }

    impl<'de, F: Deserialize<'de> + Default> Deserialize<'de> for GearModel<F> {
        fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
            #[cfg(feature = "use-std")]
            if deserializer.is_human_readable() {
                return Ok(match NamedOwned::deserialize(deserializer)? {
                    NamedOwned::Genetic(p) => GearModel::Genetic(p),
                    NamedOwned::MicroSlip(p) => GearModel::MicroSlip(p),
                });
            }
            Ok(match IndexedOwned::deserialize(deserializer)? {
                IndexedOwned::Genetic(p) => GearModel::Genetic(p),
                IndexedOwned::MicroSlip(p) => GearModel::MicroSlip(p),
            })
        }
    }

    impl<F: Serialize> GearModel<F> {
        /// The parameters alone, by name (a params file's `params`), for a report that writes
        /// the kind's name in a field of its own.
        pub fn serialize_params<S: Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
            match self {
                GearModel::Genetic(p) => p.serialize(serializer),
                GearModel::MicroSlip(p) => p.serialize(serializer),
            }
        }
    }
}

#[cfg(test)]
mod tests;
