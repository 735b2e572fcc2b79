//! Host tests of Bouc–Wen hysteresis: the closed-form step against many small steps and a fine
//! Euler integration, the bound on z, the slope, f32 against f64, and bad inputs.
extern crate std;

use super::*;
use core::f64::consts::TAU;
use proptest::prelude::*;

/// The simulator's default gear's hysteresis: z saturates at 0.4 mrad.
const GEAR: BoucWen<f64> = BoucWen { a: 1.0, beta: 1250.0, gamma: 1250.0, n: 1.0 };
/// OpenSees' Bouc–Wen of `bench/opensees` (n = 1.5): z saturates at 0.30 mrad.
const SHARP: BoucWen<f64> = BoucWen { a: 1.0, beta: 9.6e4, gamma: 9.6e4, n: 1.5 };
/// The seed loop's amplitude, rad.
const A: f64 = 1.168e-3;

fn state(params: BoucWen<f64>) -> BoucWenState<f64> {
    BoucWenState::new(params).unwrap()
}

#[test]
fn one_step_lands_where_ten_thousand_small_ones_do() {
    // γ < β, γ = β and γ > β: the three shapes of the unloading piece (c > 0, 0, < 0).
    for gamma in [400.0, 1250.0, 2000.0] {
        let params = BoucWen { gamma, ..GEAR };
        for target in [A, -A, 0.3e-3, 5e-3] {
            let mut one = state(params);
            // Up to +0.8 mrad first, so that a step down crosses z = 0.
            one.step(0.8e-3).unwrap();
            let mut many = one;
            let z_one = one.step(target).unwrap();
            let mut z_many = 0.0;
            for k in 1..=10_000 {
                z_many = many.step(0.8e-3 + (target - 0.8e-3) * k as f64 / 10_000.0).unwrap();
            }
            assert!((z_one - z_many).abs() < 1e-12, "γ {gamma}, to {target}: {z_one} vs {z_many}");
        }
    }
}

/// The largest |Δz| between the state stepped every 1000th sample and an Euler integration
/// of every one of 400,000 samples along 1.5 cycles of A·sin.
fn worst_against_euler(params: BoucWen<f64>) -> f64 {
    let mut bw = state(params);
    let (mut z, mut theta) = (0.0f64, 0.0f64);
    let n = 400_000;
    let mut worst: f64 = 0.0;
    for i in 1..=n {
        let next = A * (TAU * 1.5 * i as f64 / n as f64).sin();
        let d = next - theta;
        z += d * (params.a - z.abs().powf(params.n) * (params.beta * (d * z).signum() + params.gamma));
        theta = next;
        if i % 1000 == 0 {
            bw.step(theta).unwrap();
            worst = worst.max((bw.z() - z).abs());
        }
    }
    worst
}

#[test]
fn it_matches_a_fine_euler_integration_of_the_differential_equation() {
    for params in [GEAR, SHARP, BoucWen { n: 3.0, gamma: 500.0, beta: 2e9, ..GEAR }] {
        let worst = worst_against_euler(params);
        assert!(worst < 1e-3 * params.z_max(), "{params:?}: worst |Δz| {worst}");
    }
}

/// The module's bound on the error of a step for n ≠ 1, per u* travelled, in z_max.
const STEP_BOUND: f64 = 5e-3;

#[test]
fn for_n_other_than_one_a_large_step_lands_within_the_stated_bound() {
    // Steps of 10 u*, 3 u* and u*/2 from nine starting z, each against the same step in 10,000
    // pieces, over n from just above 1 to 6 and loops from narrow (γ > β) to wide (γ < 0).
    let mut worst = (0.0, GEAR);
    for n in [1.0 + 1e-9, 1.2, 1.5, 2.0, 3.0, 6.0] {
        for (beta, gamma) in
            [(1250.0, 1250.0), (2000.0, 500.0), (500.0, 2000.0), (1000.0, -500.0), (1000.0, -950.0), (50.0, 2450.0)]
        {
            let params = BoucWen { n, beta, gamma, ..GEAR };
            let (z_max, scale) = (params.z_max(), params.z_max() / params.a);
            for start in 0..9 {
                let from = z_max * (start as f64 / 4.0 - 1.0) * 0.99;
                for travel in [10.0f64, 3.0, 0.5, -0.5, -3.0] {
                    // From z at its bound against the travel, on to w = sign(travel)·z = `from`.
                    let sign = travel.signum();
                    let mut one = state(params);
                    one.step(-100.0 * scale * sign).unwrap();
                    while sign * one.z() < from {
                        one.step(one.theta() + 1e-3 * scale * sign).unwrap();
                    }
                    let mut many = one;
                    let start_theta = one.theta();
                    let z_one = one.step(start_theta + travel * scale).unwrap();
                    let mut z_many = 0.0;
                    for k in 1..=10_000 {
                        z_many = many.step(start_theta + travel * scale * k as f64 / 10_000.0).unwrap();
                    }
                    let per_scale = (z_one - z_many).abs() / z_max / f64::abs(travel);
                    if per_scale > worst.0 {
                        worst = (per_scale, params);
                    }
                }
            }
        }
    }
    std::println!("worst |Δz| = {:.1e}·z_max per u*, at {:?}", worst.0, worst.1);
    assert!(worst.0 < STEP_BOUND, "{worst:?}");
}

#[test]
fn n_just_above_one_agrees_with_the_exact_step() {
    let mut exact = state(GEAR);
    let mut stepped = state(BoucWen { n: 1.0 + 1e-9, ..GEAR });
    for theta in [0.8e-3, -0.2e-3, 1.5e-3, -A, 0.1e-3] {
        let (a, b) = (exact.step(theta).unwrap(), stepped.step(theta).unwrap());
        // Within the bound for the longest travel between two of these θ, 6.7 u*.
        assert!((a - b).abs() < STEP_BOUND * 6.7 * GEAR.z_max(), "at {theta}: {a} vs {b}");
    }
}

#[test]
fn z_saturates_at_its_bound_and_never_passes_it() {
    let mut bw = state(GEAR);
    for theta in [5e-3, -5e-3, 1e-3, -2e-2, 3e-2] {
        let z = bw.step(theta).unwrap();
        assert!(z.abs() <= GEAR.z_max(), "{z}");
    }
    assert!((bw.z() - GEAR.z_max()).abs() < 1e-9 * GEAR.z_max());
}

#[test]
fn the_slope_is_the_right_hand_side_of_the_equation_and_matches_a_small_step() {
    let mut bw = state(GEAR);
    bw.step(0.5e-3).unwrap();
    for rising in [true, false] {
        let h = if rising { 1e-9 } else { -1e-9 };
        let mut moved = bw;
        let dz = moved.step(bw.theta() + h).unwrap() - bw.z();
        let slope = bw.slope(rising);
        assert!((dz / h - slope).abs() < 1e-5 * GEAR.a, "rising {rising}: {} vs {slope}", dz / h);
    }
    // Loading with z at its bound: no more hysteretic deflection; unloading: A + (β − γ)·z_max.
    let params = BoucWen { gamma: 400.0, ..GEAR };
    let mut bw = state(params);
    bw.step(1.0).unwrap();
    assert!(bw.slope(true).abs() < 1e-9);
    let unloading = params.a + (params.beta - params.gamma) * params.z_max();
    assert!((bw.slope(false) - unloading).abs() < 1e-9, "{} vs {unloading}", bw.slope(false));
}

#[test]
fn a_reversal_is_continuous_in_z() {
    let mut bw = state(GEAR);
    bw.step(A).unwrap();
    let at_tip = bw.z();
    let after = bw.step(A - 1e-9).unwrap();
    assert!((after - at_tip).abs() < 3e-9, "{at_tip} → {after}");
}

#[test]
fn dither_about_a_held_load_ratchets() {
    // No return-point memory: small loops about a held deflection drift, here towards the
    // unloading branch's z, which is this physics (issue 17, "no return-point memory").
    let mut bw = state(GEAR);
    bw.step(A).unwrap();
    let start = bw.step(0.5 * A).unwrap();
    for _ in 0..200 {
        bw.step(0.5 * A + 0.05e-3).unwrap();
        bw.step(0.5 * A).unwrap();
    }
    assert!((bw.z() - start).abs() > 1e-6, "{start} → {}", bw.z());
}

#[test]
fn bad_parameters_and_deflections_are_refused() {
    for params in [
        BoucWen { a: 0.0, ..GEAR },
        BoucWen { beta: 0.0, ..GEAR },
        BoucWen { gamma: -1250.0, ..GEAR },
        BoucWen { a: f64::NAN, ..GEAR },
        BoucWen { gamma: f64::INFINITY, ..GEAR },
        BoucWen { n: 0.5, ..GEAR },
        BoucWen { n: f64::NAN, ..GEAR },
        BoucWen { n: 33.0, ..GEAR },
    ] {
        assert_eq!(BoucWenState::new(params), Err(Error::InvalidBoucWen), "{params:?}");
    }
    let mut bw = state(GEAR);
    bw.step(A).unwrap();
    let before = bw;
    assert_eq!(bw.step(f64::NAN), Err(Error::NonFiniteDeflection));
    assert_eq!(bw, before, "a refused step changes nothing");
}

fn params() -> impl Strategy<Value = BoucWen<f64>> {
    let n = prop_oneof![Just(1.0), 1.0..3.0f64];
    (1e-3..10.0f64, 1.0..1e5f64, -0.99..3.0f64, n).prop_map(|(a, beta, ratio, n)| BoucWen {
        a,
        beta,
        gamma: ratio * beta,
        n,
    })
}

proptest! {
    /// Any valid parameters on any path: z finite and within its bound, in f64 and f32, and the
    /// f32 state within rounding of the f64 one.
    #[test]
    fn z_is_finite_bounded_and_the_same_in_f32(params in params(), path in prop::collection::vec(-1.0..1.0f64, 1..200)) {
        let mut wide = state(params);
        let narrow_params =
            BoucWen { a: params.a as f32, beta: params.beta as f32, gamma: params.gamma as f32, n: params.n as f32 };
        let mut narrow = BoucWenState::new(narrow_params).unwrap();
        let scale = 10.0 * params.z_max();
        for theta in path {
            let z = wide.step(theta * scale).unwrap();
            let z32 = narrow.step((theta * scale) as f32).unwrap();
            prop_assert!(z.is_finite() && z.abs() <= params.z_max());
            prop_assert!(z32.is_finite() && z32.abs() <= narrow_params.z_max());
            prop_assert!((f64::from(z32) - z).abs() <= 1e-3 * params.z_max(), "{z32} vs {z}");
        }
    }
}

/// The f32 state against the f64 one along 200,000 ticks of a joint (20 kHz) on a motion of
/// nested and drifting reversals: within [`crate::tolerance::BOUC_WEN_DRIFT`] of z's bound.
#[test]
fn f32_tracks_f64_along_a_long_random_motion() {
    for params in [GEAR, SHARP] {
        let narrow_params =
            BoucWen { a: params.a as f32, beta: params.beta as f32, gamma: params.gamma as f32, n: params.n as f32 };
        let (mut wide, mut narrow) = (state(params), BoucWenState::new(narrow_params).unwrap());
        let mut worst: f64 = 0.0;
        for i in 0..200_000 {
            let t = f64::from(i) / 20_000.0;
            let theta = A * (0.7 * (TAU * 0.9 * t).sin() + 0.3 * (TAU * 7.3 * t).sin() * (TAU * 0.13 * t).cos());
            let z = wide.step(theta).unwrap();
            let z32 = narrow.step(theta as f32).unwrap();
            worst = worst.max((f64::from(z32) - z).abs() / params.z_max());
        }
        std::println!("n = {}: f32 z within {worst:.2e} of z_max", params.n);
        assert!(worst < crate::tolerance::BOUC_WEN_DRIFT, "{worst}");
    }
}
