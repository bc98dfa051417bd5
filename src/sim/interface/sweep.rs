//! The per-frequency solve of the interface form: assemble the interface dynamic stiffness as
//! constant terms plus rank-one modal terms, one complex symmetric LDLᵀ (checked, else the
//! pivoting LU), then every modal coordinate.

use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};

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
    pub(super) z: Mat<c64>,
    pub(super) panel: Mat<c64>,
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
}

/// The rows × 2·nb real matrix whose column b is Re v(·, b) and column nb + b is Im v(·, b):
/// complex vectors of nb frequencies laid out for one real product with a real matrix.
fn re_im_columns(rows: usize, nb: usize, v: impl Fn(usize, usize) -> c64) -> Mat<f64> {
    Mat::from_fn(rows, 2 * nb, |i, c| {
        let x = v(i, c % nb);
        if c < nb {
            x.re
        } else {
            x.im
        }
    })
}

/// A block's index in the sweep and its lines' basis coordinates (or why it failed).
type SolvedBlock = (usize, Result<Vec<Vec<c64>>, FrfError>);

/// How the modal terms of the interface dynamic stiffness are summed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ModalSums {
    /// Every mode at every frequency (the oracle).
    Exact,
    /// Modes far from a block of frequencies interpolated from Chebyshev nodes
    /// (`blocks`), the rest exact.
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

    /// Adds the constant and per-region terms of the interface dynamic stiffness at ω to the
    /// modal sums in (`z_re`, `z_im`) (lower triangles, column-major r × r) and writes the
    /// result into the lower triangle of `z`. One pass per column, which stays in cache.
    pub(super) fn assemble(
        &self,
        omega: f64,
        z_re: &mut [f64],
        z_im: &mut [f64],
        z: &mut Mat<c64>,
    ) {
        let r = self.interface_dofs;
        let kc = factor(&self.groups[0].factor, omega);
        let w2 = omega * omega;
        let regions: Vec<(c64, &Mat<f64>)> = self
            .region_stiffness
            .iter()
            .map(|(t, k)| (factor(t, omega), k))
            .collect();
        for j in 0..r {
            let (re, im) = (
                &mut z_re[j * r + j..(j + 1) * r],
                &mut z_im[j * r + j..(j + 1) * r],
            );
            let (p, m) = (
                &self.plate_stiffness.col_as_slice(j)[j..],
                &self.mass.col_as_slice(j)[j..],
            );
            for (((x, y), &pv), &mv) in re.iter_mut().zip(im.iter_mut()).zip(p).zip(m) {
                *x += kc.re * pv - w2 * mv;
                *y += kc.im * pv;
            }
            for (kr, k) in &regions {
                for ((x, y), &kv) in re
                    .iter_mut()
                    .zip(im.iter_mut())
                    .zip(&k.col_as_slice(j)[j..])
                {
                    *x += kr.re * kv;
                    *y += kr.im * kv;
                }
            }
            let dst = &mut z.col_as_slice_mut(j)[j..];
            for ((d, &x), &y) in dst.iter_mut().zip(re.iter()).zip(im.iter()) {
                *d = c64::new(x, y);
            }
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
        for (g, d) in den.iter().enumerate() {
            let c: Vec<c64> = d.iter().map(|x| x * (-w4)).collect();
            let all: Vec<usize> = (0..c.len()).collect();
            self.add_selected_terms(g, &all, &c, s, &mut z_re, &mut z_im);
        }
        self.assemble(omega, &mut z_re, &mut z_im, &mut s.z);
        let rhs = self.interface_loads(&[omega], std::slice::from_ref(&den));
        let u = self.solve_interface(omega, &rhs[0], &z_re, &z_im, (&mut s.z, &mut s.panel));
        s.z_re = z_re;
        s.z_im = z_im;
        let u = u?;
        Ok(self
            .modal_coordinates(&[omega], std::slice::from_ref(&den), vec![u])
            .remove(0))
    }

    /// The interface load f_Γ + ω² Σ_j a_j f_j/(k_g λ_j − ω²) at each of `omegas` (`den`: their
    /// [`Self::modal_denominators`]), the modal part as one product per group over all of them.
    pub(super) fn interface_loads(&self, omegas: &[f64], den: &[Vec<Vec<c64>>]) -> Vec<Vec<c64>> {
        let (r, nb) = (self.interface_dofs, omegas.len());
        let mut total = Mat::<f64>::zeros(r, 2 * nb);
        for (g, grp) in self.groups.iter().enumerate() {
            if grp.load.iter().all(|&f| f == 0.0) {
                continue;
            }
            let coef = re_im_columns(grp.load.len(), nb, |j, b| {
                den[b][g][j] * (omegas[b] * omegas[b] * grp.load[j])
            });
            faer::linalg::matmul::matmul(
                total.as_mut(),
                Accum::Add,
                grp.coupling.as_ref(),
                coef.as_ref(),
                1.0,
                Par::Seq,
            );
        }
        (0..nb)
            .map(|b| {
                (0..r)
                    .map(|i| c64::new(self.load[i] + total[(i, b)], total[(i, nb + b)]))
                    .collect()
            })
            .collect()
    }

    /// Solves the assembled interface system (`z`: its lower triangle, also given as the
    /// column-major real and imaginary slices `z_re`, `z_im`) for the load `b`: LDLᵀ checked by
    /// its residual, else the pivoting LU.
    pub(super) fn solve_interface(
        &self,
        omega: f64,
        b: &[c64],
        z_re: &[f64],
        z_im: &[f64],
        (z, panel): (&mut Mat<c64>, &mut Mat<c64>),
    ) -> Result<Vec<c64>, FrfError> {
        let r = self.interface_dofs;
        let mut u = b.to_vec();
        let by_ldlt = ldlt::factor_in_place(z, panel) && {
            ldlt::solve_in_place(z, &mut u);
            ldlt::relative_residual(z_re, z_im, &u, b) <= ldlt::RESIDUAL_TOLERANCE
        };
        if !by_ldlt {
            for j in 0..r {
                for i in j..r {
                    let v = c64::new(z_re[j * r + i], z_im[j * r + i]);
                    z[(i, j)] = v;
                    z[(j, i)] = v;
                }
            }
            let rhs = Mat::<c64>::from_fn(r, 1, |i, _| b[i]);
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
        Ok(u)
    }

    /// Every basis coordinate [u_Γ | group modes …] at each of `omegas` from its interface
    /// solution: x_j = (f_j + ω² a_jᵀ u_Γ)/(k_g λ_j − ω²), the products a_jᵀ u_Γ as one
    /// matrix product per group over all the frequencies.
    pub(super) fn modal_coordinates(
        &self,
        omegas: &[f64],
        den: &[Vec<Vec<c64>>],
        us: Vec<Vec<c64>>,
    ) -> Vec<Vec<c64>> {
        let (r, nb) = (self.interface_dofs, omegas.len());
        let u = re_im_columns(r, nb, |i, b| us[b][i]);
        let mut out: Vec<Vec<c64>> = us
            .into_iter()
            .map(|u| {
                let mut x = Vec::with_capacity(self.basis_size());
                x.extend_from_slice(&u);
                x
            })
            .collect();
        for (g, grp) in self.groups.iter().enumerate() {
            let au = grp.coupling.transpose() * &u;
            for (b, x) in out.iter_mut().enumerate() {
                let w2 = omegas[b] * omegas[b];
                x.extend((0..grp.load.len()).map(|j| {
                    let a = c64::new(au[(j, b)], au[(j, nb + b)]);
                    den[b][g][j] * (a * w2 + grp.load[j])
                }));
            }
        }
        out
    }

    /// Receptance at every sensor and frequency as modal responses × sensor weights, the
    /// modal sums interpolated where exact (`blocks`), the blocks of frequencies shared
    /// by two threads.
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
        let omegas: Vec<f64> = freqs_hz
            .iter()
            .map(|&f| std::f64::consts::TAU * f)
            .collect();
        let blocks: Vec<&[f64]> = omegas.chunks(BLOCK_FREQUENCIES).collect();
        // blocks handed out one at a time: their cost varies ten-fold (modes near a block are
        // summed at every line), so a fixed split left one thread idle for seconds
        let next = AtomicUsize::new(0);
        let failed = AtomicBool::new(false);
        let worker = || -> Vec<SolvedBlock> {
            let mut s = Scratch::new(self);
            let mut done = Vec::new();
            loop {
                let i = next.fetch_add(1, Ordering::Relaxed);
                if i >= blocks.len() || failed.load(Ordering::Relaxed) {
                    return done;
                }
                let rows = match sums {
                    ModalSums::Interpolated => self.solve_block(blocks[i], &mut s),
                    ModalSums::Exact => blocks[i]
                        .iter()
                        .map(|&w| self.solve_exact(w, &mut s))
                        .collect(),
                };
                if rows.is_err() {
                    failed.store(true, Ordering::Relaxed);
                }
                done.push((i, rows));
            }
        };
        let mut solved: Vec<SolvedBlock> = std::thread::scope(|sc| {
            let helper = sc.spawn(worker);
            let mut mine = worker();
            match helper.join() {
                Ok(theirs) => mine.extend(theirs),
                Err(_) => mine.push((
                    0,
                    Err(FrfError::Invalid {
                        what: "interface sweep".into(),
                        message: "a frequency worker panicked".into(),
                    }),
                )),
            }
            mine
        });
        solved.sort_by_key(|(i, _)| *i);
        let mut modal = Mat::<c64>::zeros(freqs_hz.len(), m);
        let mut row = 0;
        for (_, rows) in solved {
            let rows = rows?;
            // column by column: the block's lines are contiguous in each column of `modal`
            for j in 0..m {
                let col = &mut modal.col_as_slice_mut(j)[row..row + rows.len()];
                for (dst, x) in col.iter_mut().zip(&rows) {
                    *dst = x[j];
                }
            }
            row += rows.len();
        }
        if row != freqs_hz.len() {
            return Err(FrfError::Invalid {
                what: "interface sweep".into(),
                message: format!("expected {} frequency lines, got {row}", freqs_hz.len()),
            });
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
