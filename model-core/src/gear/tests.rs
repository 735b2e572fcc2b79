extern crate std;
use super::*;
use crate::checks::{bouc_wen_set, micro_slip_set, preisach_set, MICRO_SLIP_V1, PAPER_TABLE_2, SEED_TABLE_FIT};
use crate::legacy::GearModelV1;
use crate::spring::Knot;
use std::string::ToString;
use std::vec::Vec;

/// An asymmetric spring on knots, θ0 off zero, with the micro-slip set's elements.
fn knotted() -> GearModel<f64> {
    let knots = [
        Knot { x: -1.2e-3, stiffness: 2.6e4 },
        Knot { x: -0.6e-3, stiffness: 1.4e4 },
        Knot { x: 0.0, stiffness: 8.0e3 },
        Knot { x: 0.7e-3, stiffness: 1.1e4 },
        Knot { x: 1.4e-3, stiffness: 1.9e4 },
    ];
    let spring = Spring::of_knots(&knots, [-1.2e-3, 1.4e-3]).unwrap();
    GearModel::micro_slip(-8.4e-3, spring, micro_slip_set().unwrap().slip_elements()).unwrap()
}

fn all() -> [GearModel<f64>; 5] {
    [GearModel::paper(SEED_TABLE_FIT), micro_slip_set().unwrap(), knotted(), bouc_wen_set(), preisach_set()]
}

#[test]
fn every_kind_is_named_as_its_serde_form_names_it() {
    for model in all() {
        let json: serde_json::Value = serde_json::to_value(model).unwrap();
        assert_eq!(json["model"], model.kind().name(), "{json}");
        assert_eq!(Kind::from_name(model.kind().name()), Some(model.kind()));
        assert_eq!(Kind::from_name(model.kind().label()), Some(model.kind()));
    }
    assert_eq!(Kind::from_name("dahl"), None);
}

#[test]
fn files_and_the_wire_round_trip_exactly() {
    for model in all() {
        let text = serde_json::to_string_pretty(&model).unwrap();
        assert_eq!(serde_json::from_str::<GearModel<f64>>(&text).unwrap(), model, "{text}");
        let narrow = model.map(|_, v| v as f32);
        let bytes = postcard::to_stdvec(&narrow).unwrap();
        assert_eq!(postcard::from_bytes::<GearModel<f32>>(&bytes).unwrap(), narrow);
    }
    // The two fields in either order, other fields ignored (a fit report is a params file).
    let text = r#"{"params": {"zero": 0, "spring": {"c1": 1, "c2": 2, "c3": 3, "knots": [], "range": [-1, 1]},
                   "alpha": 4, "beta": 5, "omega": 6}, "rss": 1, "model": "genetic-hysteresis"}"#;
    let model = serde_json::from_str::<GearModel<f64>>(text).unwrap();
    assert_eq!(model.paper_params(), Some(Params { c1: 1.0, c2: 2.0, c3: 3.0, alpha: 4.0, beta: 5.0, omega: 6.0 }));
}

/// Files and flash records of model version 1 load as today's model with the same torque.
#[test]
fn version_1_sets_upgrade_with_the_same_torque() {
    let v1 = r#"{"model": "micro-slip", "params": {"c1": 6000, "c2": 1.2e10, "c3": 0,
                 "stiffness": [120, 135, 150, 165, 180, 195, 210, 225, 240, 255, 270, 285, 300, 315, 330, 345],
                 "slip_min": 1e-5, "slip_max": 2e-3}}"#;
    let old = serde_json::from_str::<GearModelV1<f64>>(v1).unwrap();
    assert_eq!(old, GearModelV1::MicroSlip(MICRO_SLIP_V1));
    let upgraded = old.upgrade().unwrap();
    let genetic = GearModelV1::Genetic(PAPER_TABLE_2).upgrade().unwrap();
    assert_eq!(genetic, GearModel::paper(PAPER_TABLE_2));
    // The same torque as version 1's equations: the polynomial plus the grid's elements.
    let grid: [f64; 16] = crate::memory::slip_grid(1e-5, 2e-3).unwrap();
    let mut unit = crate::SlipElements::<f64, 16>::new(grid).unwrap();
    let mut evaluator = upgraded.evaluator(0.0).unwrap();
    let poly = crate::Polynomial::new(6000.0, 1.2e10, 0.0).unwrap();
    for i in 0..2000 {
        let theta = 1.5e-3 * (f64::from(i) * 0.013).sin() * (1.0 - f64::from(i) / 4000.0);
        unit.step(theta).unwrap();
        let want = poly.evaluate(theta).torque
            + MICRO_SLIP_V1.stiffness.iter().zip(unit.elastic()).map(|(k, e)| k * e).sum::<f64>();
        let got = evaluator.step(theta).unwrap().torque;
        assert!((got - want).abs() <= 1e-12 * want.abs().max(1.0), "{i}: {got} vs {want}");
    }
    // Postcard: version 1's wire bytes (the kind's index, then its fields) read the same.
    let bytes = [&[1u8][..], &postcard::to_stdvec(&MICRO_SLIP_V1).unwrap()].concat();
    assert_eq!(postcard::from_bytes::<GearModelV1<f64>>(&bytes).unwrap(), GearModelV1::MicroSlip(MICRO_SLIP_V1));
}

#[test]
fn a_micro_slip_set_holds_at_most_16_elements() {
    let mut json = serde_json::to_value(micro_slip_set().unwrap()).unwrap();
    let elements = json["params"]["elements"].as_array_mut().unwrap();
    elements.push(elements[0].clone());
    let error = serde_json::from_value::<GearModel<f64>>(json).unwrap_err().to_string();
    assert!(error.contains("invalid length 17, expected a list of at most 16 entries"), "{error}");
}

#[test]
fn a_failed_conversion_names_the_parameter() {
    let narrow = |name: ParamName, value: f64| {
        let v = value as f32;
        if v.is_finite() {
            Ok(v)
        } else {
            Err(name)
        }
    };
    let slip = micro_slip_set().unwrap().with(ParamName::SlipStiffness(5), 1.0e300);
    assert_eq!(slip.try_map(narrow), Err(ParamName::SlipStiffness(5)));
    let genetic = GearModel::paper(PAPER_TABLE_2).with(ParamName::Beta, -1.0e300);
    assert_eq!(genetic.try_map(narrow), Err(ParamName::Beta));
    let knots = knotted().with(ParamName::KnotStiffness(3), 1.0e300);
    assert_eq!(knots.try_map(narrow), Err(ParamName::KnotStiffness(3)));
    assert_eq!(ParamName::SlipStiffness(5).to_string(), "stiffness[5]");
    let text = micro_slip_set().unwrap().to_string();
    assert!(
        text.starts_with(
            "micro-slip zero=0e0 c1=6e3 c2=1.2e10 c3=0e0 range_min=-1e0 range_max=1e0 slip[0]=1e-5 stiffness[0]=1.2e2 "
        ),
        "{text}"
    );
}

#[test]
fn check_names_the_first_bad_parameter() {
    let genetic = GearModel::paper(PAPER_TABLE_2);
    let slip = micro_slip_set().unwrap();
    let bouc_wen = bouc_wen_set();
    for model in all() {
        assert_eq!(model.check(), Ok(()), "{model:?}");
    }
    let cases = [
        (genetic.with(ParamName::C3, f64::NAN), (ParamName::C3, ParamFault::NotFinite)),
        (genetic.with(ParamName::Omega, 0.0), (ParamName::Omega, ParamFault::OutOfRange)),
        (genetic.with(ParamName::Zero, f64::INFINITY), (ParamName::Zero, ParamFault::NotFinite)),
        (slip.with(ParamName::SlipStiffness(7), f64::INFINITY), (ParamName::SlipStiffness(7), ParamFault::NotFinite)),
        (slip.with(ParamName::SlipStiffness(2), -1.0), (ParamName::SlipStiffness(2), ParamFault::OutOfRange)),
        (slip.with(ParamName::Slip(0), 0.0), (ParamName::Slip(0), ParamFault::OutOfRange)),
        (slip.with(ParamName::Slip(4), 1.0), (ParamName::Slip(5), ParamFault::OutOfRange)),
        (knotted().with(ParamName::KnotStiffness(1), -1.0), (ParamName::KnotStiffness(1), ParamFault::OutOfRange)),
        (
            bouc_wen.with(ParamName::HysteresisStiffness, f64::NAN),
            (ParamName::HysteresisStiffness, ParamFault::NotFinite),
        ),
        (bouc_wen.with(ParamName::BoucWenA, 0.0), (ParamName::BoucWenA, ParamFault::OutOfRange)),
        (bouc_wen.with(ParamName::BoucWenBeta, -1.0), (ParamName::BoucWenBeta, ParamFault::OutOfRange)),
        (bouc_wen.with(ParamName::BoucWenGamma, -1250.0), (ParamName::BoucWenGamma, ParamFault::OutOfRange)),
        (bouc_wen.with(ParamName::BoucWenN, 0.5), (ParamName::BoucWenN, ParamFault::OutOfRange)),
        (bouc_wen.with(ParamName::BoucWenN, 33.0), (ParamName::BoucWenN, ParamFault::OutOfRange)),
    ];
    for (model, fault) in cases {
        assert_eq!(model.check(), Err(fault), "{model:?}");
        assert_eq!(model.validate(), Err(Error::InvalidParameter(fault.0, fault.1)), "{model:?}");
    }
    // A name the model does not have changes nothing.
    assert_eq!(genetic.with(ParamName::Slip(0), 5.0), genetic);
}

/// The evaluator is the spring at x = θ − θ0 plus the kind's own memory at x.
#[test]
fn the_evaluator_is_the_spring_plus_the_kinds_own_memory() {
    let motion: Vec<f64> =
        (0..3000).map(|i| 1.2e-3 * (f64::from(i) * 0.01).sin() * (1.0 + f64::from(i % 7) * 0.05)).collect();
    for model in all() {
        let mut evaluator = model.evaluator(1.0e-7).unwrap();
        let mut spring = model.spring.prepare().unwrap();
        let (mut deepest, mut moved) = (0, false);
        let mut own: std::boxed::Box<dyn Hysteretic<f64>> = match &model.hysteresis {
            Hysteresis::Genetic(g) => {
                std::boxed::Box::new(GeneticMemory::<f64, TURNING_POINTS>::new(g.model().unwrap(), 1.0e-7))
            }
            Hysteresis::MicroSlip(_) => {
                std::boxed::Box::new(MicroSlip::<f64, SLIP_ELEMENTS>::new(model.slip_elements()).unwrap())
            }
            Hysteresis::BoucWen(term) => std::boxed::Box::new(BoucWenMemory::new(*term).unwrap()),
            Hysteresis::Preisach(preisach) => {
                std::boxed::Box::new(crate::preisach::PreisachMemory::<f64, TURNING_POINTS>::new(
                    crate::preisach::PreparedPreisach::new(preisach).unwrap(),
                    1.0e-7,
                ))
            }
        };
        for &theta in &motion {
            let theta = theta + model.zero;
            let x = theta - model.zero;
            let want = spring.evaluate(x).plus(own.step(x).unwrap());
            assert_eq!(evaluator.step(theta), Ok(want));
            deepest = deepest.max(evaluator.memory().depth);
            moved |= evaluator.memory().direction.is_some();
        }
        // Bouc–Wen's one state, z, is no deeper for any motion.
        assert!(deepest > 1 || model.kind() == Kind::BoucWen, "{model:?}: the motion leaves memory behind");
        assert!(moved || model.kind() == Kind::MicroSlip, "{model:?}: a direction is followed");
        evaluator.reset();
        assert_eq!(evaluator.memory(), Memory::default());
    }
}

/// A step whose sum overflows (the spring at a huge θ) is an error that leaves the evaluator as
/// it was: the memory is written only once T = S + H is known to be finite.
#[test]
fn a_step_that_overflows_leaves_the_evaluator_as_it_was() {
    let motion: Vec<f64> = (0..800).map(|i| 1.0e-3 * (f64::from(i) * 0.02).sin()).collect();
    for model in all() {
        let mut evaluator = model.evaluator(1.0e-7).unwrap();
        let mut twin = evaluator;
        for (i, &theta) in motion.iter().enumerate() {
            if i % 50 == 0 {
                let before = evaluator;
                assert_eq!(evaluator.step(1.0e306), Err(Error::Overflow), "{model:?}");
                assert_eq!(evaluator, before, "{model:?}");
            }
            assert_eq!(evaluator.step(theta), twin.step(theta));
        }
    }
}

#[test]
fn the_papers_form_is_told_apart() {
    let [genetic, slip, knots, bouc_wen, preisach] = all();
    assert_eq!(preisach.paper_params(), None);
    assert!(!preisach.kind().has_symmetric_loop());
    assert_eq!(preisach.linear_stiffness(), 9000.0);
    assert_eq!(bouc_wen.paper_params(), None);
    assert!(!bouc_wen.kind().has_symmetric_loop());
    assert_eq!(bouc_wen.linear_stiffness(), 0.85 * 9000.0);
    assert_eq!(genetic.paper_params(), Some(SEED_TABLE_FIT));
    assert!(genetic.kind().has_symmetric_loop());
    assert_eq!(slip.paper_params(), None);
    assert!(!slip.kind().has_symmetric_loop());
    assert_eq!(knots.paper_params(), None);
    assert_eq!(genetic.linear_stiffness(), SEED_TABLE_FIT.c1);
    assert_eq!(slip.linear_stiffness(), MICRO_SLIP_V1.c1);
    assert_eq!(knots.linear_stiffness(), 8.0e3);
    assert_eq!(knots.range(), [-8.4e-3 - 1.2e-3, -8.4e-3 + 1.4e-3]);
}
