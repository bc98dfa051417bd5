//! Issue 12, hit streams: per-decay results combined with their spread. A stream of hits on a
//! structure of known damping, piped through `analyze --summary`, gives per band one row whose
//! count is the number of hits and whose median D is the structure's; `summarize` of the
//! results table gives the same. The quantiles are checked against a slow oracle.

use proptest::prelude::*;

use crate::common::{add_at, csv_rows, fresh_dir, gaussian_noise, rel_err, test_hit, TestCommand};
use dampscope::analysis::spread::{quantile, Spread};
use dampscope::decay::Flag;
use dampscope::frontend::Band;

/// The median by sorting and indexing: the middle value, or the mean of the two middle ones.
fn median_oracle(v: &[f64]) -> f64 {
    let mut s = v.to_vec();
    s.sort_by(f64::total_cmp);
    let n = s.len();
    if n % 2 == 1 {
        s[n / 2]
    } else {
        0.5 * (s[n / 2 - 1] + s[n / 2])
    }
}

/// The type-7 quantile the slow way: the straight line through the sorted values placed at
/// k/(n − 1), k = 0 … n − 1, evaluated at p by walking the segments.
fn quantile_oracle(v: &[f64], p: f64) -> f64 {
    let mut s = v.to_vec();
    s.sort_by(f64::total_cmp);
    let n = s.len();
    if n == 1 {
        return s[0];
    }
    for k in 0..n - 1 {
        let (a, b) = (k as f64 / (n - 1) as f64, (k + 1) as f64 / (n - 1) as f64);
        if p <= b {
            return s[k] + (p - a) / (b - a) * (s[k + 1] - s[k]);
        }
    }
    s[n - 1]
}

proptest! {
    #[test]
    fn quantiles_are_the_sorted_values_interpolated(
        v in prop::collection::vec(-1e3f64..1e3, 1..40),
        p in 0.0f64..=1.0,
    ) {
        let mut sorted = v.clone();
        sorted.sort_by(f64::total_cmp);
        let tol = 1e-9 * (1.0 + sorted[sorted.len() - 1].abs().max(sorted[0].abs()));
        prop_assert!((quantile(&sorted, 0.5).unwrap() - median_oracle(&v)).abs() <= tol);
        prop_assert!((quantile(&sorted, p).unwrap() - quantile_oracle(&v, p)).abs() <= tol);
        prop_assert_eq!(quantile(&sorted, 0.0), Some(sorted[0]));
        prop_assert_eq!(quantile(&sorted, 1.0), Some(sorted[sorted.len() - 1]));
    }

    #[test]
    fn the_spread_does_not_depend_on_the_order_of_the_decays(
        d in prop::collection::vec(prop::option::of(1e-4f64..0.1), 1..30),
        rotate in 0usize..30,
    ) {
        let band = Band::new(100.0, 140.0).unwrap();
        let gather = |d: &[Option<f64>]| {
            let mut s = Spread::new();
            for x in d {
                let flags = if x.is_none() { vec![Flag::PoorFit] } else { vec![] };
                s.add("a", band, *x, x.map(|x| 1.1 / (x * 120.0)), &flags);
            }
            s.rows()
        };
        let mut turned = d.clone();
        turned.rotate_left(rotate % d.len());
        let (a, b) = (gather(&d), gather(&turned));
        prop_assert_eq!(&a, &b);
        let numbers: Vec<f64> = d.iter().flatten().copied().collect();
        prop_assert_eq!(a[0].n_decays, d.len());
        prop_assert_eq!(a[0].n_estimated, numbers.len());
        if !numbers.is_empty() {
            prop_assert!((a[0].d_median.unwrap() - median_oracle(&numbers)).abs() < 1e-15);
        }
    }
}

const FS: f64 = 4000.0;
/// (f_hz, D) of the two modes every hit excites: T60 0.92 s and 0.73 s.
const MODES: [(f64, f64); 2] = [(120.0, 0.01), (300.0, 0.005)];
/// Hits, 3 s apart.
const HITS: usize = 8;
/// The hit that bounces (a rebound of 0.4 after 10 ms).
const BOUNCING: usize = 5;

/// The stream as raw little-endian f32: hits of different strengths and phases over white
/// noise 60 dB below the strongest.
fn hit_stream() -> Vec<u8> {
    let seconds = 3.0 * HITS as f64;
    let n = (seconds * FS) as usize;
    let mut x = gaussian_noise(n, 1e-3, 5);
    for k in 0..HITS {
        let hit = test_hit(&MODES, k, FS, 3.0);
        let start = (3.0 * k as f64 * FS) as usize;
        add_at(&mut x, start, &hit, 1.0);
        if k == BOUNCING {
            add_at(&mut x, start + (0.010 * FS) as usize, &hit, 0.4);
        }
    }
    x.iter().flat_map(|v| (*v as f32).to_le_bytes()).collect()
}

#[test]
fn a_hit_stream_summarised_gives_each_band_its_damping_and_its_count() {
    let dir = fresh_dir("cli-summarize");
    let (results, summary) = (dir.join("results.csv"), dir.join("summary.csv"));
    TestCommand::new([
        "analyze",
        "-",
        "--raw",
        "f32",
        "--fs",
        "4000",
        "--channels",
        "1",
    ])
    .args(["--band", "100:140", "--band", "280:320", "--out"])
    .arg(&results)
    .arg("--summary")
    .arg(&summary)
    .stdin(&hit_stream())
    .ok();
    let table = csv_rows(&results);
    let rows = csv_rows(&summary);
    assert_eq!(rows.len(), MODES.len(), "{rows:?}");
    for (row, &(f, want)) in rows.iter().zip(&MODES) {
        let num = |k: &str| -> f64 { row[k].parse().unwrap_or_else(|_| panic!("{k}: {row:?}")) };
        assert!(num("f_lo_hz") < f && f < num("f_hi_hz"), "{row:?}");
        assert_eq!(row["channel"], "ch0");
        assert_eq!(
            num("n_decays") as usize,
            HITS,
            "every hit is a decay: {row:?}"
        );
        assert_eq!(num("n_estimated") as usize, HITS, "{row:?}");
        assert_eq!(row["missing"], "");
        let median = num("d_median");
        println!(
            "{f} Hz: median D {median} (true {want}), IQR {}",
            num("d_iqr")
        );
        assert!(
            rel_err(median, want) < 0.02,
            "{f} Hz: median D {median}, true {want}"
        );
        let (lo, q1, q3, hi) = (num("d_min"), num("d_q1"), num("d_q3"), num("d_max"));
        assert!(
            lo <= q1 && q1 <= median && median <= q3 && q3 <= hi,
            "{row:?}"
        );
        assert!((num("d_iqr") - (q3 - q1)).abs() < 1e-12);
        // The same as sorting the table's own numbers (written to 6 decimals there).
        let d: Vec<f64> = table
            .iter()
            .filter(|r| r["f_lo"].parse::<f64>().unwrap() < f && f < r["f_hi"].parse().unwrap())
            .map(|r| r["damping_ratio"].parse().unwrap())
            .collect();
        assert_eq!(d.len(), HITS);
        assert!(
            (median - median_oracle(&d)).abs() < 1e-6,
            "{median} vs {d:?}"
        );
        assert!((q1 - quantile_oracle(&d, 0.25)).abs() < 1e-6);
        assert!((num("t60_median_s") - 1.1 / (want * f)).abs() < 0.03 * 1.1 / (want * f));
        // The bouncing hit is the one decay flagged double_hit.
        assert!(
            row["flags"].split(';').any(|f| f == "double_hit:1"),
            "{row:?}"
        );
        let flagged = num("flagged_share");
        assert!((1.0 / HITS as f64..=1.0).contains(&flagged), "{row:?}");
    }

    // `summarize` of the table, from the file and from standard input, gives the same rows
    // (to the table's six decimals).
    let from_file = TestCommand::new(["summarize"]).arg(&results).ok();
    let from_stdin = TestCommand::new(["summarize", "-"])
        .stdin(&std::fs::read(&results).unwrap())
        .ok();
    assert_eq!(from_file, from_stdin);
    let again = dir.join("again.csv");
    std::fs::write(&again, &from_file).unwrap();
    for (a, b) in csv_rows(&again).iter().zip(&rows) {
        for (k, v) in b {
            match (v.parse::<f64>(), a[k].parse::<f64>()) {
                (Ok(x), Ok(y)) => assert!((x - y).abs() < 2e-6, "{k}: {x} vs {y}"),
                _ => assert_eq!(&a[k], v, "{k}"),
            }
        }
    }
}

#[test]
fn summarize_refuses_what_is_not_a_results_table() {
    let dir = fresh_dir("cli-summarize-bad");
    let bad = dir.join("bad.csv");
    std::fs::write(&bad, "time,ch0\n0,1\n").unwrap();
    let out = TestCommand::new(["summarize"]).arg(&bad).output();
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("no column \"channel\""), "{err}");
    let out = TestCommand::new(["summarize"])
        .arg(dir.join("absent.csv"))
        .output();
    assert_eq!(out.status.code(), Some(1));
}
