//! The stabilisation diagram read automatically: a pole is *stable* when the next lower order
//! has one with nearly the same frequency, damping and shape; stable poles are clustered over
//! the orders, and a cluster seen at enough orders is a physical mode. Noise and
//! computational poles wander from order to order and never gather enough.

use super::subspace::{mac, Pole};

/// Stability and clustering criteria (defaults within the ranges METHODS.md §7 cites from
/// pyOMA2 and the stabilisation-diagram literature: 1 % in f, 10 % in D, MAC 0.9). Measured on
/// a 99-sensor plate at 35 dB: the stricter 5 % / 0.97 lost 2–5 of 8 modes; 20 % / 0.8 let in
/// 2–4 spurious ones.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct StabilityCriteria {
    /// Largest |Δf|/f between consecutive orders (0.01).
    pub frequency_rel: f64,
    /// Largest |ΔD|/D between consecutive orders (0.1).
    pub damping_rel: f64,
    /// Smallest MAC between consecutive orders' shapes (0.9).
    pub mac_min: f64,
    /// Physical damping ratios lie in `0 < D < damping_max` (0.2).
    pub damping_max: f64,
    /// A cluster is a mode when it holds stable poles from at least this fraction of the
    /// orders swept (0.2).
    pub min_stable_fraction: f64,
    /// A mode whose shape's MPC is below [`NOISE_MPC_SCALE`]` / channels`, clamped to
    /// `mpc_min_threshold..=mpc_max_threshold`, is no mode: a pole fitted to noise or a spare
    /// pole beside a close pair (0.5).
    pub mpc_max_threshold: f64,
    /// Lower clamp of the MPC threshold (0.3): with many channels the noise quantile alone
    /// (0.14 for 99) let through a persistent spare pole of MPC 0.16 beside the 57 Hz pair of a
    /// Rayleigh-damped plate, whose true modes all have MPC > 0.95.
    pub mpc_min_threshold: f64,
}

/// The MPC of a shape of independent complex Gaussian components over `n` channels is
/// roughly exponential with mean 2/n; its 99.9 % quantile is about 2 ln(1000)/n ≈ 13.8/n
/// (Monte Carlo: 0.126 for 99 channels, 0.36 for 32, 0.58 for 16). Shapes less collinear than
/// that are noise.
pub const NOISE_MPC_SCALE: f64 = 13.8;

impl StabilityCriteria {
    /// The MPC below which a mode over `channels` channels is taken for noise.
    pub fn noise_mpc(&self, channels: usize) -> f64 {
        (NOISE_MPC_SCALE / channels.max(1) as f64)
            .max(self.mpc_min_threshold)
            .min(self.mpc_max_threshold)
    }
}

impl Default for StabilityCriteria {
    fn default() -> Self {
        StabilityCriteria {
            frequency_rel: 0.01,
            damping_rel: 0.1,
            mac_min: 0.9,
            damping_max: 0.2,
            min_stable_fraction: 0.2,
            mpc_max_threshold: 0.5,
            mpc_min_threshold: 0.3,
        }
    }
}

/// What the diagram says about one pole (for the stabilisation plot).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PoleClass {
    /// Outside the band or with an unphysical damping ratio.
    Rejected,
    /// Physical but without a match at the next lower order.
    Unstable,
    /// Matched in frequency, damping and shape at the next lower order.
    Stable,
}

/// A cluster of stable poles: one candidate mode.
#[derive(Clone, Debug)]
pub struct Cluster {
    /// The poles, at most one per order.
    pub poles: Vec<Pole>,
}

impl Cluster {
    /// Median of a pole quantity over the cluster.
    pub fn median(&self, value: impl Fn(&Pole) -> f64) -> f64 {
        let mut v: Vec<f64> = self.poles.iter().map(value).collect();
        v.sort_by(f64::total_cmp);
        let n = v.len();
        if n % 2 == 1 {
            v[n / 2]
        } else {
            0.5 * (v[n / 2 - 1] + v[n / 2])
        }
    }

    /// Sample standard deviation of a pole quantity over the cluster (0 for one pole).
    pub fn std(&self, value: impl Fn(&Pole) -> f64) -> f64 {
        let v: Vec<f64> = self.poles.iter().map(value).collect();
        let n = v.len() as f64;
        if v.len() < 2 {
            return 0.0;
        }
        let mean = v.iter().sum::<f64>() / n;
        (v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1.0)).sqrt()
    }

    /// The pole whose damping ratio is the cluster's median (its representative shape).
    pub fn representative(&self) -> &Pole {
        let d = self.median(|p| p.damping_ratio);
        self.poles
            .iter()
            .min_by(|a, b| {
                (a.damping_ratio - d)
                    .abs()
                    .total_cmp(&(b.damping_ratio - d).abs())
            })
            .expect("clusters are never empty")
    }
}

fn physical(p: &Pole, lo_hz: f64, hi_hz: f64, c: &StabilityCriteria) -> bool {
    p.f_hz >= lo_hz && p.f_hz < hi_hz && p.damping_ratio > 0.0 && p.damping_ratio < c.damping_max
}

fn matches(a: &Pole, b: &Pole, c: &StabilityCriteria) -> bool {
    (a.f_hz - b.f_hz).abs() <= c.frequency_rel * a.f_hz.abs()
        && (a.damping_ratio - b.damping_ratio).abs() <= c.damping_rel * a.damping_ratio
        && mac(&a.shape, &b.shape) >= c.mac_min
}

/// Classifies every pole of `by_order` (ascending orders) for the band `lo_hz..hi_hz`.
pub fn classify(
    by_order: &[Vec<Pole>],
    lo_hz: f64,
    hi_hz: f64,
    c: &StabilityCriteria,
) -> Vec<Vec<PoleClass>> {
    by_order
        .iter()
        .enumerate()
        .map(|(i, poles)| {
            poles
                .iter()
                .map(|p| {
                    if !physical(p, lo_hz, hi_hz, c) {
                        PoleClass::Rejected
                    } else if i > 0 && by_order[i - 1].iter().any(|q| matches(p, q, c)) {
                        PoleClass::Stable
                    } else {
                        PoleClass::Unstable
                    }
                })
                .collect()
        })
        .collect()
}

/// Joins clusters that are one mode seen in pieces: a mode whose pole misses the stability
/// test at one order starts a new cluster at the next. Two clusters are one mode when they
/// never hold a pole of the same order and their median poles match in frequency and shape.
fn merge_fragments(mut clusters: Vec<Cluster>, c: &StabilityCriteria) -> Vec<Cluster> {
    clusters.sort_by_key(|c| std::cmp::Reverse(c.poles.len()));
    let mut merged: Vec<Cluster> = Vec::new();
    for cl in clusters {
        let f = cl.median(|p| p.f_hz);
        let target = merged.iter_mut().find(|m| {
            let fm = m.median(|p| p.f_hz);
            let disjoint = cl
                .poles
                .iter()
                .all(|p| m.poles.iter().all(|q| q.order != p.order));
            disjoint
                && (f - fm).abs() <= c.frequency_rel * fm.abs()
                && mac(&cl.representative().shape, &m.representative().shape) >= c.mac_min
        });
        match target {
            Some(m) => {
                m.poles.extend(cl.poles);
                m.poles.sort_by_key(|p| p.order);
            }
            None => merged.push(cl),
        }
    }
    merged
}

/// The stable poles clustered over the orders, split into *modes* (clusters seen at enough
/// orders, see [`StabilityCriteria::min_stable_fraction`]) and *candidates* (clusters of at
/// least two poles that are not; a close mode often stabilises only at the highest orders),
/// each sorted by frequency.
pub fn select_modes(
    by_order: &[Vec<Pole>],
    classes: &[Vec<PoleClass>],
    c: &StabilityCriteria,
) -> (Vec<Cluster>, Vec<Cluster>) {
    let mut clusters: Vec<Cluster> = Vec::new();
    for (poles, class) in by_order.iter().zip(classes) {
        let stable: Vec<&Pole> = poles
            .iter()
            .zip(class)
            .filter(|(_, k)| **k == PoleClass::Stable)
            .map(|(p, _)| p)
            .collect();
        // Each cluster takes at most one pole of this order: the closest that matches it.
        let mut taken = vec![false; clusters.len()];
        for p in stable {
            let best = clusters
                .iter()
                .enumerate()
                .filter(|(i, _)| !taken[*i])
                .filter_map(|(i, cl)| {
                    let last = cl.poles.last().expect("clusters are never empty");
                    let df = (p.f_hz - last.f_hz).abs() / p.f_hz.abs();
                    let m = mac(&p.shape, &last.shape);
                    (df <= c.frequency_rel && m >= c.mac_min).then_some((i, df + (1.0 - m)))
                })
                .min_by(|a, b| a.1.total_cmp(&b.1));
            match best {
                Some((i, _)) => {
                    clusters[i].poles.push(p.clone());
                    taken[i] = true;
                }
                None => {
                    clusters.push(Cluster {
                        poles: vec![p.clone()],
                    });
                    taken.push(true);
                }
            }
        }
    }
    let clusters = merge_fragments(clusters, c);
    let min = ((c.min_stable_fraction * by_order.len() as f64).ceil() as usize).max(2);
    let (mut modes, mut candidates): (Vec<Cluster>, Vec<Cluster>) = clusters
        .into_iter()
        .filter(|cl| cl.poles.len() >= 2)
        .partition(|cl| cl.poles.len() >= min);
    for v in [&mut modes, &mut candidates] {
        v.sort_by(|a, b| a.median(|p| p.f_hz).total_cmp(&b.median(|p| p.f_hz)));
    }
    (modes, candidates)
}
