//! Dataset 58/58b: round trips, hand-written files in the spec's layouts, hostile input.

use super::*;
use crate::uff::write_function58;
use crate::uff::{parse_uff, Dataset, UffError};

fn close(a: f64, b: f64, rel: f64) -> bool {
    (a - b).abs() <= rel * a.abs().max(b.abs()).max(1e-300)
}

fn one_function(bytes: &[u8]) -> Function58 {
    let c = parse_uff(bytes).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(c.datasets.len(), 1, "{c:?}");
    match c.datasets.into_iter().next() {
        Some(Dataset::Function(f)) => *f,
        other => panic!("{other:?}"),
    }
}

fn written(f: &Function58) -> Vec<u8> {
    let mut out = Vec::new();
    write_function58(&mut out, f).unwrap();
    out
}

/// An FRF with values spread over many decades, both signs, a 3-digit exponent.
fn frf() -> Function58 {
    let values: Vec<Complex<f64>> = (0..11)
        .map(|k| {
            let x = k as f64 + 0.123_456_789_012_3;
            Complex::new(x.powi(7) * 1e-9 * (-1f64).powi(k), -1.0 / (x * 3.7e5))
        })
        .chain([Complex::new(
            1.234_567_890_123_4e-123,
            -9.876_543_210_987_6e99,
        )])
        .collect();
    let mut f = Function58::new(
        FunctionType::FrequencyResponse,
        NodeDof::new(12, 3),
        NodeDof::new(1, -3),
        Abscissa::Even {
            start: 0.0,
            increment: 0.25,
        },
        Ordinate::Complex(values),
    );
    f.id_lines[0] = "plate FRF 12+Z / 1-Z".into();
    f.id_lines[2] = "04-Mar-25 10:11:12".into();
    f.abscissa_axis = AxisInfo::new(18, "Frequency", "Hz");
    f.ordinate_axis = AxisInfo::new(12, "Acceleration", "m/s^2");
    f.denominator_axis = AxisInfo::new(13, "Force", "N");
    f.function_id = 7;
    f.response.entity = "PLATE".into();
    f
}

fn assert_same(a: &Function58, b: &Function58, rel: f64) {
    let (ya, yb) = (a.ordinate.to_complex(), b.ordinate.to_complex());
    assert_eq!(ya.len(), yb.len());
    for (k, (p, q)) in ya.iter().zip(&yb).enumerate() {
        assert!(
            close(p.re, q.re, rel) && close(p.im, q.im, rel),
            "point {k}: {p} vs {q}"
        );
    }
    let mut a2 = a.clone();
    a2.ordinate = b.ordinate.clone();
    assert_eq!(&a2, b);
}

#[test]
fn complex_frf_round_trips_to_1e_12() {
    let f = frf();
    let back = one_function(&written(&f));
    assert_same(&f, &back, 1e-12);
    assert!(back.double_precision && !back.binary);
}

#[test]
fn real_time_response_round_trips_to_1e_12() {
    let y: Vec<f64> = (0..9)
        .map(|i| (-(i as f64) * 0.3).exp() * (1.7 * i as f64).sin())
        .collect();
    let mut f = Function58::new(
        FunctionType::TimeResponse,
        NodeDof::new(4, 1),
        NodeDof::new(4, 1),
        Abscissa::Even {
            start: 0.0,
            increment: 1.0 / 4096.0,
        },
        Ordinate::Real(y),
    );
    f.abscissa_axis = AxisInfo::new(17, "Time", "s");
    let back = one_function(&written(&f));
    // The abscissa is single precision in the spec (E13.5 columns): 7 digits written.
    match back.abscissa {
        Abscissa::Even { start, increment } => {
            assert_eq!(start, 0.0);
            assert!(close(increment, 1.0 / 4096.0, 5e-7), "{increment}");
        }
        ref other => panic!("{other:?}"),
    }
    let mut g = back.clone();
    g.abscissa = f.abscissa.clone();
    assert_same(&f, &g, 1e-12);
}

#[test]
fn uneven_abscissa_real_and_complex_round_trip() {
    let x = vec![1.0, 2.5, 4.0, 8.125, 16.0];
    for ordinate in [
        Ordinate::Real(vec![1.0, -2.0, 3.333_333_333_333, 4e-20, 5e20]),
        Ordinate::Complex(
            (1..6)
                .map(|k| Complex::new(k as f64 / 3.0, -(k as f64) / 7.0))
                .collect(),
        ),
    ] {
        let f = Function58::new(
            FunctionType::Other(2),
            NodeDof::new(3, 2),
            NodeDof::new(3, 2),
            Abscissa::Uneven(x.clone()),
            ordinate,
        );
        let back = one_function(&written(&f));
        assert_eq!(back.function_type, FunctionType::Other(2));
        assert_same(&f, &back, 1e-12);
    }
}

/// A single-precision complex FRF in the spec's 6E13.5 layout with fields that touch (3-digit
/// negative exponents fill all 13 columns), D exponents and a letterless exponent.
const SINGLE_TOUCHING: &str = "    -1
    58
H_12Z_1Z
NONE
NONE
NONE
NONE
    4         1    1         0 NONE              12   3 NONE               1   3
         5         3         1  1.00000E+01  5.00000E-01  0.00000E+00
        18    0    0    0 Frequency            Hz
        12    0    0    0 Acceleration         m/s^2
        13    0    0    0 Force                N
         0    0    0    0 NONE                 NONE
-1.23456E-100-2.00000E-100  3.00000D+00   4.00000-01 -5.00000E+00  6.00000E+00
    -1
";

#[test]
fn single_precision_with_touching_fields_and_fortran_exponents() {
    let f = one_function(SINGLE_TOUCHING.as_bytes());
    assert_eq!(f.function_type, FunctionType::FrequencyResponse);
    assert_eq!((f.response.node, f.response.direction), (12, 3));
    assert_eq!((f.reference.node, f.reference.direction), (1, 3));
    assert_eq!(f.id_lines[0], "H_12Z_1Z");
    assert!(!f.double_precision);
    assert_eq!(
        f.abscissa,
        Abscissa::Even {
            start: 10.0,
            increment: 0.5
        }
    );
    assert_eq!(f.abscissa_values(), vec![10.0, 10.5, 11.0]);
    assert_eq!(
        f.ordinate,
        Ordinate::Complex(vec![
            Complex::new(-1.23456e-100, -2e-100),
            Complex::new(3.0, 0.4),
            Complex::new(-5.0, 6.0),
        ])
    );
    assert_eq!(f.ordinate_axis.units_label, "m/s^2");
    assert_eq!(f.ordinate_axis.specific_data_type, 12);
    assert_eq!(f.denominator_axis.label, "Force");
}

/// A 58b dataset per the UC-SDRL layout: `58b`, byte order, float format, 11 ASCII lines, byte
/// count; the header records; raw numbers; `-1`.
fn binary58(
    ordinate_type: i64,
    values: &[f64],
    little: bool,
    header_bytes: Option<usize>,
) -> Vec<u8> {
    let double = matches!(ordinate_type, 4 | 6);
    let complex = matches!(ordinate_type, 5 | 6);
    let n_points = values.len() / if complex { 2 } else { 1 };
    let size = values.len() * if double { 8 } else { 4 };
    let mut out = format!(
        "    -1\n    58b{:6}{:6}{:12}{:12}{:6}{:6}{:12}{:12}\n",
        if little { 1 } else { 2 },
        2,
        11,
        header_bytes.unwrap_or(size),
        0,
        0,
        0,
        0
    )
    .into_bytes();
    out.extend_from_slice(b"binary\nNONE\nNONE\nNONE\nNONE\n");
    out.extend_from_slice(
        b"    1         0    0         0 NONE               5   2 NONE               5   2\n",
    );
    out.extend_from_slice(
        format!(
            "{ordinate_type:10}{n_points:10}         1  0.00000E+00  1.00000E-03  0.00000E+00\n"
        )
        .as_bytes(),
    );
    for _ in 0..4 {
        out.extend_from_slice(b"         0    0    0    0 NONE                 NONE\n");
    }
    for v in values {
        match (double, little) {
            (true, true) => out.extend_from_slice(&v.to_le_bytes()),
            (true, false) => out.extend_from_slice(&v.to_be_bytes()),
            (false, true) => out.extend_from_slice(&(*v as f32).to_le_bytes()),
            (false, false) => out.extend_from_slice(&(*v as f32).to_be_bytes()),
        }
    }
    out.extend_from_slice(b"    -1\n");
    out
}

#[test]
fn binary_58b_in_both_byte_orders_and_precisions() {
    // 10.0 as little-endian f64 holds a '\n' byte (0x0a would be wrong to split on): the bytes
    // are taken by count, not by line.
    let values = [1.5, -2.25, 10.0, f64::from(0x0a0a_u16), 1e-3, -7.0];
    for (ty, little) in [
        (4, true),
        (4, false),
        (2, true),
        (2, false),
        (6, true),
        (5, false),
    ] {
        let f = one_function(&binary58(ty, &values, little, None));
        assert!(f.binary);
        assert_eq!(f.function_type, FunctionType::TimeResponse);
        let got: Vec<f64> = match &f.ordinate {
            Ordinate::Real(v) => v.clone(),
            Ordinate::Complex(v) => v.iter().flat_map(|z| [z.re, z.im]).collect(),
        };
        let tol = if matches!(ty, 4 | 6) { 0.0 } else { 1e-7 };
        for (a, b) in got.iter().zip(&values) {
            assert!(close(*a, *b, tol), "type {ty}, little {little}: {a} vs {b}");
        }
        assert_eq!(got.len(), values.len());
    }
}

#[test]
fn binary_58b_with_pyuffs_halved_byte_count_is_read_by_record_7() {
    // pyuff writes num_pts·8 as the byte count of complex double data (half of it).
    let values = [1.0, 2.0, 3.0, 4.0];
    let f = one_function(&binary58(6, &values, true, Some(16)));
    assert_eq!(
        f.ordinate,
        Ordinate::Complex(vec![Complex::new(1.0, 2.0), Complex::new(3.0, 4.0)])
    );
    // But data that is not followed by `-1` where record 7 says it ends is an error.
    let mut bad = binary58(6, &values, true, None);
    let n = bad.len();
    bad.insert(n - 8, b'x');
    let e = parse_uff(&bad).unwrap_err();
    assert!(e.to_string().contains("right after 32 bytes"), "{e}");
}

#[test]
fn binary_58b_claims_beyond_the_input_and_foreign_floats_are_refused() {
    let mut huge = binary58(6, &[1.0, 2.0], true, None);
    let text = String::from_utf8_lossy(&huge).replace(
        "         6         1         1",
        "         69999999999         1",
    );
    huge = text.into_bytes();
    let e = parse_uff(&huge).unwrap_err();
    assert!(matches!(e, UffError::Truncated { .. }), "{e}");
    let vms = String::from_utf8_lossy(&binary58(4, &[1.0], true, None)).replacen(
        "     1     2",
        "     1     1",
        1,
    );
    let e = parse_uff(vms.as_bytes()).unwrap_err();
    assert!(e.to_string().contains("IEEE"), "{e}");
}

#[test]
fn malformed_records_name_the_line_and_what_was_expected() {
    let text = SINGLE_TOUCHING.replace("         5         3", "         3         3");
    let e = parse_uff(text.as_bytes()).unwrap_err();
    assert!(
        matches!(&e, UffError::Malformed { dataset, line: 9, .. } if dataset == "58"),
        "{e}"
    );
    assert!(e.to_string().contains("ordinate data type"), "{e}");
    let text = SINGLE_TOUCHING.replace("3.00000D+00", "3.0000Q+00 ");
    let e = parse_uff(text.as_bytes()).unwrap_err();
    assert!(matches!(e, UffError::Malformed { line: 14, .. }), "{e}");
    assert!(e.to_string().contains("3.0000Q+00"), "{e}");
    // A huge claimed count is refused by the bytes present, before reading.
    let text = SINGLE_TOUCHING.replace("         5         3", "         59999999999");
    let e = parse_uff(text.as_bytes()).unwrap_err();
    assert!(matches!(e, UffError::Truncated { .. }), "{e}");
    // Fewer values than claimed, and more.
    let text = SINGLE_TOUCHING.replace("         5         3", "         5         4");
    assert!(matches!(
        parse_uff(text.as_bytes()).unwrap_err(),
        UffError::Truncated { .. }
    ));
    let text = SINGLE_TOUCHING.replace("         5         3", "         5         2");
    let e = parse_uff(text.as_bytes()).unwrap_err();
    assert!(e.to_string().contains("more values"), "{e}");
    // A header cut short.
    let e = parse_uff(b"    -1\n    58\nNONE\nNONE\n    -1\n").unwrap_err();
    assert!(matches!(e, UffError::Truncated { .. }), "{e}");
}

#[test]
fn the_writer_refuses_what_the_columns_cannot_hold() {
    let mut f = frf();
    f.id_lines[1] = "x".repeat(81);
    let e = write_function58(&mut Vec::new(), &f).unwrap_err();
    assert!(e.to_string().contains("ID line 2"), "{e}");
    let mut f = frf();
    f.ordinate = Ordinate::Real(vec![1.0, f64::NAN]);
    let e = write_function58(&mut Vec::new(), &f).unwrap_err();
    assert!(e.to_string().contains("ordinate value 2"), "{e}");
    let mut f = frf();
    f.response.node = 12_345_678_901;
    assert!(write_function58(&mut Vec::new(), &f).is_err());
    let mut f = frf();
    f.abscissa = Abscissa::Uneven(vec![1.0]);
    assert!(write_function58(&mut Vec::new(), &f).is_err());
}

#[test]
fn written_lines_follow_the_spec_columns() {
    let out = String::from_utf8(written(&frf())).unwrap();
    let lines: Vec<&str> = out.lines().collect();
    assert_eq!(lines[0], "    -1");
    assert_eq!(lines[1], "    58");
    assert_eq!(&lines[7][..5], "    4");
    assert_eq!(&lines[7][41..55], "        12   3");
    assert_eq!(&lines[8][..30], "         6        12         1");
    assert_eq!(lines[13].len(), 80, "{:?}", lines[13]);
    assert_eq!(*lines.last().unwrap(), "    -1");
}
