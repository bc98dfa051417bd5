//! Frequency response functions of an assembled [`FeSystem`]: the direct solution of report
//! eq. 2.6 (the slow reference), the container [`Frf`] shared by every method, and the error
//! measure of report eq. 4.8.
//!
//! At each circular frequency ω the direct solution solves the complex sparse system
//!
//! ```text
//! (Σ_r s_r(ω) K_r + jω C − ω² M) u = f,      C = α M + β K₀
//! ```
//!
//! with faer's sparse LU. The sparsity pattern never changes, so the symbolic factorisation is
//! computed once and reused for every frequency; only the numeric factorisation is repeated.

use faer::c64;
use faer::dyn_stack::{MemBuffer, MemStack};
use faer::sparse::linalg::lu::{factorize_symbolic_lu, NumericLu, SymbolicLu};
use faer::sparse::{SparseColMat, SparseColMatRef, SymbolicSparseColMat, Triplet};
use faer::{Conj, Mat, Par};

use super::assembly::sparse_from_triplets;
use super::system::{FeSystem, SensorWeights};

/// What went wrong while computing responses (FRFs, reduced models, impulse responses).
#[derive(Debug, thiserror::Error)]
pub enum FrfError {
    /// An input has the wrong size: `what` names it.
    #[error("{what}: expected {expected}, got {got}")]
    Dimension {
        /// Which input (e.g. `stiffness term 'patch 1'`, `sensor 'S12' weight dof`).
        what: String,
        /// Expected size or bound.
        expected: String,
        /// What was found.
        got: String,
    },
    /// An input value is unusable (negative frequency, NaN, unknown mode number, …).
    #[error("{what}: {message}")]
    Invalid {
        /// Which input.
        what: String,
        /// Expected vs got.
        message: String,
    },
    /// A matrix could not be factorised (singular at that frequency, out of memory, …).
    #[error("{what}: factorisation failed: {message}")]
    Factorisation {
        /// Which matrix, with the frequency if any.
        what: String,
        /// The solver's message.
        message: String,
    },
}

fn invalid(what: impl Into<String>, message: impl Into<String>) -> FrfError {
    FrfError::Invalid {
        what: what.into(),
        message: message.into(),
    }
}

/// Frequency responses at every sensor of a system, for one excitation (the system's load
/// vector `force`, N).
#[derive(Clone, Debug)]
pub struct Frf {
    /// The analysis frequencies, Hz.
    pub frequencies_hz: Vec<f64>,
    /// Sensor ids, in column order of `receptance_m_per_n`.
    pub sensor_ids: Vec<String>,
    /// Receptance (displacement per force), m/N: row = frequency, column = sensor.
    pub receptance_m_per_n: Mat<c64>,
}

impl Frf {
    /// Number of sensors (columns).
    pub fn n_sensors(&self) -> usize {
        self.receptance_m_per_n.ncols()
    }

    /// Receptance of one sensor over all frequencies, m/N.
    pub fn receptance(&self, sensor: usize) -> Vec<c64> {
        self.receptance_m_per_n
            .col(sensor)
            .iter()
            .copied()
            .collect()
    }

    /// Accelerance of one sensor, (m/s²)/N = −ω² × receptance: the sensors measure
    /// acceleration.
    pub fn accelerance(&self, sensor: usize) -> Vec<c64> {
        self.receptance_m_per_n
            .col(sensor)
            .iter()
            .zip(&self.frequencies_hz)
            .map(|(h, f)| {
                let w = 2.0 * std::f64::consts::PI * f;
                *h * (-w * w)
            })
            .collect()
    }
}

/// Checks that every matrix, the load and the sensors fit `n_free`, and that values are finite.
pub fn validate_system(sys: &FeSystem) -> Result<(), FrfError> {
    let n = sys.n_free;
    if n == 0 {
        return Err(invalid("system", "expected at least one free dof, got 0"));
    }
    let square = |what: &str, m: &SparseColMat<usize, f64>| -> Result<(), FrfError> {
        if m.nrows() != n || m.ncols() != n {
            return Err(FrfError::Dimension {
                what: what.to_string(),
                expected: format!("{n} × {n}"),
                got: format!("{} × {}", m.nrows(), m.ncols()),
            });
        }
        if m.val().iter().any(|v| !v.is_finite()) {
            return Err(invalid(
                what,
                "expected finite entries, got NaN or infinity",
            ));
        }
        Ok(())
    };
    square("mass matrix", &sys.mass)?;
    if sys.stiffness_terms.is_empty() {
        return Err(invalid(
            "stiffness terms",
            "expected at least one, got none",
        ));
    }
    for t in &sys.stiffness_terms {
        square(&format!("stiffness term '{}'", t.name), &t.matrix)?;
        if !t.loss_factor.is_finite() || t.loss_factor < 0.0 {
            return Err(invalid(
                format!("stiffness term '{}' loss factor", t.name),
                format!("expected finite ≥ 0, got {}", t.loss_factor),
            ));
        }
        if t.sls.is_some() && !(t.reference_modulus_pa.is_finite() && t.reference_modulus_pa > 0.0)
        {
            return Err(invalid(
                format!("stiffness term '{}' reference modulus", t.name),
                format!("expected > 0 Pa, got {}", t.reference_modulus_pa),
            ));
        }
    }
    if sys.force.len() != n {
        return Err(FrfError::Dimension {
            what: "load vector".into(),
            expected: format!("{n} entries"),
            got: format!("{}", sys.force.len()),
        });
    }
    if sys.force.iter().any(|v| !v.is_finite()) {
        return Err(invalid("load vector", "expected finite entries"));
    }
    for s in &sys.sensors {
        for &(dof, w) in &s.weights {
            if dof >= n || !w.is_finite() {
                return Err(invalid(
                    format!("sensor '{}' weights", s.id),
                    format!("expected dof < {n} and a finite weight, got ({dof}, {w})"),
                ));
            }
        }
    }
    if let Some((a, b)) = sys.rayleigh {
        if !a.is_finite() || !b.is_finite() {
            return Err(invalid(
                "rayleigh",
                format!("expected finite α, β, got ({a}, {b})"),
            ));
        }
    }
    Ok(())
}

/// Checks analysis frequencies: finite and ≥ 0 Hz.
pub fn validate_frequencies(freqs_hz: &[f64]) -> Result<(), FrfError> {
    for (i, f) in freqs_hz.iter().enumerate() {
        if !f.is_finite() || *f < 0.0 {
            return Err(invalid(
                format!("frequency #{i}"),
                format!("expected finite ≥ 0 Hz, got {f}"),
            ));
        }
    }
    Ok(())
}

/// Sensor value of a dof vector: Σ w_i u_i.
pub fn sensor_value(sensor: &SensorWeights, u: &[c64]) -> c64 {
    sensor
        .weights
        .iter()
        .fold(c64::new(0.0, 0.0), |acc, &(d, w)| acc + u[d] * w)
}

/// The direct solver: union sparsity pattern of M and every K_r, the maps from each matrix's
/// entries into it, and the symbolic LU computed once.
pub struct DirectSolver<'a> {
    sys: &'a FeSystem,
    pattern: SymbolicSparseColMat<usize>,
    mass_map: Vec<usize>,
    term_maps: Vec<Vec<usize>>,
    symbolic: SymbolicLu<usize>,
}

/// Index of each entry of `m` in the union pattern (both sorted by row within a column).
fn entry_map(pattern: &SymbolicSparseColMat<usize>, m: &SparseColMat<usize, f64>) -> Vec<usize> {
    let mut map = Vec::with_capacity(m.val().len());
    let (sym, _) = m.parts();
    let prow = pattern.row_idx();
    for j in 0..m.ncols() {
        let r = pattern.col_range(j);
        let rows = &prow[r.clone()];
        for k in sym.col_range(j) {
            let i = sym.row_idx()[k];
            // The union pattern holds every entry of m, so the search always succeeds.
            let pos = rows.binary_search(&i).unwrap_or(0);
            map.push(r.start + pos);
        }
    }
    map
}

impl<'a> DirectSolver<'a> {
    /// Builds the union pattern and its symbolic LU. Validates the system first.
    pub fn new(sys: &'a FeSystem) -> Result<Self, FrfError> {
        validate_system(sys)?;
        let n = sys.n_free;
        let mut trip = Vec::new();
        let mut push = |m: &SparseColMat<usize, f64>| {
            let (sym, _) = m.parts();
            for j in 0..n {
                for k in sym.col_range(j) {
                    trip.push(Triplet::new(sym.row_idx()[k], j, 0.0f64));
                }
            }
        };
        push(&sys.mass);
        for t in &sys.stiffness_terms {
            push(&t.matrix);
        }
        let union = sparse_from_triplets(n, &trip, "union sparsity pattern").map_err(|e| {
            FrfError::Factorisation {
                what: "union sparsity pattern".into(),
                message: e.to_string(),
            }
        })?;
        let pattern = union
            .symbolic()
            .to_owned()
            .map_err(|e| FrfError::Factorisation {
                what: "union sparsity pattern".into(),
                message: format!("{e:?}"),
            })?;
        let mass_map = entry_map(&pattern, &sys.mass);
        let term_maps = sys
            .stiffness_terms
            .iter()
            .map(|t| entry_map(&pattern, &t.matrix))
            .collect();
        let symbolic =
            factorize_symbolic_lu(pattern.as_ref(), Default::default()).map_err(|e| {
                FrfError::Factorisation {
                    what: "symbolic LU of the dynamic stiffness".into(),
                    message: format!("{e:?}"),
                }
            })?;
        Ok(Self {
            sys,
            pattern,
            mass_map,
            term_maps,
            symbolic,
        })
    }

    /// The values of the dynamic stiffness (Σ s_r K_r + jωC − ω²M) in the union pattern.
    fn dynamic_stiffness_values(&self, omega: f64) -> Vec<c64> {
        let mut vals = vec![c64::new(0.0, 0.0); self.pattern.row_idx().len()];
        let (alpha, beta) = self.sys.rayleigh.unwrap_or((0.0, 0.0));
        for (t, map) in self.sys.stiffness_terms.iter().zip(&self.term_maps) {
            let (sr, si) = t.factor(omega);
            let s = c64::new(sr, si + omega * beta);
            for (v, &k) in t.matrix.val().iter().zip(map) {
                vals[k] += s * *v;
            }
        }
        let sm = c64::new(-omega * omega, omega * alpha);
        for (v, &k) in self.sys.mass.val().iter().zip(&self.mass_map) {
            vals[k] += sm * *v;
        }
        vals
    }

    /// Displacements of every free dof at frequency `f_hz` for the system's load, m.
    pub fn solve(&self, f_hz: f64) -> Result<Vec<c64>, FrfError> {
        let omega = 2.0 * std::f64::consts::PI * f_hz;
        let vals = self.dynamic_stiffness_values(omega);
        let a = SparseColMatRef::new(self.pattern.as_ref(), &vals);
        // Single-threaded numeric LU: the callers already run one frequency per thread.
        let fail = |message: String| FrfError::Factorisation {
            what: format!("dynamic stiffness at {f_hz} Hz"),
            message,
        };
        let req = self
            .symbolic
            .factorize_numeric_lu_scratch::<c64>(Par::Seq, Default::default())
            .or(self.symbolic.solve_in_place_scratch::<c64>(1, Par::Seq));
        let mut mem = MemBuffer::try_new(req).map_err(|e| fail(format!("{e:?}")))?;
        let mut numeric = NumericLu::<usize, c64>::new();
        let lu = self
            .symbolic
            .factorize_numeric_lu(
                &mut numeric,
                a,
                Par::Seq,
                MemStack::new(&mut mem),
                Default::default(),
            )
            .map_err(|e| fail(format!("{e:?}")))?;
        let mut u =
            Mat::<c64>::from_fn(self.sys.n_free, 1, |i, _| c64::new(self.sys.force[i], 0.0));
        lu.solve_in_place_with_conj(Conj::No, u.as_mut(), Par::Seq, MemStack::new(&mut mem));
        let u: Vec<c64> = u.col(0).iter().copied().collect();
        if u.iter().any(|z| !z.re.is_finite() || !z.im.is_finite()) {
            return Err(FrfError::Factorisation {
                what: format!("dynamic stiffness at {f_hz} Hz"),
                message: "singular (non-finite solution)".into(),
            });
        }
        Ok(u)
    }
}

/// Direct FRF (report eq. 2.6) at every sensor: one sparse complex LU per frequency, split over
/// two threads. The slow reference against which the fast methods are tested.
pub fn direct_frf(sys: &FeSystem, freqs_hz: &[f64]) -> Result<Frf, FrfError> {
    validate_frequencies(freqs_hz)?;
    let solver = DirectSolver::new(sys)?;
    let ns = sys.sensors.len();
    let rows = parallel_rows(freqs_hz, 2, |f| {
        let u = solver.solve(f)?;
        Ok(sys.sensors.iter().map(|s| sensor_value(s, &u)).collect())
    })?;
    Ok(Frf {
        frequencies_hz: freqs_hz.to_vec(),
        sensor_ids: sys.sensors.iter().map(|s| s.id.clone()).collect(),
        receptance_m_per_n: Mat::from_fn(freqs_hz.len(), ns, |i, j| rows[i][j]),
    })
}

/// Evaluates `row(f)` for every frequency on `threads` scoped threads (contiguous chunks), and
/// returns the rows in frequency order; the first error wins.
pub(crate) fn parallel_rows<F>(
    freqs_hz: &[f64],
    threads: usize,
    row: F,
) -> Result<Vec<Vec<c64>>, FrfError>
where
    F: Fn(f64) -> Result<Vec<c64>, FrfError> + Sync,
{
    let threads = threads.max(1);
    let chunk = freqs_hz.len().div_ceil(threads).max(1);
    let results: Vec<Result<Vec<Vec<c64>>, FrfError>> = std::thread::scope(|sc| {
        let handles: Vec<_> = freqs_hz
            .chunks(chunk)
            .map(|part| {
                let row = &row;
                sc.spawn(move || part.iter().map(|&f| row(f)).collect())
            })
            .collect();
        handles
            .into_iter()
            .map(|h| {
                h.join().unwrap_or_else(|_| {
                    Err(invalid("worker thread", "a frequency worker panicked"))
                })
            })
            .collect()
    });
    let mut out = Vec::with_capacity(freqs_hz.len());
    for r in results {
        out.extend(r?);
    }
    Ok(out)
}

/// A frequency band [lo, hi] in Hz for [`band_error`] (inclusive at both ends).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FreqBand {
    /// Lower edge, Hz.
    pub lo_hz: f64,
    /// Upper edge, Hz.
    pub hi_hz: f64,
}

/// Report eq. 4.8: ε = Σ|H_est − H_ref| / Σ|H_ref| over the frequencies inside `band`.
///
/// Errors if the slices differ in length or no frequency falls in the band, or Σ|H_ref| = 0.
pub fn band_error(
    h_est: &[c64],
    h_ref: &[c64],
    freqs_hz: &[f64],
    band: FreqBand,
) -> Result<f64, FrfError> {
    if h_est.len() != freqs_hz.len() || h_ref.len() != freqs_hz.len() {
        return Err(FrfError::Dimension {
            what: "band_error inputs".into(),
            expected: format!("{} values (one per frequency)", freqs_hz.len()),
            got: format!("{} estimated, {} reference", h_est.len(), h_ref.len()),
        });
    }
    let (mut num, mut den, mut count) = (0.0, 0.0, 0usize);
    for ((e, r), f) in h_est.iter().zip(h_ref).zip(freqs_hz) {
        if *f >= band.lo_hz && *f <= band.hi_hz {
            num += (*e - *r).norm();
            den += r.norm();
            count += 1;
        }
    }
    if count == 0 || den <= 0.0 {
        return Err(invalid(
            format!("band {}–{} Hz", band.lo_hz, band.hi_hz),
            format!("expected frequencies with non-zero reference response, got {count} frequencies, Σ|H_ref| = {den}"),
        ));
    }
    Ok(num / den)
}
