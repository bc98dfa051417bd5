//! Building the interface form of a system (see the parent module): the basis
//! [Ψ | Ξ | Φ_I] and the interface matrices it projects to.

use std::time::Instant;

use faer::linalg::solvers::Solve;
use faer::sparse::SparseColMat;
use faer::{Mat, MatRef, Side};

use super::super::eigen::{check_modes, lowest_modes, ModeRequest, Modes};
use super::super::frf::FrfError;
use super::super::reduced::{factor_only, m_orthonormalise_columns, spmm, static_solver};
use super::super::substructure::{
    interior_modes, on_free_dofs, with_massless_interiors, MODE_CHECK_TOLERANCE,
};
use super::super::system::FeSystem;
use super::super::SimError;
use super::partition::Partition;
use super::{InterfaceModel, ModalGroup};

/// Wall-clock time of the building steps, s.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct BuildTimings {
    /// Modes of the structure with massless interiors (Lanczos) and of every interior (dense).
    pub modes_s: f64,
    /// Static shapes, the plate's modes with the interface held, projections.
    pub reduction_s: f64,
}

/// The basis of the interface form over the free dofs, kept only for checks (tests compare
/// the interface solve with a dense Galerkin solve on it).
pub struct InterfaceBasis {
    /// Ψ (n × r): the static response to a unit displacement of each interface dof.
    pub interface_shapes: Mat<f64>,
    /// Ξ (n × n_ζ): the plate's modes with the interface held, zero on the interface and the
    /// interiors, M-orthonormal.
    pub plate_modes: Mat<f64>,
    /// Φ_I of every region (n × n_r), zero outside its interior.
    pub interior_modes: Vec<Mat<f64>>,
}

/// A sparse matrix times each of `cols`' columns, as Ψᵀ A Ψ-style products: `left`ᵀ (A `right`).
fn project(
    left: MatRef<'_, f64>,
    a: &SparseColMat<usize, f64>,
    right: MatRef<'_, f64>,
) -> Mat<f64> {
    let ar = spmm(a, right);
    left.transpose() * &ar
}

/// The interface form of `sys` on `part`: modes of the structure with massless interiors below
/// `cutoff_hz` (free-interface modes), every interior's modes with mass, the static shapes of
/// the interface and of the load. `None` when the modes with massless interiors fail their
/// residual check ([`MODE_CHECK_TOLERANCE`]).
pub fn build(
    sys: &FeSystem,
    part: &Partition,
    cutoff_hz: f64,
    keep_basis: bool,
) -> Result<Option<(InterfaceModel, BuildTimings, Option<InterfaceBasis>)>, SimError> {
    let mut timings = BuildTimings::default();
    let n = sys.n_free;
    let r = part.interface.len();
    let t = Instant::now();
    // the Lanczos solve (one core, bound by memory) beside the interiors' eigen-solves and the
    // interface's static shapes, which do not need its modes
    let (free_modes, statics) = std::thread::scope(|sc| {
        let lanczos = sc.spawn(|| free_interface_modes(sys, part, cutoff_hz));
        let statics = interface_statics(sys, part);
        let modes = lanczos
            .join()
            .unwrap_or_else(|_| Err(SimError::Eigen("the Lanczos worker panicked".into())));
        (modes, statics)
    });
    let Some(free_modes) = free_modes? else {
        return Ok(None);
    };
    let InterfaceStatics {
        psi,
        m_psi,
        statics,
        interiors,
    } = statics?;
    timings.modes_s = t.elapsed().as_secs_f64();
    let t = Instant::now();
    // the plate's modes with the interface held: the free-interface modes and the static load
    // response without their interface traces, M-orthonormalised, then diagonalised
    let nb = free_modes.shapes.ncols();
    let mut cand = Mat::from_fn(n, nb + 1, |i, j| {
        if j < nb {
            free_modes.shapes[(i, j)]
        } else {
            statics[(i, 0)]
        }
    });
    drop(free_modes);
    let trace = Mat::from_fn(r, nb + 1, |k, j| cand[(part.interface[k], j)]);
    cand -= &psi * &trace;
    for d in (0..n).filter(|&d| part.interface_index[d].is_some() || part.in_interior[d]) {
        for j in 0..nb + 1 {
            cand[(d, j)] = 0.0;
        }
    }
    let empty = Mat::<f64>::zeros(n, 0);
    let held = m_orthonormalise_columns(&sys.mass, empty.as_ref(), empty.as_ref(), cand)?;
    let constant_terms: Vec<usize> = (0..sys.stiffness_terms.len())
        .filter(|&t| sys.stiffness_terms[t].sls.is_none())
        .collect();
    let mut k_held = Mat::<f64>::zeros(held.ncols(), held.ncols());
    for &t in &constant_terms {
        k_held += project(held.as_ref(), &sys.stiffness_terms[t].matrix, held.as_ref());
    }
    let evd = symmetric(k_held)
        .self_adjoint_eigen(Side::Lower)
        .map_err(|e| FrfError::Factorisation {
            what: "plate modes with the interface held".into(),
            message: format!("{e:?}"),
        })?;
    let nu: Vec<f64> = evd.S().column_vector().iter().copied().collect();
    let xi = &held * evd.U();
    drop(held);

    let mass = psi.transpose() * &m_psi;
    let mut plate_stiffness = Mat::<f64>::zeros(r, r);
    for &t in &constant_terms {
        plate_stiffness += project(psi.as_ref(), &sys.stiffness_terms[t].matrix, psi.as_ref());
    }
    let mut groups = vec![ModalGroup {
        coupling: m_psi.transpose() * &xi,
        eigenvalues: nu,
        load: (0..xi.ncols())
            .map(|j| (0..n).map(|i| xi[(i, j)] * sys.force[i]).sum())
            .collect(),
        factor: factor_only(constant_factor_term(sys))?,
    }];
    let mut region_stiffness = Vec::new();
    for (ri, modes) in part.interiors.iter().zip(&interiors) {
        let term = &sys.stiffness_terms[ri.term];
        region_stiffness.push((
            factor_only(term)?,
            project(psi.as_ref(), &term.matrix, psi.as_ref()),
        ));
        let m_psi_interior = Mat::from_fn(ri.dofs.len(), r, |i, k| m_psi[(ri.dofs[i], k)]);
        groups.push(ModalGroup {
            coupling: m_psi_interior.transpose() * &modes.shapes,
            eigenvalues: modes
                .frequencies_hz
                .iter()
                .map(|f| (2.0 * std::f64::consts::PI * f).powi(2))
                .collect(),
            load: vec![0.0; modes.shapes.ncols()],
            factor: factor_only(term)?,
        });
    }
    drop(m_psi);
    let load: Vec<f64> = (0..r)
        .map(|k| (0..n).map(|i| psi[(i, k)] * sys.force[i]).sum())
        .collect();
    let weights = sensor_weights(sys, part, &psi, &xi, &interiors);
    timings.reduction_s = t.elapsed().as_secs_f64();
    let basis = keep_basis.then(|| InterfaceBasis {
        interior_modes: part
            .interiors
            .iter()
            .zip(&interiors)
            .map(|(ri, m)| on_free_dofs(n, ri, &m.shapes))
            .collect(),
        interface_shapes: psi,
        plate_modes: xi,
    });
    let model = InterfaceModel {
        interface_dofs: r,
        plate_stiffness,
        region_stiffness,
        mass: symmetric(mass),
        groups,
        load,
        weights,
        sensor_ids: sys.sensors.iter().map(|s| s.id.clone()).collect(),
    };
    Ok(Some((model, timings, basis)))
}

/// The modes of the structure with massless interiors below `cutoff_hz`; `None` when they fail
/// their residual check ([`MODE_CHECK_TOLERANCE`]).
fn free_interface_modes(
    sys: &FeSystem,
    part: &Partition,
    cutoff_hz: f64,
) -> Result<Option<Modes>, SimError> {
    let massless = with_massless_interiors(sys, &part.interiors)?;
    let free_modes = lowest_modes(&massless, ModeRequest::BelowHz(cutoff_hz))?;
    let (residual, orthogonality) = check_modes(&massless, &free_modes)?;
    let suspect = |x: f64| x.is_nan() || x > MODE_CHECK_TOLERANCE;
    Ok((!(suspect(residual) || suspect(orthogonality))).then_some(free_modes))
}

/// What the interface form needs that does not depend on the free-interface modes.
struct InterfaceStatics {
    /// Ψ, n × r.
    psi: Mat<f64>,
    /// M Ψ.
    m_psi: Mat<f64>,
    /// K₀⁻¹ f (n × 1).
    statics: Mat<f64>,
    /// Every region's interior modes (over its own dofs).
    interiors: Vec<Modes>,
}

/// The interiors' modes with mass, the interface's static shapes Ψ (with one step of iterative
/// refinement) and the static load response.
fn interface_statics(sys: &FeSystem, part: &Partition) -> Result<InterfaceStatics, SimError> {
    let n = sys.n_free;
    let r = part.interface.len();
    let interiors: Vec<Modes> = part
        .interiors
        .iter()
        .map(|ri| interior_modes(sys, ri, f64::INFINITY))
        .collect::<Result<_, _>>()?;
    let llt = static_solver(sys)?;
    // Ψ = K₀⁻¹ P_Γᵀ (P_Γ K₀⁻¹ P_Γᵀ)⁻¹: unit interface displacements, statically continued
    let mut flex = Mat::<f64>::zeros(n, r);
    for (k, &d) in part.interface.iter().enumerate() {
        flex[(d, k)] = 1.0;
    }
    llt.solve_in_place(flex.as_mut());
    let flex_interface = Mat::from_fn(r, r, |i, j| {
        0.5 * (flex[(part.interface[i], j)] + flex[(part.interface[j], i)])
    });
    let flex_llt = flex_interface
        .llt(Side::Lower)
        .map_err(|e| FrfError::Factorisation {
            what: "interface flexibility".into(),
            message: format!("{e:?}"),
        })?;
    let mut psi_t = flex.transpose().to_owned();
    drop(flex);
    flex_llt.solve_in_place(psi_t.as_mut());
    let mut psi = psi_t.transpose().to_owned();
    drop(psi_t);
    set_identity_trace(&mut psi, &part.interface);
    // one step of iterative refinement: K₀Ψ must vanish off the interface (Ξ and Φ_r are
    // uncoupled from Ψ only then); its round-off residual would couple the lowest held plate
    // modes to the interface at ~1e-5
    let mut residual = Mat::<f64>::zeros(n, r);
    for t in &sys.stiffness_terms {
        residual += spmm(&t.matrix, psi.as_ref());
    }
    for &d in &part.interface {
        for j in 0..r {
            residual[(d, j)] = 0.0;
        }
    }
    llt.solve_in_place(residual.as_mut());
    psi -= &residual;
    let trace_error = Mat::from_fn(r, r, |k, j| residual[(part.interface[k], j)]);
    drop(residual);
    psi = &psi + &psi * &trace_error;
    set_identity_trace(&mut psi, &part.interface);
    let f = Mat::from_fn(n, 1, |i, _| sys.force[i]);
    let statics = llt.solve(f.as_ref());
    let m_psi = spmm(&sys.mass, psi.as_ref());
    Ok(InterfaceStatics {
        psi,
        m_psi,
        statics,
        interiors,
    })
}

/// Sets the interface rows of Ψ to the identity (they are, to round-off).
fn set_identity_trace(psi: &mut Mat<f64>, interface: &[usize]) {
    let r = psi.ncols();
    for (k, &d) in interface.iter().enumerate() {
        for j in 0..r {
            psi[(d, j)] = if j == k { 1.0 } else { 0.0 };
        }
    }
}

/// (A + Aᵀ)/2.
fn symmetric(a: Mat<f64>) -> Mat<f64> {
    Mat::from_fn(a.nrows(), a.ncols(), |i, j| 0.5 * (a[(i, j)] + a[(j, i)]))
}

/// The first frequency-independent term (all share one factor, see the partition), or the
/// first term when every term is viscoelastic.
fn constant_factor_term(sys: &FeSystem) -> &super::super::system::StiffnessTerm {
    sys.stiffness_terms
        .iter()
        .find(|t| t.sls.is_none())
        .unwrap_or(&sys.stiffness_terms[0])
}

/// Sensor rows of the basis [Ψ | Ξ | Φ_I of every region] (sensor × basis vector).
fn sensor_weights(
    sys: &FeSystem,
    part: &Partition,
    psi: &Mat<f64>,
    xi: &Mat<f64>,
    interiors: &[Modes],
) -> Mat<f64> {
    let r = psi.ncols();
    let nz = xi.ncols();
    let total = r + nz + interiors.iter().map(|m| m.shapes.ncols()).sum::<usize>();
    // local index of each interior dof in its region
    let mut local = vec![None; sys.n_free];
    for (g, ri) in part.interiors.iter().enumerate() {
        for (i, &d) in ri.dofs.iter().enumerate() {
            local[d] = Some((g, i));
        }
    }
    let mut offsets = Vec::new();
    let mut at = r + nz;
    for m in interiors {
        offsets.push(at);
        at += m.shapes.ncols();
    }
    let mut w = Mat::<f64>::zeros(sys.sensors.len(), total);
    for (s, sensor) in sys.sensors.iter().enumerate() {
        for &(d, wt) in &sensor.weights {
            for k in 0..r {
                w[(s, k)] += wt * psi[(d, k)];
            }
            for j in 0..nz {
                w[(s, r + j)] += wt * xi[(d, j)];
            }
            if let Some((g, i)) = local[d] {
                let shapes = &interiors[g].shapes;
                for c in 0..shapes.ncols() {
                    w[(s, offsets[g] + c)] += wt * shapes[(i, c)];
                }
            }
        }
    }
    w
}
