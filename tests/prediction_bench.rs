//! Benchmark (figures, not a test): how well each model predicts motions it was not fitted on,
//! on gears of three truth physics. `cargo bench -p swg-system-tests --bench prediction`, or
//! `bash bench/prediction.sh`, which also keeps the table in bench/out/prediction.md.
//!
//! For each physics (genetic with memory, micro-slip, Bouc–Wen, a catalogue three-segment gear)
//! and each training motion (the
//! bench sine, a band-limited random motion): the models are fitted to a noisy recording of
//! that motion (20-bit encoders, 0.05 N·m torque noise, as the fit benchmark), then run along
//! the measured angles of every other motion. Their torque is compared with the noise-free
//! truth; the floor is the truth physics itself run on the same measured angles (what the
//! encoders' quantisation leaves), which no model can beat by much.
//!
//! - "symmetric": today's rule, the genetic loop fit on each leg's amplitude and direction
//!   from the offline segmentation of the recording (the fit before the stateful models).
//! - "genetic": the genetic model with Madelung's rules (`fit --model genetic`).
//! - "micro-slip": Maxwell-slip with 16 elements (`fit --model micro-slip`).
//!
//! Stiffness, where the truth has a tangent (micro-slip and catalogue gears; "–" elsewhere), as
//! `prediction_corpus.rs` defines them: "tangent err" per motion (the model's dT/dθ along it
//! against the truth's tangent) and, per fit, "K err" (the goal's: the slope of the loop's
//! centre curve on the bench sine against the truth's, RMS over the truth's RMS).
#[path = "prediction_corpus.rs"]
mod corpus;

use corpus::*;
use swg_host::report::plot::{motion_svg, MotionSeries};
use swg_host::simulate::{BoucWen, Catalogue, MicroSlip, Physics};

fn main() {
    let physics = [
        ("genetic", Physics::Model),
        ("micro-slip", Physics::MicroSlip(MicroSlip::default())),
        ("bouc-wen", Physics::BoucWen(BoucWen::default())),
        ("catalogue", Physics::Catalogue(Catalogue::default())),
    ];
    let percent = |e: Option<f64>| e.map_or("–".to_string(), |e| format!("{:.1} %", 100.0 * e));
    let mut table = String::from(
        "| physics | trained on | predicts | floor RMS N·m | symmetric RMS / floor | genetic RMS / floor | micro-slip RMS / floor | floor max step N·m | symmetric step / floor | genetic step / floor | micro-slip step / floor | genetic tangent err | micro-slip tangent err |\n|---|---|---|---|---|---|---|---|---|---|---|---|---|\n",
    );
    let mut worst: Vec<(String, f64, f64, f64, String, String)> = Vec::new();
    for (name, physics) in &physics {
        // Each motion: measured, noise-free truth, and the truth on the measured angles.
        let cases: Vec<Case> = MOTIONS.iter().map(|m| case(physics, m)).collect();
        for trained_on in TRAINING {
            let training = &cases.iter().find(|c| c.motion == trained_on).expect("a training motion").measured;
            let fitted = fit_all(training);
            let (mut worst_symmetric, mut worst_genetic, mut worst_slip) = (0.0f64, 0.0f64, 0.0f64);
            let mut worst_slip_k: Option<f64> = None;
            for case in cases.iter().filter(|c| c.motion != trained_on) {
                let (m, measured, truth, floor) = (&case.motion, &case.measured, &case.truth, &case.floor);
                let predictions = predictions(&fitted, case);
                let floor_rms = case.rms(floor, truth);
                let floor_step = max_step(floor);
                let ratios: Vec<f64> = predictions.iter().map(|p| case.rms(&p.torque, truth) / floor_rms).collect();
                let steps: Vec<f64> = predictions.iter().map(|p| max_step(&p.torque) / floor_step).collect();
                let k_err = [&predictions[1], &predictions[2]].map(|p| case.stiffness_error(&p.stiffness));
                worst_slip_k = k_err[1].map(|e| worst_slip_k.map_or(e, |w| w.max(e)));
                worst_symmetric = worst_symmetric.max(ratios[0]);
                worst_genetic = worst_genetic.max(ratios[1]);
                worst_slip = worst_slip.max(ratios[2]);
                table.push_str(&format!(
                    "| {name} | {trained_on} | {m} | {floor_rms:.4} | {:.2} | {:.2} | {:.2} | {floor_step:.3} | {:.2} | {:.2} | {:.2} | {} | {} |\n",
                    ratios[0], ratios[1], ratios[2], steps[0], steps[1], steps[2], percent(k_err[0]), percent(k_err[1])
                ));
                if *name == "micro-slip" && trained_on == "sine" && (*m == "biased" || *m == "nested") {
                    let labels = ["micro-slip model (run from rest)", "today's symmetric rule"];
                    let svg = motion_svg(
                        &format!("{name} gear, {m} motion: models fitted on the bench sine"),
                        &measured.time,
                        &measured.deflection,
                        &measured.torque,
                        &[
                            MotionSeries { label: labels[0], torque: &predictions[2].torque },
                            MotionSeries { label: labels[1], torque: &predictions[0].torque },
                        ],
                    )
                    .expect("picture");
                    let path = format!("{}/../docs/prediction-{m}.svg", env!("CARGO_MANIFEST_DIR"));
                    std::fs::write(&path, svg).expect("docs/ is writable");
                }
            }
            let (slip_tangent, slip_k) =
                (percent(worst_slip_k), percent(centre_stiffness_error(physics, &fitted.micro_slip)));
            let case = format!("{name}, trained on {trained_on}");
            worst.push((case, worst_symmetric, worst_genetic, worst_slip, slip_k, slip_tangent));
        }
    }
    println!("{table}");
    println!("worst prediction RMS / floor over the predicted motions:");
    println!("| case | symmetric | genetic | micro-slip | micro-slip K err | micro-slip worst tangent err |\n|---|---|---|---|---|---|");
    for (case, s, g, m, k, t) in worst {
        println!("| {case} | {s:.2} | {g:.2} | {m:.2} | {k} | {t} |");
    }
}
