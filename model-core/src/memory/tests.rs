//! Host tests of the evaluators with memory: exactness on the symmetric loop, Madelung's
//! rules (continuity, return-point memory, wipe-out), the stack's overflow, bad inputs and
//! determinism, for the genetic, micro-slip and Preisach kinds.
extern crate std;

use super::*;
use crate::checks::{PAPER_TABLE_2, SEED_AMPLITUDE, SEED_TABLE_FIT};
use crate::tolerance::{loop_scales, Bound};
use crate::{Loop, Params};
use proptest::prelude::*;
use std::vec::Vec;

const A: f64 = SEED_AMPLITUDE;

fn model(params: Params<f64>) -> Model<f64> {
    Model::new(params).unwrap()
}

/// The micro-slip test set: eight elements on a log grid from A/100 to A whose stiffnesses add
/// up to half of the paper's c1.
fn slip_elements() -> [SlipElement<f64>; 8] {
    let grid: [f64; 8] = slip_grid(A / 100.0, A).unwrap();
    let weights = [1.0, 2.0, 3.0, 4.0, 4.0, 3.0, 2.0, 1.0];
    core::array::from_fn(|i| SlipElement { slip: grid[i], stiffness: weights[i] / 20.0 * 0.5 * PAPER_TABLE_2.c1 })
}

fn micro_slip() -> MicroSlip<f64, 8> {
    MicroSlip::new(&slip_elements()).unwrap()
}

/// The Preisach test set: a density heavier near the diagonal and towards high α, on a grid
/// of reach `reach` (rad), at most `N` turning points.
fn preisach<const N: usize>(reach: f64) -> crate::preisach::PreisachMemory<f64, N> {
    use crate::preisach::{cell, Preisach, PreparedPreisach, CELLS, INTERVALS};
    let mut weights = [0.0; CELLS];
    for i in 0..INTERVALS {
        for j in 0..=i {
            weights[cell(i, j)] = 0.02 * PAPER_TABLE_2.c1 * A * (1.0 + i as f64) / (1.0 + (i - j) as f64);
        }
    }
    Madelung::new(PreparedPreisach::new(&Preisach { reach, weights }).unwrap(), 0.0)
}

/// The test set with three giant elements (stiffness F::MAX/16, slipping at 8 rad): finite on
/// every motion of the tests, but beyond a few rad the three saturated ones overflow the float
/// type, so that a step fails after the elements have moved (and must be undone).
fn overflowing_slip<F: Real>() -> MicroSlip<F, 16> {
    let f = |v: f64| F::from(v).unwrap();
    let giant = SlipElement { slip: f(8.0), stiffness: F::max_value() / f(16.0) };
    let mut elements: Vec<SlipElement<F>> =
        slip_elements().iter().map(|e| SlipElement { slip: f(e.slip), stiffness: f(e.stiffness) }).collect();
    elements.extend([giant; 3]);
    MicroSlip::new(&elements).unwrap()
}

/// Every sample of `thetas`, stepped in turn.
fn run<H: Hysteretic<f64>>(h: &mut H, thetas: &[f64]) -> Vec<Evaluation<f64>> {
    thetas.iter().map(|&theta| h.step(theta).unwrap()).collect()
}

/// Samples on the grid θ = i·`step` from 0 through each of `points` (grid indices), landing
/// exactly on each: the same index is always the same θ, so turning points are hit exactly.
fn grid_path(points: &[i32], step: f64) -> Vec<f64> {
    let mut path = Vec::new();
    let mut at = 0i32;
    for &point in points {
        while at != point {
            at += (point - at).signum();
            path.push(f64::from(at) * step);
        }
    }
    path
}

/// θ = A·sin(2π·i/n) for i in 0..cycles·n.
fn sine(amplitude: f64, n: usize, cycles: usize) -> Vec<f64> {
    (0..cycles * n).map(|i| amplitude * (core::f64::consts::TAU * i as f64 / n as f64).sin()).collect()
}

/// The direction of motion at each sample (`first` for the first one).
fn directions(thetas: &[f64], first: Direction) -> Vec<Direction> {
    let mut direction = first;
    let mut previous = 0.0;
    thetas
        .iter()
        .map(|&theta| {
            if theta > previous {
                direction = Direction::Rising;
            } else if theta < previous {
                direction = Direction::Falling;
            }
            previous = theta;
            direction
        })
        .collect()
}

fn assert_close(got: Evaluation<f64>, want: Evaluation<f64>, relative: f64, what: &str) {
    assert!(
        (got.torque - want.torque).abs() <= relative * want.torque.abs(),
        "{what}: torque {} vs {}",
        got.torque,
        want.torque
    );
    assert!(
        (got.stiffness - want.stiffness).abs() <= relative * want.stiffness.abs(),
        "{what}: stiffness {} vs {}",
        got.stiffness,
        want.stiffness
    );
}

/// Steps `h` through `thetas` and checks that T has no jumps: between consecutive samples
/// |ΔT| ≤ 2·max|K|·|Δθ| + rounding, with max|K| over both samples and eight points between
/// (from a copy of the state stepped there). The paper's branches start with a square-root
/// edge (|cos φ| → 0), where the secant is up to twice the tangent at the step's far end.
fn continuous<H: Hysteretic<f64> + Copy>(mut h: H, thetas: &[f64], what: &str) -> Vec<Evaluation<f64>> {
    let mut evaluations: Vec<Evaluation<f64>> = Vec::new();
    let mut previous = 0.0;
    for (i, &theta) in thetas.iter().enumerate() {
        let mut between = h;
        let e = h.step(theta).unwrap();
        if let Some(last) = evaluations.last() {
            let mut steepest = last.stiffness.abs().max(e.stiffness.abs());
            for j in 1..8 {
                let inside = previous + (theta - previous) * f64::from(j) / 8.0;
                steepest = steepest.max(between.step(inside).unwrap().stiffness.abs());
            }
            let step = (theta - previous).abs();
            let allowed = 2.0 * steepest * step + 1e-9 * (1.0 + last.torque.abs());
            assert!(
                (e.torque - last.torque).abs() <= allowed,
                "{what}: jump {} > {allowed} at sample {i}, θ {previous} → {theta}",
                e.torque - last.torque,
            );
        }
        evaluations.push(e);
        previous = theta;
    }
    evaluations
}

fn same_bits(a: Evaluation<f64>, b: Evaluation<f64>) -> bool {
    a.torque.to_bits() == b.torque.to_bits() && a.stiffness.to_bits() == b.stiffness.to_bits()
}

// ---------------------------------------------------------------------------------------------
// The genetic kind on the symmetric loop
// ---------------------------------------------------------------------------------------------

#[test]
fn on_loop_reproduces_loop_evaluate_from_the_first_sample() {
    for params in [PAPER_TABLE_2, SEED_TABLE_FIT] {
        let m = model(params);
        for amplitude in [A, 0.5 * A, 2.0e-3] {
            let on_loop: Loop<f64> = m.at_amplitude(amplitude).unwrap();
            for (start, sign) in [(Direction::Rising, 1.0), (Direction::Falling, -1.0)] {
                let thetas: Vec<f64> = sine(amplitude, 400, 3).iter().map(|t| sign * t).collect();
                let mut memory = GeneticMemory::<f64, 8>::on_loop(m, 0.0, amplitude, start).unwrap();
                let got = run(&mut memory, &thetas);
                for ((&theta, direction), got) in thetas.iter().zip(directions(&thetas, start)).zip(got) {
                    let want = on_loop.evaluate(theta, direction).unwrap();
                    assert_close(got, want, 1e-12, "on_loop vs Loop::evaluate");
                }
                // A steady loop does not grow the stack.
                assert!(memory.depth() <= 2, "{:?}", memory.turning_points());
            }
        }
    }
}

#[test]
fn from_rest_it_joins_the_loop_after_the_first_quarter_cycle() {
    for params in [PAPER_TABLE_2, SEED_TABLE_FIT] {
        let m = model(params);
        let on_loop = m.at_amplitude(A).unwrap();
        for sign in [1.0, -1.0] {
            let thetas: Vec<f64> = sine(A, 400, 3).iter().map(|t| sign * t).collect();
            let mut memory = GeneticMemory::<f64, 8>::new(m, 0.0);
            let got = run(&mut memory, &thetas);
            let dirs = directions(&thetas, Direction::Rising);
            // First loading is the virgin curve: the spring alone (H = 0).
            for (&theta, got) in thetas.iter().zip(&got).take(100) {
                assert_eq!(got.torque, m.polynomial.evaluate(theta).torque);
            }
            for i in 101..thetas.len() {
                let want = on_loop.evaluate(thetas[i], dirs[i]).unwrap();
                assert_close(got[i], want, 1e-12, "from rest vs Loop::evaluate");
            }
        }
    }
}

#[test]
fn f32_on_the_symmetric_loop_stays_within_the_bound_of_f64() {
    for params in [PAPER_TABLE_2, SEED_TABLE_FIT] {
        let m64 = model(params);
        let m32 = Model::new(params.to_f32()).unwrap();
        let scales = loop_scales(&m64, A).unwrap();
        let mut memory = GeneticMemory::<f32, 8>::on_loop(m32, 0.0, A as f32, Direction::Rising).unwrap();
        let thetas: Vec<f64> = sine(A, 1000, 2).iter().map(|&t| f64::from(t as f32)).collect();
        for (&theta, direction) in thetas.iter().zip(directions(&thetas, Direction::Rising)) {
            let e = memory.step(theta as f32).unwrap();
            let bound = Bound::at(&m64, theta, direction, A, scales).unwrap();
            assert!(bound.admits(f64::from(e.torque), f64::from(e.stiffness)), "θ {theta}: {e:?} vs {bound:?}");
        }
    }
}

#[test]
fn an_inner_branch_has_the_stiffness_of_its_torque() {
    let m = model(PAPER_TABLE_2);
    let from = TurningPoint { theta: 0.8 * A, hysteresis: 1.3 };
    let to = TurningPoint { theta: -0.3 * A, hysteresis: -0.4 };
    let h = |theta: f64| branch(&m, from, to, theta).unwrap();
    // The ends are exact: continuity and return-point memory.
    assert_eq!(h(from.theta).torque, from.hysteresis);
    assert_eq!(h(to.theta).torque, to.hysteresis);
    for i in 1..100 {
        let theta = from.theta + (to.theta - from.theta) * f64::from(i) / 100.0;
        let step = 1e-6 * A;
        let t = |d: f64| h(theta + d).torque;
        let fd = (8.0 * (t(step) - t(-step)) - (t(2.0 * step) - t(-2.0 * step))) / (12.0 * step);
        let analytic = h(theta).stiffness;
        assert!((analytic - fd).abs() <= 1e-5 * analytic.abs().max(1e3), "θ {theta}: {analytic} vs {fd}");
    }
    // Zero width: flat.
    assert_eq!(branch(&m, from, from, 0.1 * A), Ok(Evaluation { torque: from.hysteresis, stiffness: 0.0 }));
}

// ---------------------------------------------------------------------------------------------
// Madelung's rules on the genetic kind
// ---------------------------------------------------------------------------------------------

#[test]
fn return_point_memory_closes_the_inner_loop_exactly() {
    let m = model(PAPER_TABLE_2);
    let step = A / 500.0;
    // Up to 500, down to −200, an inner loop up to 100 and back to −200, on to −400.
    let inner = grid_path(&[500, -200, 100, -50, 20, -200, -400], step);
    let plain = grid_path(&[500, -200, -400], step);
    let mut with_inner = GeneticMemory::<f64, 8>::new(m, 0.0);
    let mut without = GeneticMemory::<f64, 8>::new(m, 0.0);
    let got = run(&mut with_inner, &inner);
    let want = run(&mut without, &plain);
    // Before the inner loop, at its return, and on the continuation: bit for bit.
    let b = f64::from(-200) * step;
    let at_b: Vec<Evaluation<f64>> = inner.iter().zip(&got).filter(|(t, _)| **t == b).map(|(_, e)| *e).collect();
    assert_eq!(at_b.len(), 2);
    assert_eq!(at_b[0].torque, at_b[1].torque);
    let tail = 200;
    for (g, w) in got[got.len() - tail..].iter().zip(&want[want.len() - tail..]) {
        assert!(same_bits(*g, *w), "{g:?} vs {w:?}");
    }
    assert_eq!(with_inner.turning_points(), without.turning_points());
}

#[test]
fn a_larger_excursion_wipes_out_the_inner_loops() {
    let m = model(PAPER_TABLE_2);
    let mut memory = GeneticMemory::<f64, 16>::new(m, 0.0);
    let step = A / 1000.0;
    run(&mut memory, &grid_path(&[900, -800, 700, -600, 500, -400, 300], step));
    assert_eq!(memory.depth(), 6);
    // Down past −400 and −600: two inner loops gone (the reversal at 300 was pushed first).
    run(&mut memory, &grid_path(&[300, -700], step)[300..]);
    assert_eq!(memory.depth(), 3, "{:?}", memory.turning_points());
    // Past everything: virgin again, the spring alone.
    let e = memory.step(-1000.0 * step).unwrap();
    assert_eq!(memory.depth(), 0);
    assert_eq!(e.torque, m.polynomial.evaluate(-1000.0 * step).torque);
}

#[test]
fn a_full_stack_retraces_the_innermost_excursion_continuously() {
    let m = model(PAPER_TABLE_2);
    let step = A / 1000.0;
    // Nested, shrinking reversals: the fifth does not fit in N = 4.
    let points = [900, -800, 700, -600, 500, -400];
    let mut memory = GeneticMemory::<f64, 4>::new(m, 0.0);
    let thetas = grid_path(&points, step);
    let before = run(&mut memory, &thetas);
    assert_eq!(memory.depth(), 4);
    assert!(memory.is_retracing(), "{:?}", memory.turning_points());
    // The last leg went back along the branch 600 → −600 → … : the same T as on the way out.
    let leg = thetas.len() - 900;
    for (k, e) in before[leg..].iter().enumerate() {
        let theta = thetas[leg + k];
        let earlier = thetas[..leg].iter().rposition(|t| *t == theta).unwrap();
        assert!(same_bits(*e, before[earlier]) || theta == f64::from(500) * step, "θ {theta}");
    }
    // Past the branch's start (−600): the branch it lay on (700 → −800) takes over.
    let more = grid_path(&[-400, -700, 800], step);
    let after = run(&mut memory, &more[400..]);
    // No jumps over the whole motion.
    let all: Vec<f64> = thetas.iter().chain(&more[400..]).copied().collect();
    let evaluations = continuous(GeneticMemory::<f64, 4>::new(m, 0.0), &all, "overflow");
    assert!(same_bits(*evaluations.last().unwrap(), *after.last().unwrap()));
    // Back up past the reversal that found the stack full (500), which dropping the newest
    // stored pair instead would have kept as a point off the branch below: no jump there
    // (that rule jumps by 1.36 N·m at θ = 500 on this path).
    let up = grid_path(&[900, -800, 700, -600, 500, -400, 800], step);
    continuous(GeneticMemory::<f64, 4>::new(m, 0.0), &up, "overflow, then back up");
    assert!(!memory.is_retracing());
    assert!(memory.depth() <= 4);
}

#[test]
fn noise_inside_the_band_records_no_turning_points() {
    let m = model(PAPER_TABLE_2);
    let band = 5e-6;
    let mut memory = GeneticMemory::<f64, 8>::new(m, band);
    let mut state = 0x1234_5678u32;
    let thetas: Vec<f64> = (0..4000)
        .map(|i| {
            state ^= state << 13;
            state ^= state >> 17;
            state ^= state << 5;
            let noise = (f64::from(state) / f64::from(u32::MAX) * 2.0 - 1.0) * 0.4 * band;
            A * (core::f64::consts::TAU * f64::from(i) / 2000.0).sin() + noise
        })
        .collect();
    let pushes = |memory: &mut GeneticMemory<f64, 8>| {
        let mut pushes = 0;
        let mut depth = 0;
        for &theta in &thetas {
            memory.step(theta).unwrap();
            pushes += usize::from(memory.depth() > depth);
            depth = memory.depth();
        }
        pushes
    };
    // Two cycles from rest: four turning points, at most one push each.
    let with_band = pushes(&mut memory);
    assert!(with_band <= 4, "{with_band}");
    let without = pushes(&mut GeneticMemory::new(m, 0.0));
    assert!(without > 50, "without a band the same noise makes inner loops: {without}");
}

#[test]
fn reset_returns_to_rest() {
    let m = model(PAPER_TABLE_2);
    let mut memory = GeneticMemory::<f64, 8>::on_loop(m, 0.0, A, Direction::Rising).unwrap();
    run(&mut memory, &grid_path(&[300, -200, 100], A / 1000.0));
    memory.reset();
    assert_eq!(memory, GeneticMemory::new(m, 0.0));
    assert_eq!(memory.step(0.5 * A).unwrap().torque, m.polynomial.evaluate(0.5 * A).torque);
}

#[test]
fn non_finite_deflections_are_errors_that_change_nothing() {
    let m = model(PAPER_TABLE_2);
    let mut memory = GeneticMemory::<f64, 8>::new(m, 0.0);
    run(&mut memory, &grid_path(&[300, -200], A / 1000.0));
    let mut slip = micro_slip();
    run(&mut slip, &grid_path(&[300, -200], A / 1000.0));
    let (memory_before, slip_before) = (memory, slip);
    for theta in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
        assert_eq!(memory.step(theta), Err(Error::NonFiniteDeflection));
        assert_eq!(slip.step(theta), Err(Error::NonFiniteDeflection));
    }
    // Overflow at a huge deflection (the spring; the micro-slip set's giant elements): an error,
    // and the sample is skipped.
    assert_eq!(memory.step(1e300), Err(Error::Overflow));
    let mut giant = overflowing_slip::<f64>();
    run(&mut giant, &grid_path(&[300, -200], A / 1000.0));
    let giant_before = giant;
    assert_eq!(giant.step(1e300), Err(Error::Overflow));
    assert_eq!(giant, giant_before);
    assert_eq!(memory, memory_before);
    assert_eq!(slip, slip_before);
}

/// Grid indices of a motion that fills a stack of 16 and retraces past it (20 nested
/// reversals), closes an inner loop exactly at its target (−560 → 580 → −560: the reversal
/// pops the branch and pushes its target again) and wipes out everything (past ±900).
fn deep_motion() -> Vec<i32> {
    let mut points: Vec<i32> = (0..20).map(|k| if k % 2 == 0 { 900 - 20 * k } else { -(900 - 20 * k) }).collect();
    points.extend([-560, 580, -560, 950, -300]);
    points
}

/// Steps `h` through `thetas`, each sample preceded by the steps to each of `bad`, which must
/// fail (by overflow) and leave `h` exactly as it was: the whole state, including stack slots
/// above the depth, although such a step may already have turned, pushed the extreme and
/// popped every turning point before the spring overflowed. The good sample after them gives
/// the bits and the state an untouched copy gives.
fn failed_steps_change_nothing<F: Real, H: Hysteretic<F> + Copy + PartialEq + core::fmt::Debug>(
    mut h: H,
    thetas: &[F],
    bad: &[F],
    what: &str,
) -> H {
    for (i, &theta) in thetas.iter().enumerate() {
        let before = h;
        for &b in bad {
            assert_eq!(h.step(b), Err(Error::Overflow), "{what}: sample {i}, step to {b:?}");
            assert_eq!(h, before, "{what}: sample {i}, after the failed step to {b:?}");
        }
        let mut untouched = before;
        let (got, want) = (h.step(theta).unwrap(), untouched.step(theta).unwrap());
        let bits = |e: Evaluation<F>| (e.torque.integer_decode(), e.stiffness.integer_decode());
        assert_eq!(bits(got), bits(want), "{what}: sample {i}");
        assert_eq!(h, untouched, "{what}: sample {i}");
    }
    h
}

#[test]
fn a_failed_step_leaves_the_state_as_it_was_at_any_depth() {
    let step = A / 1000.0;
    let thetas = grid_path(&deep_motion(), step);
    let thetas_f32: Vec<f32> = thetas.iter().map(|&t| t as f32).collect();
    let (m, m32) = (model(PAPER_TABLE_2), Model::new(PAPER_TABLE_2.to_f32()).unwrap());
    // The spring overflows beyond about 1e62 rad in f64 and 1e8 rad in f32, on either side.
    let (bad, bad32) = ([1e300, -1e300], [1e30f32, -1e30]);
    for band in [0.0, 2.5 * step] {
        let mut deepest = GeneticMemory::<f64, 16>::new(m, band);
        let mut depth = 0;
        for &theta in &thetas {
            deepest.step(theta).unwrap();
            depth = depth.max(deepest.depth());
        }
        assert!(depth == 16 && deepest.depth() == 1, "the motion fills the stack and wipes it out");
        failed_steps_change_nothing(GeneticMemory::<f64, 16>::new(m, band), &thetas, &bad, "N=16");
        failed_steps_change_nothing(GeneticMemory::<f64, 4>::new(m, band), &thetas, &bad, "N=4");
        let f32_memory = GeneticMemory::<f32, 16>::new(m32, band as f32);
        failed_steps_change_nothing(f32_memory, &thetas_f32, &bad32, "f32, N=16");
    }
    let slip = failed_steps_change_nothing(overflowing_slip::<f64>(), &thetas, &bad, "micro-slip");
    assert!(slip.slipping() > 0);
    failed_steps_change_nothing(overflowing_slip::<f32>(), &thetas_f32, &bad32, "micro-slip, f32");
}

/// The count of slipping elements that the step keeps is the elements' own (|e_i| = d_i),
/// after every step, and 0 at rest.
#[test]
fn micro_slip_counts_its_slipping_elements() {
    let mut slip = micro_slip();
    assert_eq!(slip.slipping(), 0);
    let mut seen = std::collections::BTreeSet::new();
    for theta in grid_path(&deep_motion(), A / 1000.0) {
        slip.step(theta).unwrap();
        let at_limit =
            slip.elastic().iter().zip(slip.elements()).filter(|(e, element)| e.abs() == element.slip).count();
        assert_eq!(slip.slipping(), at_limit);
        seen.insert(slip.slipping());
    }
    assert!(seen.len() > 4, "{seen:?}");
    slip.reset();
    assert_eq!(slip, micro_slip());
}

/// An element at its lower limit that the motion moves up by less than e's rounding stays at
/// −d but sticks: the motion reversed, so its spring adds to the stiffness again. (Each heading
/// tests only the limit it can reach: `slide`.) Standing still, it still slips.
#[test]
fn an_element_moved_off_its_limit_by_less_than_its_rounding_sticks() {
    let mut slip = MicroSlip::<f64, 1>::new(&[SlipElement { slip: 1.0, stiffness: 100.0 }]).unwrap();
    slip.step(2.0).unwrap();
    let down = slip.step(1.0e-20).unwrap();
    assert_eq!((slip.elastic(), slip.slipping(), down.stiffness), (&[-1.0][..], 1, 0.0));
    let still = slip.step(1.0e-20).unwrap();
    assert_eq!((slip.slipping(), still.stiffness), (1, 0.0), "no motion, no reversal");
    let up = slip.step(2.0e-20).unwrap();
    assert_eq!((slip.elastic(), slip.slipping(), up.stiffness), (&[-1.0][..], 0, 100.0));
}

#[test]
fn bad_arguments_are_errors() {
    let m = model(PAPER_TABLE_2);
    for a in [0.0, -A, f64::NAN, f64::INFINITY] {
        assert_eq!(GeneticMemory::<f64, 4>::on_loop(m, 0.0, a, Direction::Rising), Err(Error::InvalidAmplitude));
    }
    // A negative or NaN band counts as 0, as the firmware's tracker.
    assert_eq!(GeneticMemory::<f64, 4>::new(m, -1.0).band(), 0.0);
    assert_eq!(GeneticMemory::<f64, 4>::new(m, f64::NAN).band(), 0.0);
}

// ---------------------------------------------------------------------------------------------
// The micro-slip kind
// ---------------------------------------------------------------------------------------------

#[test]
fn the_slip_grid_is_logarithmic_with_exact_ends() {
    let grid: [f64; 5] = slip_grid(1e-6, 1e-2).unwrap();
    assert_eq!(grid[0], 1e-6);
    assert_eq!(grid[4], 1e-2);
    for (d, want) in grid.iter().zip([1e-6, 1e-5, 1e-4, 1e-3, 1e-2]) {
        assert!((d - want).abs() <= 1e-12 * want, "{d} vs {want}");
    }
    assert_eq!(slip_grid::<f64, 1>(1e-6, 1e-2), Ok([1e-6]));
    assert_eq!(slip_grid::<f64, 0>(1e-6, 1e-2), Ok([]));
    let f32_grid: [f32; 3] = slip_grid(1e-6, 1e-4).unwrap();
    assert!((f32_grid[1] - 1e-5).abs() < 1e-10);
    for (min, max) in [(0.0, 1.0), (-1.0, 1.0), (1.0, 1.0), (2.0, 1.0), (f64::NAN, 1.0), (1e-3, f64::INFINITY)] {
        assert_eq!(slip_grid::<f64, 4>(min, max), Err(Error::InvalidSlipRange), "{min} {max}");
    }
}

#[test]
fn slip_elements_are_validated() {
    let good = slip_elements();
    assert!(MicroSlip::<f64, 8>::new(&good).is_ok());
    assert_eq!(MicroSlip::<f64, 4>::new(&good), Err(Error::InvalidSlipRange), "more elements than room");
    let mut negative = good;
    negative[3].stiffness = -1.0;
    assert_eq!(MicroSlip::<f64, 8>::new(&negative), Err(Error::InvalidSlipStiffness(3)));
    let mut nan = good;
    nan[7].stiffness = f64::NAN;
    assert_eq!(MicroSlip::<f64, 8>::new(&nan), Err(Error::InvalidSlipStiffness(7)));
    let mut zero = good;
    zero[0].slip = 0.0;
    assert_eq!(MicroSlip::<f64, 8>::new(&zero), Err(Error::InvalidSlipRange));
    assert_eq!(SlipElements::<f64, 2>::new([1e-3, 0.0]), Err(Error::InvalidSlipRange));
    // The errors say what is wrong.
    assert_eq!(
        std::format!("{}", Error::InvalidSlipStiffness(3)),
        "micro-slip element 3: stiffness must be a finite number >= 0 N·m/rad"
    );
}

/// H = Σ k_i·e_i with the fit's unit columns e_i (and dH/dθ the k_i of the sticking elements):
/// the fit's columns are what the evaluator runs.
#[test]
fn micro_slip_is_its_unit_columns() {
    let elements = slip_elements();
    let mut slip = micro_slip();
    let mut unit = SlipElements::<f64, 8>::new(elements.map(|e| e.slip)).unwrap();
    let thetas = grid_path(&[800, -600, 300, -100, 1000], A / 1000.0);
    for &theta in &thetas {
        let e = slip.step(theta).unwrap();
        unit.step(theta).unwrap();
        let (mut torque, mut stiffness) = (0.0, 0.0);
        for ((element, e), sticks) in elements.iter().zip(unit.elastic()).zip(unit.sticking()) {
            torque += element.stiffness * e;
            stiffness += if sticks { element.stiffness } else { 0.0 };
        }
        assert!((e.torque - torque).abs() <= 1e-12 * torque.abs().max(1.0), "θ {theta}");
        assert!((e.stiffness - stiffness).abs() <= 1e-12 * stiffness.abs().max(1.0), "θ {theta}");
    }
    assert_eq!(slip.elastic(), unit.elastic());
}

#[test]
fn micro_slip_loops_are_point_symmetric_and_dissipate() {
    let mut slip = micro_slip();
    let step = A / 1000.0;
    // Settle on the loop ±A, then trace one cycle.
    run(&mut slip, &grid_path(&[1000, -1000, 1000], step));
    let cycle = grid_path(&[1000, -1000, 1000], step);
    let got = run(&mut slip, &cycle[1000..]);
    let (falling, rising) = got.split_at(2000);
    // Masing: the rising branch is the falling one turned by 180°.
    for (i, up) in rising.iter().enumerate() {
        let down = falling[i];
        assert!((up.torque + down.torque).abs() <= 1e-9 * up.torque.abs().max(1.0), "{i}");
    }
    // ∮T dθ > 0: the loop dissipates.
    let thetas = &cycle[1000..];
    let work: f64 =
        (1..thetas.len()).map(|i| 0.5 * (got[i].torque + got[i - 1].torque) * (thetas[i] - thetas[i - 1])).sum();
    assert!(work > 0.0, "{work}");
}

#[test]
fn micro_slip_runs_in_f32() {
    let narrow = slip_elements().map(|e| SlipElement { slip: e.slip as f32, stiffness: e.stiffness as f32 });
    let mut s32 = MicroSlip::<f32, 8>::new(&narrow).unwrap();
    let mut s64 = micro_slip();
    let (scale, _) = loop_scales(&model(PAPER_TABLE_2), A).unwrap();
    for theta in grid_path(&[700, -500, 200, -900], A / 700.0) {
        let e32 = s32.step(theta as f32).unwrap();
        let e64 = s64.step(f64::from(theta as f32)).unwrap();
        assert!((f64::from(e32.torque) - e64.torque).abs() <= 1e-5 * scale, "θ {theta}");
    }
}

/// libm's functions with h·e^(−rφ) formed directly, as the firmware's fast path forms it: the
/// direct form, tested here in f64.
struct DirectLibm;

impl Elementary<f64> for DirectLibm {
    fn sqrt(v: f64) -> f64 {
        v.sqrt()
    }
    fn asin(x: f64) -> f64 {
        x.asin()
    }
    fn exp(y: f64) -> f64 {
        y.exp()
    }
    fn ln(v: f64) -> f64 {
        v.ln()
    }
    fn exp_m1(y: f64) -> f64 {
        y.exp_m1()
    }
    fn ln_1p(v: f64) -> f64 {
        v.ln_1p()
    }
    const DIRECT_DECAY: bool = true;
}

/// The kept branch constants, made when the branch changed, equal those made afresh from the
/// stack (and the retrace flag) with the same elementary functions, bit for bit; the step's
/// results in the direct form equal the log form's to rounding.
fn kept_branch_is_fresh<const N: usize>(thetas: &[f64], band: f64) -> Result<(), TestCaseError> {
    let m = model(PAPER_TABLE_2);
    let (mut log, mut direct) = (GeneticMemory::<f64, N>::new(m, band), GeneticMemory::<f64, N>::new(m, band));
    for (i, &theta) in thetas.iter().enumerate() {
        let (by_log, by_direct) = (log.step(theta).unwrap(), direct.step_with::<DirectLibm>(theta).unwrap());
        prop_assert_eq!((log.branch, log.exits), log.fresh_branch::<Libm>(), "N={} sample {}", N, i);
        prop_assert_eq!((direct.branch, direct.exits), direct.fresh_branch::<DirectLibm>(), "N={} sample {}", N, i);
        let thetas =
            |memory: &GeneticMemory<f64, N>| memory.turning_points().iter().map(|p| p.theta).collect::<Vec<_>>();
        prop_assert_eq!(thetas(&log), thetas(&direct));
        let scale = 1.0 + by_log.torque.abs();
        prop_assert!((by_log.torque - by_direct.torque).abs() <= 1e-12 * scale, "{:?} vs {:?}", by_log, by_direct);
        let k_scale = 1e3 + by_log.stiffness.abs();
        prop_assert!(
            (by_log.stiffness - by_direct.stiffness).abs() <= 1e-12 * k_scale,
            "{:?} vs {:?}",
            by_log,
            by_direct
        );
    }
    Ok(())
}

// ---------------------------------------------------------------------------------------------
// Property tests for every kind with return-point memory
// ---------------------------------------------------------------------------------------------

/// Turning points as grid indices in [−1000, 1000] (the grid step A/1000: |θ| ≤ A).
fn reversal_points(count: usize) -> impl Strategy<Value = Vec<i32>> {
    prop::collection::vec(-1000i32..=1000, 2..count)
}

/// Nested, shrinking reversals around a random centre: deep stacks, to overflow small N; then
/// a few random reversals that wipe some of them out.
fn nested_points() -> impl Strategy<Value = Vec<i32>> {
    let after = prop::collection::vec(-1000i32..=1000, 0..4);
    (-100i32..=100, prop::collection::vec(5i32..=60, 4..16), after).prop_map(|(centre, shrinks, after)| {
        let mut half = 1000 - centre.abs();
        let mut sign = 1;
        let mut points = Vec::new();
        for shrink in shrinks {
            half = (half - shrink).max(1);
            points.push(centre + sign * half);
            sign = -sign;
        }
        points.extend(after);
        points
    })
}

/// The genetic kind with stacks of 3, 4 and 16, the micro-slip kind and the Preisach kind (its grid
/// beyond the motion, and within it with a stack of 3), on the same path.
fn every_kind(thetas: &[f64]) -> Vec<(&'static str, Vec<Evaluation<f64>>)> {
    let m = model(PAPER_TABLE_2);
    std::vec![
        ("genetic N=3", run(&mut GeneticMemory::<f64, 3>::new(m, 0.0), thetas)),
        ("genetic N=4", run(&mut GeneticMemory::<f64, 4>::new(m, 0.0), thetas)),
        ("genetic N=16", run(&mut GeneticMemory::<f64, 16>::new(m, 0.0), thetas)),
        ("genetic on loop", run(&mut GeneticMemory::<f64, 16>::on_loop(m, 0.0, A, Direction::Rising).unwrap(), thetas)),
        ("micro-slip", run(&mut micro_slip(), thetas)),
        ("preisach N=16", run(&mut preisach::<16>(1.2 * A), thetas)),
        ("preisach N=3, grid within the motion", run(&mut preisach::<3>(0.6 * A), thetas)),
    ]
}

/// Every kind on `thetas`, checked for jumps by [`continuous`].
fn every_kind_is_continuous(thetas: &[f64]) {
    let m = model(PAPER_TABLE_2);
    continuous(GeneticMemory::<f64, 3>::new(m, 0.0), thetas, "genetic N=3");
    continuous(GeneticMemory::<f64, 4>::new(m, 0.0), thetas, "genetic N=4");
    continuous(GeneticMemory::<f64, 16>::new(m, 0.0), thetas, "genetic N=16");
    let on_loop = GeneticMemory::<f64, 16>::on_loop(m, 0.0, A, Direction::Rising).unwrap();
    continuous(on_loop, thetas, "genetic on loop");
    continuous(GeneticMemory::<f64, 16>::new(model(SEED_TABLE_FIT), 0.0), thetas, "genetic, seed fit");
    continuous(micro_slip(), thetas, "micro-slip");
    continuous(preisach::<16>(1.2 * A), thetas, "preisach N=16");
    continuous(preisach::<3>(0.6 * A), thetas, "preisach N=3, grid within the motion");
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(24))]

    #[test]
    fn kept_branch_constants_are_fresh_after_any_motion(
        points in prop_oneof![reversal_points(12), nested_points()],
        band in prop_oneof![Just(0.0), 0.0..2e-5],
    ) {
        let thetas = grid_path(&points, A / 1000.0);
        kept_branch_is_fresh::<3>(&thetas, band)?;
        kept_branch_is_fresh::<4>(&thetas, band)?;
        kept_branch_is_fresh::<16>(&thetas, band)?;
    }

    #[test]
    fn torque_is_continuous_on_any_motion(points in reversal_points(10)) {
        every_kind_is_continuous(&grid_path(&points, A / 1000.0));
    }

    #[test]
    fn torque_is_continuous_when_the_stack_overflows(points in nested_points()) {
        let thetas = grid_path(&points, A / 1000.0);
        every_kind_is_continuous(&thetas);
        let mut small = GeneticMemory::<f64, 3>::new(model(PAPER_TABLE_2), 0.0);
        for &theta in &thetas {
            small.step(theta).unwrap();
            prop_assert!(small.depth() <= 3);
        }
    }

    /// Go to b, make an excursion that stays inside the last leg, come back to b and go on:
    /// T at b is what it was, and the continuation is as if the inner loop never happened.
    #[test]
    fn return_point_memory(
        history in reversal_points(6),
        leg in 20i32..=600,
        inner in prop::collection::vec(0.0f64..1.0, 1..6),
        onward in 1i32..=300,
    ) {
        let start = *history.last().unwrap();
        let direction = if start > 0 { -1 } else { 1 };
        let b = start + direction * leg;
        // Inner reversals strictly between the last turning point and b.
        let mut excursion: Vec<i32> =
            inner.iter().map(|fraction| b - direction * (1 + (fraction * f64::from(leg - 2)) as i32)).collect();
        excursion.push(b);
        let end = b + direction * onward;
        let with: Vec<i32> = history.iter().copied().chain([b]).chain(excursion).chain([end]).collect();
        let without: Vec<i32> = history.iter().copied().chain([b, end]).collect();
        let (with, without) = (grid_path(&with, A / 1000.0), grid_path(&without, A / 1000.0));
        let tail = usize::try_from(onward).unwrap();
        let b_theta = f64::from(b) * (A / 1000.0);
        let arrival = grid_path(&[history.as_slice(), &[b]].concat(), A / 1000.0).len() - 1;
        for ((what, got), (_, want)) in every_kind(&with).into_iter().zip(every_kind(&without)) {
            let at_b: Vec<f64> =
                with.iter().zip(&got).skip(arrival).filter(|(t, _)| **t == b_theta).map(|(_, e)| e.torque).collect();
            prop_assert!(at_b.len() >= 2);
            let first = at_b[0];
            for t in &at_b {
                prop_assert!((t - first).abs() <= 1e-9 * (1.0 + first.abs()), "{}: T(b) {} vs {}", what, t, first);
            }
            for (g, w) in got[got.len() - tail..].iter().zip(&want[want.len() - tail..]) {
                prop_assert!((g.torque - w.torque).abs() <= 1e-9 * (1.0 + w.torque.abs()), "{}: {:?} vs {:?}", what, g, w);
            }
        }
    }

    /// Past every turning point so far, the history is gone: the genetic kind is back on the
    /// virgin curve (empty stack), every micro-slip element is saturated.
    #[test]
    fn a_larger_excursion_wipes_out_everything(points in reversal_points(12), sign in prop::bool::ANY) {
        let mut thetas = grid_path(&points, A / 1000.0);
        let mut memory = GeneticMemory::<f64, 16>::new(model(PAPER_TABLE_2), 0.0);
        let mut slip = micro_slip();
        let (mut relays, mut virgin) = (preisach::<16>(1.2 * A), preisach::<16>(1.2 * A));
        run(&mut memory, &thetas);
        run(&mut slip, &thetas);
        run(&mut relays, &thetas);
        let depth = memory.depth();
        let far = if sign { 3.0 * A } else { -3.0 * A };
        thetas.push(far);
        memory.step(far).unwrap();
        slip.step(far).unwrap();
        prop_assert!(memory.depth() == 0 && depth <= 16);
        // Every relay switched one way: the same H as from rest.
        prop_assert_eq!(relays.step(far).unwrap(), virgin.step(far).unwrap());
        prop_assert_eq!(relays.depth(), 0);
        let limit = if sign { 1.0 } else { -1.0 };
        for (e, element) in slip.elastic().iter().zip(slip.elements()) {
            prop_assert_eq!(*e, limit * element.slip);
        }
    }

    /// Any finite deflection, huge or tiny, in any order: finite results or an error, never
    /// NaN and never a panic; the same state and input give the same bits.
    #[test]
    fn any_finite_input_is_finite_or_an_error(
        thetas in prop::collection::vec(prop_oneof![
            -2.0 * A..2.0 * A,
            -1e-12..1e-12,
            prop::num::f64::NORMAL | prop::num::f64::SUBNORMAL | prop::num::f64::ZERO,
        ], 1..200),
        band in prop_oneof![Just(0.0), 0.0..1e-5],
    ) {
        let m = model(PAPER_TABLE_2);
        let mut memory = GeneticMemory::<f64, 4>::new(m, band);
        let mut slip = micro_slip();
        let mut relays = preisach::<4>(A);
        for &theta in &thetas {
            for alternating in [theta, -theta] {
                let (memory_copy, slip_copy, relays_copy) = (memory, slip, relays);
                let results = [memory.step(alternating), slip.step(alternating), relays.step(alternating)];
                let (mut memory_again, mut slip_again, mut relays_again) = (memory_copy, slip_copy, relays_copy);
                let again =
                    [memory_again.step(alternating), slip_again.step(alternating), relays_again.step(alternating)];
                for (result, again) in results.iter().zip(&again) {
                    match (result, again) {
                        (Ok(e), Ok(f)) => {
                            prop_assert!(e.torque.is_finite() && e.stiffness.is_finite(), "{:?} at {}", e, alternating);
                            prop_assert!(same_bits(*e, *f));
                        }
                        (Err(e), Err(f)) => prop_assert!(*e == Error::Overflow && e == f),
                        _ => prop_assert!(false, "not deterministic at {}", alternating),
                    }
                }
                prop_assert!(memory.depth() <= 4 && relays.depth() <= 4);
            }
        }
    }

    /// The same state and input give bit-identical output, and equal states.
    #[test]
    fn deterministic(points in reversal_points(10), cut in 0usize..5000) {
        let thetas = grid_path(&points, A / 1000.0);
        let cut = cut.min(thetas.len());
        let mut first = GeneticMemory::<f64, 4>::new(model(SEED_TABLE_FIT), 0.0);
        let mut first_slip = micro_slip();
        let mut first_relays = preisach::<4>(A);
        run(&mut first, &thetas[..cut]);
        run(&mut first_slip, &thetas[..cut]);
        run(&mut first_relays, &thetas[..cut]);
        let (mut second, mut second_slip, mut second_relays) = (first, first_slip, first_relays);
        for &theta in &thetas[cut..] {
            prop_assert!(same_bits(first.step(theta).unwrap(), second.step(theta).unwrap()));
            prop_assert!(same_bits(first_slip.step(theta).unwrap(), second_slip.step(theta).unwrap()));
            prop_assert!(same_bits(first_relays.step(theta).unwrap(), second_relays.step(theta).unwrap()));
        }
        prop_assert_eq!(first, second);
        prop_assert_eq!(first_slip, second_slip);
        prop_assert_eq!(first_relays, second_relays);
    }
}
