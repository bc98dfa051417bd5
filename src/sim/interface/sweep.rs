//! The per-frequency solve of the interface form: assemble the interface dynamic stiffness as
//! constant terms plus rank-one modal terms, one dense LU, then every modal coordinate.

use faer::linalg::matmul::triangular::{matmul as tri_matmul, BlockStructure};
use faer::{c64, Accum, Mat, Par};

use super::super::factored::{FactoredFrf, FrfSolve};
use super::super::frf::{validate_frequencies, FrfError};
use super::super::reduced::lu_solve_sequential;
use super::InterfaceModel;

/// Working matrices of one thread's frequencies (allocated once per thread: allocating them per
/// frequency would fault fresh pages in at every one).
pub(super) struct Scratch {
    z_re: Mat<f64>,
    z_im: Mat<f64>,
    scaled_re: Vec<Mat<f64>>,
    scaled_im: Vec<Mat<f64>>,
    z: Mat<c64>,
}

impl Scratch {
    pub(super) fn new(model: &InterfaceModel) -> Self {
        let r = model.interface_dofs;
        let per_group = |g: &super::ModalGroup| Mat::<f64>::zeros(r, g.eigenvalues.len());
        Scratch {
            z_re: Mat::zeros(r, r),
            z_im: Mat::zeros(r, r),
            scaled_re: model.groups.iter().map(per_group).collect(),
            scaled_im: model.groups.iter().map(per_group).collect(),
            z: Mat::zeros(r, r),
        }
    }
}

/// k(ω) of a term as a complex number.
fn factor(t: &super::super::system::StiffnessTerm, omega: f64) -> c64 {
    let (a, b) = t.factor(omega);
    c64::new(a, b)
}

impl InterfaceModel {
    /// 1/(k_g(ω) λ_j − ω²) for every mode of every group.
    pub(super) fn modal_denominators(&self, omega: f64) -> Vec<Vec<c64>> {
        self.groups
            .iter()
            .map(|g| {
                let k = factor(&g.factor, omega);
                g.eigenvalues
                    .iter()
                    .map(|&l| c64::new(1.0, 0.0) / (k * l - c64::new(omega * omega, 0.0)))
                    .collect()
            })
            .collect()
    }

    /// The constant and per-region terms of the interface dynamic stiffness at ω into
    /// (`z_re`, `z_im`), lower triangles.
    pub(super) fn interface_base(&self, omega: f64, z_re: &mut Mat<f64>, z_im: &mut Mat<f64>) {
        let r = self.interface_dofs;
        let kc = factor(&self.groups[0].factor, omega);
        let w2 = omega * omega;
        for j in 0..r {
            for i in j..r {
                z_re[(i, j)] = kc.re * self.plate_stiffness[(i, j)] - w2 * self.mass[(i, j)];
                z_im[(i, j)] = kc.im * self.plate_stiffness[(i, j)];
            }
        }
        for (t, k) in &self.region_stiffness {
            let kr = factor(t, omega);
            for j in 0..r {
                for i in j..r {
                    z_re[(i, j)] += kr.re * k[(i, j)];
                    z_im[(i, j)] += kr.im * k[(i, j)];
                }
            }
        }
    }

    /// Adds Σ_j c_j a_j a_jᵀ of group `g` (lower triangles).
    pub(super) fn add_modal_terms(
        &self,
        g: usize,
        coefficients: &[c64],
        scratch: (&mut Mat<f64>, &mut Mat<f64>),
        z_re: &mut Mat<f64>,
        z_im: &mut Mat<f64>,
    ) {
        let a = &self.groups[g].coupling;
        let (sre, sim) = scratch;
        for (j, c) in coefficients.iter().enumerate() {
            for i in 0..a.nrows() {
                sre[(i, j)] = a[(i, j)] * c.re;
                sim[(i, j)] = a[(i, j)] * c.im;
            }
        }
        for (dst, src) in [(z_re, &*sre), (z_im, &*sim)] {
            tri_matmul(
                dst.as_mut(),
                BlockStructure::TriangularLower,
                Accum::Add,
                src.as_ref(),
                BlockStructure::Rectangular,
                a.transpose(),
                BlockStructure::Rectangular,
                1.0,
                Par::Seq,
            );
        }
    }

    /// Every basis coordinate [u_Γ | group modes …] at ω, the modal sums done term by term.
    pub(super) fn solve_exact(&self, omega: f64, s: &mut Scratch) -> Result<Vec<c64>, FrfError> {
        let den = self.modal_denominators(omega);
        let w2 = omega * omega;
        let w4 = w2 * w2;
        let Scratch {
            z_re,
            z_im,
            scaled_re,
            scaled_im,
            z,
        } = s;
        self.interface_base(omega, z_re, z_im);
        for (g, d) in den.iter().enumerate() {
            let c: Vec<c64> = d.iter().map(|x| x * (-w4)).collect();
            self.add_modal_terms(g, &c, (&mut scaled_re[g], &mut scaled_im[g]), z_re, z_im);
        }
        self.finish(omega, &den, z_re, z_im, z)
    }

    /// Solves the assembled interface system (lower triangles of `z_re`, `z_im`) and recovers
    /// the modal coordinates.
    pub(super) fn finish(
        &self,
        omega: f64,
        den: &[Vec<c64>],
        z_re: &Mat<f64>,
        z_im: &Mat<f64>,
        z: &mut Mat<c64>,
    ) -> Result<Vec<c64>, FrfError> {
        let r = self.interface_dofs;
        let w2 = omega * omega;
        for j in 0..r {
            for i in j..r {
                let v = c64::new(z_re[(i, j)], z_im[(i, j)]);
                z[(i, j)] = v;
                z[(j, i)] = v;
            }
        }
        let mut rhs = Mat::<c64>::from_fn(r, 1, |i, _| c64::new(self.load[i], 0.0));
        for (g, d) in self.groups.iter().zip(den) {
            for (j, dj) in d.iter().enumerate() {
                if g.load[j] != 0.0 {
                    let c = dj * (w2 * g.load[j]);
                    for i in 0..r {
                        rhs[(i, 0)] += c * g.coupling[(i, j)];
                    }
                }
            }
        }
        let u = lu_solve_sequential(z, rhs.as_ref());
        if u.iter().any(|x| !x.re.is_finite() || !x.im.is_finite()) {
            return Err(FrfError::Factorisation {
                what: format!(
                    "interface dynamic stiffness at {} Hz",
                    omega / std::f64::consts::TAU
                ),
                message: "singular (non-finite solution)".into(),
            });
        }
        let mut out = Vec::with_capacity(self.basis_size());
        out.extend_from_slice(&u);
        for (g, d) in self.groups.iter().zip(den) {
            for (j, dj) in d.iter().enumerate() {
                let mut au = c64::new(0.0, 0.0);
                for i in 0..r {
                    au += u[i] * g.coupling[(i, j)];
                }
                out.push(dj * (au * w2 + g.load[j]));
            }
        }
        Ok(out)
    }

    /// Receptance at every sensor and frequency as modal responses × sensor weights, the
    /// frequencies split over two threads.
    pub fn factored_frf(&self, freqs_hz: &[f64]) -> Result<FactoredFrf, FrfError> {
        validate_frequencies(freqs_hz)?;
        let m = self.basis_size();
        let threads = 2usize;
        let chunk = freqs_hz.len().div_ceil(threads).max(1);
        let parts: Vec<Result<Vec<Vec<c64>>, FrfError>> = std::thread::scope(|sc| {
            let handles: Vec<_> = freqs_hz
                .chunks(chunk)
                .map(|part| {
                    sc.spawn(move || {
                        let mut s = Scratch::new(self);
                        part.iter()
                            .map(|&f| self.solve_exact(std::f64::consts::TAU * f, &mut s))
                            .collect()
                    })
                })
                .collect();
            handles
                .into_iter()
                .map(|h| {
                    h.join().unwrap_or_else(|_| {
                        Err(FrfError::Invalid {
                            what: "interface sweep".into(),
                            message: "a frequency worker panicked".into(),
                        })
                    })
                })
                .collect()
        });
        let mut modal = Mat::<c64>::zeros(freqs_hz.len(), m);
        let mut row = 0;
        for p in parts {
            for x in p? {
                for (j, v) in x.into_iter().enumerate() {
                    modal[(row, j)] = v;
                }
                row += 1;
            }
        }
        let weights = Mat::<c64>::from_fn(self.weights.nrows(), m, |i, j| {
            c64::new(self.weights[(i, j)], 0.0)
        });
        Ok(FactoredFrf {
            frequencies_hz: freqs_hz.to_vec(),
            sensor_ids: self.sensor_ids.clone(),
            modal,
            weights,
            solve: FrfSolve::Interface {
                interface_dofs: self.interface_dofs,
                modes: m - self.interface_dofs,
            },
        })
    }
}
