//! The parameter sets of model version 1, before the spring was free-form and the deflection had
//! a zero: read from params files and flash records written then, never written, and upgraded
//! to today's [`GearModel`] with the same torque:
//!
//! - the genetic kind: [`Params`] (c1, c2, c3, α, β, ω) → the paper's model, θ0 = 0;
//! - the micro-slip kind: [`SlipParamsV1`] (the odd polynomial and 16 element stiffnesses on a
//!   log grid of slip deflections from `slip_min` to `slip_max`) → θ0 = 0, the polynomial
//!   spring, the 16 elements with the grid's slip deflections.
use crate::gear::{GearModel, SLIP_ELEMENTS};
use crate::memory::{slip_grid, SlipElement};
use crate::spring::Spring;
use crate::{Error, Params, Real};

/// The micro-slip kind of model version 1.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
#[cfg_attr(feature = "serde", serde(bound(deserialize = "F: serde::Deserialize<'de> + Default")))]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct SlipParamsV1<F> {
    pub c1: F,
    pub c2: F,
    pub c3: F,
    /// k_i ≥ 0 of element i, on the log grid.
    #[cfg_attr(feature = "serde", serde(with = "crate::serde_array"))]
    pub stiffness: [F; SLIP_ELEMENTS],
    /// d_min, rad.
    pub slip_min: F,
    /// d_max, rad.
    pub slip_max: F,
}

/// A model of version 1, of either kind: on the wire and in flash records the kind's index and
/// its parameters in order; in files `{"model": name, "params": {…}}`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum GearModelV1<F> {
    Genetic(Params<F>),
    MicroSlip(SlipParamsV1<F>),
}

impl<F: Real> GearModelV1<F> {
    /// Today's model with the same torque.
    pub fn upgrade(&self) -> Result<GearModel<F>, Error> {
        match self {
            GearModelV1::Genetic(params) => Ok(GearModel::paper(*params)),
            GearModelV1::MicroSlip(p) => {
                let grid = slip_grid::<F, SLIP_ELEMENTS>(p.slip_min, p.slip_max)?;
                let mut elements = [SlipElement::default(); SLIP_ELEMENTS];
                for ((element, slip), stiffness) in elements.iter_mut().zip(grid).zip(p.stiffness) {
                    *element = SlipElement { slip, stiffness };
                }
                GearModel::micro_slip(F::zero(), Spring::polynomial(p.c1, p.c2, p.c3), &elements)
            }
        }
    }
}

#[cfg(feature = "serde")]
mod serde_forms {
    use super::*;
    use serde::{Deserialize, Deserializer};

    #[cfg(feature = "use-std")]
    #[derive(Deserialize)]
    #[serde(tag = "model", content = "params")]
    #[serde(bound(deserialize = "F: Deserialize<'de> + Default"))]
    enum Named<F> {
        #[serde(rename = "genetic-hysteresis")]
        Genetic(Params<F>),
        #[serde(rename = "micro-slip")]
        MicroSlip(SlipParamsV1<F>),
    }

    #[derive(Deserialize)]
    #[serde(bound(deserialize = "F: Deserialize<'de> + Default"))]
    enum Indexed<F> {
        Genetic(Params<F>),
        MicroSlip(SlipParamsV1<F>),
    }

    impl<'de, F: Deserialize<'de> + Default> Deserialize<'de> for GearModelV1<F> {
        fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
            #[cfg(feature = "use-std")]
            if deserializer.is_human_readable() {
                return Ok(match Named::deserialize(deserializer)? {
                    Named::Genetic(p) => GearModelV1::Genetic(p),
                    Named::MicroSlip(p) => GearModelV1::MicroSlip(p),
                });
            }
            Ok(match Indexed::deserialize(deserializer)? {
                Indexed::Genetic(p) => GearModelV1::Genetic(p),
                Indexed::MicroSlip(p) => GearModelV1::MicroSlip(p),
            })
        }
    }
}
