//! The per-frequency solve of the interface form: assemble the interface dynamic stiffness as
//! constant terms plus rank-one modal terms, one dense LU, then every modal coordinate.

use faer::linalg::matmul::triangular::{matmul as tri_matmul, BlockStructure};
use faer::{c64, Accum, Mat, MatMut, Par};

use super::super::factored::{FactoredFrf, FrfSolve};
use super::super::frf::{validate_frequencies, FrfError};
use super::super::reduced::lu_solve_sequential;
use super::blocks::BLOCK_FREQUENCIES;
use super::{ldlt, InterfaceModel};

/// Working matrices of one thread's frequencies (allocated once per thread: allocating them per
/// frequency would fault fresh pages in at every one). Interface matrices are kept as
/// column-major r × r slices whose lower triangles are used.
pub(super) struct Scratch {
    z_re: Vec<f64>,
    z_im: Vec<f64>,
    scaled_re: Mat<f64>,
    scaled_im: Mat<f64>,
    gathered: Mat<f64>,
    z: Mat<c64>,
    panel: Mat<c64>,
}

impl Scratch {
    pub(super) fn new(model: &InterfaceModel) -> Self {
        let r = model.interface_dofs;
        let widest = model
            .groups
            .iter()
            .map(|g| g.eigenvalues.len())
            .max()
            .unwrap_or(0);
        Scratch {
            z_re: vec![0.0; r * r],
            z_im: vec![0.0; r * r],
            scaled_re: Mat::zeros(r, widest),
            scaled_im: Mat::zeros(r, widest),
            gathered: Mat::zeros(r, widest),
            z: Mat::zeros(r, r),
            panel: Mat::zeros(r, ldlt::PANEL),
        }
    }

    /// The complex interface matrix the factorisation works in, and its panel scratch.
    pub(super) fn complex_mut(&mut self) -> (&mut Mat<c64>, &mut Mat<c64>) {
        (&mut self.z, &mut self.panel)
    }
}

/// dst[j.., j] += a · src[j.., j] for every column j: the lower triangle of an r × r
/// column-major slice plus a multiple of a matrix's.
pub(super) fn add_lower(dst: &mut [f64], src: &Mat<f64>, a: f64) {
    let r = src.nrows();
    for j in 0..r {
        let d = &mut dst[j * r + j..(j + 1) * r];
        for (x, y) in d.iter_mut().zip(&src.col_as_slice(j)[j..]) {
            *x += a * y;
        }
    }
}

/// How the modal terms of the interface dynamic stiffness are summed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ModalSums {
    /// Every mode at every frequency (the oracle).
    Exact,
    /// Modes far from a block of frequencies interpolated from Chebyshev nodes
    /// ([`super::blocks`]), the rest exact.
    Interpolated,
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

    /// Adds the constant and per-region terms of the interface dynamic stiffness at ω to
    /// (`z_re`, `z_im`), lower triangles.
    pub(super) fn add_interface_base(&self, omega: f64, z_re: &mut [f64], z_im: &mut [f64]) {
        let kc = factor(&self.groups[0].factor, omega);
        add_lower(z_re, &self.plate_stiffness, kc.re);
        add_lower(z_re, &self.mass, -omega * omega);
        add_lower(z_im, &self.plate_stiffness, kc.im);
        for (t, k) in &self.region_stiffness {
            let kr = factor(t, omega);
            add_lower(z_re, k, kr.re);
            add_lower(z_im, k, kr.im);
        }
    }

    /// Adds Σ_{j ∈ cols} c_j a_j a_jᵀ of group `g` (lower triangles; `c` indexed by mode).
    pub(super) fn add_selected_terms(
        &self,
        g: usize,
        cols: &[usize],
        c: &[c64],
        s: &mut Scratch,
        z_re: &mut [f64],
        z_im: &mut [f64],
    ) {
        if cols.is_empty() {
            return;
        }
        let a = &self.groups[g].coupling;
        let (r, k) = (a.nrows(), cols.len());
        for (at, &j) in cols.iter().enumerate() {
            let (cr, ci) = (c[j].re, c[j].im);
            let src = a.col_as_slice(j);
            let gathered = s.gathered.col_as_slice_mut(at);
            gathered.copy_from_slice(src);
            for (x, &v) in s.scaled_re.col_as_slice_mut(at).iter_mut().zip(src) {
                *x = v * cr;
            }
            for (x, &v) in s.scaled_im.col_as_slice_mut(at).iter_mut().zip(src) {
                *x = v * ci;
            }
        }
        let gathered = s.gathered.as_ref().subcols(0, k);
        for (dst, src) in [(z_re, &s.scaled_re), (z_im, &s.scaled_im)] {
            tri_matmul(
                MatMut::from_column_major_slice_mut(dst, r, r),
                BlockStructure::TriangularLower,
                Accum::Add,
                src.as_ref().subcols(0, k),
                BlockStructure::Rectangular,
                gathered.transpose(),
                BlockStructure::Rectangular,
                1.0,
                Par::Seq,
            );
        }
    }

    /// Every basis coordinate [u_Γ | group modes …] at ω, the modal sums done term by term.
    pub(super) fn solve_exact(&self, omega: f64, s: &mut Scratch) -> Result<Vec<c64>, FrfError> {
        let den = self.modal_denominators(omega);
        let w4 = omega.powi(4);
        let mut z_re = std::mem::take(&mut s.z_re);
        let mut z_im = std::mem::take(&mut s.z_im);
        z_re.iter_mut().for_each(|x| *x = 0.0);
        z_im.iter_mut().for_each(|x| *x = 0.0);
        self.add_interface_base(omega, &mut z_re, &mut z_im);
        for (g, d) in den.iter().enumerate() {
            let c: Vec<c64> = d.iter().map(|x| x * (-w4)).collect();
            let all: Vec<usize> = (0..c.len()).collect();
            self.add_selected_terms(g, &all, &c, s, &mut z_re, &mut z_im);
        }
        let out = self.finish(omega, &den, &z_re, &z_im, (&mut s.z, &mut s.panel));
        s.z_re = z_re;
        s.z_im = z_im;
        out
    }

    /// Solves the assembled interface system (lower triangles of the column-major `z_re`,
    /// `z_im`) and recovers the modal coordinates.
    pub(super) fn finish(
        &self,
        omega: f64,
        den: &[Vec<c64>],
        z_re: &[f64],
        z_im: &[f64],
        (z, panel): (&mut Mat<c64>, &mut Mat<c64>),
    ) -> Result<Vec<c64>, FrfError> {
        let r = self.interface_dofs;
        let w2 = omega * omega;
        for j in 0..r {
            for i in j..r {
                z[(i, j)] = c64::new(z_re[j * r + i], z_im[j * r + i]);
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
        let b: Vec<c64> = rhs.col(0).iter().copied().collect();
        let mut u = b.clone();
        let by_ldlt = ldlt::factor_in_place(z, panel) && {
            ldlt::solve_in_place(z, &mut u);
            ldlt::relative_residual(z_re, z_im, &u, &b) <= ldlt::RESIDUAL_TOLERANCE
        };
        if !by_ldlt {
            for j in 0..r {
                for i in j..r {
                    let v = c64::new(z_re[j * r + i], z_im[j * r + i]);
                    z[(i, j)] = v;
                    z[(j, i)] = v;
                }
            }
            u = lu_solve_sequential(z, rhs.as_ref());
        }
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
                let au: c64 = u
                    .iter()
                    .zip(g.coupling.col_as_slice(j))
                    .map(|(x, &a)| x * a)
                    .sum();
                out.push(dj * (au * w2 + g.load[j]));
            }
        }
        Ok(out)
    }

    /// Receptance at every sensor and frequency as modal responses × sensor weights, the
    /// modal sums interpolated where exact ([`super::blocks`]), the frequencies split over two
    /// threads.
    pub fn factored_frf(&self, freqs_hz: &[f64]) -> Result<FactoredFrf, FrfError> {
        self.factored_frf_with(freqs_hz, ModalSums::Interpolated)
    }

    /// [`Self::factored_frf`] with the modal sums done as `sums` says.
    pub fn factored_frf_with(
        &self,
        freqs_hz: &[f64],
        sums: ModalSums,
    ) -> Result<FactoredFrf, FrfError> {
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
                        let omegas: Vec<f64> =
                            part.iter().map(|&f| std::f64::consts::TAU * f).collect();
                        let mut rows = Vec::with_capacity(part.len());
                        for block in omegas.chunks(BLOCK_FREQUENCIES) {
                            match sums {
                                ModalSums::Interpolated => {
                                    rows.extend(self.solve_block(block, &mut s)?)
                                }
                                ModalSums::Exact => {
                                    for &w in block {
                                        rows.push(self.solve_exact(w, &mut s)?);
                                    }
                                }
                            }
                        }
                        Ok(rows)
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
