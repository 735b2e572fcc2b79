//! The models a gear engineer would otherwise use, fitted to the same data.
use crate::input::Branch;
use crate::numeric::linalg::solve_spd;

/// One straight line T = intercept + stiffness·θ on one branch.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct BranchLine {
    pub branch: &'static str,
    pub intercept_nm: f64,
    pub stiffness_nm_per_rad: f64,
    pub n: usize,
    pub rss: f64,
}

/// A separate least-squares line for each branch present in the data.
pub fn lines_per_branch(theta: &[f64], torque: &[f64], branch: &[Branch]) -> Vec<BranchLine> {
    Branch::ALL
        .iter()
        .filter_map(|&b| {
            let points: Vec<(f64, f64)> =
                (0..theta.len()).filter(|&i| branch[i] == b).map(|i| (theta[i], torque[i])).collect();
            let n = points.len();
            let (mut m, mut r) = ([[0.0; 2]; 2], [0.0; 2]);
            for &(x, t) in &points {
                m[0][0] += 1.0;
                m[0][1] += x;
                m[1][1] += x * x;
                r[0] += t;
                r[1] += x * t;
            }
            m[1][0] = m[0][1];
            let [intercept, slope] = solve_spd(m, r)?;
            let rss = points.iter().map(|(x, t)| (t - intercept - slope * x).powi(2)).sum();
            Some(BranchLine { branch: b.name(), intercept_nm: intercept, stiffness_nm_per_rad: slope, n, rss })
        })
        .collect()
}

/// The catalogue stiffness curve of strain wave gears: odd-symmetric, through the origin,
/// stiffness K1 up to torque T1, K2 up to T2, K3 beyond.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct ThreeSegment {
    pub t1_nm: f64,
    pub t2_nm: f64,
    pub k1_nm_per_rad: f64,
    pub k2_nm_per_rad: f64,
    pub k3_nm_per_rad: f64,
    pub rss: f64,
}

/// Least-squares three-segment curve. For fixed breakpoints (in deflection) it is linear in
/// K1, K2, K3; prefix sums over the samples sorted by |θ| make each breakpoint pair O(log n),
/// so a grid plus a pattern search finds the best pair.
pub fn three_segment(theta: &[f64], torque: &[f64]) -> Option<ThreeSegment> {
    let sums = RegionSums::new(theta, torque);
    let a_max = sums.abs_theta.last().copied()?;
    if !(a_max > 0.0) {
        return None;
    }
    const GRID: usize = 64;
    let mut best = (f64::INFINITY, 0.0, 0.0);
    for i in 1..GRID {
        for j in i + 1..=GRID {
            let (b1, b2) = (a_max * i as f64 / GRID as f64, a_max * j as f64 / GRID as f64);
            if let Some((rss, _)) = sums.solve(b1, b2) {
                if rss < best.0 {
                    best = (rss, b1, b2);
                }
            }
        }
    }
    let mut step = a_max / GRID as f64;
    while step > 1e-9 * a_max {
        let (rss0, b1, b2) = best;
        for (d1, d2) in [(step, 0.0), (-step, 0.0), (0.0, step), (0.0, -step), (step, step), (-step, -step)] {
            let (c1, c2) = (b1 + d1, b2 + d2);
            if c1 > 0.0 && c2 > c1 {
                if let Some((rss, _)) = sums.solve(c1, c2) {
                    if rss < best.0 {
                        best = (rss, c1, c2);
                    }
                }
            }
        }
        if best.0 >= rss0 {
            step /= 2.0;
        }
    }
    let (rss, b1, b2) = best;
    let (_, [k1, k2, k3]) = sums.solve(b1, b2)?;
    let t1 = k1 * b1;
    Some(ThreeSegment {
        t1_nm: t1,
        t2_nm: t1 + k2 * (b2 - b1),
        k1_nm_per_rad: k1,
        k2_nm_per_rad: k2,
        k3_nm_per_rad: k3,
        rss,
    })
}

/// Prefix sums over samples sorted by |θ|: count, θ², θ·T, |θ|, sign·T.
struct RegionSums {
    abs_theta: Vec<f64>,
    prefix: Vec<[f64; 5]>,
    total_tt: f64,
}

impl RegionSums {
    fn new(theta: &[f64], torque: &[f64]) -> Self {
        let mut order: Vec<usize> = (0..theta.len()).collect();
        order.sort_by(|&a, &b| theta[a].abs().total_cmp(&theta[b].abs()));
        let mut prefix = vec![[0.0; 5]];
        let mut acc = [0.0; 5];
        for &i in &order {
            let (x, t) = (theta[i], torque[i]);
            let s = if x >= 0.0 { 1.0 } else { -1.0 };
            acc[0] += 1.0;
            acc[1] += x * x;
            acc[2] += x * t;
            acc[3] += x.abs();
            acc[4] += s * t;
            prefix.push(acc);
        }
        RegionSums {
            abs_theta: order.iter().map(|&i| theta[i].abs()).collect(),
            prefix,
            total_tt: torque.iter().map(|t| t * t).sum(),
        }
    }

    fn range(&self, from: usize, to: usize) -> [f64; 5] {
        std::array::from_fn(|k| self.prefix[to][k] - self.prefix[from][k])
    }

    /// RSS and (K1, K2, K3) for breakpoints b1 < b2 in |θ|.
    fn solve(&self, b1: f64, b2: f64) -> Option<(f64, [f64; 3])> {
        let i1 = self.abs_theta.partition_point(|&a| a <= b1);
        let i2 = self.abs_theta.partition_point(|&a| a <= b2);
        let n = self.abs_theta.len();
        let [_, xx1, xt1, _, _] = self.range(0, i1);
        let [n2, xx2, xt2, ax2, st2] = self.range(i1, i2);
        let [n3, xx3, xt3, ax3, st3] = self.range(i2, n);
        let d = b2 - b1;
        // Rows: region 1 (θ, 0, 0); region 2 (s·b1, θ − s·b1, 0); region 3 (s·b1, s·d, θ − s·b2).
        let m = [
            [xx1 + (n2 + n3) * b1 * b1, b1 * ax2 - n2 * b1 * b1 + n3 * b1 * d, b1 * (ax3 - n3 * b2)],
            [0.0, xx2 - 2.0 * b1 * ax2 + n2 * b1 * b1 + n3 * d * d, d * (ax3 - n3 * b2)],
            [0.0, 0.0, xx3 - 2.0 * b2 * ax3 + n3 * b2 * b2],
        ];
        let m = [[m[0][0], m[0][1], m[0][2]], [m[0][1], m[1][1], m[1][2]], [m[0][2], m[1][2], m[2][2]]];
        let r = [xt1 + b1 * (st2 + st3), xt2 - b1 * st2 + d * st3, xt3 - b2 * st3];
        let k = solve_spd(m, r)?;
        let explained: f64 = k.iter().zip(r).map(|(a, b)| a * b).sum();
        Some(((self.total_tt - explained).max(0.0), k))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn three_segment_recovers_a_catalogue_curve() {
        let (k1, k2, k3, t1, t2) = (1.0e4, 2.0e4, 3.0e4, 5.0, 15.0);
        let b1 = t1 / k1;
        let b2 = b1 + (t2 - t1) / k2;
        let curve = |x: f64| {
            let a = x.abs();
            let t = if a <= b1 {
                k1 * a
            } else if a <= b2 {
                t1 + k2 * (a - b1)
            } else {
                t2 + k3 * (a - b2)
            };
            t.copysign(x)
        };
        let theta: Vec<f64> = (-200..=200).map(|i| i as f64 * 7e-6 + 1e-7).collect();
        let torque: Vec<f64> = theta.iter().map(|&x| curve(x)).collect();
        let fit = three_segment(&theta, &torque).unwrap();
        assert!(fit.rss < 1e-6, "{fit:?}");
        assert!((fit.t1_nm - t1).abs() < 1e-3 && (fit.t2_nm - t2).abs() < 1e-3, "{fit:?}");
        assert!((fit.k3_nm_per_rad - k3).abs() < 1e-3 * k3);
    }

    #[test]
    fn one_line_per_branch() {
        let theta = [0.0, 1.0, 2.0, 2.0, 1.0, 0.0];
        let torque = [1.0, 3.0, 5.0, 4.0, 2.0, 0.0];
        let branch = [Branch::ForwardLoading; 3].into_iter().chain([Branch::ForwardUnloading; 3]).collect::<Vec<_>>();
        let lines = lines_per_branch(&theta, &torque, &branch);
        assert_eq!(lines.len(), 2);
        assert!((lines[0].stiffness_nm_per_rad - 2.0).abs() < 1e-12 && (lines[0].intercept_nm - 1.0).abs() < 1e-12);
        assert!((lines[1].stiffness_nm_per_rad - 2.0).abs() < 1e-12 && lines[1].intercept_nm.abs() < 1e-12);
    }
}
