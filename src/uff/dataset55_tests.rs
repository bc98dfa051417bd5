//! Dataset 55: round trips in both precisions, raw analyses, broken records.
use super::*;
use crate::uff::{parse_uff, Dataset};

fn close(a: f64, b: f64, rel: f64) -> bool {
    (a - b).abs() <= rel * a.abs().max(b.abs()).max(1e-300)
}

fn shape_nodes(per_node: usize, complex: bool) -> Vec<NodeValues> {
    (1..=4)
        .map(|node| NodeValues {
            node: node * 10,
            values: (0..per_node)
                .map(|k| {
                    let x = (node as f64 * 1.37 + k as f64 * 0.731).sin() / 3.0;
                    Complex::new(x, if complex { -x * 0.456_789_123_456 } else { 0.0 })
                })
                .collect(),
        })
        .collect()
}

fn round_trip(s: &ModeShape55) -> ModeShape55 {
    let mut out = Vec::new();
    write_mode_shape55(&mut out, s).unwrap();
    match parse_uff(&out).unwrap().datasets.remove(0) {
        Dataset::ModeShape(m) => *m,
        other => panic!("{other:?}"),
    }
}

fn assert_close_shapes(a: &ModeShape55, b: &ModeShape55, rel: f64) {
    assert_eq!(a.nodes.len(), b.nodes.len());
    for (p, q) in a.nodes.iter().zip(&b.nodes) {
        assert_eq!(p.node, q.node);
        for (x, y) in p.values.iter().zip(&q.values) {
            assert!(
                close(x.re, y.re, rel) && close(x.im, y.im, rel),
                "{x} vs {y}"
            );
        }
    }
    let (fa, fb) = (
        a.analysis.frequency_hz().unwrap(),
        b.analysis.frequency_hz().unwrap(),
    );
    assert!(close(fa, fb, rel), "{fa} vs {fb}");
    let (da, db) = (
        a.analysis.damping_ratio().unwrap(),
        b.analysis.damping_ratio().unwrap(),
    );
    assert!(close(da, db, rel), "{da} vs {db}");
    let mut c = b.clone();
    (c.nodes, c.analysis) = (a.nodes.clone(), a.analysis.clone());
    assert_eq!(a, &c);
}

#[test]
fn normal_and_complex_modes_round_trip_to_1e_12_in_double_precision() {
    let mut normal =
        ModeShape55::normal_mode(3, 56.789_012_345_67, 0.024_977_123_4, shape_nodes(6, false));
    normal.double_precision = true;
    assert_eq!(normal.data_characteristic, 3);
    assert_close_shapes(&normal, &round_trip(&normal), 1e-12);
    let mut cplx =
        ModeShape55::complex_mode(7, 123.456_789_012_3, 0.012_345_678_9, shape_nodes(3, true));
    cplx.double_precision = true;
    let back = round_trip(&cplx);
    assert_close_shapes(&cplx, &back, 1e-12);
    assert!(close(
        back.analysis.damping_ratio().unwrap(),
        0.012_345_678_9,
        1e-12
    ));
    assert!(close(
        back.analysis.frequency_hz().unwrap(),
        123.456_789_012_3,
        1e-12
    ));
}

#[test]
fn single_precision_follows_the_spec_and_keeps_6_digits() {
    let s = ModeShape55::complex_mode(1, 5.2314, 0.024_599, shape_nodes(3, true));
    let mut out = Vec::new();
    write_mode_shape55(&mut out, &s).unwrap();
    let text = String::from_utf8(out).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    assert_eq!(
        lines[7],
        "         1         3         2         8         5         3"
    );
    assert_eq!(lines[8], "         2         6         1         1");
    assert_eq!(lines[9].len(), 78, "{:?}", lines[9]);
    let back = round_trip(&s);
    assert!(!back.double_precision);
    assert_close_shapes(&s, &back, 5e-6);
}

#[test]
fn other_analyses_are_kept_raw_and_broken_records_named() {
    let f = "    -1\n    55\nNONE\nNONE\nNONE\nNONE\nNONE\n         1         5         2         8         2         3\n         2         1         1        17\n  1.25000E+02\n         4\n  1.00000E+00 -2.00000E+00  3.00000E+00\n    -1\n";
    let c = parse_uff(f.as_bytes()).unwrap();
    let m = c.mode_shapes().next().unwrap();
    assert_eq!(
        m.analysis,
        ShapeAnalysis::Other {
            analysis_type: 5,
            integers: vec![1, 17],
            reals: vec![125.0]
        }
    );
    assert_eq!(m.nodes[0].node, 4);
    assert_eq!(m.nodes[0].values[1], Complex::new(-2.0, 0.0));
    let bad = f.replace(
        "  1.00000E+00 -2.00000E+00  3.00000E+00",
        "  1.00000E+00 -2.00000E+00",
    );
    let e = parse_uff(bad.as_bytes()).unwrap_err();
    assert!(matches!(e, UffError::Truncated { .. }), "{e}");
    assert!(e.to_string().contains("node 4"), "{e}");
    let bad = f.replace("         2         3\n", "         3         3\n");
    let e = parse_uff(bad.as_bytes()).unwrap_err();
    assert!(e.to_string().contains("data type"), "{e}");
    let mut s = ModeShape55::normal_mode(1, 10.0, 0.01, shape_nodes(3, true));
    assert!(write_mode_shape55(&mut Vec::new(), &s).is_err());
    s.complex = true;
    s.nodes[2].values.pop();
    let e = write_mode_shape55(&mut Vec::new(), &s).unwrap_err();
    assert!(e.to_string().contains("node 30"), "{e}");
}
