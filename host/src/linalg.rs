//! The small dense solves the fits need. Four or five unknowns at a time: a hand-written
//! Cholesky on stack arrays beats pulling a linear-algebra crate into the build.

/// Solves the symmetric positive (semi-)definite system `m·x = r`. Columns are equilibrated
/// first (the fit's columns differ by many orders of magnitude); a column whose pivot
/// vanishes relative to its diagonal is dropped (its unknown set to 0), so collinear data
/// gives the minimum-norm-like answer instead of garbage. `None` if nothing is left.
pub fn solve_spd<const N: usize>(m: [[f64; N]; N], r: [f64; N]) -> Option<[f64; N]> {
    let scale: [f64; N] = std::array::from_fn(|i| {
        let d = m[i][i];
        if d > 0.0 && d.is_finite() { 1.0 / d.sqrt() } else { 0.0 }
    });
    let mut a = [[0.0; N]; N];
    for i in 0..N {
        for j in 0..N {
            a[i][j] = m[i][j] * scale[i] * scale[j];
        }
    }
    // Cholesky a = L·Lᵀ, in place in the lower triangle.
    let mut active = [false; N];
    for j in 0..N {
        let mut d = a[j][j];
        for k in 0..j {
            d -= a[j][k] * a[j][k];
        }
        if scale[j] == 0.0 || !(d > 1e-13) {
            for i in j..N {
                a[i][j] = 0.0;
            }
            continue;
        }
        active[j] = true;
        let l = d.sqrt();
        a[j][j] = l;
        for i in j + 1..N {
            let mut s = a[i][j];
            for k in 0..j {
                s -= a[i][k] * a[j][k];
            }
            a[i][j] = s / l;
        }
    }
    if !active.iter().any(|&x| x) {
        return None;
    }
    let mut y = [0.0; N];
    for i in 0..N {
        if !active[i] {
            continue;
        }
        let mut s = r[i] * scale[i];
        for k in 0..i {
            s -= a[i][k] * y[k];
        }
        y[i] = s / a[i][i];
    }
    let mut x = [0.0; N];
    for i in (0..N).rev() {
        if !active[i] {
            continue;
        }
        let mut s = y[i];
        for k in i + 1..N {
            s -= a[k][i] * x[k];
        }
        x[i] = s / a[i][i];
    }
    let solution: [f64; N] = std::array::from_fn(|i| x[i] * scale[i]);
    solution.iter().all(|v| v.is_finite()).then_some(solution)
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
