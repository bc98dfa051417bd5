//! The interface form: the fast FRF of models with viscoelastic regions, solved per frequency on
//! the regions' interface only.
//!
//! Why: a soft viscoelastic patch has hundreds of local modes (the example's has 1047 below
//! 2.6 kHz). Kept as coordinates of one reduced model they make every frequency a dense solve of
//! size ~1700, or one state-space eigen-solve of size ~4700 (minutes either way). But each
//! interior mode touches the rest of the structure only through the interface Γ (the dofs next
//! to the interior, 324 on the example), and only through the mass; the plate's modes with Γ
//! held touch Γ only through the mass too. In the basis
//!
//! ```text
//! u = Ψ u_Γ + Ξ ζ + Σ_r Φ_r η_r
//! ```
//!
//! - Ψ: static shapes of unit interface displacements, K₀⁻¹P_Γᵀ(P_Γ K₀⁻¹ P_Γᵀ)⁻¹ (the interiors
//!   follow statically);
//! - Ξ: the plate's modes with Γ and the interiors held, taken within the span of the modes of
//!   the structure with massless interiors (below the cut-off) and the static load response,
//!   each without its interface trace — the same span as those vectors and Ψ, so the same
//!   accuracy as the Craig–Bampton basis with residual vectors ([`super::substructure`]), which
//!   free-interface modes give and fixed-interface plate modes do not;
//! - Φ_r: every interior's fixed-interface modes with mass (K_r,ii φ = λ M_ii φ, all of them,
//!   so the interior is represented exactly);
//!
//! the stiffness does not couple the three groups (Ψ is static, Ξ and Φ_r vanish on Γ, and the
//! regions' stiffness is K₀-orthogonal to Ψ), the Ξ and Φ_r blocks are diagonal, and both
//! couple to u_Γ through the mass only. Eliminating ζ and η exactly leaves, at every ω, an
//! r × r complex system on the interface,
//!
//! ```text
//! [k_c K_Γ + Σ_r k_r(ω) K̃_r − ω² M_Γ − ω⁴ Σ_groups Σ_j a_j a_jᵀ/(k_g λ_j − ω²)] u_Γ
//!     = f_Γ + ω² Σ_j a_j f_j/(k_g λ_j − ω²),
//! ```
//!
//! then x_j = (f_j + ω² a_jᵀ u_Γ)/(k_g λ_j − ω²) for every modal coordinate: a sum of rank-one
//! terms and one dense LU of the interface per frequency, instead of a solve of the whole
//! reduced model. Any frequency dependence that is a scalar factor per region (the standard
//! linear solid, a structural loss) is exact; Rayleigh damping and regions of different
//! constant loss are not supported here (the caller falls back to [`super::reduced`]).

mod blocks;
mod build;
mod ldlt;
mod partition;
mod sweep;

pub use build::{build, BuildTimings, InterfaceBasis};
pub use partition::{partition, NotApplicable, Partition};
pub use sweep::ModalSums;

use faer::Mat;

use super::system::StiffnessTerm;

/// Modal coordinates that couple to the interface through the mass only: the plate's modes with
/// the interface held (group 0) or one region's interior modes.
#[derive(Clone, Debug)]
pub struct ModalGroup {
    /// Column j: a_j, the interface mass coupling of mode j (r entries).
    pub coupling: Mat<f64>,
    /// λ_j, rad²/s², at the group's reference stiffness.
    pub eigenvalues: Vec<f64>,
    /// f_j, the modal load (zero for interior modes).
    pub load: Vec<f64>,
    /// The stiffness factor k_g(ω) of the group's modes (its matrix is a placeholder).
    pub factor: StiffnessTerm,
}

/// The interface form of a system: everything its per-frequency solve needs.
#[derive(Clone, Debug)]
pub struct InterfaceModel {
    /// Number of interface dofs r.
    pub interface_dofs: usize,
    /// Ψᵀ K_c Ψ, the frequency-independent regions' stiffness on the interface (factor of
    /// group 0).
    pub plate_stiffness: Mat<f64>,
    /// Ψᵀ K_r Ψ of every viscoelastic region, with its factor.
    pub region_stiffness: Vec<(StiffnessTerm, Mat<f64>)>,
    /// Ψᵀ M Ψ.
    pub mass: Mat<f64>,
    /// The plate's held modes, then each region's interior modes.
    pub groups: Vec<ModalGroup>,
    /// Ψᵀ f.
    pub load: Vec<f64>,
    /// Sensor rows of the basis [Ψ | Ξ | Φ_1 | …] (sensor × basis vector).
    pub weights: Mat<f64>,
    /// Sensor ids (rows of `weights`).
    pub sensor_ids: Vec<String>,
}

impl InterfaceModel {
    /// Number of basis vectors: interface dofs plus every group's modes.
    pub fn basis_size(&self) -> usize {
        self.interface_dofs
            + self
                .groups
                .iter()
                .map(|g| g.eigenvalues.len())
                .sum::<usize>()
    }
}
