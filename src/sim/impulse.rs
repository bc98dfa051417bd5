//! Impulse responses by inverse real FFT of the accelerance (report eq. 3.1).
//!
//! The accelerance H(f) (m/s² per N) is sampled at f_k = k·df, k = 0 … N−1, with
//! f_{N−1} = fmax. With L = 2(N−1) and Δt = 1/(2 fmax) = 1/(L df),
//!
//! ```text
//! h(nΔt) = ∫ H(f) e^{j2πf nΔt} df ≈ df Σ_{k=−(N−1)}^{N−1} H(f_k) e^{j2πkn/L}
//!        = 2 fmax · IFFT_L(H)_n          (IFFT_L normalised by 1/L)
//! ```
//!
//! using H(−f) = H(f)*. The result is the response to a unit impulse of force, in
//! (m/s²)/(N·s), at Δt = 1/(2 fmax), of length L = 1/(df Δt) samples (duration 1/df). The
//! imaginary parts of the DC and fmax bins are dropped (a real signal's spectrum is real there).

use faer::c64;
use realfft::RealFftPlanner;

use super::frf::FrfError;

/// Checks that `freqs_hz` is the grid 0, df, …, fmax (N ≥ 2 points) and returns (df, fmax).
pub fn uniform_grid(freqs_hz: &[f64]) -> Result<(f64, f64), FrfError> {
    let n = freqs_hz.len();
    if n < 2 {
        return Err(FrfError::Dimension {
            what: "impulse-response frequency grid".into(),
            expected: "at least 2 frequencies (0 and fmax)".into(),
            got: format!("{n}"),
        });
    }
    let fmax = freqs_hz[n - 1];
    let df = fmax / (n - 1) as f64;
    for (k, f) in freqs_hz.iter().enumerate() {
        let want = k as f64 * df;
        if !(f.is_finite() && (f - want).abs() <= 1e-9 * fmax.max(1.0)) || df <= 0.0 {
            return Err(FrfError::Invalid {
                what: format!("impulse-response frequency #{k}"),
                message: format!("expected the uniform grid k·df = {want} Hz (df = {df}), got {f}"),
            });
        }
    }
    Ok((df, fmax))
}

/// Impulse response (m/s²)/(N·s) at Δt = 1/(2 fmax) from the accelerance sampled at
/// 0, df, …, fmax (`h_hz.len()` = N ≥ 2). Length 2(N−1).
pub fn impulse_response(accelerance: &[c64], fmax_hz: f64) -> Result<Vec<f64>, FrfError> {
    let n = accelerance.len();
    if n < 2 {
        return Err(FrfError::Dimension {
            what: "accelerance".into(),
            expected: "at least 2 samples (0 and fmax)".into(),
            got: format!("{n}"),
        });
    }
    if !(fmax_hz.is_finite() && fmax_hz > 0.0) {
        return Err(FrfError::Invalid {
            what: "fmax".into(),
            message: format!("expected a finite frequency > 0 Hz, got {fmax_hz}"),
        });
    }
    let len = 2 * (n - 1);
    let mut planner = RealFftPlanner::<f64>::new();
    let c2r = planner.plan_fft_inverse(len);
    let mut spec: Vec<realfft::num_complex::Complex<f64>> = accelerance
        .iter()
        .map(|z| realfft::num_complex::Complex::new(z.re, z.im))
        .collect();
    spec[0].im = 0.0;
    spec[n - 1].im = 0.0;
    let mut out = c2r.make_output_vec();
    c2r.process(&mut spec, &mut out)
        .map_err(|e| FrfError::Invalid {
            what: "inverse FFT".into(),
            message: e.to_string(),
        })?;
    let scale = 2.0 * fmax_hz / len as f64;
    out.iter_mut().for_each(|x| *x *= scale);
    Ok(out)
}
