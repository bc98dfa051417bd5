//! Dataset 55: data at nodes — here mode shapes with their frequency and damping.
//!
//! Records 1–5 are ID lines. Record 6 (`6I10`): model type (1 structural), analysis type
//! (2 normal mode, 3 complex eigenvalue first order, 7 second order, others kept raw), data
//! characteristic (2: 3 DOF translation, 3: 6 DOF translation and rotation), specific data type
//! (8 displacement, 11 velocity, 12 acceleration, …), data type, values per node. Record 7
//! (`8I10`): number of integers, number of reals, the integers (load case, mode number).
//! Record 8 (`6E13.5`): the reals — normal mode: frequency (Hz), modal mass, viscous damping
//! ratio, hysteretic damping ratio; complex eigenvalue: eigenvalue (re, im), modal A (re, im),
//! modal B (re, im). Then per node: its label (`I10`) and its values (`6E13.5`; complex data as
//! real part, imaginary part).
//!
//! Precision. The spec's data types are 2 (real) and 5 (complex) with `E13.5` columns: single
//! precision (7 significant digits written, 6 for negative values), what pyuff and most tools read. With
//! [`ModeShape55::double_precision`] set the writer uses data types 4 and 6 and `E20.12`
//! columns, four a line, for records 8 and 10 — the double-precision codes of dataset 2414,
//! carried over to 55 (I-DEAS writes such files; pyuff does not read them). The reader takes
//! both.

use std::io::Write;

use realfft::num_complex::Complex;

use super::fortran::{self, columns, e_field, text};
use super::reader::{bad_number, malformed, quote, read_reals, truncated, Line};
use super::write58::i_field;
use super::UffError;

const DS: &str = "55";

/// The analysis a 55 dataset belongs to (record 6 field 2 with records 7 and 8).
#[derive(Clone, Debug, PartialEq)]
pub enum ShapeAnalysis {
    /// 2: a real (normal) mode.
    NormalMode {
        /// Load case number.
        load_case: i64,
        /// Mode number.
        mode: i64,
        /// Natural frequency, Hz.
        frequency_hz: f64,
        /// Modal mass (0 when unknown).
        modal_mass: f64,
        /// Modal viscous damping ratio ζ (fraction, not %).
        viscous_damping_ratio: f64,
        /// Modal hysteretic damping ratio (loss factor / 2 convention of the source).
        hysteretic_damping_ratio: f64,
    },
    /// 3 (first order) or 7 (second order): a complex mode.
    ComplexEigenvalue {
        /// Analysis type 7 (second order) rather than 3.
        second_order: bool,
        /// Load case number.
        load_case: i64,
        /// Mode number.
        mode: i64,
        /// The pole s = −ζω_n + jω_n√(1−ζ²), rad/s.
        eigenvalue: Complex<f64>,
        /// Modal A.
        modal_a: Complex<f64>,
        /// Modal B.
        modal_b: Complex<f64>,
    },
    /// Any other analysis type, with record 7's integers and record 8's reals as read.
    Other {
        /// Record 6 field 2.
        analysis_type: i64,
        /// Record 7 fields 3… .
        integers: Vec<i64>,
        /// Record 8.
        reals: Vec<f64>,
    },
}

impl ShapeAnalysis {
    fn code(&self) -> i64 {
        match self {
            ShapeAnalysis::NormalMode { .. } => 2,
            ShapeAnalysis::ComplexEigenvalue { second_order, .. } => {
                if *second_order {
                    7
                } else {
                    3
                }
            }
            ShapeAnalysis::Other { analysis_type, .. } => *analysis_type,
        }
    }

    /// Natural frequency in Hz (|s|/2π for a complex mode).
    pub fn frequency_hz(&self) -> Option<f64> {
        match self {
            ShapeAnalysis::NormalMode { frequency_hz, .. } => Some(*frequency_hz),
            ShapeAnalysis::ComplexEigenvalue { eigenvalue, .. } => {
                Some(eigenvalue.norm() / std::f64::consts::TAU)
            }
            ShapeAnalysis::Other { .. } => None,
        }
    }

    /// Viscous damping ratio ζ (−Re s/|s| for a complex mode).
    pub fn damping_ratio(&self) -> Option<f64> {
        match self {
            ShapeAnalysis::NormalMode {
                viscous_damping_ratio,
                ..
            } => Some(*viscous_damping_ratio),
            ShapeAnalysis::ComplexEigenvalue { eigenvalue, .. } => {
                Some(-eigenvalue.re / eigenvalue.norm())
            }
            ShapeAnalysis::Other { .. } => None,
        }
    }

    /// Record 7's integers and record 8's reals.
    fn parameters(&self) -> (Vec<i64>, Vec<f64>) {
        match self {
            ShapeAnalysis::NormalMode {
                load_case,
                mode,
                frequency_hz,
                modal_mass,
                viscous_damping_ratio,
                hysteretic_damping_ratio,
            } => (
                vec![*load_case, *mode],
                vec![
                    *frequency_hz,
                    *modal_mass,
                    *viscous_damping_ratio,
                    *hysteretic_damping_ratio,
                ],
            ),
            ShapeAnalysis::ComplexEigenvalue {
                load_case,
                mode,
                eigenvalue: e,
                modal_a: a,
                modal_b: b,
                ..
            } => (
                vec![*load_case, *mode],
                vec![e.re, e.im, a.re, a.im, b.re, b.im],
            ),
            ShapeAnalysis::Other {
                integers, reals, ..
            } => (integers.clone(), reals.clone()),
        }
    }
}

/// The values at one node (real shapes have zero imaginary parts).
#[derive(Clone, Debug, PartialEq)]
pub struct NodeValues {
    /// Node label.
    pub node: i64,
    /// `values_per_node` values: x, y, z (and rx, ry, rz).
    pub values: Vec<Complex<f64>>,
}

/// One dataset 55: a mode shape over nodes with its analysis parameters.
#[derive(Clone, Debug, PartialEq)]
pub struct ModeShape55 {
    /// Records 1–5.
    pub id_lines: [String; 5],
    /// 1 structural.
    pub model_type: i64,
    /// Analysis type and its parameters.
    pub analysis: ShapeAnalysis,
    /// 2: 3 DOF translation, 3: 6 DOF translation and rotation.
    pub data_characteristic: i64,
    /// 8 displacement, 11 velocity, 12 acceleration, …
    pub specific_data_type: i64,
    /// Complex values (data type 5/6) rather than real (2/4).
    pub complex: bool,
    /// Double-precision data types 4/6 (see the module note); as read, and how it is written.
    pub double_precision: bool,
    /// Values per node (3 or 6 for shapes).
    pub values_per_node: usize,
    /// The nodes and their values.
    pub nodes: Vec<NodeValues>,
}

impl ModeShape55 {
    fn with(analysis: ShapeAnalysis, complex: bool, nodes: Vec<NodeValues>) -> Self {
        let values_per_node = nodes.first().map_or(3, |n| n.values.len());
        ModeShape55 {
            id_lines: std::array::from_fn(|_| "NONE".to_string()),
            model_type: 1,
            analysis,
            data_characteristic: if values_per_node == 6 { 3 } else { 2 },
            specific_data_type: 8,
            complex,
            double_precision: false,
            values_per_node,
            nodes,
        }
    }

    /// A normal (real) mode: analysis type 2, displacement, single precision, modal mass 0
    /// (unknown); 3 or 6 values per node as `nodes` hold.
    pub fn normal_mode(
        mode: i64,
        frequency_hz: f64,
        damping_ratio: f64,
        nodes: Vec<NodeValues>,
    ) -> Self {
        let analysis = ShapeAnalysis::NormalMode {
            load_case: 1,
            mode,
            frequency_hz,
            modal_mass: 0.0,
            viscous_damping_ratio: damping_ratio,
            hysteretic_damping_ratio: 0.0,
        };
        ModeShape55::with(analysis, false, nodes)
    }

    /// A complex mode: analysis type 3, eigenvalue s = −ζω_n + jω_n√(1−ζ²) with ω_n = 2πf_n
    /// (rad/s), modal A and B 0, complex displacement values.
    pub fn complex_mode(
        mode: i64,
        frequency_hz: f64,
        damping_ratio: f64,
        nodes: Vec<NodeValues>,
    ) -> Self {
        let w = std::f64::consts::TAU * frequency_hz;
        let analysis = ShapeAnalysis::ComplexEigenvalue {
            second_order: false,
            load_case: 1,
            mode,
            eigenvalue: Complex::new(
                -damping_ratio * w,
                w * (1.0 - damping_ratio * damping_ratio).sqrt(),
            ),
            modal_a: Complex::new(0.0, 0.0),
            modal_b: Complex::new(0.0, 0.0),
        };
        ModeShape55::with(analysis, true, nodes)
    }
}

/// `count` integers in `I10` columns, eight a line, from `lines[*next..]`.
fn read_ints(
    lines: &[Line],
    next: &mut usize,
    count: usize,
    what: &str,
) -> Result<Vec<i64>, UffError> {
    let mut out = Vec::new();
    while out.len() < count {
        let line = lines.get(*next).ok_or_else(|| {
            truncated(
                DS,
                lines.last().map_or(0, |l| l.no + 1),
                format!("{count} integers of {what}"),
                format!("{}", out.len()),
            )
        })?;
        *next += 1;
        for k in 0..8.min(count - out.len()) {
            let v = fortran::int(columns(line.text, 10 * k, 10 * k + 10))
                .map_err(|e| bad_number(DS, line.no, &format!("{what} (I10)"), e))?;
            out.push(v);
        }
    }
    Ok(out)
}

/// A dataset 55 (`lines` = everything between the number line and the closing `-1`).
pub(crate) fn parse(lines: &[Line], id_line: usize) -> Result<ModeShape55, UffError> {
    if lines.len() < 8 {
        return Err(truncated(
            DS,
            lines.last().map_or(id_line + 1, |l| l.no + 1),
            "records 1-8 (ID lines, data definition, analysis parameters)",
            format!("{} lines", lines.len()),
        ));
    }
    let mut next = 5;
    let r6 = read_ints(lines, &mut next, 6, "record 6")?;
    let (data_type, ndv) = (r6[4], r6[5]);
    if !matches!(data_type, 2 | 4 | 5 | 6) {
        return Err(malformed(
            DS,
            lines[5].no,
            "data type 2, 4 (real) or 5, 6 (complex) in columns 41-50",
            data_type.to_string(),
        ));
    }
    let values_per_node = usize::try_from(ndv)
        .ok()
        .filter(|&n| (1..=1000).contains(&n))
        .ok_or_else(|| {
            malformed(
                DS,
                lines[5].no,
                "1 to 1000 values per node in columns 51-60",
                ndv.to_string(),
            )
        })?;
    let complex = matches!(data_type, 5 | 6);
    let double_precision = matches!(data_type, 4 | 6);
    let pattern: &[usize] = if double_precision { &[20] } else { &[13] };
    let counts = read_ints(lines, &mut next, 2, "record 7")?;
    let r7_line = lines[6].no;
    let count = |v: i64, what: &str| {
        usize::try_from(v)
            .ok()
            .filter(|&n| n <= 100)
            .ok_or_else(|| malformed(DS, r7_line, format!("0 to 100 {what}"), v.to_string()))
    };
    let (n_int, n_real) = (count(counts[0], "integers")?, count(counts[1], "reals")?);
    next = 6;
    let ints = read_ints(lines, &mut next, 2 + n_int, "record 7")?.split_off(2);
    let reals = read_reals(DS, lines, &mut next, n_real, pattern, "record 8")?;
    let analysis_type = r6[1];
    let need = |ni: usize, nr: usize| {
        if ints.len() >= ni && reals.len() >= nr {
            Ok(())
        } else {
            Err(malformed(
                DS,
                r7_line,
                format!("at least {ni} integers and {nr} reals for analysis type {analysis_type}"),
                format!("{} and {}", ints.len(), reals.len()),
            ))
        }
    };
    let analysis = match analysis_type {
        2 => {
            need(2, 4)?;
            ShapeAnalysis::NormalMode {
                load_case: ints[0],
                mode: ints[1],
                frequency_hz: reals[0],
                modal_mass: reals[1],
                viscous_damping_ratio: reals[2],
                hysteretic_damping_ratio: reals[3],
            }
        }
        3 | 7 => {
            need(2, 6)?;
            ShapeAnalysis::ComplexEigenvalue {
                second_order: analysis_type == 7,
                load_case: ints[0],
                mode: ints[1],
                eigenvalue: Complex::new(reals[0], reals[1]),
                modal_a: Complex::new(reals[2], reals[3]),
                modal_b: Complex::new(reals[4], reals[5]),
            }
        }
        _ => ShapeAnalysis::Other {
            analysis_type,
            integers: ints,
            reals,
        },
    };
    let per_node = values_per_node * if complex { 2 } else { 1 };
    let mut nodes = Vec::new();
    while let Some(line) = lines.get(next) {
        next += 1;
        if fortran::blank(line.text) {
            continue;
        }
        let node = fortran::int(columns(line.text, 0, 10))
            .ok()
            .filter(|_| fortran::blank(columns(line.text, 10, usize::MAX)))
            .ok_or_else(|| {
                malformed(
                    DS,
                    line.no,
                    "record 9: a node label (I10)",
                    quote(line.text),
                )
            })?;
        let v = read_reals(
            DS,
            lines,
            &mut next,
            per_node,
            pattern,
            &format!("record 10 of node {node}"),
        )?;
        let values = if complex {
            v.chunks_exact(2)
                .map(|c| Complex::new(c[0], c[1]))
                .collect()
        } else {
            v.iter().map(|&x| Complex::new(x, 0.0)).collect()
        };
        nodes.push(NodeValues { node, values });
    }
    Ok(ModeShape55 {
        id_lines: std::array::from_fn(|i| text(lines[i].text)),
        model_type: r6[0],
        analysis,
        data_characteristic: r6[2],
        specific_data_type: r6[3],
        complex,
        double_precision,
        values_per_node,
        nodes,
    })
}

fn unwritable(what: &str, detail: impl Into<String>) -> UffError {
    UffError::Unwritable {
        dataset: DS.into(),
        what: what.into(),
        detail: detail.into(),
    }
}

/// Reals in lines of `per_line` fields of `width` columns.
fn real_lines(
    values: &[f64],
    width: usize,
    decimals: usize,
    what: &str,
) -> Result<String, UffError> {
    let per_line = if width == 13 { 6 } else { 4 };
    let mut s = String::new();
    for chunk in values.chunks(per_line) {
        for v in chunk {
            s += &e_field(*v, width, decimals)
                .ok_or_else(|| unwritable(what, format!("{v} is not finite")))?;
        }
        s.push('\n');
    }
    Ok(s)
}

/// Writes `shape` as a dataset 55: single precision (data type 2/5, `E13.5` columns with 7
/// digits, pyuff reads it) or, with `double_precision`, types 4/6 in `E20.12` columns (13
/// digits; see the module note). Checked whole before anything is written: every node must
/// hold `values_per_node` values, a real shape no imaginary part.
pub fn write_mode_shape55(w: &mut impl Write, shape: &ModeShape55) -> Result<(), UffError> {
    let (width, decimals) = if shape.double_precision {
        (20, 12)
    } else {
        (13, 6)
    };
    let data_type = match (shape.complex, shape.double_precision) {
        (false, false) => 2,
        (false, true) => 4,
        (true, false) => 5,
        (true, true) => 6,
    };
    let mut s = String::from("    -1\n    55\n");
    for (i, id) in shape.id_lines.iter().enumerate() {
        let id = if id.trim().is_empty() { "NONE" } else { id };
        fortran::a_field(id, 80).ok_or_else(|| {
            unwritable(
                &format!("ID line {}", i + 1),
                "more than 80 ASCII characters or a line break",
            )
        })?;
        s += id.trim_end();
        s.push('\n');
    }
    let i10 = |v: i64, what: &str| i_field(DS, v, 10, what);
    s += &format!(
        "{}{}{}{}{}{}\n",
        i10(shape.model_type, "model type")?,
        i10(shape.analysis.code(), "analysis type")?,
        i10(shape.data_characteristic, "data characteristic")?,
        i10(shape.specific_data_type, "specific data type")?,
        i10(data_type, "data type")?,
        i10(shape.values_per_node as i64, "values per node")?,
    );
    let (ints, reals) = shape.analysis.parameters();
    let mut r7 = vec![ints.len() as i64, reals.len() as i64];
    r7.extend(&ints);
    for chunk in r7.chunks(8) {
        for v in chunk {
            s += &i10(*v, "record 7")?;
        }
        s.push('\n');
    }
    s += &real_lines(&reals, width, decimals, "record 8")?;
    for n in &shape.nodes {
        if n.values.len() != shape.values_per_node {
            return Err(unwritable(
                &format!("node {}", n.node),
                format!(
                    "{} values, expected {} per node",
                    n.values.len(),
                    shape.values_per_node
                ),
            ));
        }
        if !shape.complex && n.values.iter().any(|z| z.im != 0.0) {
            return Err(unwritable(
                &format!("node {}", n.node),
                "an imaginary part in a real shape (set `complex`)",
            ));
        }
        s += &i10(n.node, "node label")?;
        s.push('\n');
        let flat: Vec<f64> = if shape.complex {
            n.values.iter().flat_map(|z| [z.re, z.im]).collect()
        } else {
            n.values.iter().map(|z| z.re).collect()
        };
        s += &real_lines(
            &flat,
            width,
            decimals,
            &format!("values of node {}", n.node),
        )?;
    }
    s += "    -1\n";
    w.write_all(s.as_bytes()).map_err(|source| UffError::Write {
        dataset: DS.into(),
        source,
    })
}

#[cfg(test)]
#[path = "dataset55_tests.rs"]
mod tests;
