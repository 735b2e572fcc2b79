//! The small dense solves the fits need: four to ten unknowns at a time (the model's columns
//! and the diagnosis' effects), in a flat `Vec`. Hand-written because the fits need what a
//! library Cholesky does not do: equilibrated columns and dropping a column whose pivot
//! vanishes (collinear data), instead of failing or returning garbage.

/// Solves the symmetric positive (semi-)definite system `m·x = r`. Columns are equilibrated
/// first (the fit's columns differ by many orders of magnitude); a column whose pivot
/// vanishes relative to its diagonal is dropped (its unknown set to 0), so collinear data
/// gives the minimum-norm-like answer instead of garbage. `None` if nothing is left.
pub fn solve_spd<const N: usize>(m: [[f64; N]; N], r: [f64; N]) -> Option<[f64; N]> {
    let flat: Vec<f64> = m.iter().flatten().copied().collect();
    let solution = Cholesky::new(N, &flat)?.solve(&r);
    solution.iter().all(|v| v.is_finite()).then(|| std::array::from_fn(|i| solution[i]))
}

/// Cholesky factor of an equilibrated symmetric matrix, for solves and variances.
pub struct Cholesky {
    n: usize,
    /// Row-major lower triangle; dropped columns are all zero.
    lower: Vec<f64>,
    scale: Vec<f64>,
    active: Vec<bool>,
}

impl Cholesky {
    /// Factors the row-major `n`×`n` matrix `m`.
    pub fn new(n: usize, m: &[f64]) -> Option<Cholesky> {
        let scale: Vec<f64> = (0..n)
            .map(|i| {
                let d = m[i * n + i];
                if d > 0.0 && d.is_finite() {
                    1.0 / d.sqrt()
                } else {
                    0.0
                }
            })
            .collect();
        let mut a: Vec<f64> = (0..n * n).map(|k| m[k] * scale[k / n] * scale[k % n]).collect();
        let mut active = vec![false; n];
        for j in 0..n {
            let mut d = a[j * n + j];
            for k in 0..j {
                d -= a[j * n + k] * a[j * n + k];
            }
            if scale[j] == 0.0 || !(d > 1e-13) {
                for i in j..n {
                    a[i * n + j] = 0.0;
                }
                continue;
            }
            active[j] = true;
            let l = d.sqrt();
            a[j * n + j] = l;
            for i in j + 1..n {
                let mut s = a[i * n + j];
                for k in 0..j {
                    s -= a[i * n + k] * a[j * n + k];
                }
                a[i * n + j] = s / l;
            }
        }
        active.iter().any(|&x| x).then_some(Cholesky { n, lower: a, scale, active })
    }

    /// x with m·x = r; dropped unknowns are 0.
    pub fn solve(&self, r: &[f64]) -> Vec<f64> {
        let (n, a) = (self.n, &self.lower);
        let mut y = vec![0.0; n];
        for i in 0..n {
            if self.active[i] {
                let mut s = r[i] * self.scale[i];
                for k in 0..i {
                    s -= a[i * n + k] * y[k];
                }
                y[i] = s / a[i * n + i];
            }
        }
        let mut x = vec![0.0; n];
        for i in (0..n).rev() {
            if self.active[i] {
                let mut s = y[i];
                for k in i + 1..n {
                    s -= a[k * n + i] * x[k];
                }
                x[i] = s / a[i * n + i];
            }
        }
        x.iter().zip(&self.scale).map(|(x, s)| x * s).collect()
    }

    /// Diagonal element `i` of m⁻¹: the variance of unknown `i` per unit residual variance.
    pub fn inverse_diagonal(&self, i: usize) -> f64 {
        let mut unit = vec![0.0; self.n];
        unit[i] = 1.0;
        self.solve(&unit)[i]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn solves_a_badly_scaled_system() {
        // Columns 1, 1e6·t, 1e-6·t² over t in 0..10.
        let cols = |t: f64| [1.0, 1e6 * t, 1e-6 * t * t];
        let truth = [2.0, -3e-6, 5e6];
        let mut m = [[0.0; 3]; 3];
        let mut r = [0.0; 3];
        for i in 0..11 {
            let c = cols(i as f64);
            let y: f64 = c.iter().zip(truth).map(|(a, b)| a * b).sum();
            for a in 0..3 {
                r[a] += c[a] * y;
                for b in 0..3 {
                    m[a][b] += c[a] * c[b];
                }
            }
        }
        let x = solve_spd(m, r).unwrap();
        for (got, want) in x.iter().zip(truth) {
            assert!((got - want).abs() <= 1e-9 * want.abs(), "{got} vs {want}");
        }
    }

    #[test]
    fn drops_a_collinear_column() {
        // Second column is twice the first.
        let m = [[1.0, 2.0], [2.0, 4.0]];
        let x = solve_spd(m, [3.0, 6.0]).unwrap();
        assert_eq!(x, [3.0, 0.0]);
        assert_eq!(solve_spd([[0.0]], [1.0]), None);
    }
}
