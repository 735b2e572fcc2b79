//! `diagnose`'s held-out samples: interleaved cycles over the whole recording.
use swg_host::diagnose::Observed;
use swg_host::input::Dataset;
use swg_host::prepare::prepare;
use swg_host::simulate::{simulate, Simulation};

/// A recording's held-out samples are whole cycles spread over it, not its last quarter: a
/// gear warms and a sensor drifts over a recording, and the last quarter would judge an effect
/// on how the model extrapolates the drift.
#[test]
fn a_recordings_held_out_samples_are_interleaved_cycles_over_the_whole_recording() {
    let params =
        swg_host::report::params::parse_model("seed".as_ref(), include_str!("../../data/seed/lht-20-50-fit.json"))
            .unwrap();
    let simulation = Simulation {
        params,
        amplitude_rad: 1.168e-3,
        frequencies_hz: vec![0.5],
        cycles: 12,
        sample_rate_hz: 1000.0,
        ratio: 50.0,
        input_speed_rad_s: 0.0,
        input_bits: Some(20),
        output_bits: Some(20),
        torque_noise_nm: 0.05,
        temperature: None,
        effects: Vec::new(),
        seed: 1,
    };
    let dataset = Dataset::Recording(simulate(&simulation).unwrap());
    let mut prepared = prepare(&dataset).unwrap();
    let data = std::mem::take(&mut prepared.data);
    let n = data.theta.len();
    let observed = Observed::with_data(dataset, &prepared, data);
    let held = observed.held_out();
    let held = held.as_ref();
    assert_eq!(observed.held_out_count(), held.len());
    // About one cycle in four, from the first quarter of the recording to the last.
    assert!(held.len() > n / 6 && held.len() < n / 3, "{} of {n}", held.len());
    assert!(held.first().is_some_and(|&i| i < n / 4) && held.last().is_some_and(|&i| i >= 3 * n / 4), "{held:?}");
    // Every sample once, fitted or held out.
    let mut all: Vec<usize> = observed.training().iter().chain(held).copied().collect();
    all.sort_unstable();
    assert_eq!(all, (0..n).collect::<Vec<_>>());
    // Each held-out span is a whole cycle, between two maxima of the deflection.
    for span in observed.held_out_spans().iter().filter(|s| s.held_out) {
        let at = |i: usize| observed.data.theta[i];
        let peak = observed.data.theta.iter().fold(0.0f64, |m, t| m.max(*t));
        assert!(at(span.range.start) > 0.99 * peak && at(span.range.end) > 0.99 * peak, "{span:?}");
    }
}
