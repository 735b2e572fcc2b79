//! The prediction goals that hold, on a few cases of the benchmark's corpus
//! (`bench/prediction.sh` runs them all): a model fitted on the bench sine predicts a nested
//! motion of its own family's gear within 1.3× the floor, the truth physics on the same
//! measured angles, where today's symmetric rule is several times worse.
#[path = "prediction_corpus.rs"]
mod corpus;

use corpus::*;
use model_core::Kind;
use swg_host::simulate::{Catalogue, MicroSlip, Physics, Preisach};

/// RMS against the truth of the symmetric rule and of the model of `kind`, divided by the
/// floor's.
fn ratios(physics: &Physics, trained_on: &'static str, predicted: &'static str, kind: Kind) -> (f64, f64) {
    let fitted = fit_some(&case(physics, trained_on).measured, &[kind], false);
    let target = case(physics, predicted);
    let floor = target.rms(&target.floor, &target.truth);
    let ratio = |p: Predicted| target.rms(&p.torque, &target.truth) / floor;
    (ratio(symmetric_prediction(&fitted.symmetric, &target.measured)), ratio(prediction(fitted.of(kind), &target)))
}

#[test]
fn the_micro_slip_model_predicts_a_micro_slip_gear_near_the_floor() {
    let (symmetric, micro_slip) = ratios(&Physics::MicroSlip(MicroSlip::default()), "sine", "nested", Kind::MicroSlip);
    assert!(micro_slip <= 1.3, "micro-slip model: {micro_slip:.2}× the floor");
    assert!(symmetric > 3.0 * micro_slip, "today's rule {symmetric:.2}× against {micro_slip:.2}×");
}

/// The random motion reaches +1.00 mrad and −1.17: predicting the sine (±1.17) runs the + side
/// beyond the samples, where the gear stiffens (k3); the shorter side continued with the longer
/// one's gain in stiffness follows it (1.04×; the edge's straight line: 5.05×). Its slowly
/// starting biased motion is read at rest where it is (a rest window that took in the s-ramp's
/// first 0.2 s put the prediction at 2.08×).
#[test]
fn the_micro_slip_model_fitted_on_random_motion_predicts_the_wider_sine_and_a_slow_start() {
    let physics = Physics::MicroSlip(MicroSlip::default());
    let fitted = fit_some(&case(&physics, "random").measured, &[Kind::MicroSlip], false);
    for predicted in ["sine", "biased"] {
        let target = case(&physics, predicted);
        let floor = target.rms(&target.floor, &target.truth);
        let micro_slip = prediction(fitted.of(Kind::MicroSlip), &target);
        let ratio = target.rms(&micro_slip.torque, &target.truth) / floor;
        assert!(ratio <= 1.3, "{predicted}: {ratio:.2}× the floor");
    }
}

#[test]
fn the_genetic_model_with_memory_predicts_a_genetic_gear_near_the_floor() {
    let (symmetric, genetic) = ratios(&Physics::Model, "random", "biased", Kind::Genetic);
    assert!(genetic <= 1.3, "genetic model: {genetic:.2}× the floor");
    assert!(symmetric > 3.0 * genetic, "today's rule {symmetric:.2}× against {genetic:.2}×");
}

/// Issue 16's catalogue goal: met by the free knots (nested 1.04×, hold 1.04×, K 2.5 % off);
/// the uniform knot rule alone misses it (1.47×, 5.5 %).
#[test]
fn the_micro_slip_model_predicts_a_catalogue_gear_and_its_stiffness_near_the_truth() {
    // The spring's stiffness steps at two torques: the knots must follow them for the torque to
    // come near the floor and the stiffness K (the loop's centre-curve slope) near the truth's.
    let physics = Physics::Catalogue(Catalogue::default());
    let fitted = fit_some(&case(&physics, "sine").measured, &[Kind::MicroSlip], false);
    let k_err = centre_stiffness_error(&physics, fitted.of(Kind::MicroSlip)).expect("the catalogue gear has a tangent");
    println!("catalogue, trained on sine: K err {:.2} %", 100.0 * k_err);
    for predicted in ["nested", "hold"] {
        let target = case(&physics, predicted);
        let floor = target.rms(&target.floor, &target.truth);
        let micro_slip = prediction(fitted.of(Kind::MicroSlip), &target);
        let ratio = target.rms(&micro_slip.torque, &target.truth) / floor;
        println!("catalogue, {predicted}: {ratio:.2}× the floor");
        assert!(ratio <= 1.3, "{predicted}: {ratio:.2}× the floor");
    }
    assert!(k_err <= 0.03, "K err {:.2} %", 100.0 * k_err);
}

/// The Preisach kind: a sine identifies a density only along its major loop's edges, the
/// smoothness asked of it fills the rest (without it the micro-slip gear's other motions were
/// 1.45× the floor); fitted on the random motion, which reaches +1.00 mrad and −1.17, the cells
/// beyond +1.00 take their diagonal neighbours' weights (the point mirror's put the gear that
/// grips harder on the + side at 1.66× on the sine).
#[test]
fn the_preisach_model_predicts_micro_slip_and_preisach_gears_near_the_floor() {
    for (physics, trained_on) in [
        (Physics::MicroSlip(MicroSlip::default()), "sine"),
        (Physics::Preisach(Preisach::default()), "sine"),
        (Physics::Preisach(Preisach::default()), "random"),
    ] {
        let fitted = fit_some(&case(&physics, trained_on).measured, &[Kind::Preisach], false);
        for predicted in MOTIONS.iter().filter(|m| **m != trained_on) {
            let target = case(&physics, predicted);
            let floor = target.rms(&target.floor, &target.truth);
            let ratio = target.rms(&prediction(fitted.of(Kind::Preisach), &target).torque, &target.truth) / floor;
            println!("{}, trained on {trained_on}, {predicted}: {ratio:.2}× the floor", physics.name());
            assert!(ratio <= 1.3, "{} trained on {trained_on}, {predicted}: {ratio:.2}× the floor", physics.name());
        }
    }
}
