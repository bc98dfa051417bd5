//! The missing physics a diagnosis can name, each a change that the model file can express
//! (FORMATS.md §3), and the update that applies it to a model.

use crate::sim::model::{Damping, Edge, EdgeSpring, Model, PointMass, Rayleigh};
use crate::sim::Sls;

use super::regions::Region;

/// One change to the model.
#[derive(Clone, Debug, PartialEq)]
pub enum Hypothesis {
    /// A point mass the model lacks (`[[point_mass]]`).
    AddedMass {
        /// Position, m.
        x_m: f64,
        /// Position, m.
        y_m: f64,
        /// Mass, kg.
        mass_kg: f64,
    },
    /// A region whose Young's modulus is `youngs_factor` times the plate's (`[[patch]]` with
    /// `youngs_modulus`).
    StiffnessChange {
        /// The region.
        region: Region,
        /// E_region / E_plate.
        youngs_factor: f64,
    },
    /// An edge held by distributed z springs (`[[edge_spring]]`), instead of pinned when the
    /// model pins it, or added when the model leaves it free.
    BoundaryCompliance {
        /// The edge.
        edge: Edge,
        /// Spring stiffness per metre of edge, N/m².
        stiffness_per_length: f64,
        /// Whether the model pinned the edge (the spring replaces the pin).
        was_pinned: bool,
    },
    /// Extra frequency-independent loss in a region (`[[patch]]` with `loss_factor`).
    LocalizedDamping {
        /// The region.
        region: Region,
        /// Loss factor added to the plate's.
        delta_g: f64,
    },
    /// A viscoelastic region: a standard linear solid whose loss peaks at one frequency, with
    /// the stiffening that goes with it and, if the data asks for it, a layer's added mass
    /// (`[[patch]]` with `sls` and `density`).
    ViscoelasticDamping {
        /// The region.
        region: Region,
        /// The region's modulus law (e_inf, e, eta).
        sls: Sls,
        /// Peak loss factor of the law (what the damping evidence measured).
        peak_loss: f64,
        /// Frequency of the loss peak, Hz.
        peak_hz: f64,
        /// ρ_region / ρ_plate (1: no added mass).
        density_factor: f64,
    },
    /// The plate's damping law replaced: loss factor g (every plate region) and Rayleigh
    /// damping C = αM + βK₀ (`[material] loss_factor`, `[damping] rayleigh`).
    DampingLaw {
        /// Structural loss factor of the plate.
        loss_factor: f64,
        /// α, 1/s.
        alpha: f64,
        /// β, s.
        beta: f64,
    },
}

impl Hypothesis {
    /// The FORMATS.md §5 kind.
    pub fn kind(&self) -> &'static str {
        match self {
            Hypothesis::AddedMass { .. } => "added_mass",
            Hypothesis::StiffnessChange { .. } => "stiffness_change",
            Hypothesis::BoundaryCompliance { .. } => "boundary_compliance",
            Hypothesis::LocalizedDamping { .. } => "localized_damping",
            Hypothesis::ViscoelasticDamping { .. } => "viscoelastic_damping",
            Hypothesis::DampingLaw { .. } => "damping_law",
        }
    }

    /// This hypothesis with a viscoelastic layer's density factor set to `factor` (other kinds
    /// unchanged).
    pub fn with_density_factor(&self, factor: f64) -> Hypothesis {
        let mut h = self.clone();
        if let Hypothesis::ViscoelasticDamping { density_factor, .. } = &mut h {
            *density_factor = factor;
        }
        h
    }

    /// The region, for region kinds.
    pub fn region(&self) -> Option<Region> {
        match self {
            Hypothesis::StiffnessChange { region, .. }
            | Hypothesis::LocalizedDamping { region, .. }
            | Hypothesis::ViscoelasticDamping { region, .. } => Some(*region),
            _ => None,
        }
    }

    /// Whether the change leaves the undamped modes alone (loss only): a view of the updated
    /// model may then reuse the modes.
    pub fn is_loss_only(&self) -> bool {
        matches!(
            self,
            Hypothesis::LocalizedDamping { .. } | Hypothesis::DampingLaw { .. }
        )
    }

    /// The same change at another region (for a region kind; others unchanged).
    pub fn with_region(&self, r: Region) -> Hypothesis {
        let mut h = self.clone();
        match &mut h {
            Hypothesis::StiffnessChange { region, .. }
            | Hypothesis::LocalizedDamping { region, .. }
            | Hypothesis::ViscoelasticDamping { region, .. } => *region = r,
            _ => {}
        }
        h
    }

    /// `model` with the change applied. Patches are appended, so they take precedence over
    /// the model's own where they overlap.
    pub fn apply(&self, model: &Model) -> Model {
        let mut m = model.clone();
        let base = &model.material;
        match self {
            Hypothesis::AddedMass { x_m, y_m, mass_kg } => m.point_masses.push(PointMass {
                x: *x_m,
                y: *y_m,
                mass: *mass_kg,
            }),
            Hypothesis::StiffnessChange {
                region,
                youngs_factor,
            } => m.patches.push(crate::sim::model::Patch {
                youngs_modulus: Some(base.youngs_modulus * youngs_factor),
                ..region.patch()
            }),
            Hypothesis::BoundaryCompliance {
                edge,
                stiffness_per_length,
                ..
            } => {
                m.supports.pinned_edges.retain(|e| e != edge.name());
                m.edge_springs.retain(|s| s.edge != edge.name());
                m.edge_springs.push(EdgeSpring {
                    edge: edge.name().to_string(),
                    stiffness_per_length: *stiffness_per_length,
                });
            }
            Hypothesis::LocalizedDamping { region, delta_g } => {
                m.patches.push(crate::sim::model::Patch {
                    loss_factor: Some(base.loss_factor + delta_g),
                    ..region.patch()
                })
            }
            Hypothesis::ViscoelasticDamping {
                region,
                sls,
                density_factor,
                ..
            } => m.patches.push(crate::sim::model::Patch {
                density: (*density_factor != 1.0).then(|| base.density * density_factor),
                sls: Some(*sls),
                ..region.patch()
            }),
            Hypothesis::DampingLaw {
                loss_factor,
                alpha,
                beta,
            } => {
                // Patches that only inherited the plate's loss inherit the new one; patches
                // with their own loss factor keep it.
                m.material.loss_factor = *loss_factor;
                m.damping = (*alpha > 0.0 || *beta > 0.0).then_some(Damping {
                    rayleigh: Rayleigh {
                        alpha: *alpha,
                        beta: *beta,
                    },
                });
            }
        }
        m
    }
}

/// The standard linear solid whose loss factor E''/E' peaks at `peak_loss` at `peak_hz`, with
/// relaxed modulus `e_inf_pa`. For E* = e_inf + e·jωτ/(1 + jωτ), r = e/e_inf, the loss peaks
/// at ωτ = 1/√(1 + r) with the value r/(2√(1 + r)); so r = 2η(η + √(η² + 1)).
pub fn sls_with_peak(e_inf_pa: f64, peak_loss: f64, peak_hz: f64) -> Sls {
    let eta = peak_loss.max(0.0);
    let r = 2.0 * eta * (eta + (eta * eta + 1.0).sqrt());
    let e = (r * e_inf_pa).max(1e-12 * e_inf_pa);
    let tau = 1.0 / (2.0 * std::f64::consts::PI * peak_hz * (1.0 + r).sqrt());
    Sls {
        e,
        e_inf: e_inf_pa,
        eta: e * tau,
    }
}

/// The loss factor E''/E' of `sls` at `f_hz`.
pub fn sls_loss(sls: &Sls, f_hz: f64) -> f64 {
    let (re, im) = sls.modulus(2.0 * std::f64::consts::PI * f_hz);
    im / re
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_sls_built_for_a_peak_has_that_peak() {
        for (eta, f0) in [(0.05, 40.0), (0.3, 90.0), (1.0, 10.0)] {
            let sls = sls_with_peak(7e10, eta, f0);
            let at = sls_loss(&sls, f0);
            assert!((at / eta - 1.0).abs() < 1e-9, "{eta}: {at}");
            assert!(sls_loss(&sls, f0 * 1.05) < at && sls_loss(&sls, f0 / 1.05) < at);
        }
    }

    #[test]
    fn a_soft_edge_replaces_the_pin() {
        let model = Model::reference_plate();
        let h = Hypothesis::BoundaryCompliance {
            edge: Edge::Y1,
            stiffness_per_length: 5e6,
            was_pinned: true,
        };
        let m = h.apply(&model);
        assert_eq!(m.supports.pinned_edges, vec!["y0".to_string()]);
        assert_eq!(m.edge_springs.len(), 1);
        m.validate().unwrap();
        let law = Hypothesis::DampingLaw {
            loss_factor: 0.0,
            alpha: 9.4,
            beta: 2.3e-5,
        }
        .apply(&model);
        assert_eq!(law.material.loss_factor, 0.0);
        assert_eq!(law.damping.unwrap().rayleigh.alpha, 9.4);
    }
}
