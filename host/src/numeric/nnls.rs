//! Least squares with some unknowns held ≥ 0 (Lawson & Hanson's active-set method), on the
//! normal equations. Written here rather than taken from the `nnls` crate because that crate
//! works on the whole m×n design matrix (ndarray, copied): for a 10-million-sample recording and
//! 19 unknowns that is 1.5 GB, while the normal equations are 19×19 whatever the length.
use super::linalg::Cholesky;

/// Minimises xᵀGx − 2hᵀx (i.e. ‖Ax − b‖² with G = AᵀA, h = Aᵀb) over the n = `h.len()`
/// unknowns, with x_j ≥ 0 for every j where `nonnegative[j]` and the others free. `gram` is
/// G row-major. Returns `None` when the free unknowns alone are undetermined by the data.
///
/// The columns are scaled to unit norm first (G_jj = 1): the bounds keep their sign, and the
/// optimality test compares gradients of like scale (a fit's columns differ by orders of
/// magnitude).
pub fn nnls_normal(gram: &[f64], h: &[f64], nonnegative: &[bool]) -> Option<Vec<f64>> {
    let n = h.len();
    debug_assert_eq!(gram.len(), n * n);
    debug_assert_eq!(nonnegative.len(), n);
    let norm: Vec<f64> = (0..n).map(|j| gram[j * n + j].sqrt()).map(|d| if d > 0.0 { d } else { 1.0 }).collect();
    let scaled: Vec<f64> = (0..n * n).map(|k| gram[k] / (norm[k / n] * norm[k % n])).collect();
    let rhs: Vec<f64> = h.iter().zip(&norm).map(|(h, d)| h / d).collect();
    let x = lawson_hanson(&scaled, &rhs, nonnegative)?;
    Some(x.iter().zip(&norm).map(|(x, d)| x / d).collect())
}

/// Lawson & Hanson's active-set method on scaled normal equations.
fn lawson_hanson(gram: &[f64], h: &[f64], nonnegative: &[bool]) -> Option<Vec<f64>> {
    let n = h.len();
    // The passive set: unknowns solved for freely; the others sit at 0.
    let mut passive: Vec<bool> = nonnegative.iter().map(|&bounded| !bounded).collect();
    let mut x = solve_passive(gram, h, &passive)?;
    let tolerance = 1e-12 * h.iter().map(|v| v.abs()).fold(0.0, f64::max).max(f64::MIN_POSITIVE);
    // Unknowns that entered and were pushed straight back (round-off): not tried again until
    // another one enters for good.
    let mut rejected = vec![false; n];
    // Lawson & Hanson bound the outer loop by 3n; each round frees one bounded unknown.
    for _ in 0..3 * n.max(1) {
        let gradient: Vec<f64> = (0..n).map(|i| h[i] - (0..n).map(|j| gram[i * n + j] * x[j]).sum::<f64>()).collect();
        let entering = (0..n)
            .filter(|&j| !passive[j] && !rejected[j] && gradient[j] > tolerance)
            .max_by(|&a, &b| gradient[a].total_cmp(&gradient[b]));
        let Some(entering) = entering else { break };
        passive[entering] = true;
        // Inner loop: step towards the passive solution until no bounded unknown goes negative.
        // Each pass drops at least the blocking unknown (set to 0 exactly: its step's end can
        // round to a hair above 0), so it ends within n passes.
        for _ in 0..n {
            let z = solve_passive(gram, h, &passive)?;
            let blocking = (0..n)
                .filter(|&j| passive[j] && nonnegative[j] && z[j] <= 0.0)
                .map(|j| (x[j] / (x[j] - z[j]), j))
                .min_by(|a, b| a.0.total_cmp(&b.0));
            let Some((alpha, blocked)) = blocking.filter(|(alpha, _)| alpha.is_finite()) else {
                x = z;
                break;
            };
            for j in 0..n {
                x[j] += alpha * (z[j] - x[j]);
                if passive[j] && nonnegative[j] && (x[j] <= 0.0 || j == blocked) {
                    passive[j] = false;
                    x[j] = 0.0;
                }
            }
        }
        if passive[entering] {
            rejected.iter_mut().for_each(|r| *r = false);
        } else {
            rejected[entering] = true;
        }
    }
    Some(x)
}

/// The least-squares solution over the passive unknowns, the others 0.
fn solve_passive(gram: &[f64], h: &[f64], passive: &[bool]) -> Option<Vec<f64>> {
    let n = h.len();
    let index: Vec<usize> = (0..n).filter(|&j| passive[j]).collect();
    let mut x = vec![0.0; n];
    if index.is_empty() {
        return Some(x);
    }
    let m = index.len();
    let sub: Vec<f64> = index.iter().flat_map(|&i| index.iter().map(move |&j| gram[i * n + j])).collect();
    let rhs: Vec<f64> = index.iter().map(|&i| h[i]).collect();
    let solution = Cholesky::new(m, &sub)?.solve(&rhs);
    for (&i, value) in index.iter().zip(solution) {
        x[i] = value;
    }
    Some(x)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// G = AᵀA, h = Aᵀb for a dense row-major A (m×n).
    fn normal(a: &[&[f64]], b: &[f64]) -> (Vec<f64>, Vec<f64>) {
        let n = a[0].len();
        let mut g = vec![0.0; n * n];
        let mut h = vec![0.0; n];
        for (row, &bi) in a.iter().zip(b) {
            for i in 0..n {
                h[i] += row[i] * bi;
                for j in 0..n {
                    g[i * n + j] += row[i] * row[j];
                }
            }
        }
        (g, h)
    }

    #[test]
    fn matches_scipy_on_small_problems() {
        // scipy.optimize.nnls([[1,0],[1,0],[0,1]], [2,1,1]) = [1.5, 1].
        let (g, h) = normal(&[&[1.0, 0.0], &[1.0, 0.0], &[0.0, 1.0]], &[2.0, 1.0, 1.0]);
        let x = nnls_normal(&g, &h, &[true, true]).unwrap();
        assert!((x[0] - 1.5).abs() < 1e-12 && (x[1] - 1.0).abs() < 1e-12, "{x:?}");
        // scipy gives [1.37279152, 0, 0.47173145]: the middle unknown would be negative.
        let (g, h) =
            normal(&[&[1.0, 0.5, 0.0], &[1.0, 0.6, 0.0], &[0.9, 0.5, 0.1], &[0.0, 0.0, 1.0]], &[2.0, 1.0, 1.0, 0.5]);
        let x = nnls_normal(&g, &h, &[true, true, true]).unwrap();
        for (got, want) in x.iter().zip([1.37279152, 0.0, 0.47173145]) {
            assert!((got - want).abs() < 1e-6, "{x:?}");
        }
    }

    #[test]
    fn free_unknowns_may_be_negative_and_bounded_ones_may_not() {
        // b = −2·a0 + 3·a1 − 1·a2 exactly; a2 is held ≥ 0, so it goes to 0 and the rest refit.
        let rows: Vec<[f64; 3]> = (0..20).map(|i| i as f64 / 10.0).map(|t| [1.0, t, t * t]).collect();
        let b: Vec<f64> = rows.iter().map(|r| -2.0 * r[0] + 3.0 * r[1] - r[2]).collect();
        let a: Vec<&[f64]> = rows.iter().map(|r| r.as_slice()).collect();
        let (g, h) = normal(&a, &b);
        let free = nnls_normal(&g, &h, &[false, false, false]).unwrap();
        assert!((free[0] + 2.0).abs() < 1e-9 && (free[2] + 1.0).abs() < 1e-9, "{free:?}");
        let bounded = nnls_normal(&g, &h, &[false, false, true]).unwrap();
        assert_eq!(bounded[2], 0.0);
        assert!(bounded[0] < 0.0, "free unknowns keep their sign: {bounded:?}");
    }
}
