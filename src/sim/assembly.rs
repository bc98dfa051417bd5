//! Assembly of a [`Model`] into the [`FeSystem`] over the free dofs.
//!
//! - Constraints (FORMATS.md §3): a pinned edge fixes ux = uy = uz = 0 on the mid-plane line of
//!   that edge (node layer k = nz/2). When nz is odd the mid-plane lies inside an element, half
//!   way between two node layers: uz = 0 on both, and the mid-plane's ux and uy — the mean of
//!   the two layers' — are held at 0 by a penalty on (u_lower + u_upper)
//!   ([`MIDPLANE_PIN_PENALTY`]), so the section turns freely about the line. Fixing ux = uy on
//!   the lower layer instead (up to 2026-11-27) pinned the bottom face: with nz = 1 the first
//!   mode of a plate pinned on two edges came out 60 % high (42.6 against 26.5 Hz with nz = 2).
//! - One [`StiffnessTerm`] per region: "plate", then "patch p" for each patch that owns elements
//!   (SLS patches assembled with `sls.e_inf`), then `"edge spring <edge>"` (z springs on the edge's
//!   mid-plane line, consistent linear line integration, loss factor 0).
//! - Mass: consistent element mass plus point masses, each added as m·w wᵀ in x, y and z with the
//!   mid-plane interpolation weights w of its position (so a rigid translation carries m).
//! - Force: the excitation's amplitude spread on the nodes by the same interpolation.
//!
//! All elements are equal boxes, so element matrices are computed once per region material.

use faer::sparse::{SparseColMat, SymbolicSparseColMat, Triplet};

use super::combination::sparse_combination;
use super::element::{
    elasticity, hex8_incompatible_internal, hex8_incompatible_stiffness, hex8_mass, Mat33,
};
use super::error::SimError;
use super::mesh::Mesh;
use super::model::{Edge, Model};
use super::scatter_plan::ScatterPlan;
use super::system::{FeSystem, SensorWeights, StiffnessTerm};

/// Map from global dof to free dof (`None` when constrained).
#[derive(Clone, Debug)]
pub struct DofMap {
    /// `free[g]` = free index of global dof g.
    pub free: Vec<Option<usize>>,
    /// Number of free dofs.
    pub n_free: usize,
}

impl DofMap {
    /// Numbers the dofs that remain free after the model's pinned edges.
    pub fn new(model: &Model, mesh: &Mesh) -> Result<DofMap, SimError> {
        let mut fixed = vec![false; mesh.n_dofs()];
        let layers = mesh.midplane_layers();
        for edge in model.pinned_edges()? {
            for &(k, _) in &layers {
                for node in edge_nodes(mesh, edge, k) {
                    fixed[3 * node + 2] = true;
                    if layers.len() == 1 {
                        fixed[3 * node] = true;
                        fixed[3 * node + 1] = true;
                    }
                }
            }
        }
        let mut n_free = 0;
        let free = fixed
            .iter()
            .map(|&f| {
                if f {
                    None
                } else {
                    n_free += 1;
                    Some(n_free - 1)
                }
            })
            .collect();
        Ok(DofMap { free, n_free })
    }
}

/// The penalty on u_lower + u_upper (x and y) that pins the mid-plane line of an edge between
/// two node layers (odd nz), relative to the largest diagonal entry of a plate element's
/// stiffness. The reference plate with nz = 1 gives the same frequencies to 1e-9 with 1e4 and
/// 1e6; larger penalties cost the factorised pencil digits (from 1e5 the Lanczos and dense
/// eigenvalues part by more than 1e-8, test `sparse_eigen_solver_agrees_with_a_dense_oracle`).
pub const MIDPLANE_PIN_PENALTY: f64 = 1e4;

/// The penalty triplets of the pinned edges' mid-plane lines for odd nz ([`MIDPLANE_PIN_PENALTY`]
/// × `k_ref`); empty for even nz, whose mid-plane nodes are fixed.
fn midplane_pin_triplets(
    model: &Model,
    mesh: &Mesh,
    map: &DofMap,
    k_ref: f64,
) -> Result<Vec<Triplet<usize, usize, f64>>, SimError> {
    let layers = mesh.midplane_layers();
    let mut out = Vec::new();
    if layers.len() != 2 {
        return Ok(out);
    }
    let k = MIDPLANE_PIN_PENALTY * k_ref;
    for edge in model.pinned_edges()? {
        let lower = edge_nodes(mesh, edge, layers[0].0);
        let upper = edge_nodes(mesh, edge, layers[1].0);
        for (&a, &b) in lower.iter().zip(&upper) {
            for c in 0..2 {
                if let (Some(p), Some(q)) = (map.free[3 * a + c], map.free[3 * b + c]) {
                    for (r, s) in [(p, p), (p, q), (q, p), (q, q)] {
                        out.push(Triplet::new(r, s, k));
                    }
                }
            }
        }
    }
    Ok(out)
}

/// The nodes of node layer k along an edge, in order along the edge.
fn edge_nodes(mesh: &Mesh, edge: Edge, k: usize) -> Vec<usize> {
    match edge {
        Edge::X0 => (0..=mesh.ny).map(|j| mesh.node(0, j, k)).collect(),
        Edge::X1 => (0..=mesh.ny).map(|j| mesh.node(mesh.nx, j, k)).collect(),
        Edge::Y0 => (0..=mesh.nx).map(|i| mesh.node(i, 0, k)).collect(),
        Edge::Y1 => (0..=mesh.nx).map(|i| mesh.node(i, mesh.ny, k)).collect(),
    }
}

/// Builds a square sparse matrix from triplets (duplicates are summed); `what` names it.
///
/// Why not faer's `try_new_from_triplets`: it sorts all triplets (3.3 M per matrix on the
/// reference mesh), which was a fifth of a `diagnose` run that assembles many candidate models.
/// Here the triplets are bucketed by column (one counting pass) and only each column's few
/// hundred entries are sorted; the result is the same matrix (tested against faer's).
pub fn sparse_from_triplets(
    n: usize,
    triplets: &[Triplet<usize, usize, f64>],
    what: &str,
) -> Result<SparseColMat<usize, f64>, SimError> {
    if let Some(t) = triplets.iter().find(|t| t.row >= n || t.col >= n) {
        return Err(SimError::Linear {
            what: what.to_string(),
            message: format!(
                "entry ({}, {}) outside the expected {n} × {n} matrix",
                t.row, t.col
            ),
        });
    }
    let mut start = vec![0usize; n + 1];
    for t in triplets {
        start[t.col + 1] += 1;
    }
    for c in 0..n {
        start[c + 1] += start[c];
    }
    let mut bucket = vec![(0usize, 0.0f64); triplets.len()];
    let mut next = start.clone();
    for t in triplets {
        bucket[next[t.col]] = (t.row, t.val);
        next[t.col] += 1;
    }
    drop(next);
    let mut col_ptr = Vec::with_capacity(n + 1);
    let mut row_idx = Vec::with_capacity(triplets.len());
    let mut values = Vec::with_capacity(triplets.len());
    col_ptr.push(0);
    for c in 0..n {
        let column = &mut bucket[start[c]..start[c + 1]];
        column.sort_unstable_by_key(|&(row, _)| row);
        for &(row, v) in column.iter() {
            if row_idx.len() > col_ptr[c] && row_idx.last() == Some(&row) {
                *values.last_mut().expect("a value per row index") += v;
            } else {
                row_idx.push(row);
                values.push(v);
            }
        }
        col_ptr.push(row_idx.len());
    }
    let symbolic = SymbolicSparseColMat::new_checked(n, n, col_ptr, None, row_idx);
    Ok(SparseColMat::new(symbolic, values))
}

/// The name of region `r`'s stiffness term: "plate", then "patch p".
fn region_name(r: usize) -> String {
    if r == 0 {
        "plate".to_string()
    } else {
        format!("patch {}", r - 1)
    }
}

/// Scatters an element matrix over element dofs `dofs` (`None`: constrained) into triplets.
fn scatter<const D: usize>(
    out: &mut Vec<Triplet<usize, usize, f64>>,
    ke: &nalgebra::SMatrix<f64, D, D>,
    dofs: &[Option<usize>; D],
) {
    for (q, dq) in dofs.iter().enumerate() {
        let Some(col) = *dq else { continue };
        for (p, dp) in dofs.iter().enumerate() {
            if let Some(row) = *dp {
                out.push(Triplet::new(row, col, ke[(p, q)]));
            }
        }
    }
}

/// The free indices of an element's dofs: 24 nodal, then (for [`Formulation::InternalDofs`])
/// its 9 incompatible-mode dofs numbered after all nodal free dofs.
fn element_dofs(nodes: &[usize; 8], map: &DofMap, element: usize) -> [Option<usize>; 33] {
    let mut dofs = [None; 33];
    for (a, &n) in nodes.iter().enumerate() {
        for c in 0..3 {
            dofs[3 * a + c] = map.free[3 * n + c];
        }
    }
    for (i, d) in dofs[24..].iter_mut().enumerate() {
        *d = Some(map.n_free + 9 * element + i);
    }
    dofs
}

/// How the incompatible modes enter the global system.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Formulation {
    /// CalculiX C3D8I: the 9 incompatible-mode amplitudes of every element stay as internal
    /// dofs carrying the bubbles' consistent mass (n_free grows by 9 per element; sensors and
    /// forces act on nodal dofs only). Matches the CalculiX reference frequencies.
    #[default]
    InternalDofs,
    /// Wilson–Taylor with static condensation (K_e = K_uu − K_uα K_αα⁻¹ K_αu, nodal mass only):
    /// fewer dofs, slightly stiffer in dynamics (Guyan reduction of the above).
    Condensed,
}

/// Interpolation of a mid-plane point onto free dofs of component `c` (constrained dofs drop).
fn point_dofs(mesh: &Mesh, map: &DofMap, x_m: f64, y_m: f64, c: usize) -> Vec<(usize, f64)> {
    mesh.midplane_weights(x_m, y_m)
        .into_iter()
        .filter_map(|(node, w)| map.free[3 * node + c].map(|d| (d, w)))
        .collect()
}

/// The out-of-plane weights of sensors at arbitrary `positions` (between nodes too: bilinear
/// on the mid-plane), over the free dofs of `model` as [`assemble`] numbers them; e.g. to read
/// the model's mode shapes where a recording set's sensors were.
pub fn sensors_at(
    model: &Model,
    positions: &[crate::sim::model::SensorPosition],
) -> Result<Vec<SensorWeights>, SimError> {
    model.validate()?;
    let mesh = Mesh::new(model);
    let map = DofMap::new(model, &mesh)?;
    Ok(positions
        .iter()
        .map(|s| SensorWeights {
            weights: point_dofs(&mesh, &map, s.x_m, s.y_m, 2),
            id: s.id.clone(),
            x_m: s.x_m,
            y_m: s.y_m,
        })
        .collect())
}

/// Assembles the model into an [`FeSystem`] over the free dofs ([`Formulation::InternalDofs`]).
pub fn assemble(model: &Model) -> Result<FeSystem, SimError> {
    assemble_with(model, Formulation::default())
}

/// Assembles the model with a chosen [`Formulation`] of the incompatible modes.
pub fn assemble_with(model: &Model, formulation: Formulation) -> Result<FeSystem, SimError> {
    assemble_planned(model, formulation, super::reuse::active())
}

/// [`assemble_with`] through triplets whatever the scope: the scatter plan's oracle.
#[cfg(test)]
pub(crate) fn assemble_by_triplets(
    model: &Model,
    formulation: Formulation,
) -> Result<FeSystem, SimError> {
    assemble_planned(model, formulation, false)
}

/// [`assemble_with`]; `planned`: by the mesh's kept [`ScatterPlan`] instead of triplets.
fn assemble_planned(
    model: &Model,
    formulation: Formulation,
    planned: bool,
) -> Result<FeSystem, SimError> {
    model.validate()?;
    let mesh = Mesh::new(model);
    let map = DofMap::new(model, &mesh)?;
    if map.n_free == 0 {
        return Err(SimError::InvalidValue {
            key: "supports.pinned_edges".into(),
            message: "every dof is constrained".into(),
        });
    }
    let coords = mesh.element_box();
    let n_regions = 1 + model.patches.len();
    let materials: Vec<_> = std::iter::once(model.material_of_plate())
        .chain(model.patches.iter().map(|p| model.material_of_patch(p)))
        .collect();
    // Element matrices once per region (elements are equal boxes).
    let internal = formulation == Formulation::InternalDofs;
    let mut kes = Vec::with_capacity(n_regions);
    let mut mes = Vec::with_capacity(n_regions);
    for (r, m) in materials.iter().enumerate() {
        let first = mesh
            .region_of_element
            .iter()
            .position(|&x| x == r)
            .unwrap_or(0);
        let c = elasticity(m.youngs_modulus, m.poisson);
        if internal {
            let (k, mm) = hex8_incompatible_internal(&coords, &c, m.density, first)?;
            kes.push(k);
            mes.push(mm);
        } else {
            let mut k = Mat33::zeros();
            let mut mm = Mat33::zeros();
            k.fixed_view_mut::<24, 24>(0, 0)
                .copy_from(&hex8_incompatible_stiffness(&coords, &c, first)?);
            mm.fixed_view_mut::<24, 24>(0, 0)
                .copy_from(&hex8_mass(&coords, m.density));
            kes.push(k);
            mes.push(mm);
        }
    }
    let n = if internal {
        map.n_free + 9 * mesh.n_elements()
    } else {
        map.n_free
    };
    let dofs_of = |i: usize, j: usize, k: usize, e: usize| {
        let mut dofs = element_dofs(&mesh.element_nodes(i, j, k), &map, e);
        if !internal {
            dofs[24..].iter_mut().for_each(|d| *d = None);
        }
        dofs
    };
    // Point masses.
    let mut point_masses = Vec::new();
    for pm in &model.point_masses {
        for c in 0..3 {
            let w = point_dofs(&mesh, &map, pm.x, pm.y, c);
            for &(p, wp) in &w {
                for &(q, wq) in &w {
                    point_masses.push(Triplet::new(p, q, pm.mass * wp * wq));
                }
            }
        }
    }
    let (mass, stiffness) = if planned {
        let plan = ScatterPlan::for_mesh(&mesh, &map, internal, n, &dofs_of)?;
        let region = &mesh.region_of_element;
        let mut members = vec![Vec::new(); n_regions];
        for (e, &r) in region.iter().enumerate() {
            members[r].push(e);
        }
        let all: Vec<usize> = (0..mesh.n_elements()).collect();
        let mut mass = plan.assemble(&all, |e| &mes[region[e]]);
        if !plan.add_in_place(&mut mass, &point_masses) {
            let extra = sparse_from_triplets(n, &point_masses, "point masses")?;
            mass = sparse_combination(n, &[(1.0, &mass), (1.0, &extra)], "mass matrix")?;
        }
        let stiffness = members
            .iter()
            .enumerate()
            .map(|(r, elements)| {
                (!elements.is_empty()).then(|| plan.assemble(elements, |_| &kes[r]))
            })
            .collect();
        (mass, stiffness)
    } else {
        let mut k_trip: Vec<Vec<Triplet<usize, usize, f64>>> = vec![Vec::new(); n_regions];
        let mut m_trip = Vec::with_capacity(mesh.n_elements() * 33 * 33);
        for k in 0..mesh.nz {
            for j in 0..mesh.ny {
                for i in 0..mesh.nx {
                    let e = (k * mesh.ny + j) * mesh.nx + i;
                    let r = mesh.region_of_element[e];
                    let dofs = dofs_of(i, j, k, e);
                    scatter(&mut k_trip[r], &kes[r], &dofs);
                    scatter(&mut m_trip, &mes[r], &dofs);
                }
            }
        }
        m_trip.extend_from_slice(&point_masses);
        let mass = sparse_from_triplets(n, &m_trip, "mass matrix")?;
        drop(m_trip);
        let stiffness = k_trip
            .iter()
            .enumerate()
            .map(|(r, trip)| {
                let name = region_name(r);
                (!trip.is_empty())
                    .then(|| sparse_from_triplets(n, trip, &format!("stiffness of {name}")))
                    .transpose()
            })
            .collect::<Result<Vec<_>, _>>()?;
        (mass, stiffness)
    };
    let mut stiffness = stiffness;
    let k_ref = (0..24).map(|i| kes[0][(i, i)].abs()).fold(0.0, f64::max);
    let pins = midplane_pin_triplets(model, &mesh, &map, k_ref)?;
    if let Some(plate) = stiffness
        .iter_mut()
        .flatten()
        .next()
        .filter(|_| !pins.is_empty())
    {
        let extra = sparse_from_triplets(n, &pins, "mid-plane pins")?;
        *plate = sparse_combination(n, &[(1.0, plate), (1.0, &extra)], "stiffness of plate")?;
    }
    let mut terms = Vec::new();
    for (r, matrix) in stiffness.into_iter().enumerate() {
        let Some(matrix) = matrix else { continue };
        let m = &materials[r];
        terms.push(StiffnessTerm {
            matrix,
            name: region_name(r),
            loss_factor: m.loss_factor,
            sls: m.sls,
            reference_modulus_pa: m.youngs_modulus,
        });
    }
    for (s, spring) in model.edge_springs.iter().enumerate() {
        let edge = Edge::parse(&spring.edge, &format!("edge_spring[{s}].edge"))?;
        let trip = edge_spring_triplets(&mesh, &map, edge, spring.stiffness_per_length);
        let name = format!("edge spring {}", edge.name());
        terms.push(StiffnessTerm {
            matrix: sparse_from_triplets(n, &trip, &name)?,
            name,
            loss_factor: 0.0,
            sls: None,
            reference_modulus_pa: 1.0,
        });
    }
    let ex = &model.excitation;
    let comp = match ex.dir.as_str() {
        "x" => 0,
        "y" => 1,
        _ => 2,
    };
    let mut force = vec![0.0; n];
    for (d, w) in point_dofs(&mesh, &map, ex.x, ex.y, comp) {
        force[d] += ex.force * w;
    }
    let sensors = model
        .sensor_positions()?
        .into_iter()
        .map(|s| SensorWeights {
            weights: point_dofs(&mesh, &map, s.x_m, s.y_m, 2),
            id: s.id,
            x_m: s.x_m,
            y_m: s.y_m,
        })
        .collect();
    Ok(FeSystem {
        n_free: n,
        mass,
        stiffness_terms: terms,
        rayleigh: model
            .damping
            .as_ref()
            .map(|d| (d.rayleigh.alpha, d.rayleigh.beta)),
        force,
        sensors,
    })
}

/// Consistent z springs along an edge's mid-plane line: per segment of length d between nodes
/// a, b: k d/6 [[2, 1], [1, 2]] on (uz_a, uz_b); for odd nz the line is interpolated from the
/// two bounding layers (weights ½).
fn edge_spring_triplets(
    mesh: &Mesh,
    map: &DofMap,
    edge: Edge,
    k_per_m: f64,
) -> Vec<Triplet<usize, usize, f64>> {
    let seg = match edge {
        Edge::X0 | Edge::X1 => mesh.dy_m,
        Edge::Y0 | Edge::Y1 => mesh.dx_m,
    };
    let layers = mesh.midplane_layers();
    let lines: Vec<(Vec<usize>, f64)> = layers
        .iter()
        .map(|&(k, w)| (edge_nodes(mesh, edge, k), w))
        .collect();
    let n_pts = lines[0].0.len();
    let mut out = Vec::new();
    for s in 0..n_pts - 1 {
        for (pa, pb, coef) in [
            (s, s, 2.0),
            (s, s + 1, 1.0),
            (s + 1, s, 1.0),
            (s + 1, s + 1, 2.0),
        ] {
            for (la, wa) in &lines {
                for (lb, wb) in &lines {
                    let (Some(r), Some(c)) = (map.free[3 * la[pa] + 2], map.free[3 * lb[pb] + 2])
                    else {
                        continue;
                    };
                    out.push(Triplet::new(r, c, k_per_m * seg / 6.0 * coef * wa * wb));
                }
            }
        }
    }
    out
}

/// Where each dof of `from`'s system lands in `to`'s, for two models on the same mesh that
/// differ only in which edges are pinned (`None`: constrained in `to`). Internal
/// (incompatible-mode) dofs follow the nodal ones in both: `n_from` is the size of `from`'s
/// system (its nodal free dofs plus, for [`Formulation::InternalDofs`], 9 per element). A mode
/// of a pinned plate is then a valid vector of the plate with that edge released.
pub fn dof_embedding(
    from: &Model,
    to: &Model,
    n_from: usize,
) -> Result<Vec<Option<usize>>, SimError> {
    if (from.mesh.nx, from.mesh.ny, from.mesh.nz) != (to.mesh.nx, to.mesh.ny, to.mesh.nz) {
        return Err(SimError::InvalidValue {
            key: "mesh".into(),
            message: "expected two models on the same mesh".into(),
        });
    }
    let mesh = Mesh::new(from);
    let (a, b) = (DofMap::new(from, &mesh)?, DofMap::new(to, &mesh)?);
    let mut out = vec![None; n_from];
    for (g, slot) in a.free.iter().enumerate() {
        if let Some(i) = slot {
            out[*i] = b.free[g];
        }
    }
    for (i, o) in out.iter_mut().enumerate().skip(a.n_free) {
        *o = Some(i - a.n_free + b.n_free);
    }
    Ok(out)
}

/// The z springs of `k_per_m` N/m² along `edge`'s mid-plane line, over `model`'s free dofs in
/// a system of size `n` (as [`assemble`] builds the term "edge spring …").
pub fn edge_spring_matrix(
    model: &Model,
    edge: Edge,
    k_per_m: f64,
    n: usize,
) -> Result<SparseColMat<usize, f64>, SimError> {
    let mesh = Mesh::new(model);
    let map = DofMap::new(model, &mesh)?;
    let trip = edge_spring_triplets(&mesh, &map, edge, k_per_m);
    sparse_from_triplets(n, &trip, &format!("edge spring {}", edge.name()))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The counting-sort builder gives faer's matrix: same pattern, values summed (to
    /// round-off: the duplicates may be summed in another order).
    #[test]
    fn sparse_from_triplets_equals_faers_builder() {
        let mut state = 7u64;
        let mut rnd = |m: usize| {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state % m as u64) as usize
        };
        for n in [1usize, 2, 17, 300] {
            // duplicates on purpose (few distinct positions), some columns left empty
            let trip: Vec<Triplet<usize, usize, f64>> = (0..8 * n)
                .map(|k| {
                    let (r, c) = (rnd(n), rnd(n.div_ceil(2)) * 2 % n);
                    Triplet::new(r, c, (k % 13) as f64 - 6.0 + 0.125 * (k % 5) as f64)
                })
                .collect();
            let ours = sparse_from_triplets(n, &trip, "test").unwrap();
            let theirs = SparseColMat::<usize, f64>::try_new_from_triplets(n, n, &trip).unwrap();
            crate::sim::combination::assert_same_pattern(
                &ours,
                &theirs,
                &format!("n {n}"),
                |a, b| (a - b).abs() <= 1e-12 * (1.0 + b.abs()),
            );
        }
        let bad = [Triplet::new(0usize, 3usize, 1.0)];
        let err = sparse_from_triplets(3, &bad, "the test matrix").unwrap_err();
        assert!(
            err.to_string().contains("outside the expected 3 × 3"),
            "{err}"
        );
    }
}
