//! The diagnosis on a corpus of simulated recordings: every effect alone and concealed (its
//! RMS share of the baseline's residual between 0.5× and 1.5× the noise RMS), pairs of effects,
//! recordings with none (turning input, several excitation frequencies, a temperature column),
//! active loops, gears of other physics, and channel delays. On every genetic gear exactly the
//! right set must be found — named, or kept as either of two (damping or a delay) — each
//! magnitude within 25 % of the truth, but for the cases of stated known limits; no effect may
//! be named on a gear of other physics or for its rival (wrong physics), on any case.
//!
//! Gears, noise, excitation, magnitudes and seeds are drawn at random from the case's seed;
//! `SWG_CORPUS_SEED=N` shifts every seed, to check the detector on recordings it was never
//! run on (`bench/diagnose.sh` does that and reports both runs).
use model_core::{GearModel, Identifiable, Model, Params};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use swg_host::diagnose::diagnose_dataset;
use swg_host::diagnose::effects::{Effect, EffectValue};
use swg_host::fit::{fit, rss, FitOptions};
use swg_host::input::Dataset;
use swg_host::prepare::prepare;
use swg_host::simulate::{simulate, simulate_experiment, BoucWen, Experiment, MicroSlip, Motion, Physics, Simulation};

/// A magnitude to start from; the generator rescales it to the wanted share.
fn unit(effect: Effect) -> f64 {
    match effect {
        Effect::Backlash => 1e-5,
        Effect::CoulombFriction => 0.05,
        Effect::ViscousDamping => 20.0,
        Effect::KinematicError => 3e-6,
        Effect::ThermalDrift => 1e-4,
        Effect::TorqueOffset => 0.05,
        Effect::ChannelDelay => 1e-3,
    }
}

struct Case {
    name: String,
    simulation: Simulation,
    /// The gear's truth physics and the motion played: the genetic model's sine for the cases
    /// made by [`make_case`].
    physics: Physics,
    motion: Motion,
    truth: Vec<EffectValue>,
    /// The gear's loop runs the active way (∮T dθ < 0): the diagnosis must say so.
    active: bool,
    /// Why the set found may fall short of the truth on this case (`None`: it must be right).
    /// Its misses and false alarms are counted all the same; wrong physics never passes.
    known_limit: Option<&'static str>,
}

#[derive(Clone, Copy)]
struct Setting {
    turning_input: bool,
    frequencies: usize,
    temperature: bool,
}

/// The genetic truth every corpus case simulates.
fn genetic(sim: &Simulation) -> Params<f64> {
    sim.params.paper_params().expect("the corpus simulates the paper's genetic model")
}

/// RMS of the true model's residual on a recording: the noise (torque and errors in θ) as
/// the diagnosis sees it.
fn noise_rms(sim: &Simulation) -> f64 {
    let prepared = prepare(&Dataset::Recording(simulate(sim).unwrap())).unwrap();
    let model = Model::new(genetic(sim)).unwrap();
    (rss(&model, &prepared.data).unwrap() / prepared.data.theta.len() as f64).sqrt()
}

/// An effect's share of the residual: the RMS residual of the baseline model fitted to a
/// noise-free recording with the effect. What the baseline absorbs (a backlash mostly looks
/// like a softer gear) does not count: the share is what is left to find.
fn share_of_residual(sim: &Simulation) -> f64 {
    let prepared = prepare(&Dataset::Recording(simulate(sim).unwrap())).unwrap();
    fit(&prepared.data, &FitOptions { noise: prepared.noise, ..FitOptions::default() }, |_| {}).unwrap().rms
}

fn make_case(name: &str, effects: &[Effect], setting: Setting, seed: u64) -> Case {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let amplitude = rng.random_range(0.9e-3..1.4e-3);
    let params = Params::from_identifiable(
        rng.random_range(1.5e4..3.0e4),
        rng.random_range(0.0..6.0e9),
        0.0,
        // h < 0 and r < 1.9: the loop runs the passive way (torque higher while θ rises); the
        // genetic loop of h < 0 turns active beyond r ≈ 1.9.
        Identifiable { h: -rng.random_range(0.8..2.5), r: rng.random_range(0.6..1.8) },
        amplitude,
    )
    .unwrap();
    let needs_turning = setting.turning_input || effects.contains(&Effect::KinematicError);
    // Friction, damping and a channel delay open the loop as rate-independent hysteresis does
    // unless the loop is seen at a second rate: such a case plays a slow block, then a fast one.
    let setting = if effects.iter().any(|e| e.is_rate_dependent()) {
        Setting { frequencies: setting.frequencies.max(2), ..setting }
    } else {
        setting
    };
    let needs_temperature = setting.temperature || effects.contains(&Effect::ThermalDrift);
    // Blocks an octave or more apart: a second rate at every place on the loop.
    let base = rng.random_range(0.2..0.5);
    let frequencies: Vec<f64> = (0..setting.frequencies).map(|k| base * (1.0 + k as f64)).collect();
    let mut simulation = Simulation {
        params: GearModel::paper(params),
        amplitude_rad: amplitude,
        cycles: if frequencies.len() > 1 { 3 } else { 5 },
        frequencies_hz: frequencies,
        sample_rate_hz: 1000.0,
        ratio: 50.0,
        input_speed_rad_s: if needs_turning { rng.random_range(2.0..6.0) } else { 0.0 },
        input_bits: Some(20),
        output_bits: Some(if rng.random_bool(0.5) { 20 } else { 21 }),
        torque_noise_nm: rng.random_range(0.02..0.08),
        temperature: needs_temperature.then(|| (rng.random_range(20.0..30.0), rng.random_range(0.3..1.0))),
        effects: Vec::new(),
        seed: rng.random(),
    };
    let noise_rms = noise_rms(&simulation);
    let mut truth = Vec::new();
    for &effect in effects {
        // The effect's own share at the unit magnitude, measured without noise.
        let quiet = Simulation {
            torque_noise_nm: 0.0,
            input_bits: None,
            output_bits: None,
            effects: vec![EffectValue { effect, value: unit(effect) }],
            ..simulation.clone()
        };
        let share_at_unit = share_of_residual(&quiet);
        let share = rng.random_range(0.5..1.5);
        let sign = if matches!(effect, Effect::Backlash | Effect::KinematicError) || rng.random_bool(0.5) {
            1.0
        } else {
            -1.0
        };
        truth.push(EffectValue { effect, value: sign * unit(effect) * share * noise_rms / share_at_unit });
    }
    simulation.effects = truth.clone();
    Case {
        name: format!("{name} (seed {seed})"),
        simulation,
        physics: Physics::Model,
        motion: Motion::Sine,
        truth,
        active: false,
        known_limit: None,
    }
}

/// A gear whose hysteresis is not the genetic model's: Maxwell-slip or Bouc–Wen (the simulator's
/// defaults), under `motion` at `frequencies`, with `effects` of fixed magnitude on top.
fn other_physics_case(
    physics: Physics,
    motion: Motion,
    frequencies: Vec<f64>,
    effects: Vec<EffectValue>,
    seed: u64,
) -> Case {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let simulation = Simulation {
        params: GearModel::paper(
            Params::from_identifiable(2.0e4, 4.0e9, 0.0, Identifiable { h: 1.5, r: 1.2 }, 1.2e-3).unwrap(),
        ),
        amplitude_rad: rng.random_range(1.0e-3..1.3e-3),
        cycles: 4,
        frequencies_hz: frequencies,
        sample_rate_hz: 1000.0,
        ratio: 50.0,
        input_speed_rad_s: 0.0,
        input_bits: Some(20),
        output_bits: Some(20),
        torque_noise_nm: rng.random_range(0.02..0.06),
        temperature: None,
        effects: effects.clone(),
        seed: rng.random(),
    };
    let effect_names: Vec<&str> = effects.iter().map(|e| e.effect.name()).collect();
    let name = format!(
        "{} gear, {} at {:?} Hz{} (seed {seed})",
        physics.name(),
        motion.name(),
        simulation.frequencies_hz,
        if effects.is_empty() { String::new() } else { format!(", {}", effect_names.join(" + ")) }
    );
    Case { name, simulation, physics, motion, truth: effects, active: false, known_limit: None }
}

struct Outcome {
    name: String,
    named: Vec<(Effect, f64)>,
    /// Each effect of a torque the diagnosis kept as either of two (damping or a delay), with
    /// its magnitude fitted in its own place.
    undecided: Vec<(Effect, f64)>,
    truth: Vec<EffectValue>,
    /// The effects the diagnosis said cannot be told from this data.
    untellable: Vec<Effect>,
    /// Why the diagnosis turned down each other effect, to read when a case goes wrong.
    rejected: Vec<String>,
    /// The gear's hysteresis is not the genetic model's.
    other_physics: bool,
    /// The diagnosis named the model's form.
    form: bool,
    /// The diagnosis named an asymmetric spring (no gear of the corpus has one).
    asymmetry: bool,
    /// The diagnosis named kinks of the spring (every gear of the corpus has a smooth one).
    kinks: bool,
    /// The diagnosis named loops that do not follow Masing's rule on a gear whose loops do (the
    /// micro-slip gears; the genetic gears, which run one loop under a sine).
    non_masing_on_masing: bool,
    /// The diagnosis named loops that drift on a gear with return-point memory (the micro-slip
    /// and genetic gears).
    ratcheting_with_memory: bool,
    /// The passivity check flagged the loop active exactly when it is.
    passivity_right: bool,
    known_limit: Option<&'static str>,
}

impl Outcome {
    /// Every effect of the truth named or kept undecided, and nothing named beyond it.
    fn right_set(&self) -> bool {
        self.truth.iter().all(|t| self.found(t.effect).is_some())
            && self.named.iter().all(|(e, _)| self.truth.iter().any(|t| t.effect == *e))
    }

    /// The magnitude of `effect` if named, or kept as one of two.
    fn found(&self, effect: Effect) -> Option<f64> {
        self.named.iter().chain(&self.undecided).find(|(e, _)| *e == effect).map(|(_, m)| *m)
    }

    /// Relative magnitude errors of the effects found.
    fn magnitude_errors(&self) -> Vec<f64> {
        self.truth
            .iter()
            .filter_map(|t| {
                let m = self.found(t.effect)?;
                // Kinematic error is reported as an amplitude: compare magnitudes.
                let (m, v) = if t.effect == Effect::KinematicError { (m.abs(), t.value.abs()) } else { (m, t.value) };
                Some((m - v).abs() / v.abs())
            })
            .collect()
    }
}

fn corpus(base_seed: u64) -> Vec<Case> {
    let plain = Setting { turning_input: false, frequencies: 1, temperature: false };
    let mut cases = Vec::new();
    let mut seed = base_seed;
    let mut next = || {
        seed += 1;
        seed
    };
    // The channel delay's cases come last, so that the cases before it keep their seeds.
    for effect in Effect::ALL.into_iter().filter(|e| *e != Effect::ChannelDelay) {
        for _ in 0..3 {
            cases.push(make_case(effect.name(), &[effect], plain, next()));
        }
    }
    for pair in [
        [Effect::CoulombFriction, Effect::ViscousDamping],
        [Effect::CoulombFriction, Effect::Backlash],
        [Effect::ViscousDamping, Effect::KinematicError],
        [Effect::ThermalDrift, Effect::TorqueOffset],
        [Effect::Backlash, Effect::TorqueOffset],
        [Effect::KinematicError, Effect::CoulombFriction],
    ] {
        cases.push(make_case(&format!("{} + {}", pair[0], pair[1]), &pair, plain, next()));
    }
    for (name, setting) in [
        ("none", plain),
        ("none", plain),
        ("none, turning input", Setting { turning_input: true, ..plain }),
        ("none, turning input", Setting { turning_input: true, ..plain }),
        ("none, three frequencies", Setting { frequencies: 3, ..plain }),
        ("none, three frequencies", Setting { frequencies: 3, ..plain }),
        ("none, two frequencies", Setting { frequencies: 2, ..plain }),
        ("none, two frequencies", Setting { frequencies: 2, ..plain }),
        ("none, temperature column", Setting { temperature: true, ..plain }),
        ("none, all of these", Setting { turning_input: true, frequencies: 3, temperature: true }),
    ] {
        cases.push(make_case(name, &[], setting, next()));
    }
    // Loops that run the active way, as the seed table's and any h > 0 genetic gear's do: the
    // torque channel or the branch labels are off. Flagged, and no effect is named for it.
    for frequencies in [1, 2] {
        let mut case = make_case("none, active loop", &[], Setting { frequencies, ..plain }, next());
        let p = genetic(&case.simulation);
        let id = p.identifiable(case.simulation.amplitude_rad).unwrap();
        case.simulation.params = GearModel::paper(
            Params::from_identifiable(
                p.c1,
                p.c2,
                p.c3,
                Identifiable { h: -id.h, r: id.r },
                case.simulation.amplitude_rad,
            )
            .unwrap(),
        );
        case.active = true;
        cases.push(case);
    }
    // Gears of other physics: the diagnosis must name their shape, never an effect they lack.
    for physics in [Physics::MicroSlip(MicroSlip::default()), Physics::BoucWen(BoucWen::default())] {
        for (motion, frequencies) in [
            (Motion::Sine, vec![0.3]),
            (Motion::Sine, vec![0.2, 0.6]),
            (Motion::Random, vec![0.3]),
            (Motion::Nested, vec![0.3]),
            (Motion::Biased { bias_rad: None }, vec![0.3]),
            (Motion::Hold { load_rad: None }, vec![0.3]),
        ] {
            cases.push(other_physics_case(physics.clone(), motion, frequencies, Vec::new(), next()));
        }
        // And a real damping or channel delay on top, seen at two rates: it is named (or missed,
        // counted), never the other.
        for effect in [
            EffectValue { effect: Effect::ViscousDamping, value: 40.0 },
            EffectValue { effect: Effect::ChannelDelay, value: -2e-3 },
        ] {
            cases.push(other_physics_case(physics.clone(), Motion::Sine, vec![0.2, 0.6], vec![effect], next()));
        }
    }
    for _ in 0..3 {
        cases.push(make_case("channel_delay", &[Effect::ChannelDelay], plain, next()));
    }
    let mut case =
        make_case("channel_delay + coulomb_friction", &[Effect::ChannelDelay, Effect::CoulombFriction], plain, next());
    case.known_limit = Some(
        "friction of this size is mostly taken by the loop's own opening h, and what is left spoils the delay's rate check",
    );
    cases.push(case);
    // A channel delay seen at one rate opens or closes the loop as hysteresis does: it cannot be
    // told from this data, and nothing may be named for it (the truth to find is empty).
    for _ in 0..2 {
        let mut case = make_case("channel_delay at one rate", &[Effect::ChannelDelay], plain, next());
        case.simulation.frequencies_hz.truncate(1);
        case.truth.clear();
        case.known_limit = Some("the loop the delay bends may leave a constant that an offset takes");
        cases.push(case);
    }
    cases
}

/// ∮T dθ and ∫|T||dθ| per cycle of the case's noise-free recording, from its first maximum of θ
/// to its last.
fn truth_energy_per_cycle(case: &Case) -> (f64, f64) {
    let quiet = Simulation { torque_noise_nm: 0.0, input_bits: None, output_bits: None, ..case.simulation.clone() };
    let experiment = Experiment {
        simulation: quiet,
        motion: case.motion.clone(),
        physics: case.physics.clone(),
        deflection_zero_rad: 0.0,
    };
    let recording = simulate_experiment(&experiment).unwrap();
    let (theta, torque) = (&recording.deflection, &recording.torque);
    let maxima: Vec<usize> =
        (1..theta.len() - 1).filter(|&i| theta[i] > theta[i - 1] && theta[i] >= theta[i + 1]).collect();
    let (Some(&first), Some(&last)) = (maxima.first(), maxima.last()) else { return (0.0, 0.0) };
    let cycles = (maxima.len() - 1).max(1) as f64;
    let energy: f64 = (first..last).map(|i| 0.5 * (torque[i] + torque[i + 1]) * (theta[i + 1] - theta[i])).sum();
    let work: f64 =
        (first..last).map(|i| 0.5 * (torque[i].abs() + torque[i + 1].abs()) * (theta[i + 1] - theta[i]).abs()).sum();
    (energy / cycles, work / cycles)
}

fn run(case: &Case) -> Outcome {
    let experiment = Experiment {
        simulation: case.simulation.clone(),
        motion: case.motion.clone(),
        physics: case.physics.clone(),
        deflection_zero_rad: 0.0,
    };
    let recording = simulate_experiment(&experiment).unwrap();
    // SWG_CORPUS_WRITE=DIR keeps each case's recording, to run `swg-host diagnose` on it.
    if let Ok(dir) = std::env::var("SWG_CORPUS_WRITE") {
        let file = std::path::Path::new(&dir).join(format!("{}.csv", case.name.replace([' ', '/', ','], "_")));
        recording.write(std::fs::File::create(file).unwrap()).unwrap();
    }
    let outcome = diagnose_dataset(Dataset::Recording(recording), None, 1).unwrap();
    let flagged_active = outcome.passivity.as_ref().is_some_and(|p| p.active);
    // Negative damping or friction (the corpus draws either sign) gives energy back too. A loop
    // whose energy is within 1 % of its work of zero may be called either way.
    let (energy, work) = truth_energy_per_cycle(case);
    let active = case.active || energy < -0.01 * work;
    let ambiguous = !case.active && energy.abs() <= 0.01 * work;
    if flagged_active != active && !ambiguous {
        println!("    passivity of {}: {:?}", case.name, outcome.passivity.as_ref().map(|p| &p.words));
    }
    let asymmetry = outcome.asymmetry.named().is_some();
    let kinks = outcome.kinks.named().is_some();
    let with_memory = matches!(case.physics, Physics::Model | Physics::MicroSlip(_));
    let non_masing_on_masing = outcome.non_masing.named().is_some() && with_memory;
    let ratcheting_with_memory = outcome.ratcheting.named().is_some() && with_memory;
    let diagnosis = outcome.diagnosis;
    let named = diagnosis.findings.iter().map(|f| (f.effect, f.magnitude)).collect();
    let undecided = diagnosis.undecided.iter().flat_map(|u| u.effects.into_iter().zip(u.magnitudes)).collect();
    let rejected =
        diagnosis.rejected.iter().map(|r| format!("{} ({:.3e}): {}", r.effect, r.magnitude, r.reason)).collect();
    let untellable = outcome
        .observed
        .cannot_reveal
        .iter()
        .map(|(effect, _)| *effect)
        .chain(diagnosis.untellable.iter().map(|u| u.effect))
        .collect();
    let other_physics = !matches!(case.physics, Physics::Model);
    Outcome {
        name: case.name.clone(),
        named,
        undecided,
        truth: case.truth.clone(),
        untellable,
        rejected,
        other_physics,
        form: diagnosis.model_form.is_some(),
        asymmetry,
        kinks,
        non_masing_on_masing,
        ratcheting_with_memory,
        passivity_right: flagged_active == active || ambiguous,
        known_limit: case.known_limit,
    }
}

#[test]
fn names_exactly_the_missing_physics_with_its_magnitude() {
    let base_seed = std::env::var("SWG_CORPUS_SEED").ok().and_then(|s| s.parse().ok()).unwrap_or(0);
    let mut cases = corpus(base_seed);
    assert!(cases.len() >= 50);
    // SWG_CORPUS_ONLY=TEXT runs only the cases whose name contains TEXT (while working on one).
    if let Ok(only) = std::env::var("SWG_CORPUS_ONLY") {
        cases.retain(|c| c.name.contains(&only));
    }
    let outcomes: Vec<Outcome> = cases.par_iter().map(run).collect();

    let mut right = 0;
    let mut wrong_physics = 0;
    let mut forms = 0;
    let mut passivity_wrong = 0;
    let mut false_alarms = 0;
    let mut misses = 0;
    let mut said_untellable = 0;
    let mut undecided = 0;
    let mut errors = Vec::new();
    let mut failures = Vec::new();
    for o in &outcomes {
        let truth: Vec<String> = o.truth.iter().map(|t| format!("{}={:.3e}", t.effect, t.value)).collect();
        let named: Vec<String> = o.named.iter().map(|(e, m)| format!("{e}={m:.3e}")).collect();
        let kept: Vec<String> = o.undecided.iter().map(|(e, m)| format!("{e}={m:.3e}")).collect();
        let magnitude_errors = o.magnitude_errors();
        let worst = magnitude_errors.iter().copied().fold(0.0, f64::max);
        println!(
            "{:<52} truth [{}]  named [{}]{}  worst magnitude error {:.1} %",
            o.name,
            truth.join(", "),
            named.join(", "),
            if kept.is_empty() { String::new() } else { format!("  undecided [{}]", kept.join(" or ")) },
            100.0 * worst
        );
        // An effect named on a gear of other physics stands in for its shape, and a rate effect
        // named for its rival (damping for a channel delay, or the reverse) for another
        // mechanism: wrong physics. Any other effect named that is not there: a false alarm.
        for (effect, _) in o.named.iter().filter(|(e, _)| o.truth.iter().all(|t| t.effect != *e)) {
            let rival_of_truth = o.truth.iter().any(|t| t.effect.rival() == Some(*effect));
            if o.other_physics || rival_of_truth {
                wrong_physics += 1;
            } else {
                false_alarms += 1;
            }
        }
        if o.asymmetry {
            wrong_physics += 1;
            println!("    an asymmetric spring named on {}, whose spring is symmetric", o.name);
        }
        if o.kinks {
            wrong_physics += 1;
            println!("    kinks of the spring named on {}, whose spring is smooth", o.name);
        }
        if o.non_masing_on_masing {
            wrong_physics += 1;
            println!("    loops that break Masing's rule named on {}, whose loops follow it", o.name);
        }
        if o.ratcheting_with_memory {
            wrong_physics += 1;
            println!("    loops that drift named on {}, whose loops close", o.name);
        }
        forms += usize::from(o.other_physics && o.form);
        let missed: Vec<Effect> = o.truth.iter().map(|t| t.effect).filter(|&e| o.found(e).is_none()).collect();
        misses += missed.len();
        said_untellable += missed.iter().filter(|e| o.untellable.contains(e)).count();
        undecided += o
            .truth
            .iter()
            .filter(|t| o.named.iter().all(|(e, _)| *e != t.effect) && o.found(t.effect).is_some())
            .count();
        errors.extend(magnitude_errors);
        if o.right_set() {
            right += 1;
        }
        if !o.passivity_right {
            passivity_wrong += 1;
            println!("    passivity check wrong on {}", o.name);
        }
        // On a gear of other physics the diagnosis must name no effect it lacks (counted above);
        // a real effect on top of it may be missed (counted, not failed), as on a known limit.
        if !o.right_set() {
            if let Some(why) = o.known_limit {
                println!("    known limit: {why}");
            }
        }
        // On a gear of other physics the genetic baseline's misfit leaks into a magnitude too.
        if !o.other_physics && o.known_limit.is_none() && (!o.right_set() || worst > 0.25) {
            failures.push(o.name.clone());
            for reason in &o.rejected {
                println!("    rejected {reason}");
            }
        }
    }
    errors.sort_by(f64::total_cmp);
    let median_error = errors.get(errors.len() / 2).copied().unwrap_or(0.0);
    let max_error = errors.last().copied().unwrap_or(0.0);
    println!(
        "corpus seed {base_seed}: {right}/{} right set, {wrong_physics} wrong physics named, {false_alarms} false alarms, {misses} misses ({said_untellable} said to be untellable from the data), {undecided} told as either of two, magnitude error median {:.1} % max {:.1} %; model form named on {forms}/{} gears of other physics; passivity wrong on {passivity_wrong}",
        outcomes.len(),
        100.0 * median_error,
        100.0 * max_error,
        outcomes.iter().filter(|o| o.other_physics).count()
    );
    assert_eq!(
        wrong_physics, 0,
        "an effect was named on a gear of other physics, a rate effect for its rival, an asymmetric spring on a \
         symmetric gear, loops that break Masing's rule on a gear whose loops follow it, or loops that drift on a gear whose \
         loops close"
    );
    assert_eq!(passivity_wrong, 0, "the passivity check missed an active loop or flagged a passive one");
    assert!(failures.is_empty(), "wrong set or magnitude off by > 25 % on a genetic gear: {failures:?}");
}

/// On a gear whose stiffness hardly changes along the loop, damping c·dθ/dt and a channel delay
/// −τ·K·dθ/dt are one column: the diagnosis names neither, keeps the torque in the model (so
/// that no other effect leans on it) and reports it as either of the two.
#[test]
fn damping_on_a_linear_gear_is_not_told_from_a_channel_delay() {
    let amplitude = 1.2e-3;
    let simulation = Simulation {
        params: GearModel::paper(
            Params::from_identifiable(2.0e4, 0.0, 0.0, Identifiable { h: -0.3, r: 1.0 }, amplitude).unwrap(),
        ),
        amplitude_rad: amplitude,
        cycles: 3,
        frequencies_hz: vec![0.3, 0.6],
        sample_rate_hz: 1000.0,
        ratio: 50.0,
        input_speed_rad_s: 0.0,
        input_bits: Some(20),
        output_bits: Some(20),
        torque_noise_nm: 0.03,
        temperature: None,
        effects: vec![EffectValue { effect: Effect::ViscousDamping, value: 30.0 }],
        seed: 5,
    };
    let outcome = diagnose_dataset(Dataset::Recording(simulate(&simulation).unwrap()), None, 1).unwrap();
    let diagnosis = outcome.diagnosis;
    for f in &diagnosis.findings {
        println!("named {} = {:.4e}", f.effect, f.magnitude);
    }
    for r in &diagnosis.rejected {
        println!("rejected {}: {}", r.effect, r.reason);
    }
    assert!(diagnosis.findings.is_empty(), "an effect was named");
    let [undecided] = &diagnosis.undecided[..] else {
        panic!("expected one undecided torque: {:?}", diagnosis.undecided)
    };
    let mut effects = undecided.effects;
    effects.sort();
    assert_eq!(effects, [Effect::ViscousDamping, Effect::ChannelDelay]);
    let damping = undecided.magnitudes[undecided.effects.iter().position(|e| *e == Effect::ViscousDamping).unwrap()];
    assert!((damping - 30.0).abs() < 0.25 * 30.0, "damping {damping} N·m·s/rad, truth 30");
}

/// The genetic loop is infinitely stiff at its tips, where the measured rate is small but not
/// zero: a delay's column −K·dθ/dt ran far beyond the torque it stands for there, and this
/// case's delay of 2.76 ms was refused ("the torque fits worse with it": RSS 612 → 1056 N·m²)
/// and a torque offset named instead. With the model torque's time derivative as its column,
/// the delay is kept (named, or undecided against damping: the loop's stiffness changes too
/// little here to tell) and nothing else is named.
#[test]
fn a_channel_delay_on_a_loop_infinitely_stiff_at_its_tips_is_not_taken_for_an_offset() {
    let plain = Setting { turning_input: false, frequencies: 1, temperature: false };
    let outcome = run(&make_case("channel_delay", &[Effect::ChannelDelay], plain, 2054));
    println!("named {:?}, undecided {:?}, rejected {:?}", outcome.named, outcome.undecided, outcome.rejected);
    assert!(outcome.right_set(), "named {:?}, truth {:?}", outcome.named, outcome.truth);
    let errors = outcome.magnitude_errors();
    assert!(errors.iter().all(|&e| e < 0.1), "magnitude errors {errors:?}");
}

/// The corpus case `name` at corpus seed `base_seed`, diagnosed.
fn corpus_case(base_seed: u64, name: &str) -> Outcome {
    let case = corpus(base_seed).into_iter().find(|c| c.name == name).unwrap_or_else(|| panic!("no case {name}"));
    let outcome = run(&case);
    println!("named {:?}, undecided {:?}, rejected {:?}", outcome.named, outcome.undecided, outcome.rejected);
    outcome
}

#[test]
fn the_samples_before_a_mid_motion_recordings_extremes_are_not_taken_for_an_offset() {
    // A sine that starts on its loop: before its extremes, the genetic form runs from rest
    // along a loop the gear was already on, and that misfit read as a torque offset.
    for name in ["channel_delay at one rate (seed 3057)", "channel_delay at one rate (seed 3058)"] {
        let outcome = corpus_case(3000, name);
        assert!(outcome.named.is_empty() && outcome.undecided.is_empty(), "{name}: {:?}", outcome.named);
    }
}

#[test]
fn a_finding_that_the_effects_accepted_after_it_take_over_is_withdrawn() {
    // Coulomb friction is accepted first (−0.15 N·m), then damping and the kinematic error
    // explain the same residual and leave it at 0.006 N·m: without it the criterion rises by 0.
    let outcome = corpus_case(7000, "viscous_damping + kinematic_error (seed 7021)");
    assert!(outcome.right_set(), "named {:?}, truth {:?}", outcome.named, outcome.truth);
    assert!(outcome.rejected.iter().any(|r| r.contains("coulomb_friction") && r.contains("accepted first")));
}

#[test]
fn damping_and_a_delay_are_not_told_apart_where_their_halves_do_not_separate() {
    // A channel delay beside friction, on loops whose moving halves differ in stiffness by only
    // 9 %: neither half's ratio can refute either mechanism, so the rate torque stays undecided.
    let outcome = corpus_case(3000, "channel_delay + coulomb_friction (seed 3056)");
    assert!(outcome.named.iter().all(|(e, _)| *e != Effect::ViscousDamping), "{:?}", outcome.named);
    assert!(outcome.undecided.iter().any(|(e, _)| *e == Effect::ChannelDelay), "{:?}", outcome.undecided);
}

#[test]
fn an_effect_the_torque_as_measured_fits_a_little_worse_with_is_still_judged() {
    // Friction beside a delay kept undecided: weighed by the noise the friction drops the
    // criterion, while the unweighted RSS over the scored samples rises by 0.8 % (56.59 →
    // 57.02 (N·m)²). Any rise refused it; a rise beyond the 5 % an effect must explain does.
    let outcome = corpus_case(1000, "channel_delay + coulomb_friction (seed 1056)");
    assert!(outcome.named.iter().any(|(e, _)| *e == Effect::CoulombFriction), "{:?}", outcome.named);
    assert!(outcome.right_set(), "named {:?}, truth {:?}", outcome.named, outcome.truth);
}
