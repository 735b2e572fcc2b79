extern crate std;
use super::*;
use crate::checks::{MICRO_SLIP_SET, PAPER_TABLE_2, SEED_TABLE_FIT};
use std::string::ToString;
use std::vec::Vec;

fn both() -> [GearModel<f64>; 2] {
    [GearModel::Genetic(SEED_TABLE_FIT), GearModel::MicroSlip(MICRO_SLIP_SET)]
}

#[test]
fn every_kind_is_named_as_its_serde_form_names_it() {
    for model in both() {
        let json: serde_json::Value = serde_json::to_value(model).unwrap();
        assert_eq!(json["model"], model.kind().name(), "{json}");
        assert_eq!(Kind::from_name(model.kind().name()), Some(model.kind()));
        assert_eq!(Kind::from_name(model.kind().label()), Some(model.kind()));
    }
    assert_eq!(Kind::from_name("dahl"), None);
}

#[test]
fn files_and_the_wire_round_trip_exactly() {
    for model in both() {
        let text = serde_json::to_string_pretty(&model).unwrap();
        assert_eq!(serde_json::from_str::<GearModel<f64>>(&text).unwrap(), model, "{text}");
        let narrow = model.map(|_, v| v as f32);
        let bytes = postcard::to_stdvec(&narrow).unwrap();
        assert_eq!(postcard::from_bytes::<GearModel<f32>>(&bytes).unwrap(), narrow);
    }
    // The two fields in either order, other fields ignored (a fit report is a params file).
    let text = r#"{"params": {"c1": 1, "c2": 2, "c3": 3, "alpha": 4, "beta": 5, "omega": 6}, "rss": 1,
                   "model": "genetic-hysteresis"}"#;
    let GearModel::Genetic(p) = serde_json::from_str::<GearModel<f64>>(text).unwrap() else { panic!() };
    assert_eq!((p.c1, p.omega), (1.0, 6.0));
}

#[test]
fn a_micro_slip_set_needs_every_element() {
    let mut json = serde_json::to_value(GearModel::MicroSlip(MICRO_SLIP_SET)).unwrap();
    let elements = json["params"]["stiffness"].as_array_mut().unwrap();
    elements.pop();
    let error = serde_json::from_value::<GearModel<f64>>(json.clone()).unwrap_err().to_string();
    assert!(error.contains("invalid length 15, expected a list of 16 numbers"), "{error}");
    json["params"]["stiffness"].as_array_mut().unwrap().extend([1.0.into(), 2.0.into()]);
    let error = serde_json::from_value::<GearModel<f64>>(json).unwrap_err().to_string();
    assert!(error.contains("invalid length 17"), "{error}");
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
    let mut slip = MICRO_SLIP_SET;
    slip.stiffness[5] = 1.0e300;
    assert_eq!(GearModel::MicroSlip(slip).try_map(narrow), Err(ParamName::SlipStiffness(5)));
    let genetic = GearModel::Genetic(PAPER_TABLE_2).with(ParamName::Beta, -1.0e300);
    assert_eq!(genetic.try_map(narrow), Err(ParamName::Beta));
    assert_eq!(ParamName::SlipStiffness(5).to_string(), "stiffness[5]");
    let text = GearModel::MicroSlip(MICRO_SLIP_SET).to_string();
    assert!(text.starts_with("micro-slip c1=6e3 c2=1.2e10 c3=0e0 stiffness[0]=1.2e2 "), "{text}");
    assert!(text.ends_with("stiffness[15]=3.45e2 slip_min=1e-5 slip_max=2e-3"), "{text}");
}

#[test]
fn check_names_the_first_bad_parameter() {
    let genetic = GearModel::Genetic(PAPER_TABLE_2);
    let slip = GearModel::MicroSlip(MICRO_SLIP_SET);
    assert_eq!(genetic.check(), Ok(()));
    assert_eq!(slip.check(), Ok(()));
    let cases = [
        (genetic.with(ParamName::C3, f64::NAN), (ParamName::C3, ParamFault::NotFinite)),
        (genetic.with(ParamName::Omega, 0.0), (ParamName::Omega, ParamFault::OutOfRange)),
        (slip.with(ParamName::SlipStiffness(7), f64::INFINITY), (ParamName::SlipStiffness(7), ParamFault::NotFinite)),
        (slip.with(ParamName::SlipStiffness(2), -1.0), (ParamName::SlipStiffness(2), ParamFault::OutOfRange)),
        (slip.with(ParamName::SlipMin, 0.0), (ParamName::SlipMin, ParamFault::OutOfRange)),
        (slip.with(ParamName::SlipMax, 1.0e-6), (ParamName::SlipMax, ParamFault::OutOfRange)),
    ];
    for (model, fault) in cases {
        assert_eq!(model.check(), Err(fault), "{model:?}");
        assert!(model.validate().is_err(), "{model:?}");
    }
    // A name the kind does not have changes nothing.
    assert_eq!(genetic.with(ParamName::SlipMin, 5.0), genetic);
}

#[test]
fn the_evaluator_is_the_kinds_own() {
    let motion: Vec<f64> =
        (0..3000).map(|i| 1.2e-3 * (f64::from(i) * 0.01).sin() * (1.0 + f64::from(i % 7) * 0.05)).collect();
    for model in both() {
        let mut evaluator = model.evaluator(1.0e-7).unwrap();
        let mut deepest = 0;
        match model {
            GearModel::Genetic(p) => {
                let mut own = GeneticMemory::<f64, TURNING_POINTS>::new(Model::new(p).unwrap(), 1.0e-7);
                for &theta in &motion {
                    assert_eq!(evaluator.step(theta), own.step(theta));
                    assert_eq!(evaluator.memory(), Memory { direction: own.direction(), depth: own.depth() });
                    deepest = deepest.max(own.depth());
                }
            }
            GearModel::MicroSlip(p) => {
                let mut own = MicroSlip::<f64, SLIP_ELEMENTS>::new(p).unwrap();
                for &theta in &motion {
                    assert_eq!(evaluator.step(theta), own.step(theta));
                    assert_eq!(evaluator.memory(), Memory { direction: None, depth: own.slipping() });
                    deepest = deepest.max(own.slipping());
                }
            }
        }
        assert!(deepest > 1, "{model:?}: the motion leaves memory behind");
        evaluator.reset();
        assert_eq!(evaluator, model.evaluator(1.0e-7).unwrap());
    }
}

#[test]
fn only_the_genetic_kind_has_a_stateless_loop() {
    let [genetic, slip] = both();
    assert_eq!(genetic.symmetric_model(), Ok(Some(Model::new(SEED_TABLE_FIT).unwrap())));
    assert!(genetic.kind().has_symmetric_loop());
    assert_eq!(slip.symmetric_model(), Ok(None));
    assert!(!slip.kind().has_symmetric_loop());
    assert_eq!(genetic.linear_stiffness(), SEED_TABLE_FIT.c1);
    assert_eq!(slip.linear_stiffness(), MICRO_SLIP_SET.c1);
}
