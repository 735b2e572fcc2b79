//! Particle swarm optimisation (the paper's global search) and Brent's 1-D minimiser (the
//! polish). Both are a few dozen lines; the general optimisation crates would bring a
//! generic-math stack into the build for these two loops.
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

#[derive(Clone, Debug)]
pub struct PsoOptions {
    pub particles: usize,
    pub max_iterations: usize,
    /// Stop after this many iterations without improving the best value.
    pub stall_iterations: usize,
    pub seed: u64,
}

#[derive(Clone, Debug, PartialEq)]
pub struct PsoResult {
    pub best: Vec<f64>,
    pub value: f64,
    pub iterations: usize,
    pub evaluations: usize,
    /// Spread of the personal bests around the best, per coordinate: a bracket for the polish.
    pub spread: Vec<f64>,
}

/// Minimises `objective` over the box `bounds` with a global-best swarm using Clerc's
/// constriction coefficients (w = 0.7298, c1 = c2 = 1.49618). Deterministic for a seed.
/// `progress(iteration, best)` is called after each iteration.
pub fn pso(
    mut objective: impl FnMut(&[f64]) -> f64,
    bounds: &[(f64, f64)],
    options: &PsoOptions,
    mut progress: impl FnMut(usize, f64),
) -> PsoResult {
    const INERTIA: f64 = 0.7298;
    const PULL: f64 = 1.49618;
    let dims = bounds.len();
    let mut rng = ChaCha8Rng::seed_from_u64(options.seed);
    let mut evaluations = 0;
    let mut evaluate = |x: &[f64]| {
        evaluations += 1;
        let v = objective(x);
        if v.is_nan() {
            f64::INFINITY
        } else {
            v
        }
    };
    let width: Vec<f64> = bounds.iter().map(|(lo, hi)| hi - lo).collect();
    let mut position: Vec<Vec<f64>> = (0..options.particles.max(1))
        .map(|_| bounds.iter().map(|&(lo, hi)| rng.random_range(lo..=hi)).collect())
        .collect();
    let mut velocity: Vec<Vec<f64>> =
        position.iter().map(|_| width.iter().map(|w| rng.random_range(-0.5..=0.5) * w * 0.5).collect()).collect();
    let mut personal = position.clone();
    let mut personal_value: Vec<f64> = position.iter().map(|x| evaluate(x)).collect();
    let (best_index, _) =
        personal_value.iter().enumerate().fold((0, f64::INFINITY), |acc, (i, &v)| if v < acc.1 { (i, v) } else { acc });
    let mut best = personal[best_index].clone();
    let mut best_value = personal_value[best_index];
    let mut stalled = 0;
    let mut iterations = 0;
    while iterations < options.max_iterations && stalled < options.stall_iterations {
        iterations += 1;
        let before = best_value;
        for p in 0..position.len() {
            for d in 0..dims {
                let (r1, r2): (f64, f64) = (rng.random(), rng.random());
                let v = INERTIA * velocity[p][d]
                    + PULL * r1 * (personal[p][d] - position[p][d])
                    + PULL * r2 * (best[d] - position[p][d]);
                velocity[p][d] = v.clamp(-0.5 * width[d], 0.5 * width[d]);
                let (lo, hi) = bounds[d];
                let x = position[p][d] + velocity[p][d];
                if x < lo || x > hi {
                    velocity[p][d] = 0.0;
                }
                position[p][d] = x.clamp(lo, hi);
            }
            let value = evaluate(&position[p]);
            if value < personal_value[p] {
                personal_value[p] = value;
                personal[p].clone_from(&position[p]);
                if value < best_value {
                    best_value = value;
                    best.clone_from(&position[p]);
                }
            }
        }
        if best_value < before - 1e-12 * before.abs() {
            stalled = 0;
        } else {
            stalled += 1;
        }
        progress(iterations, best_value);
    }
    let spread = (0..dims).map(|d| personal.iter().map(|x| (x[d] - best[d]).abs()).fold(0.0, f64::max)).collect();
    PsoResult { best, value: best_value, iterations, evaluations, spread }
}

/// Brent's method: the minimum of `f` on [lo, hi] to within `tolerance` in x, by golden
/// sections and parabolic steps. Returns (x, f(x), evaluations).
pub fn brent(mut f: impl FnMut(f64) -> f64, lo: f64, hi: f64, tolerance: f64) -> (f64, f64, usize) {
    const GOLDEN: f64 = 0.381_966_011_250_105;
    let (mut a, mut b) = (lo.min(hi), lo.max(hi));
    let mut x = a + GOLDEN * (b - a);
    let (mut w, mut v) = (x, x);
    let mut fx = f(x);
    let (mut fw, mut fv) = (fx, fx);
    let mut evaluations = 1;
    let (mut d, mut e) = (0.0f64, 0.0f64);
    for _ in 0..200 {
        let middle = 0.5 * (a + b);
        let tol1 = tolerance + 1e-12 * x.abs();
        let tol2 = 2.0 * tol1;
        if (x - middle).abs() <= tol2 - 0.5 * (b - a) {
            break;
        }
        let mut golden = true;
        if e.abs() > tol1 {
            // Parabola through (v, fv), (w, fw), (x, fx).
            let r = (x - w) * (fx - fv);
            let q = (x - v) * (fx - fw);
            let mut p = (x - v) * q - (x - w) * r;
            let mut q = 2.0 * (q - r);
            if q > 0.0 {
                p = -p;
            }
            q = q.abs();
            if p.abs() < (0.5 * q * e).abs() && p > q * (a - x) && p < q * (b - x) {
                e = d;
                d = p / q;
                let u = x + d;
                if u - a < tol2 || b - u < tol2 {
                    d = if x < middle { tol1 } else { -tol1 };
                }
                golden = false;
            }
        }
        if golden {
            e = if x < middle { b - x } else { a - x };
            d = GOLDEN * e;
        }
        let u = if d.abs() >= tol1 { x + d } else { x + tol1.copysign(d) };
        let fu = f(u);
        evaluations += 1;
        if fu <= fx {
            if u < x {
                b = x
            } else {
                a = x
            }
            (v, fv, w, fw, x, fx) = (w, fw, x, fx, u, fu);
        } else {
            if u < x {
                a = u
            } else {
                b = u
            }
            if fu <= fw || w == x {
                (v, fv, w, fw) = (w, fw, u, fu);
            } else if fu <= fv || v == x || v == w {
                (v, fv) = (u, fu);
            }
        }
    }
    (x, fx, evaluations)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pso_finds_the_global_minimum_of_a_multimodal_function() {
        // Rastrigin in 2-D: global minimum 0 at the origin among many local minima.
        let rastrigin =
            |x: &[f64]| x.iter().map(|v| v * v - 10.0 * (2.0 * std::f64::consts::PI * v).cos() + 10.0).sum::<f64>();
        let options = PsoOptions { particles: 40, max_iterations: 300, stall_iterations: 60, seed: 3 };
        let result = pso(rastrigin, &[(-5.12, 5.12), (-5.12, 5.12)], &options, |_, _| {});
        assert!(result.value < 1e-6, "{result:?}");
        // Deterministic for a seed.
        let again = pso(rastrigin, &[(-5.12, 5.12), (-5.12, 5.12)], &options, |_, _| {});
        assert_eq!(result, again);
    }

    #[test]
    fn brent_converges_on_a_smooth_minimum() {
        let (x, fx, evaluations) = brent(|x| (x - 0.3).powi(2) + (3.0 * x).cos(), -2.0, 2.0, 1e-10);
        // f'(x) = 2(x − 0.3) − 3 sin 3x = 0
        assert!((2.0 * (x - 0.3) - 3.0 * (3.0 * x).sin()).abs() < 1e-8, "{x} {fx}");
        assert!(evaluations < 40);
    }
}
