//! Cross-checks against pyrato's own reference results (tests/data/pyrato, from shared/reference/pyrato_tests).

use dampscope::decay::lundeby::{lundeby, LundebySettings};

fn reference_dir() -> std::path::PathBuf {
    let d = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/pyrato");
    assert!(d.is_dir(), "reference data missing: {}", d.display());
    d
}

fn read_matrix(path: &std::path::Path) -> Vec<Vec<f64>> {
    std::fs::read_to_string(path)
        .unwrap()
        .lines()
        .filter(|l| !l.trim().is_empty() && !l.starts_with('#'))
        .map(|l| {
            l.split(',')
                .map(|v| v.trim().parse::<f64>().unwrap())
                .collect()
        })
        .collect()
}

#[test]
fn lundeby_matches_pyrato_intersection_time() {
    let dir = reference_dir();
    let rows = read_matrix(&dir.join("analytic_rir_psnr50_2D.csv"));
    let expected = read_matrix(&dir.join("intersection_time_2D.csv"));
    for (ch, rir) in rows.iter().enumerate() {
        let energy: Vec<f64> = rir.iter().map(|x| x * x).collect();
        let got = lundeby(&energy, 3000.0, &LundebySettings::default()).expect("lundeby");
        let (t_i, t_late, noise) = (expected[0][ch], expected[1][ch], expected[2][ch]);
        eprintln!(
            "ch{ch}: t_i {} vs {t_i}, T_late {} vs {t_late}, N {} vs {noise}",
            got.intersection_time_s, got.late_t60_s, got.noise_energy
        );
        assert!((got.intersection_time_s / t_i - 1.0).abs() < 1e-9, "t_i");
        assert!((got.late_t60_s / t_late - 1.0).abs() < 1e-9, "T_late");
        assert!((got.noise_energy / noise - 1.0).abs() < 1e-9, "noise");
    }
}
