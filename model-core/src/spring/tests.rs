extern crate std;
use super::*;
use proptest::prelude::*;
use std::string::ToString;
use std::vec;
use std::vec::Vec;

/// An asymmetric stiffening spring: softer on the + side, knots 0.3 mrad apart.
fn asymmetric() -> Spring<f64> {
    let knots = [
        Knot { x: -1.2e-3, stiffness: 3.0e4 },
        Knot { x: -0.6e-3, stiffness: 2.0e4 },
        Knot { x: 0.0, stiffness: 1.0e4 },
        Knot { x: 0.5e-3, stiffness: 1.4e4 },
        Knot { x: 1.0e-3, stiffness: 2.2e4 },
    ];
    Spring::of_knots(&knots, [-1.3e-3, 1.1e-3]).unwrap()
}

fn columns(spring: &Spring<f64>, x: f64) -> (Vec<f64>, Vec<f64>) {
    let xs: Vec<f64> = spring.knots().iter().map(|k| k.x).collect();
    let (mut t, mut k) = (vec![0.0; xs.len()], vec![0.0; xs.len()]);
    basis(&xs, x, &mut t, &mut k);
    (t, k)
}

#[test]
fn the_polynomial_alone_is_the_papers_spring_within_its_range() {
    let spring = Spring::polynomial(9.0e3, 1.2e10, -3.0e14);
    let mut prepared = spring.prepare().unwrap();
    let polynomial = Polynomial::new(9.0e3, 1.2e10, -3.0e14).unwrap();
    for x in [-1.5e-3, -1.0e-4, 0.0, 7.0e-4, 1.2e-3] {
        assert_eq!(prepared.evaluate(x), polynomial.evaluate(x));
    }
}

#[test]
fn beyond_the_range_the_spring_continues_with_its_edge_stiffness() {
    let mut spring = Spring::polynomial(9.0e3, 1.2e10, 3.0e15);
    spring.range = [-1.0e-3, 1.2e-3];
    let mut prepared = spring.prepare().unwrap();
    let edge = Polynomial::new(9.0e3, 1.2e10, 3.0e15).unwrap().evaluate(1.2e-3);
    let at = |x: f64| edge.torque + edge.stiffness * (x - 1.2e-3);
    for x in [1.2e-3, 1.5e-3, 2.4e-3, 1.0e-2] {
        let e = prepared.evaluate(x);
        assert!((e.torque - at(x)).abs() <= 1e-12 * at(x).abs(), "{x}: {e:?}");
        assert_eq!(e.stiffness, edge.stiffness);
    }
    assert_eq!(prepared.excess(2.4e-3), 2.4e-3 - 1.2e-3);
    assert_eq!(prepared.excess(-0.5e-3), 0.0);
    // The quintic itself at 10 mrad: 3e5 N·m; the line: a few hundred.
    assert!(prepared.evaluate(1.0e-2).torque < 1.0e3);
}

#[test]
fn the_knots_stiffness_is_linear_between_them_and_integrates_from_zero() {
    let spring = asymmetric();
    let mut prepared = spring.prepare().unwrap();
    assert_eq!(prepared.evaluate(0.0).torque, 0.0);
    assert_eq!(prepared.evaluate(0.0).stiffness, 1.0e4);
    // Halfway between 0.5 and 1 mrad: the mean of 1.4e4 and 2.2e4.
    assert!((prepared.evaluate(0.75e-3).stiffness - 1.8e4).abs() < 1e-6);
    // P(0.5 mrad) = the trapezoid 0.5e-3 · (1e4 + 1.4e4)/2 = 6 N·m; left of the first knot the
    // first knot's stiffness.
    assert!((prepared.evaluate(0.5e-3).torque - 6.0).abs() < 1e-12);
    let first = prepared.evaluate(-1.2e-3);
    let beyond = prepared.evaluate(-1.25e-3);
    assert!((beyond.torque - (first.torque - 3.0e4 * 0.05e-3)).abs() < 1e-12);
    assert_eq!(beyond.stiffness, 3.0e4);
}

#[test]
fn the_fits_columns_are_the_springs_own() {
    let spring = asymmetric();
    let mut prepared = spring.prepare().unwrap();
    for i in 0..=260 {
        let x = -1.3e-3 + 2.4e-3 * f64::from(i) / 260.0;
        let (t, k) = columns(&spring, x);
        let torque: f64 = spring.knots().iter().zip(&t).map(|(knot, b)| knot.stiffness * b).sum();
        let stiffness: f64 = spring.knots().iter().zip(&k).map(|(knot, h)| knot.stiffness * h).sum();
        let e = prepared.evaluate(x);
        assert!((torque - e.torque).abs() <= 1e-9 * (1.0 + e.torque.abs()), "{x}: {torque} vs {e:?}");
        assert!((stiffness - e.stiffness).abs() <= 1e-9 * e.stiffness, "{x}: {stiffness} vs {e:?}");
    }
}

#[test]
fn check_names_the_bad_parameter() {
    let good = asymmetric();
    let with = |edit: fn(&mut Spring<f64>)| {
        let mut s = good;
        edit(&mut s);
        s.check()
    };
    assert_eq!(good.check(), Ok(()));
    assert_eq!(with(|s| s.knots.0[3].x = -1.0), Err((ParamName::Knot(3), ParamFault::OutOfRange)));
    assert_eq!(with(|s| s.knots.0[1].stiffness = -1.0), Err((ParamName::KnotStiffness(1), ParamFault::OutOfRange)));
    assert_eq!(with(|s| s.knots.0[2].x = f64::NAN), Err((ParamName::Knot(2), ParamFault::NotFinite)));
    assert_eq!(with(|s| s.range = [1.0e-4, 1.0e-3]), Err((ParamName::RangeMin, ParamFault::OutOfRange)));
    assert_eq!(with(|s| s.range = [-1.0e-3, -1.0e-4]), Err((ParamName::RangeMax, ParamFault::OutOfRange)));
    assert_eq!(with(|s| s.c2 = f64::INFINITY), Err((ParamName::C2, ParamFault::NotFinite)));
    assert_eq!(with(|s| s.knots.1 = 40), Err((ParamName::Knot(17), ParamFault::OutOfRange)));
    assert!(Spring::of_knots(&[Knot { x: 0.0, stiffness: 1.0 }; 18], [-1.0, 1.0]).is_err());
}

#[test]
fn files_list_the_knots_in_use() {
    let spring = asymmetric();
    let json = serde_json::to_value(spring).unwrap();
    assert_eq!(json["knots"].as_array().unwrap().len(), 5, "{json}");
    assert_eq!(json["knots"][3]["x"], 0.5e-3);
    assert_eq!(serde_json::from_value::<Spring<f64>>(json.clone()).unwrap(), spring);
    let bytes = postcard::to_stdvec(&spring).unwrap();
    assert_eq!(postcard::from_bytes::<Spring<f64>>(&bytes).unwrap(), spring);
    let mut many = json;
    many["knots"] = serde_json::Value::Array(vec![many["knots"][0].clone(); 18]);
    let error = serde_json::from_value::<Spring<f64>>(many).unwrap_err().to_string();
    assert!(error.contains("at most 17"), "{error}");
}

fn a_spring() -> impl Strategy<Value = Spring<f64>> {
    (1usize..=MAX_KNOTS, prop::collection::vec((1.0e-5..4.0e-4f64, 0.0..5.0e4f64), MAX_KNOTS), 0usize..MAX_KNOTS)
        .prop_map(|(n, steps, zero_at)| {
            let mut x = 0.0;
            let mut knots: Vec<Knot<f64>> = steps[..n]
                .iter()
                .map(|&(step, stiffness)| {
                    x += step;
                    Knot { x, stiffness }
                })
                .collect();
            let shift = knots[zero_at.min(n - 1)].x;
            knots.iter_mut().for_each(|k| k.x -= shift);
            let lo = knots[0].x.min(0.0) - 1.0e-4;
            let hi = knots[n - 1].x.max(0.0) + 1.0e-4;
            Spring::of_knots(&knots, [lo, hi]).unwrap()
        })
}

proptest! {
    /// Continuous torque and stiffness everywhere (knots, range edges), monotone with K ≥ 0, and
    /// the same values whatever the order of evaluation (the segment cursor).
    #[test]
    fn continuous_monotone_and_order_free(spring in a_spring(), order in prop::collection::vec(0usize..400, 50)) {
        let mut prepared = spring.prepare().unwrap();
        let [lo, hi] = spring.range;
        let xs: Vec<f64> = (0..400).map(|i| lo - 2.0e-4 + (hi - lo + 4.0e-4) * f64::from(i) / 399.0).collect();
        let along: Vec<Evaluation<f64>> = xs.iter().map(|&x| prepared.evaluate(x)).collect();
        let scale = along.iter().map(|e| e.stiffness).fold(1.0, f64::max);
        for (pair, e) in xs.windows(2).zip(along.windows(2)) {
            let dx = pair[1] - pair[0];
            prop_assert!(e[1].torque >= e[0].torque - 1e-12 * scale, "not monotone at {}", pair[0]);
            // No step: the torque moves by at most the largest stiffness in between times Δx.
            let between = spring.knots().iter().filter(|k| (pair[0]..=pair[1]).contains(&k.x)).map(|k| k.stiffness);
            let largest = between.fold(e[0].stiffness.max(e[1].stiffness), f64::max);
            let step = (e[1].torque - e[0].torque).abs();
            prop_assert!(step <= largest * dx * (1.0 + 1e-9) + 1e-12 * scale);
        }
        for &i in &order {
            prop_assert_eq!(prepared.evaluate(xs[i]), along[i]);
        }
    }
}
