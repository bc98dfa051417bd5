//! Assembly by a kept scatter plan: the global sparsity pattern of a mesh and, for every
//! element, where each entry of its 33 × 33 matrix lands in it.
//!
//! A diagnosis assembles dozens of candidate models of one mesh. Through triplets each
//! assembly wrote ~3.5 M of them and bucketed and sorted them again (~0.5 s on the reference
//! plate, a quarter of a diagnosis). The plan is built once per mesh, supports and
//! formulation (inside a [`super::reuse::scope`]); assembling is then one add per element
//! entry. The matrices are the triplet path's: the same patterns (the entries a region's
//! elements touch), the same values up to the order duplicates are summed (tested against it).

use faer::sparse::{SparseColMat, SymbolicSparseColMat, Triplet};
use std::sync::{Arc, Mutex};

use super::assembly::{sparse_from_triplets, DofMap};
use super::combination::has_pattern;
use super::element::Mat33;
use super::error::SimError;
use super::mesh::Mesh;

/// Side of an element matrix (24 nodal dofs, 9 incompatible-mode dofs).
const D: usize = 33;
/// Marks an entry of a constrained dof in [`ScatterPlan::positions`].
const NOWHERE: u32 = u32::MAX;

/// What a plan depends on: the mesh's divisions and the free-dof numbering.
#[derive(Clone, PartialEq, Eq)]
struct PlanKey {
    divisions: (usize, usize, usize),
    internal: bool,
    free: Vec<Option<usize>>,
}

/// The union pattern of all elements and each element entry's place in it.
pub(super) struct ScatterPlan {
    key: PlanKey,
    n: usize,
    col_ptr: Vec<usize>,
    row_idx: Vec<usize>,
    /// Element e's entry (p, q) (column-major, as [`Mat33`] stores it) goes to
    /// `positions[e·D² + q·D + p]` of the values ([`NOWHERE`]: a constrained dof).
    positions: Vec<u32>,
}

/// Plans kept (most recently used first): a diagnosis alternates the pinned plate, the plate
/// with an edge released, and the edge's own model.
const KEPT_PLANS: usize = 4;

static KEPT: Mutex<Vec<Arc<ScatterPlan>>> = Mutex::new(Vec::new());

fn kept() -> std::sync::MutexGuard<'static, Vec<Arc<ScatterPlan>>> {
    // A panic while holding the lock leaves only complete plans behind.
    KEPT.lock().unwrap_or_else(|e| e.into_inner())
}

impl ScatterPlan {
    /// The plan of `mesh` with `map`; inside a reuse scope the kept one, or built and kept.
    /// `dofs_of(e)` gives element e's free dofs (the assembly's numbering); `n` is the size.
    pub(super) fn for_mesh(
        mesh: &Mesh,
        map: &DofMap,
        internal: bool,
        n: usize,
        dofs_of: &dyn Fn(usize, usize, usize, usize) -> [Option<usize>; D],
    ) -> Result<Arc<ScatterPlan>, SimError> {
        let key = PlanKey {
            divisions: (mesh.nx, mesh.ny, mesh.nz),
            internal,
            free: map.free.clone(),
        };
        if super::reuse::active() {
            let mut plans = kept();
            if let Some(i) = plans.iter().position(|p| p.key == key && p.n == n) {
                let plan = plans.remove(i);
                plans.insert(0, plan.clone());
                return Ok(plan);
            }
        }
        let plan = Arc::new(Self::build(mesh, key, n, dofs_of)?);
        if super::reuse::active() {
            let mut plans = kept();
            plans.insert(0, plan.clone());
            plans.truncate(KEPT_PLANS);
        }
        Ok(plan)
    }

    /// Forgets the kept plan (the last reuse scope closed).
    pub(super) fn forget() {
        kept().clear();
    }

    fn build(
        mesh: &Mesh,
        key: PlanKey,
        n: usize,
        dofs_of: &dyn Fn(usize, usize, usize, usize) -> [Option<usize>; D],
    ) -> Result<Self, SimError> {
        let mut element_dofs = Vec::with_capacity(mesh.n_elements());
        for k in 0..mesh.nz {
            for j in 0..mesh.ny {
                for i in 0..mesh.nx {
                    let e = (k * mesh.ny + j) * mesh.nx + i;
                    element_dofs.push((e, dofs_of(i, j, k, e)));
                }
            }
        }
        let mut trip = Vec::new();
        for (_, dofs) in &element_dofs {
            for &col in dofs.iter().flatten() {
                for &row in dofs.iter().flatten() {
                    trip.push(Triplet::new(row, col, 0.0));
                }
            }
        }
        let pattern = sparse_from_triplets(n, &trip, "element pattern")?;
        drop(trip);
        let (col_ptr, row_idx) = (
            pattern.symbolic().col_ptr().to_vec(),
            pattern.symbolic().row_idx().to_vec(),
        );
        if row_idx.len() >= NOWHERE as usize {
            return Err(SimError::Linear {
                what: "element pattern".into(),
                message: format!("{} entries, expected fewer than {NOWHERE}", row_idx.len()),
            });
        }
        let mut positions = vec![NOWHERE; mesh.n_elements() * D * D];
        for (e, dofs) in &element_dofs {
            for (q, col) in dofs.iter().enumerate() {
                let Some(col) = *col else { continue };
                let rows = &row_idx[col_ptr[col]..col_ptr[col + 1]];
                for (p, row) in dofs.iter().enumerate() {
                    let Some(row) = *row else { continue };
                    let at = rows
                        .binary_search(&row)
                        .expect("every element entry is in the pattern built from them");
                    positions[e * D * D + q * D + p] = (col_ptr[col] + at) as u32;
                }
            }
        }
        Ok(Self {
            key,
            n,
            col_ptr,
            row_idx,
            positions,
        })
    }

    /// Σ over `elements` of their matrix `of(e)` as a matrix of the entries they touch. A
    /// region of many elements is summed into the whole pattern and compressed; a small one
    /// (a patch, one cell of a scan) by its own entries only, sorted by place.
    pub(super) fn assemble<'a>(
        &self,
        elements: &[usize],
        of: impl Fn(usize) -> &'a Mat33,
    ) -> SparseColMat<usize, f64> {
        let nnz = self.row_idx.len();
        if elements.len() * D * D < nnz / 2 {
            return self.assemble_small(elements, of);
        }
        let mut values = vec![0.0; nnz];
        let mut touched = vec![false; nnz];
        for &e in elements {
            let place = &self.positions[e * D * D..(e + 1) * D * D];
            for (&at, &v) in place.iter().zip(of(e).as_slice()) {
                if at != NOWHERE {
                    values[at as usize] += v;
                    touched[at as usize] = true;
                }
            }
        }
        if touched.iter().all(|&t| t) {
            let symbolic = SymbolicSparseColMat::new_checked(
                self.n,
                self.n,
                self.col_ptr.clone(),
                None,
                self.row_idx.clone(),
            );
            return SparseColMat::new(symbolic, values);
        }
        let mut col_ptr = Vec::with_capacity(self.n + 1);
        let (mut rows, mut kept) = (Vec::new(), Vec::new());
        col_ptr.push(0);
        for c in 0..self.n {
            for at in self.col_ptr[c]..self.col_ptr[c + 1] {
                if touched[at] {
                    rows.push(self.row_idx[at]);
                    kept.push(values[at]);
                }
            }
            col_ptr.push(rows.len());
        }
        SparseColMat::new(
            SymbolicSparseColMat::new_checked(self.n, self.n, col_ptr, None, rows),
            kept,
        )
    }

    /// [`Self::assemble`] for few elements: their entries sorted by place in the pattern
    /// (which is column-major order), equal places summed.
    fn assemble_small<'a>(
        &self,
        elements: &[usize],
        of: impl Fn(usize) -> &'a Mat33,
    ) -> SparseColMat<usize, f64> {
        let mut entries: Vec<(u32, f64)> = Vec::with_capacity(elements.len() * D * D);
        for &e in elements {
            let place = &self.positions[e * D * D..(e + 1) * D * D];
            entries.extend(
                place
                    .iter()
                    .zip(of(e).as_slice())
                    .filter(|(&at, _)| at != NOWHERE)
                    .map(|(&at, &v)| (at, v)),
            );
        }
        entries.sort_by_key(|&(at, _)| at);
        let mut col_ptr = vec![0usize; self.n + 1];
        let (mut rows, mut values): (Vec<usize>, Vec<f64>) = (Vec::new(), Vec::new());
        let mut last = None;
        for (at, v) in entries {
            if last == Some(at) {
                *values.last_mut().expect("a value per place") += v;
                continue;
            }
            last = Some(at);
            let at = at as usize;
            let col = self.col_ptr.partition_point(|&start| start <= at) - 1;
            col_ptr[col + 1] += 1;
            rows.push(self.row_idx[at]);
            values.push(v);
        }
        for c in 0..self.n {
            col_ptr[c + 1] += col_ptr[c];
        }
        SparseColMat::new(
            SymbolicSparseColMat::new_checked(self.n, self.n, col_ptr, None, rows),
            values,
        )
    }

    /// Adds `entries` (row, column, value) to `m`, a matrix of this plan's whole pattern, in
    /// place; `false` (and `m` unchanged) when one lies outside the pattern.
    pub(super) fn add_in_place(
        &self,
        m: &mut SparseColMat<usize, f64>,
        entries: &[Triplet<usize, usize, f64>],
    ) -> bool {
        if !has_pattern(m, &self.col_ptr, &self.row_idx) {
            return false;
        }
        let mut places = Vec::with_capacity(entries.len());
        for t in entries {
            let rows = &self.row_idx[self.col_ptr[t.col]..self.col_ptr[t.col + 1]];
            match rows.binary_search(&t.row) {
                Ok(at) => places.push(self.col_ptr[t.col] + at),
                Err(_) => return false,
            }
        }
        let values = m.val_mut();
        for (t, at) in entries.iter().zip(places) {
            values[at] += t.val;
        }
        true
    }
}

#[cfg(test)]
mod tests {
    use crate::sim::assembly::{assemble_by_triplets, assemble_with, Formulation};
    use crate::sim::model::{EdgeSpring, Model, PointMass};
    use crate::sim::FeSystem;
    use faer::sparse::SparseColMat;

    fn same_matrix(a: &SparseColMat<usize, f64>, b: &SparseColMat<usize, f64>, what: &str) {
        let scale = b.val().iter().fold(0.0f64, |m, v| m.max(v.abs()));
        crate::sim::combination::assert_same_pattern(a, b, what, |x, y| {
            (x - y).abs() <= 1e-13 * scale
        });
    }

    fn same_system(a: &FeSystem, b: &FeSystem) {
        assert_eq!(a.n_free, b.n_free);
        same_matrix(&a.mass, &b.mass, "mass");
        assert_eq!(a.stiffness_terms.len(), b.stiffness_terms.len());
        for (s, t) in a.stiffness_terms.iter().zip(&b.stiffness_terms) {
            assert_eq!(s.name, t.name);
            assert_eq!(s.loss_factor, t.loss_factor);
            same_matrix(&s.matrix, &t.matrix, &s.name);
        }
        assert_eq!(a.force, b.force);
    }

    /// The plan's matrices are the triplet path's (kept as its oracle), for a coarse plate
    /// with a patch (and a patch that covers no element), point masses (one on a node, one
    /// off the mesh's nodes), an edge spring, free and pinned edges, both formulations, and
    /// the plan reused across those models.
    #[test]
    fn plan_assembly_is_the_triplet_assembly() {
        let base = Model::from_toml_str(
            &std::fs::read_to_string("examples/plate-viscoelastic-patch.toml").unwrap(),
        )
        .unwrap();
        let mut coarse = base.clone();
        coarse.mesh.nx = 8;
        coarse.mesh.ny = 12;
        coarse.mesh.nz = 3;
        let mut loaded = coarse.clone();
        loaded.point_masses = vec![
            PointMass {
                x: 0.5,
                y: 0.75,
                mass: 2.0,
            },
            PointMass {
                x: 0.61,
                y: 1.3,
                mass: 0.5,
            },
        ];
        loaded.edge_springs = vec![EdgeSpring {
            edge: "x0".into(),
            stiffness_per_length: 1e6,
        }];
        let mut tiny_patch = coarse.clone();
        tiny_patch.patches[0].x = [0.01, 0.02];
        tiny_patch.patches[0].y = [0.01, 0.02];
        let mut free = coarse.clone();
        free.supports.pinned_edges.clear();
        for formulation in [Formulation::InternalDofs, Formulation::Condensed] {
            let _scope = crate::sim::reuse::scope();
            for model in [&coarse, &loaded, &tiny_patch, &free, &coarse] {
                let planned = assemble_with(model, formulation).unwrap();
                let oracle = assemble_by_triplets(model, formulation).unwrap();
                same_system(&planned, &oracle);
            }
        }
    }
}
