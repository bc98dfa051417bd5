//! Small hand-built finite-element-like systems for the response tests: a pinned membrane
//! lattice (one z dof per node, springs between neighbours) with an optional "patch" region, and
//! dense eigenvectors as stand-in modes.
#![allow(dead_code)]

use dampscope::sim::system::{FeSystem, SensorWeights, Sls, StiffnessTerm};
use faer::sparse::{SparseColMat, Triplet};
use faer::{Mat, Side};

/// Lattice description.
pub struct Lattice {
    pub nx: usize,
    pub ny: usize,
    /// Node mass, kg.
    pub mass_kg: f64,
    /// Neighbour spring, N/m.
    pub k_n_per_m: f64,
    /// Plate loss factor.
    pub g_plate: f64,
    /// Patch node range (i0..i1, j0..j1) and its spring, loss factor, SLS.
    pub patch: Option<Patch>,
}

pub struct Patch {
    pub i: (usize, usize),
    pub j: (usize, usize),
    pub k_n_per_m: f64,
    pub g: f64,
    pub sls: Option<Sls>,
}

fn sparse(n: usize, t: &[Triplet<usize, usize, f64>]) -> SparseColMat<usize, f64> {
    SparseColMat::try_new_from_triplets(n, n, t).expect("valid triplets")
}

impl Lattice {
    /// Builds the system. Nodes with j = 0 or j = ny−1 are pinned (not free). Excitation: unit
    /// force at node (1, 1). Sensors: the driving point and the far corner (nx−2, ny−2).
    pub fn system(&self) -> FeSystem {
        let free = |i: usize, j: usize| -> Option<usize> {
            if j == 0 || j + 1 == self.ny {
                None
            } else {
                Some((j - 1) * self.nx + i)
            }
        };
        let n = self.nx * (self.ny - 2);
        let in_patch = |i: usize, j: usize| {
            self.patch
                .as_ref()
                .is_some_and(|p| i >= p.i.0 && i < p.i.1 && j >= p.j.0 && j < p.j.1)
        };
        let mut kp = Vec::new();
        let mut kq = Vec::new();
        let mut add = |a: (usize, usize), b: (usize, usize), patch: bool, k: f64| {
            let t = if patch { &mut kq } else { &mut kp };
            let (fa, fb) = (free(a.0, a.1), free(b.0, b.1));
            if let Some(x) = fa {
                t.push(Triplet::new(x, x, k));
            }
            if let Some(y) = fb {
                t.push(Triplet::new(y, y, k));
            }
            if let (Some(x), Some(y)) = (fa, fb) {
                t.push(Triplet::new(x, y, -k));
                t.push(Triplet::new(y, x, -k));
            }
        };
        for j in 0..self.ny {
            for i in 0..self.nx {
                for (di, dj) in [(1, 0), (0, 1)] {
                    let (i2, j2) = (i + di, j + dj);
                    if i2 >= self.nx || j2 >= self.ny {
                        continue;
                    }
                    let patch = in_patch(i, j) && in_patch(i2, j2);
                    let k = match (&self.patch, patch) {
                        (Some(p), true) => p.k_n_per_m,
                        _ => self.k_n_per_m,
                    };
                    add((i, j), (i2, j2), patch, k);
                }
            }
        }
        let mut terms = vec![StiffnessTerm {
            name: "plate".into(),
            matrix: sparse(n, &kp),
            loss_factor: self.g_plate,
            sls: None,
            reference_modulus_pa: 1.0,
        }];
        if let Some(p) = &self.patch {
            terms.push(StiffnessTerm {
                name: "patch 1".into(),
                matrix: sparse(n, &kq),
                loss_factor: p.g,
                sls: p.sls,
                reference_modulus_pa: p.sls.map_or(1.0, |s| s.e_inf),
            });
        }
        let mass: Vec<_> = (0..n).map(|d| Triplet::new(d, d, self.mass_kg)).collect();
        let mut force = vec![0.0; n];
        let drive = free(1, 1).expect("free");
        force[drive] = 1.0;
        let far = free(self.nx - 2, self.ny - 2).expect("free");
        FeSystem {
            n_free: n,
            mass: sparse(n, &mass),
            stiffness_terms: terms,
            rayleigh: None,
            force,
            sensors: vec![
                SensorWeights {
                    id: "drive".into(),
                    x_m: 1.0,
                    y_m: 1.0,
                    weights: vec![(drive, 1.0)],
                },
                SensorWeights {
                    id: "far".into(),
                    x_m: (self.nx - 2) as f64,
                    y_m: (self.ny - 2) as f64,
                    // an interpolated sensor: half-way between two nodes
                    weights: vec![(far, 0.5), (far - 1, 0.5)],
                },
            ],
        }
    }
}

/// Dense undamped modes of (K₀, M), mass-normalised, ascending: (frequencies_hz, shapes).
pub fn dense_modes(sys: &FeSystem) -> (Vec<f64>, Mat<f64>) {
    let n = sys.n_free;
    let mut k = Mat::<f64>::zeros(n, n);
    for t in &sys.stiffness_terms {
        k += t.matrix.to_dense();
    }
    let m = sys.mass.to_dense();
    // M⁻¹ᐟ² K M⁻¹ᐟ² with a diagonal M (the lattice is lumped)
    let s: Vec<f64> = (0..n).map(|i| 1.0 / m[(i, i)].sqrt()).collect();
    let a = Mat::from_fn(n, n, |i, j| s[i] * k[(i, j)] * s[j]);
    let evd = a.self_adjoint_eigen(Side::Lower).expect("eigen");
    let u = evd.U();
    let lam: Vec<f64> = evd.S().column_vector().iter().copied().collect();
    let freqs = lam
        .iter()
        .map(|l| l.max(0.0).sqrt() / (2.0 * std::f64::consts::PI))
        .collect();
    let shapes = Mat::from_fn(n, n, |i, j| s[i] * u[(i, j)]);
    (freqs, shapes)
}

/// The first `count` columns / frequencies of a mode set.
pub fn first_modes(freqs: &[f64], shapes: &Mat<f64>, count: usize) -> (Vec<f64>, Mat<f64>) {
    (freqs[..count].to_vec(), shapes.subcols(0, count).to_owned())
}

/// 0, df, …, fmax.
pub fn grid(df_hz: f64, fmax_hz: f64) -> Vec<f64> {
    let n = (fmax_hz / df_hz).round() as usize + 1;
    (0..n).map(|k| k as f64 * df_hz).collect()
}
