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
            // Two passes over the branch's samples rather than a copy of them.
            let on_branch = || (0..theta.len()).filter(move |&i| branch[i] == b);
            let (mut m, mut r) = ([[0.0; 2]; 2], [0.0; 2]);
            let mut n = 0;
            for i in on_branch() {
                let (x, t) = (theta[i], torque[i]);
                n += 1;
                m[0][0] += 1.0;
                m[0][1] += x;
                m[1][1] += x * x;
                r[0] += t;
                r[1] += x * t;
            }
            m[1][0] = m[0][1];
            let [intercept, slope] = solve_spd(m, r)?;
            let rss = on_branch().map(|i| (torque[i] - intercept - slope * theta[i]).powi(2)).sum();
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
    let sums = RegionSums::new(theta, torque)?;
    let a_max = theta[sums.order.last().copied()? as usize].abs();
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

/// Prefix sums over the samples sorted by |θ|: θ², θ·T, |θ|, sign·T (and the count, which is
/// the position). Kept every [`CHECKPOINT`] positions and completed from there when asked for:
/// the same additions in the same order as a sum per sample, which took 40 bytes a sample.
struct RegionSums<'a> {
    theta: &'a [f64],
    torque: &'a [f64],
    /// Sample indices in order of |θ|: u32, half the room of usize.
    order: Vec<u32>,
    /// The prefix sums before positions 0, CHECKPOINT, 2·CHECKPOINT, …
    checkpoints: Vec<[f64; 4]>,
    total_tt: f64,
}

/// Positions between two stored prefix sums.
const CHECKPOINT: usize = 32;

impl<'a> RegionSums<'a> {
    /// `None` beyond u32::MAX samples (hundreds of gigabytes of recording).
    fn new(theta: &'a [f64], torque: &'a [f64]) -> Option<Self> {
        let mut order: Vec<u32> = (0..u32::try_from(theta.len()).ok()?).collect();
        // Ties in index order, as a stable sort leaves them, without its buffer.
        order.sort_unstable_by(|&a, &b| theta[a as usize].abs().total_cmp(&theta[b as usize].abs()).then(a.cmp(&b)));
        let mut sums = RegionSums {
            theta,
            torque,
            checkpoints: Vec::with_capacity(order.len() / CHECKPOINT + 1),
            order,
            total_tt: torque.iter().map(|t| t * t).sum(),
        };
        let mut acc = [0.0; 4];
        for (k, &i) in sums.order.iter().enumerate() {
            if k % CHECKPOINT == 0 {
                sums.checkpoints.push(acc);
            }
            sums.add(&mut acc, i);
        }
        if sums.order.len() % CHECKPOINT == 0 {
            sums.checkpoints.push(acc);
        }
        Some(sums)
    }

    #[inline(always)]
    fn add(&self, acc: &mut [f64; 4], i: u32) {
        let (x, t) = (self.theta[i as usize], self.torque[i as usize]);
        let s = if x >= 0.0 { 1.0 } else { -1.0 };
        acc[0] += x * x;
        acc[1] += x * t;
        acc[2] += x.abs();
        acc[3] += s * t;
    }

    /// The sums over the first `position` samples in order of |θ|.
    fn prefix(&self, position: usize) -> [f64; 4] {
        let mut acc = self.checkpoints[position / CHECKPOINT];
        for &i in &self.order[position / CHECKPOINT * CHECKPOINT..position] {
            self.add(&mut acc, i);
        }
        acc
    }

    /// Count, θ², θ·T, |θ|, sign·T over positions `from..to`.
    fn range(&self, from: usize, to: usize) -> [f64; 5] {
        let (a, b) = (self.prefix(from), self.prefix(to));
        [to as f64 - from as f64, b[0] - a[0], b[1] - a[1], b[2] - a[2], b[3] - a[3]]
    }

    /// Samples with |θ| ≤ `bound`: a position in `order`.
    fn count_within(&self, bound: f64) -> usize {
        self.order.partition_point(|&i| self.theta[i as usize].abs() <= bound)
    }

    /// RSS and (K1, K2, K3) for breakpoints b1 < b2 in |θ|.
    fn solve(&self, b1: f64, b2: f64) -> Option<(f64, [f64; 3])> {
        let i1 = self.count_within(b1);
        let i2 = self.count_within(b2);
        let n = self.order.len();
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
    fn prefix_sums_from_checkpoints_are_the_running_sums() {
        // Lengths either side of a multiple of the checkpoint spacing, where the last prefix
        // is a stored one or completed from the one before.
        for n in [1, CHECKPOINT - 1, CHECKPOINT, 2 * CHECKPOINT, 2 * CHECKPOINT + 1] {
            let theta: Vec<f64> = (0..n).map(|i| ((i * 7919) % 101) as f64 * 1e-5 - 5e-4).collect();
            let torque: Vec<f64> = (0..n).map(|i| (i as f64 * 0.37).sin()).collect();
            let sums = RegionSums::new(&theta, &torque).unwrap();
            let mut running = [0.0; 4];
            for position in 0..=n {
                assert_eq!(sums.prefix(position), running, "n {n} position {position}");
                if let Some(&i) = sums.order.get(position) {
                    sums.add(&mut running, i);
                }
            }
            assert!(sums.order.windows(2).all(|w| theta[w[0] as usize].abs() <= theta[w[1] as usize].abs()));
        }
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
