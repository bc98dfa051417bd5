//! Frequency responses kept as a product: modal responses (frequency × basis vector) times
//! sensor weights (sensor × basis vector).
//!
//! The fast and the truncated methods both compute H(f) = R(f) Wᵀ, with R small (a few hundred
//! basis vectors) and W one row per sensor. Keeping the two factors apart lets `simulate`
//! stream a recording set of any number of sensors (`super::stream`): the impulse responses are
//! made per basis vector and combined per block of samples, never held per sensor.

use faer::{c64, Mat};

use super::frf::Frf;

/// How the responses of a reduced model were solved (reported by `simulate --timings`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case", tag = "kind")]
pub enum FrfSolve {
    /// Modal superposition of a model whose damping does not depend on frequency (one real
    /// eigen-solve), or of truncated modes.
    #[default]
    Modal,
    /// One eigen-decomposition of the state-space form with this many states.
    StateSpace {
        /// Size of the state matrix.
        states: usize,
    },
    /// A dense LU of the reduced dynamic stiffness at every frequency.
    PerFrequencyLu,
    /// The interface form ([`super::interface`]): modal terms summed onto the viscoelastic
    /// regions' interface and one LU of it per frequency.
    Interface {
        /// Interface dofs (size of the per-frequency LU).
        interface_dofs: usize,
        /// Modal coordinates eliminated onto the interface.
        modes: usize,
    },
}

impl std::fmt::Display for FrfSolve {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            FrfSolve::Modal => write!(f, "modal superposition"),
            FrfSolve::StateSpace { states } => write!(f, "state space of {states} states"),
            FrfSolve::PerFrequencyLu => write!(f, "dense LU per frequency"),
            FrfSolve::Interface {
                interface_dofs,
                modes,
            } => write!(
                f,
                "interface form ({interface_dofs} interface dofs, {modes} modes)"
            ),
        }
    }
}

/// H(f) = `modal` × `weights`ᵀ: receptance (m/N) at every frequency and sensor.
#[derive(Clone, Debug)]
pub struct FactoredFrf {
    /// The analysis frequencies, Hz (rows of `modal`).
    pub frequencies_hz: Vec<f64>,
    /// Sensor ids (rows of `weights`).
    pub sensor_ids: Vec<String>,
    /// Response of each basis vector, m/N per unit weight: row = frequency, column = vector.
    pub modal: Mat<c64>,
    /// Weight of each basis vector at each sensor: row = sensor, column = vector.
    pub weights: Mat<c64>,
    /// How `modal` was solved.
    pub solve: FrfSolve,
}

impl FactoredFrf {
    /// Number of sensors.
    pub fn n_sensors(&self) -> usize {
        self.weights.nrows()
    }

    /// Number of basis vectors (the inner dimension of the product).
    pub fn basis_size(&self) -> usize {
        self.modal.ncols()
    }

    /// Whether every weight is real (the modal and truncated paths): the streamed impulse
    /// responses then need one time signal per basis vector instead of two.
    pub fn real_weights(&self) -> bool {
        (0..self.weights.ncols())
            .all(|j| (0..self.weights.nrows()).all(|i| self.weights[(i, j)].im == 0.0))
    }

    /// The full receptance matrix (frequency × sensor): the product, held in memory.
    pub fn to_frf(&self) -> Frf {
        Frf {
            frequencies_hz: self.frequencies_hz.clone(),
            sensor_ids: self.sensor_ids.clone(),
            receptance_m_per_n: &self.modal * self.weights.transpose(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn product_matches_the_sum_over_basis_vectors() {
        let modal = Mat::<c64>::from_fn(3, 2, |k, i| c64::new(k as f64 + 1.0, i as f64 - 0.5));
        let weights = Mat::<c64>::from_fn(4, 2, |s, i| c64::new(0.5 * s as f64, (i * s) as f64));
        let f = FactoredFrf {
            frequencies_hz: vec![0.0, 1.0, 2.0],
            sensor_ids: (0..4).map(|s| format!("S{s}")).collect(),
            modal: modal.clone(),
            weights: weights.clone(),
            solve: FrfSolve::Modal,
        };
        assert!(!f.real_weights());
        let full = f.to_frf();
        for k in 0..3 {
            for s in 0..4 {
                let want: c64 = (0..2).map(|i| modal[(k, i)] * weights[(s, i)]).sum();
                assert!((full.receptance_m_per_n[(k, s)] - want).norm() < 1e-12);
            }
        }
    }
}
