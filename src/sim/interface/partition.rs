//! Which dofs are a viscoelastic region's interior, which are its interface with the rest of the
//! structure, and whether a system has the structure the interface form needs.

use faer::sparse::SparseColMat;

use super::super::substructure::{sls_interiors, RegionInterior};
use super::super::system::FeSystem;

/// Why a system cannot be solved in the interface form (the caller then uses the general
/// reduced model); kept for `--timings` and tests.
#[derive(Clone, Debug, PartialEq)]
pub enum NotApplicable {
    /// No viscoelastic (SLS) region, or one without interior dofs.
    NoViscoelasticInterior,
    /// Rayleigh damping couples every coordinate with a frequency-dependent term.
    Rayleigh,
    /// The frequency-independent regions have different loss factors (the plate's modes would
    /// not be shared by their damping).
    MixedConstantLoss,
    /// The load acts on an interior dof.
    LoadInInterior,
    /// A region's stiffness touches a dof that is neither its interior nor its interface.
    Unstructured(String),
    /// An interior is too large for its dense eigen-solve.
    InteriorTooLarge(usize),
}

/// The partition of the free dofs: the interiors of the SLS regions (each touched by one
/// region's stiffness only), the interface Γ (every other dof coupled to an interior through
/// that region's stiffness or the mass), and the rest (the plate).
#[derive(Clone, Debug, PartialEq)]
pub struct Partition {
    /// One interior per SLS region.
    pub interiors: Vec<RegionInterior>,
    /// The interface dofs, ascending.
    pub interface: Vec<usize>,
    /// For every free dof: its position in `interface`, or `None`.
    pub interface_index: Vec<Option<usize>>,
    /// For every free dof: whether it is interior to some region.
    pub in_interior: Vec<bool>,
}

/// Columns j of `a` with a nonzero entry in a row where `rows[i]` holds.
fn columns_reaching(a: &SparseColMat<usize, f64>, rows: &[bool]) -> Vec<bool> {
    let (sym, val) = a.parts();
    (0..a.ncols())
        .map(|j| {
            sym.col_range(j)
                .any(|k| val[k] != 0.0 && rows[sym.row_idx()[k]])
        })
        .collect()
}

/// Dofs that `a` touches (a nonzero in their column).
fn touched(a: &SparseColMat<usize, f64>) -> Vec<bool> {
    let (sym, val) = a.parts();
    (0..a.ncols())
        .map(|j| sym.col_range(j).any(|k| val[k] != 0.0))
        .collect()
}

/// The partition of `sys`, or why the interface form does not apply. `max_interior_dofs`
/// bounds each interior (its modes come from a dense eigen-solve).
pub fn partition(sys: &FeSystem, max_interior_dofs: usize) -> Result<Partition, NotApplicable> {
    if matches!(sys.rayleigh, Some((a, b)) if a != 0.0 || b != 0.0) {
        return Err(NotApplicable::Rayleigh);
    }
    let sls_terms = sys
        .stiffness_terms
        .iter()
        .filter(|t| t.sls.is_some())
        .count();
    let interiors = sls_interiors(sys);
    if sls_terms == 0 || interiors.len() != sls_terms {
        return Err(NotApplicable::NoViscoelasticInterior);
    }
    let mut constant = sys.stiffness_terms.iter().filter(|t| t.sls.is_none());
    if let Some(first) = constant.next() {
        if constant.any(|t| t.loss_factor != first.loss_factor) {
            return Err(NotApplicable::MixedConstantLoss);
        }
    }
    if let Some(big) = interiors.iter().find(|r| r.dofs.len() > max_interior_dofs) {
        return Err(NotApplicable::InteriorTooLarge(big.dofs.len()));
    }
    let n = sys.n_free;
    let mut in_interior = vec![false; n];
    for r in &interiors {
        r.dofs.iter().for_each(|&d| in_interior[d] = true);
    }
    if interiors
        .iter()
        .flat_map(|r| &r.dofs)
        .any(|&d| sys.force[d] != 0.0)
    {
        return Err(NotApplicable::LoadInInterior);
    }
    let mut on_interface = vec![false; n];
    for r in &interiors {
        let mut mine = vec![false; n];
        r.dofs.iter().for_each(|&d| mine[d] = true);
        let term = &sys.stiffness_terms[r.term];
        let by_k = columns_reaching(&term.matrix, &mine);
        let by_m = columns_reaching(&sys.mass, &mine);
        let mut boundary = vec![false; n];
        for j in 0..n {
            if (by_k[j] || by_m[j]) && !mine[j] {
                if in_interior[j] {
                    return Err(NotApplicable::Unstructured(format!(
                        "the interiors of {} and another region are coupled",
                        term.name
                    )));
                }
                boundary[j] = true;
            }
        }
        if let Some(d) = touched(&term.matrix)
            .iter()
            .enumerate()
            .position(|(j, &t)| t && !mine[j] && !boundary[j])
        {
            return Err(NotApplicable::Unstructured(format!(
                "{} touches dof {d}, which is neither its interior nor its interface",
                term.name
            )));
        }
        for j in 0..n {
            on_interface[j] |= boundary[j];
        }
    }
    let interface: Vec<usize> = (0..n).filter(|&j| on_interface[j]).collect();
    let mut interface_index = vec![None; n];
    for (k, &d) in interface.iter().enumerate() {
        interface_index[d] = Some(k);
    }
    Ok(Partition {
        interiors,
        interface,
        interface_index,
        in_interior,
    })
}
