//! Impulse responses (eq. 3.1) against the analytic single-dof impulse response.

use dampscope::sim::impulse::{impulse_response, uniform_grid};
use faer::c64;

const TAU: f64 = 2.0 * std::f64::consts::PI;

/// m ẍ + c ẋ + k x = δ(t): x(t) = e^{−ζωₙt} sin(ω_d t)/(m ω_d); for t > 0,
/// ẍ = −(c ẋ + k x)/m, plus δ(t)/m at t = 0.
#[test]
fn sdof_accelerance_gives_the_analytic_impulse_response() {
    let (m, fn_hz, zeta) = (2.0, 20.0, 0.02);
    let wn = TAU * fn_hz;
    let (k, c) = (m * wn * wn, 2.0 * zeta * wn * m);
    let (fmax, df) = (2000.0, 0.25);
    let n = (fmax / df) as usize + 1;
    let freqs: Vec<f64> = (0..n).map(|i| i as f64 * df).collect();
    assert_eq!(uniform_grid(&freqs).unwrap(), (df, fmax));
    let acc: Vec<c64> = freqs
        .iter()
        .map(|f| {
            let w = TAU * f;
            c64::new(-w * w, 0.0) / c64::new(k - w * w * m, w * c)
        })
        .collect();
    let h = impulse_response(&acc, fmax).unwrap();
    assert_eq!(h.len(), 2 * (n - 1));
    let dt = 1.0 / (2.0 * fmax);
    let wd = wn * (1.0 - zeta * zeta).sqrt();
    let analytic = |t: f64| {
        let e = (-zeta * wn * t).exp();
        let x = e * (wd * t).sin() / (m * wd);
        let v = e * (wd * (wd * t).cos() - zeta * wn * (wd * t).sin()) / (m * wd);
        -(c * v + k * x) / m
    };
    let amp = wn / m; // envelope of ẍ at t = 0+
    let mut worst: f64 = 0.0;
    for (i, hi) in h.iter().enumerate().take(h.len() / 2).skip(1) {
        worst = worst.max((hi - analytic(i as f64 * dt)).abs());
    }
    eprintln!(
        "max |h − h_analytic| = {:.3e} of the envelope {amp:.3e}",
        worst
    );
    assert!(worst < 5e-3 * amp, "worst {worst} vs envelope {amp}");
    // the mass line 1/m over the whole band is a discrete delta of weight 1/m: h[0] ≈ 2 fmax/m
    let want0 = 2.0 * fmax / m;
    assert!(
        (h[0] - want0).abs() < 0.01 * want0,
        "h[0] = {} vs {want0}",
        h[0]
    );
    // energy of the response decays at the analytic rate: compare 0.5 s windows 1 s apart
    let energy = |t0: f64| -> f64 {
        let a = (t0 / dt) as usize;
        h[a..a + (0.5 / dt) as usize].iter().map(|x| x * x).sum()
    };
    let ratio_db = 10.0 * (energy(0.5) / energy(1.5)).log10();
    let want_db = 10.0 * (2.0 * zeta * wn).exp().log10();
    assert!(
        (ratio_db - want_db).abs() < 0.05,
        "{ratio_db} vs {want_db} dB"
    );
}

#[test]
fn bad_grids_are_errors() {
    assert!(uniform_grid(&[0.0]).is_err());
    assert!(uniform_grid(&[0.0, 1.0, 2.5]).is_err());
    assert!(uniform_grid(&[1.0, 2.0, 3.0]).is_err());
    assert!(impulse_response(&[c64::new(0.0, 0.0)], 10.0).is_err());
    assert!(impulse_response(&[c64::new(0.0, 0.0); 3], -1.0).is_err());
}

/// Peak-SNR noise: σ = max|h| · 10^(−snr/20) per channel, reproducible from the seed.
#[test]
fn noise_has_the_requested_peak_snr_and_is_seeded() {
    use dampscope::sim::frf::Frf;
    use dampscope::sim::simulate::impulse_responses;
    let (fmax, n) = (1000.0, 4001);
    let freqs: Vec<f64> = (0..n).map(|i| i as f64 * fmax / (n - 1) as f64).collect();
    // receptance of a SDOF at 50 Hz, two sensors with different gains
    let rec = |f: f64, g: f64| {
        let w = TAU * f;
        let wn = TAU * 50.0;
        c64::new(g, 0.0) / c64::new(wn * wn - w * w, 0.02 * wn * w)
    };
    let frf = Frf {
        frequencies_hz: freqs.clone(),
        sensor_ids: vec!["a".into(), "b".into()],
        receptance_m_per_n: faer::Mat::from_fn(n, 2, |k, s| rec(freqs[k], 1.0 + 9.0 * s as f64)),
    };
    let clean = impulse_responses(&frf, fmax, None, 0).unwrap();
    let noisy = impulse_responses(&frf, fmax, Some(30.0), 7).unwrap();
    let again = impulse_responses(&frf, fmax, Some(30.0), 7).unwrap();
    assert_eq!(noisy, again);
    for (c, x) in clean.iter().zip(&noisy) {
        let peak = c.iter().fold(0.0f64, |a, v| a.max(v.abs()));
        let sigma = 10f64.powf(-30.0 / 20.0) * peak;
        let var: f64 = c.iter().zip(x).map(|(a, b)| (b - a).powi(2)).sum::<f64>() / c.len() as f64;
        let got = var.sqrt();
        // 8000 samples: the rms estimate is within ±3 % (≈ 4 standard errors)
        assert!((got / sigma - 1.0).abs() < 0.03, "rms {got} vs σ {sigma}");
    }
    assert!(impulse_responses(&frf, fmax, Some(f64::NAN), 0).is_err());
}
