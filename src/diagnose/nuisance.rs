//! The model-form nuisance every frequency fit carries: the user's model is not the structure's
//! twin, and a correct model of another discretisation or plate theory differs from it by an
//! offset (a global stiffness or density error: every ln f moves alike) and a drift in f² (a
//! coarser mesh's discretisation error grows as (kh)²). Physics is only claimed for the part
//! of ln(f_measured / f_model) that these two columns cannot explain. A point mass, a stiffer
//! region or a soft edge are local: their patterns over the modes follow φ², a region's strain
//! energy or the edge's motion, not f.

/// The nuisance columns 1 and (f/f_max)² over the paired modes, orthonormalised, and least
/// squares with them profiled out.
#[derive(Clone, Debug)]
pub struct Nuisance {
    basis: Vec<Vec<f64>>,
}

impl Nuisance {
    /// The nuisance over modes of undamped frequencies `frequencies_hz` (one per pair).
    pub fn new(frequencies_hz: &[f64]) -> Self {
        let fmax = frequencies_hz.iter().copied().fold(1e-300, f64::max);
        let columns = [
            vec![1.0; frequencies_hz.len()],
            frequencies_hz.iter().map(|f| (f / fmax).powi(2)).collect(),
        ];
        let mut basis: Vec<Vec<f64>> = Vec::new();
        for c in columns {
            let mut v = c;
            for b in &basis {
                let d = dot(&v, b);
                v.iter_mut().zip(b).for_each(|(x, y)| *x -= d * y);
            }
            let norm = dot(&v, &v).sqrt();
            if norm > 1e-12 {
                basis.push(v.iter().map(|x| x / norm).collect());
            }
        }
        Self { basis }
    }

    /// Parameters the nuisance spends.
    pub fn params(&self) -> f64 {
        self.basis.len() as f64
    }

    /// `v` with its nuisance part removed (the projection onto the nuisance's complement).
    pub fn residual(&self, v: &[f64]) -> Vec<f64> {
        let mut r = v.to_vec();
        for b in &self.basis {
            let d = dot(&r, b);
            r.iter_mut().zip(b).for_each(|(x, y)| *x -= d * y);
        }
        r
    }

    /// Least squares of y = nuisance + m·a, m ≥ 0 when `non_negative`: (m, residual sum of
    /// squares).
    pub fn fit(&self, y: &[f64], a: &[f64], non_negative: bool) -> (f64, f64) {
        let (yr, ar) = (self.residual(y), self.residual(a));
        let (ay, aa) = (dot(&ar, &yr), dot(&ar, &ar));
        let mut m = if aa > 0.0 { ay / aa } else { 0.0 };
        if non_negative {
            m = m.max(0.0);
        }
        (m, (dot(&yr, &yr) - 2.0 * m * ay + m * m * aa).max(0.0))
    }
}

/// Σ aᵢbᵢ.
pub fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An offset and an f² drift are explained away entirely; a pattern unlike both is not.
    #[test]
    fn offset_and_drift_are_profiled_out() {
        let f = [5.0, 11.0, 21.0, 30.0, 36.0, 48.0];
        let nuisance = Nuisance::new(&f);
        let y: Vec<f64> = f.iter().map(|f| 0.003 - 1e-6 * f * f).collect();
        let r = nuisance.residual(&y);
        assert!(dot(&r, &r) < 1e-20, "{r:?}");
        let a = [0.0, -0.01, 0.0, -0.01, 0.0, 0.0];
        let with: Vec<f64> = y.iter().zip(&a).map(|(y, a)| y + 0.5 * a).collect();
        let (m, rss) = nuisance.fit(&with, &a, true);
        assert!((m - 0.5).abs() < 1e-9 && rss < 1e-20, "{m} {rss}");
        assert_eq!(nuisance.fit(&with, &a.map(|v| -v), true).0, 0.0);
    }
}
