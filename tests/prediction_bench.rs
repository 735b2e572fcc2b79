//! Benchmark (figures, not a test): how well each model predicts motions it was not fitted on,
//! on gears of five truth physics. `cargo bench -p swg-system-tests --bench prediction`, or
//! `bash bench/prediction.sh`, which also keeps the table in bench/out/prediction.md.
//!
//! For each physics (genetic with memory, micro-slip, Bouc–Wen, a catalogue three-segment gear,
//! slip elements that grip harder on one side: a Preisach gear that is not Masing) and each
//! training motion (the
//! bench sine, a band-limited random motion): the models are fitted to a noisy recording of
//! that motion (20-bit encoders, 0.05 N·m torque noise, as the fit benchmark), then run along
//! the measured angles of every other motion. Their torque is compared with the noise-free
//! truth; the floor is the truth physics itself run on the same measured angles (what the
//! encoders' quantisation leaves), which no model can beat by much.
//!
//! - "symmetric": today's rule, the genetic loop fit on each leg's amplitude and direction
//!   from the offline segmentation of the recording (the fit before the stateful models).
//! - each kind as `fit --model KIND` fits it (genetic, micro-slip, bouc-wen, preisach);
//! - "auto": the kind `fit --model auto` chooses by held-out error, refitted on every sample.
//!
//! Stiffness, where the truth has a tangent (micro-slip and catalogue gears; "–" elsewhere), as
//! `prediction_corpus.rs` defines them: "tangent err" per motion (the model's dT/dθ along it
//! against the truth's tangent) and, per fit, "K err" (the goal's: the slope of the loop's
//! centre curve on the bench sine against the truth's, RMS over the truth's RMS).
#[path = "prediction_corpus.rs"]
mod corpus;

use corpus::*;
use model_core::Kind;
use swg_host::report::plot::{motion_svg, MotionSeries};
use swg_host::simulate::{BoucWen, Catalogue, MicroSlip, Physics, Preisach};

fn main() {
    let physics = [
        ("genetic", Physics::Model),
        ("micro-slip", Physics::MicroSlip(MicroSlip::default())),
        ("bouc-wen", Physics::BoucWen(BoucWen::default())),
        ("catalogue", Physics::Catalogue(Catalogue::default())),
        ("preisach", Physics::Preisach(Preisach::default())),
    ];
    let percent = |e: Option<f64>| e.map_or("–".to_string(), |e| format!("{:.1} %", 100.0 * e));
    let kinds: Vec<&str> = Kind::ALL.iter().map(|k| k.label()).collect();
    let mut table = format!(
        "| physics | trained on | predicts | floor RMS N·m | symmetric | {} | auto (its choice) | auto step / floor's |\n|---|---|---|---|---|{}---|---|\n",
        kinds.join(" | "),
        "---|".repeat(kinds.len())
    );
    let mut stiffness = format!(
        "| physics | trained on | {} | auto |\n|---|---|{}---|\n",
        kinds.iter().map(|k| format!("{k} K err / worst tangent err")).collect::<Vec<_>>().join(" | "),
        "---|".repeat(kinds.len())
    );
    let mut worst_rows = String::new();
    for (name, physics) in &physics {
        // Each motion: measured, noise-free truth, and the truth on the measured angles.
        let cases: Vec<Case> = MOTIONS.iter().map(|m| case(physics, m)).collect();
        for trained_on in TRAINING {
            let training = &cases.iter().find(|c| c.motion == trained_on).expect("a training motion").measured;
            let fitted = fit_all(training);
            let auto = fitted.auto.as_ref().expect("auto is fitted");
            // Worst RMS / floor and worst tangent error of: symmetric, each kind, auto.
            let models = 2 + Kind::ALL.len();
            let mut worst = vec![0.0f64; models];
            let mut worst_tangent: Vec<Option<f64>> = vec![None; models];
            for case in cases.iter().filter(|c| c.motion != trained_on) {
                let (m, measured, truth, floor) = (&case.motion, &case.measured, &case.truth, &case.floor);
                let predictions = predictions(&fitted, case);
                let floor_rms = case.rms(floor, truth);
                let ratios: Vec<f64> = predictions.iter().map(|p| case.rms(&p.torque, truth) / floor_rms).collect();
                for (i, p) in predictions.iter().enumerate() {
                    worst[i] = worst[i].max(ratios[i]);
                    if let Some(e) = case.stiffness_error(&p.stiffness) {
                        worst_tangent[i] = Some(worst_tangent[i].map_or(e, |w: f64| w.max(e)));
                    }
                }
                let auto_step = max_step(&predictions[models - 1].torque) / max_step(floor);
                let per_kind: Vec<String> = ratios[1..models - 1].iter().map(|r| format!("{r:.2}")).collect();
                table.push_str(&format!(
                    "| {name} | {trained_on} | {m} | {floor_rms:.4} | {:.2} | {} | {:.2} ({}) | {auto_step:.2} |\n",
                    ratios[0],
                    per_kind.join(" | "),
                    ratios[models - 1],
                    auto.kind().label()
                ));
                if *name == "micro-slip" && trained_on == "sine" && (*m == "biased" || *m == "nested") {
                    let labels = ["micro-slip model (run from rest)", "today's symmetric rule"];
                    let slip = 1 + Kind::ALL.iter().position(|k| *k == Kind::MicroSlip).expect("a kind");
                    let svg = motion_svg(
                        &format!("{name} gear, {m} motion: models fitted on the bench sine"),
                        &measured.time,
                        &measured.deflection,
                        &measured.torque,
                        &[
                            MotionSeries { label: labels[0], torque: &predictions[slip].torque },
                            MotionSeries { label: labels[1], torque: &predictions[0].torque },
                        ],
                    )
                    .expect("picture");
                    let path = format!("{}/../docs/prediction-{m}.svg", env!("CARGO_MANIFEST_DIR"));
                    std::fs::write(&path, svg).expect("docs/ is writable");
                }
            }
            let k_err = |model| percent(centre_stiffness_error(physics, model));
            let per_kind: Vec<String> = fitted
                .kinds
                .iter()
                .zip(&worst_tangent[1..])
                .map(|(model, t)| format!("{} / {}", k_err(model), percent(*t)))
                .collect();
            if physics.tangent_along(&[0.0]).expect("valid physics").is_some() {
                stiffness.push_str(&format!(
                    "| {name} | {trained_on} | {} | {} / {} ({}) |\n",
                    per_kind.join(" | "),
                    k_err(auto),
                    percent(worst_tangent[models - 1]),
                    auto.kind().label()
                ));
            }
            let figures: Vec<String> = worst.iter().map(|w| format!("{w:.2}")).collect();
            worst_rows.push_str(&format!(
                "| {name}, trained on {trained_on} | {} ({}) |\n",
                figures.join(" | "),
                auto.kind().label()
            ));
        }
    }
    println!("prediction RMS / floor (the truth physics on the same measured angles):\n\n{table}");
    println!("stiffness where the truth has a tangent: K err (the loop's centre slope on the bench sine) / the worst tangent err over the predicted motions:\n\n{stiffness}");
    println!("worst prediction RMS / floor over the predicted motions:\n");
    println!(
        "| case | symmetric | {} | auto (its choice) |\n|---|---|{}---|",
        kinds.join(" | "),
        "---|".repeat(kinds.len())
    );
    print!("{worst_rows}");
}
