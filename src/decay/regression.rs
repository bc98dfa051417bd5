//! Least-squares line fits of the normalised Schroeder curve in dB against time.

/// A straight line `level_db = intercept_db + slope_db_per_s · t` fitted to decay points.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LineFit {
    /// Slope in dB per second (negative for a decay).
    pub slope_db_per_s: f64,
    /// Level at t = 0 in dB.
    pub intercept_db: f64,
    /// Coefficient of determination of the fit.
    pub r2: f64,
    /// Number of points fitted.
    pub n_points: usize,
}

impl LineFit {
    /// Time for a 60 dB fall at the fitted slope, in seconds; `None` when the line does not fall.
    pub fn t60_s(&self) -> Option<f64> {
        (self.slope_db_per_s < 0.0).then(|| -60.0 / self.slope_db_per_s)
    }
}

/// Fits a line to `(times_s[i], levels_db[i])`. `None` with fewer than 2 points or zero time span.
pub fn fit_line(times_s: &[f64], levels_db: &[f64]) -> Option<LineFit> {
    let n = times_s.len().min(levels_db.len());
    if n < 2 {
        return None;
    }
    let nf = n as f64;
    let t_mean = times_s[..n].iter().sum::<f64>() / nf;
    let l_mean = levels_db[..n].iter().sum::<f64>() / nf;
    let (mut stt, mut stl, mut sll) = (0.0, 0.0, 0.0);
    for i in 0..n {
        let dt = times_s[i] - t_mean;
        let dl = levels_db[i] - l_mean;
        stt += dt * dt;
        stl += dt * dl;
        sll += dl * dl;
    }
    if stt <= 0.0 {
        return None;
    }
    let slope = stl / stt;
    let r2 = if sll > 0.0 {
        (stl * stl) / (stt * sll)
    } else {
        1.0
    };
    Some(LineFit {
        slope_db_per_s: slope,
        intercept_db: l_mean - slope * t_mean,
        r2,
        n_points: n,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn recovers_an_exact_line() {
        let t: Vec<f64> = (0..50).map(|i| i as f64 * 0.01).collect();
        let l: Vec<f64> = t.iter().map(|t| 3.0 - 60.0 * t / 1.7).collect();
        let fit = fit_line(&t, &l).unwrap();
        assert!((fit.t60_s().unwrap() - 1.7).abs() < 1e-12);
        assert!((fit.intercept_db - 3.0).abs() < 1e-12);
        assert!((fit.r2 - 1.0).abs() < 1e-12);
    }

    #[test]
    fn rising_line_has_no_t60() {
        let fit = fit_line(&[0.0, 1.0, 2.0], &[0.0, 1.0, 2.0]).unwrap();
        assert_eq!(fit.t60_s(), None);
    }
}
