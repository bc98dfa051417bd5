//! The assembled finite-element system: the seam between the model/element/assembly side of the
//! simulator and the response side (modes, FRFs, impulse responses).
//!
//! Only free (unconstrained) degrees of freedom appear. The dynamic stiffness at circular
//! frequency ω is
//!
//! ```text
//! K(ω) = Σ_r s_r(ω) · K_r,      s_r(ω) = (1 + j g_r)                      (structural damping)
//!                               s_r(ω) = E*(ω)/E_ref,r · (1 + j g_r)      (viscoelastic SLS region)
//! ```
//!
//! and the equation of motion in the frequency domain is (K(ω) + jω C − ω² M) u = f, with
//! C = α M + β K₀ (Rayleigh) and K₀ = Σ_r K_r (every region at its reference modulus).

use faer::sparse::SparseColMat;

/// Standard linear solid of FORMATS.md §3 / report eq. 2.12:
/// E*(ω) = ((1/(jωη) + 1/e)⁻¹ + e_inf). Moduli in Pa, η in Pa·s.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Sls {
    /// Spring of the Maxwell arm, Pa.
    pub e: f64,
    /// Parallel (relaxed) spring, Pa: the modulus at ω = 0.
    pub e_inf: f64,
    /// Dashpot of the Maxwell arm, Pa·s.
    pub eta: f64,
}

impl Sls {
    /// Complex modulus E*(ω) = e_inf + e·jωτ/(1 + jωτ), τ = η/e, as (real, imaginary) in Pa.
    pub fn modulus(&self, omega_rad_s: f64) -> (f64, f64) {
        let x = omega_rad_s * self.eta / self.e;
        let d = 1.0 + x * x;
        (self.e_inf + self.e * x * x / d, self.e * x / d)
    }
}

/// One region's share of the stiffness, with how it varies with frequency.
#[derive(Clone, Debug)]
pub struct StiffnessTerm {
    /// A short name for logs and diagnosis ("plate", "patch 1", "edge spring y1", …).
    pub name: String,
    /// K_r over the free dofs, assembled with the region's reference modulus `reference_modulus_pa`.
    pub matrix: SparseColMat<usize, f64>,
    /// Structural loss factor g_r: K_r (1 + j g_r).
    pub loss_factor: f64,
    /// For a viscoelastic region: its SLS; the matrix is then scaled by E*(ω)/reference_modulus_pa.
    pub sls: Option<Sls>,
    /// The Young's modulus the matrix was assembled with, Pa (for an SLS region: `sls.e_inf`).
    pub reference_modulus_pa: f64,
}

impl StiffnessTerm {
    /// The complex factor s_r(ω) that multiplies `matrix` at circular frequency ω, as (re, im).
    pub fn factor(&self, omega_rad_s: f64) -> (f64, f64) {
        let (er, ei) = match &self.sls {
            Some(sls) => {
                let (a, b) = sls.modulus(omega_rad_s);
                (a / self.reference_modulus_pa, b / self.reference_modulus_pa)
            }
            None => (1.0, 0.0),
        };
        // (er + j ei)(1 + j g)
        let g = self.loss_factor;
        (er - ei * g, ei + er * g)
    }
}

/// A sensor's z displacement as a weighted sum of free dofs (interpolated inside its element).
#[derive(Clone, Debug, PartialEq)]
pub struct SensorWeights {
    /// Sensor id.
    pub id: String,
    /// Position in plate coordinates, m.
    pub x_m: f64,
    /// Position in plate coordinates, m.
    pub y_m: f64,
    /// (free dof index, weight) pairs.
    pub weights: Vec<(usize, f64)>,
}

/// The assembled system over the free dofs.
#[derive(Clone, Debug)]
pub struct FeSystem {
    /// Number of free dofs.
    pub n_free: usize,
    /// Consistent mass matrix (plus point masses), kg.
    pub mass: SparseColMat<usize, f64>,
    /// Stiffness per region (plate, patches, edge springs), N/m.
    pub stiffness_terms: Vec<StiffnessTerm>,
    /// Rayleigh coefficients (α in 1/s, β in s): C = α M + β K₀. `None` for no viscous damping.
    pub rayleigh: Option<(f64, f64)>,
    /// Load vector over the free dofs for the model's excitation, N.
    pub force: Vec<f64>,
    /// Output sensors.
    pub sensors: Vec<SensorWeights>,
}
