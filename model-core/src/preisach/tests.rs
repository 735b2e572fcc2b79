//! The Preisach kind: its tabulated Everett function against the cells' geometry, the
//! evaluator against the fit's columns, Rayleigh's closed forms and the micro-slip kind on the
//! uniform density, loops that depend on where they sit, dissipation, f32, bad sets. Madelung's
//! rules (continuity, return-point memory, wipe-out, overflow, bad inputs) are the memory's
//! property tests, which run this kind beside the others (`memory/tests.rs`).
extern crate std;

use super::*;
use crate::memory::{MicroSlip, SlipElement};
use proptest::prelude::*;
use std::vec::Vec;

/// The thresholds' reach of the tests, rad.
const R: f64 = 1.0e-3;

/// A density that is not Masing: heavier towards high α and near the diagonal, none in some
/// cells, so that loops depend on where they sit.
pub(crate) fn uneven(reach: f64) -> Preisach<f64> {
    let mut weights = [0.0; CELLS];
    for (c, i, j) in cells() {
        let near_diagonal = 1.0 / (1.0 + (i - j) as f64);
        let high = 1.0 + i as f64 / 4.0;
        weights[c] = if (i + 2 * j) % 7 == 3 { 0.0 } else { 0.4 * near_diagonal * high };
    }
    Preisach { reach, weights }
}

/// The uniform density of `mu` N·m/rad² over the whole triangle: a cell's weight is μ times
/// its area (h², the diagonal's h²/2).
fn uniform(mu: f64) -> Preisach<f64> {
    let h = 2.0 * R / INTERVALS as f64;
    let mut weights = [0.0; CELLS];
    for (c, i, j) in cells() {
        weights[c] = mu * h * h * if i == j { 0.5 } else { 1.0 };
    }
    Preisach { reach: R, weights }
}

fn memory(preisach: &Preisach<f64>) -> PreisachMemory<f64, 16> {
    Madelung::new(PreparedPreisach::new(preisach).unwrap(), 0.0)
}

/// x = `amplitude`·(0.75·sin φ + 0.25·sin 9φ), two cycles: nested reversals.
fn nested(amplitude: f64, n: usize) -> Vec<f64> {
    (0..n)
        .map(|i| {
            let phi = 2.0 * core::f64::consts::TAU * i as f64 / n as f64;
            amplitude * (0.75 * phi.sin() + 0.25 * (9.0 * phi).sin())
        })
        .collect()
}

#[test]
fn the_tabulated_everett_function_is_the_cells_shares() {
    let preisach = uneven(R);
    let prepared = PreparedPreisach::new(&preisach).unwrap();
    let top = INTERVALS as f64;
    let mut worst = 0.0f64;
    for a in 0..=160 {
        for b in 0..=a {
            // Off the nodes as well as on them (1/20 of an interval).
            let (u, v) = (top * a as f64 / 160.0, top * b as f64 / 160.0);
            let (value, du, dv) = prepared.everett_at(End::of(u), End::of(v));
            let (mut want, mut want_du, mut want_dv) = (0.0, 0.0, 0.0);
            for (c, i, j) in cells() {
                let (share, d_u, d_v) = triangle_share(i, j, u, v);
                want += preisach.weights[c] * share;
                want_du += preisach.weights[c] * d_u;
                want_dv += preisach.weights[c] * d_v;
            }
            // At u = INTERVALS the table's last interval is read with f = 1 (its slope from
            // below); the shares say no relay is left above.
            if a < 160 {
                worst = worst.max((du - want_du).abs()).max((dv - want_dv).abs());
            }
            worst = worst.max((value - want).abs());
        }
    }
    assert!(worst < 1e-12, "table against cells: {worst}");
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(32))]

    /// H = Σ w_c·h_c and K = Σ w_c·h_c′ at every sample of any motion, within the grid and
    /// beyond it: the evaluator's tables and the fit's columns are one model.
    #[test]
    fn the_evaluator_is_the_sum_of_the_fits_columns(
        points in prop::collection::vec(-1.4 * R..1.4 * R, 2..12),
        steps in 3usize..40,
    ) {
        let preisach = uneven(R);
        let mut evaluator = memory(&preisach);
        let mut columns = CellMemory::<f64, 16>::new(PreisachCells::new(R).unwrap(), 0.0);
        let mut at = 0.0;
        for &point in &points {
            for k in 1..=steps {
                let x = at + (point - at) * k as f64 / steps as f64;
                let e = evaluator.step(x).unwrap();
                let c = columns.columns(x).unwrap();
                let h: f64 = preisach.weights.iter().zip(&c.value).map(|(w, v)| w * v).sum();
                let k_sum: f64 = preisach.weights.iter().zip(&c.slope).map(|(w, s)| w * s).sum();
                prop_assert!((e.torque - h).abs() <= 1e-12, "H {} vs Σ {} at {}", e.torque, h, x);
                prop_assert!((e.stiffness - k_sum).abs() <= 1e-9 * (1.0 + k_sum.abs()), "K {} vs Σ {} at {}", e.stiffness, k_sum, x);
            }
            at = point;
        }
    }

    /// Any loop, run around in either direction from anywhere, dissipates: ∮ T dx ≥ 0 with
    /// T = −P (the spring stores and returns what it takes).
    #[test]
    fn every_closed_loop_dissipates(
        history in prop::collection::vec(-R..R, 0..6),
        ends in (-R..R, -R..R),
    ) {
        let mut h = memory(&uneven(R));
        let mut at = 0.0;
        for &x in &history {
            for k in 1..=20 {
                h.step(at + (x - at) * f64::from(k) / 20.0).unwrap();
            }
            at = x;
        }
        // From `at` to each end, then twice around the loop between them; the second lap is
        // closed (return-point memory), and its work is the loop's area.
        let (a, b) = ends;
        let mut lap = Vec::new();
        for (from, to) in [(at, a), (a, b), (b, a), (a, b), (b, a)] {
            for k in 1..=400 {
                lap.push(from + (to - from) * f64::from(k) / 400.0);
            }
        }
        let evaluations: Vec<f64> = lap.iter().map(|&x| h.step(x).unwrap().torque).collect();
        let second = 1200..2000;
        let work: f64 = second
            .clone()
            .map(|i| 0.5 * (evaluations[i] + evaluations[i - 1]) * (lap[i] - lap[i - 1]))
            .sum();
        prop_assert!(work >= -1e-12, "∮ H dx = {work} on the loop {a} ↔ {b}");
    }
}

/// Rayleigh's law, which a uniform density μ gives: P = μx² on the first loading from rest,
/// and back from x_a by μ·(x_a − x)²/2.
#[test]
fn a_uniform_density_follows_rayleighs_parabolas() {
    let mu = 2.0e9;
    let mut h = memory(&uniform(mu));
    let top = 0.8 * R;
    for k in 0..=100 {
        let x = top * f64::from(k) / 100.0;
        let e = h.step(x).unwrap();
        assert!((e.torque + mu * x * x).abs() < 1e-9, "virgin at {x}: {} vs {}", e.torque, -mu * x * x);
        if k > 0 {
            assert!((e.stiffness + 2.0 * mu * x).abs() < 1e-6 * mu * R, "virgin K at {x}: {}", e.stiffness);
        }
    }
    for k in 1..=100 {
        let x = top - 1.5 * top * f64::from(k) / 100.0;
        let e = h.step(x).unwrap();
        let want = -mu * top * top + mu * (top - x) * (top - x) / 2.0;
        assert!((e.torque - want).abs() < 1e-9, "down from {top} at {x}: {} vs {want}", e.torque);
    }
}

/// The micro-slip kind is the density that depends on α − β only; on this grid, the uniform
/// density. It is a continuum of elements with slip deflections spread evenly over (0, R],
/// k = 2μ per rad of slip deflection, beside a spring 2μR·x that the relays soften:
/// H_preisach = H_micro-slip − 2μR·x. Micro-slip with M elements at the midpoints of M equal
/// bins approaches it as 1/M².
#[test]
fn micro_slip_is_the_uniform_density() {
    let mu = 2.0e9;
    let motion = nested(0.95 * R, 4000);
    fn elements<const M: usize>(mu: f64) -> [SlipElement<f64>; M] {
        let bin = R / M as f64;
        core::array::from_fn(|k| SlipElement { slip: (k as f64 + 0.5) * bin, stiffness: 2.0 * mu * bin })
    }
    let mut worst = [0.0f64; 2];
    let (mut coarse, mut fine) = (
        MicroSlip::<f64, 16>::new(&elements::<16>(mu)).unwrap(),
        MicroSlip::<f64, 64>::new(&elements::<64>(mu)).unwrap(),
    );
    let mut h = memory(&uniform(mu));
    for &x in &motion {
        let preisach = h.step(x).unwrap().torque;
        for (slot, slip) in worst.iter_mut().zip([coarse.step(x).unwrap(), fine.step(x).unwrap()]) {
            *slot = slot.max((preisach - (slip.torque - 2.0 * mu * R * x)).abs());
        }
    }
    let scale = mu * R * R;
    std::println!(
        "uniform density against micro-slip, worst |ΔH|/μR²: 16 elements {:.2e}, 64 elements {:.2e}",
        worst[0] / scale,
        worst[1] / scale
    );
    assert!(worst[0] < 4e-3 * scale, "16 elements: {} of μR² = {scale}", worst[0]);
    assert!(worst[1] < worst[0] / 10.0, "64 elements: {} against 16: {}", worst[1], worst[0]);
}

/// Masing's rule says a minor loop's shape does not depend on where it sits. A uniform density
/// obeys it; the uneven one does not: loops of one amplitude at three biases differ in area.
#[test]
fn minor_loops_depend_on_where_they_sit_unless_the_density_is_uniform() {
    let area = |preisach: &Preisach<f64>, bias: f64| {
        let mut h = memory(preisach);
        let amplitude = 0.15 * R;
        let mut path: Vec<f64> = (1..=200).map(|k| bias * f64::from(k) / 200.0).collect();
        for _ in 0..2 {
            for (from, to) in [(bias, bias + amplitude), (bias + amplitude, bias - amplitude), (bias - amplitude, bias)]
            {
                path.extend((1..=200).map(|k| from + (to - from) * f64::from(k) / 200.0));
            }
        }
        let torque: Vec<f64> = path.iter().map(|&x| h.step(x).unwrap().torque).collect();
        let lap = path.len() - 600..path.len();
        lap.map(|i| 0.5 * (torque[i] + torque[i - 1]) * (path[i] - path[i - 1])).sum::<f64>()
    };
    let biases = [-0.5 * R, 0.0, 0.5 * R];
    let spread = |preisach: &Preisach<f64>| {
        let areas: Vec<f64> = biases.iter().map(|&b| area(preisach, b)).collect();
        let (lo, hi) = areas.iter().fold((f64::MAX, f64::MIN), |(lo, hi), a| (lo.min(*a), hi.max(*a)));
        assert!(lo > 0.0, "areas {areas:?}");
        (hi - lo) / hi
    };
    assert!(spread(&uniform(2.0e9)) < 1e-9, "uniform");
    assert!(spread(&uneven(R)) > 0.2, "uneven: {}", spread(&uneven(R)));
}

/// Beyond ±R every relay has switched: H holds, the hysteresis adds no stiffness, and coming
/// back the relays switch again from the grid's edge.
#[test]
fn beyond_the_grid_the_hysteresis_holds() {
    let mut h = memory(&uneven(R));
    let at_edge = h.step(R).unwrap();
    for x in [1.01 * R, 2.0 * R, 100.0 * R] {
        let e = h.step(x).unwrap();
        assert_eq!(e.torque, at_edge.torque);
        assert_eq!(e.stiffness, 0.0);
    }
    let back = h.step(0.5 * R).unwrap();
    assert!(back.torque > at_edge.torque && back.stiffness < 0.0, "{back:?}");
}

#[test]
fn f32_follows_f64() {
    let preisach = uneven(R);
    let single = Preisach { reach: R as f32, weights: preisach.weights.map(|w| w as f32) };
    let mut h64 = memory(&preisach);
    let mut h32 = PreisachMemory::<f32, 16>::new(PreparedPreisach::new(&single).unwrap(), 0.0);
    let scale = preisach.total();
    for &x in &nested(1.1 * R, 4000) {
        let (e64, e32) = (h64.step(x).unwrap(), h32.step(x as f32).unwrap());
        assert!((f64::from(e32.torque) - e64.torque).abs() < 1e-5 * scale, "{e32:?} vs {e64:?} at {x}");
    }
}

#[test]
fn bad_sets_are_refused() {
    let good = uneven(R);
    let mut negative = good;
    negative.weights[7] = -1e-9;
    let mut not_finite = good;
    not_finite.weights[0] = f64::NAN;
    for bad in [Preisach { reach: 0.0, ..good }, Preisach { reach: f64::INFINITY, ..good }, negative, not_finite] {
        assert_eq!(PreparedPreisach::new(&bad), Err(Error::InvalidPreisach));
    }
    assert_eq!(PreisachCells::new(-R), Err(Error::InvalidPreisach));
}
