//! The modal sums of the interface form over blocks of frequencies: a mode whose term is smooth
//! over a block (its resonance is far away) is summed at a few Chebyshev nodes and interpolated;
//! only the modes near the block are summed at every frequency.
//!
//! Why: the sums Σ_j c_j(ω) a_j a_jᵀ over ~1400 modes cost r² per mode and frequency, three
//! times the interface LU on the example. Over a block of [`BLOCK_FREQUENCIES`] lines most
//! c_j(ω) = −ω⁴/(k(ω)λ_j − ω²) are analytic far around the block, so their polynomial
//! interpolant at [`NODES`] Chebyshev points is exact to round-off, and their sum is
//! interpolated as one matrix per node. Which modes qualify is not guessed from pole
//! positions: each mode's interpolant is compared with its exact value at every frequency of
//! the block ([`FAR_TOLERANCE`]), so the interpolated sum is within that tolerance of the exact
//! one term by term ([`InterfaceModel::solve_exact`] is the oracle in the tests).

use faer::{c64, Accum, Mat, MatRef, Par};

use super::super::frf::FrfError;
use super::sweep::Scratch;
use super::InterfaceModel;

/// Frequencies per block (the last block of a sweep may be shorter).
pub const BLOCK_FREQUENCIES: usize = 256;

/// Chebyshev nodes per block.
pub const NODES: usize = 16;

/// A block is halved when its near modes' exact sums cost more than this many times its far
/// modes' node sums (and each half keeps at least 2 × [`NODES`] lines).
const SPLIT_RATIO: usize = 2;

/// Frequencies whose interpolated sums are formed together (one pass over the node sums).
const BATCH: usize = 8;

/// A mode is interpolated over a block when its interpolant is within this fraction of its
/// largest |c_j| over the block at every frequency of the block.
pub const FAR_TOLERANCE: f64 = 1e-11;

/// Chebyshev points of the second kind on [lo, hi] and their barycentric weights.
fn chebyshev_nodes(lo: f64, hi: f64) -> (Vec<f64>, Vec<f64>) {
    let (c, h) = (0.5 * (lo + hi), 0.5 * (hi - lo));
    let nodes = (0..NODES)
        .map(|l| c + h * (std::f64::consts::PI * l as f64 / (NODES - 1) as f64).cos())
        .collect();
    let weights = (0..NODES)
        .map(|l| {
            let s = if l % 2 == 0 { 1.0 } else { -1.0 };
            if l == 0 || l == NODES - 1 {
                0.5 * s
            } else {
                s
            }
        })
        .collect();
    (nodes, weights)
}

/// The barycentric interpolation weights β_l(x) (Σ β_l = 1) of the nodes at x.
fn interpolation_weights(x: f64, nodes: &[f64], bary: &[f64]) -> Vec<f64> {
    if let Some(l) = nodes.iter().position(|&v| v == x) {
        let mut e = vec![0.0; nodes.len()];
        e[l] = 1.0;
        return e;
    }
    let terms: Vec<f64> = nodes.iter().zip(bary).map(|(&v, &w)| w / (x - v)).collect();
    let sum: f64 = terms.iter().sum();
    terms.into_iter().map(|t| t / sum).collect()
}

/// −ω⁴/(k_g(ω)λ_j − ω²) of every mode of a group from its denominators.
fn sum_coefficients(omega: f64, den: &[c64]) -> Vec<c64> {
    let w4 = omega.powi(4);
    den.iter().map(|d| d * (-w4)).collect()
}

/// Columns of the interface matrices whose lower triangles one product of
/// [`interpolate_lower`] covers.
const COLUMN_CHUNK: usize = 16;

/// dst[:, b] = Σ_l nodes[:, l] weights[l, b] on the rows of the lower triangles of r × r
/// column-major matrices (and a few upper entries next to them; the rest of `dst` is left as
/// it was): half the memory traffic of the full product, which is bound by it.
fn interpolate_lower(nodes: &Mat<f64>, weights: MatRef<'_, f64>, dst: &mut Mat<f64>, r: usize) {
    let nb = weights.ncols();
    for j0 in (0..r).step_by(COLUMN_CHUNK) {
        let j1 = (j0 + COLUMN_CHUNK).min(r);
        let (row0, rows) = (j0 * r + j0, j1 * r - (j0 * r + j0));
        faer::linalg::matmul::matmul(
            dst.as_mut().submatrix_mut(row0, 0, rows, nb),
            Accum::Replace,
            nodes.as_ref().subrows(row0, rows),
            weights,
            1.0,
            Par::Seq,
        );
    }
}

impl InterfaceModel {
    /// Every basis coordinate at every frequency of one block (ascending angular frequencies
    /// `omegas`), the modal sums interpolated where that is exact to [`FAR_TOLERANCE`].
    pub(super) fn solve_block(
        &self,
        omegas: &[f64],
        s: &mut Scratch,
    ) -> Result<Vec<Vec<c64>>, FrfError> {
        if omegas.len() < 2 * NODES {
            return omegas.iter().map(|&w| self.solve_exact(w, s)).collect();
        }
        let (lo, hi) = (omegas[0], omegas[omegas.len() - 1]);
        let (nodes, bary) = chebyshev_nodes(lo, hi);
        let beta: Vec<Vec<f64>> = omegas
            .iter()
            .map(|&w| interpolation_weights(w, &nodes, &bary))
            .collect();
        let den_at: Vec<Vec<Vec<c64>>> =
            omegas.iter().map(|&w| self.modal_denominators(w)).collect();
        // the sums' coefficients at every node and frequency, per group: [point][group][mode]
        let coefficients = |w: f64, den: &[Vec<c64>]| -> Vec<Vec<c64>> {
            den.iter().map(|d| sum_coefficients(w, d)).collect()
        };
        let at_nodes: Vec<Vec<Vec<c64>>> = nodes
            .iter()
            .map(|&w| coefficients(w, &self.modal_denominators(w)))
            .collect();
        let at_freqs: Vec<Vec<Vec<c64>>> = omegas
            .iter()
            .zip(&den_at)
            .map(|(&w, den)| coefficients(w, den))
            .collect();
        // which modes are far from the block, per group
        let mut far: Vec<Vec<bool>> = Vec::with_capacity(self.groups.len());
        for (g, grp) in self.groups.iter().enumerate() {
            far.push(
                (0..grp.eigenvalues.len())
                    .map(|j| {
                        let mut err: f64 = 0.0;
                        let mut scale: f64 = 0.0;
                        for (b, wts) in beta.iter().enumerate() {
                            let p: c64 = (0..NODES).map(|l| at_nodes[l][g][j] * wts[l]).sum();
                            err = err.max((p - at_freqs[b][g][j]).norm_sqr());
                            scale = scale.max(at_freqs[b][g][j].norm_sqr());
                        }
                        err <= FAR_TOLERANCE * FAR_TOLERANCE * scale
                    })
                    .collect(),
            );
        }
        // Modes near the block are summed at every line, far ones at the NODES nodes: when the
        // near ones cost more than SPLIT_RATIO times the node sums, two half blocks (with
        // fewer near modes each) are cheaper despite their second set of node sums.
        let near_count = far.iter().flatten().filter(|&&f| !f).count();
        let far_count = far.iter().flatten().filter(|&&f| f).count();
        if omegas.len() >= 4 * NODES && near_count * omegas.len() > SPLIT_RATIO * NODES * far_count
        {
            let (first, second) = omegas.split_at(omegas.len() / 2);
            let mut out = self.solve_block(first, s)?;
            out.extend(self.solve_block(second, s)?);
            return Ok(out);
        }
        let r = self.interface_dofs;
        let far_groups: Vec<(usize, Vec<usize>)> = far
            .iter()
            .enumerate()
            .map(|(g, f)| (g, (0..f.len()).filter(|&j| f[j]).collect()))
            .collect();
        let near_groups: Vec<(usize, Vec<usize>)> = far
            .iter()
            .enumerate()
            .map(|(g, f)| (g, (0..f.len()).filter(|&j| !f[j]).collect()))
            .collect();
        // the far modes' sum at every node: column l of `node_re`/`node_im` is the r × r
        // column-major sum at node l (lower triangle)
        let mut node_re = Mat::<f64>::zeros(r * r, NODES);
        let mut node_im = Mat::<f64>::zeros(r * r, NODES);
        for (l, at_node) in at_nodes.iter().enumerate() {
            for (g, cols) in &far_groups {
                self.add_selected_terms(
                    *g,
                    cols,
                    &at_node[*g],
                    s,
                    node_re.col_as_slice_mut(l),
                    node_im.col_as_slice_mut(l),
                );
            }
        }
        let mut out = Vec::with_capacity(omegas.len());
        let mut comb_re = Mat::<f64>::zeros(r * r, BATCH);
        let mut comb_im = Mat::<f64>::zeros(r * r, BATCH);
        for start in (0..omegas.len()).step_by(BATCH) {
            let nb = BATCH.min(omegas.len() - start);
            let batch = &omegas[start..start + nb];
            // the interpolated far sums of a batch of frequencies: (r² × nodes)(nodes × nb)
            let weights = Mat::<f64>::from_fn(NODES, nb, |l, b| beta[start + b][l]);
            interpolate_lower(&node_re, weights.as_ref(), &mut comb_re, r);
            interpolate_lower(&node_im, weights.as_ref(), &mut comb_im, r);
            let den = &den_at[start..start + nb];
            let rhs = self.interface_loads(batch, den);
            let mut us = Vec::with_capacity(nb);
            for (b, &w) in batch.iter().enumerate() {
                let (z_re, z_im) = (comb_re.col_as_slice_mut(b), comb_im.col_as_slice_mut(b));
                for (g, cols) in &near_groups {
                    self.add_selected_terms(*g, cols, &at_freqs[start + b][*g], s, z_re, z_im);
                }
                self.assemble(w, z_re, z_im, &mut s.z);
                us.push(self.solve_interface(w, &rhs[b], z_re, z_im, (&mut s.z, &mut s.panel))?);
            }
            out.extend(self.modal_coordinates(batch, den, us));
        }
        Ok(out)
    }
}
