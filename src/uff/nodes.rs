//! Node coordinates (datasets 15 and 2411) and units (dataset 164).
//!
//! 15: one record per node, `4I10,1P3E13.5`: label, definition coordinate system, displacement
//! coordinate system, colour, x, y, z (single precision). 2411: two records per node, `4I10`
//! (label, export coordinate system, displacement coordinate system, colour) then `1P3D25.16`
//! (x, y, z, double precision). 164: `I10,20A1,I10` (units code, description, temperature
//! mode) then `3D25.17` over two lines: the factors that convert file units to SI by
//! division (length, force, temperature, temperature offset).

use std::io::Write;

use super::fortran::{self, columns, e_field, text};
use super::reader::{bad_number, malformed, quote, read_reals, truncated, Line};
use super::write58::i_field;
use super::UffError;

/// One node: label, coordinate systems, colour, coordinates in the file's length unit.
#[derive(Clone, Debug, PartialEq)]
pub struct Node {
    /// Node label (the node number datasets 58 and 55 refer to).
    pub label: i64,
    /// Definition (15) or export (2411) coordinate system number.
    pub coordinate_system: i64,
    /// Displacement coordinate system number.
    pub displacement_system: i64,
    /// Colour code.
    pub color: i64,
    /// x, y, z in the file's length unit (see [`Units164`]).
    pub xyz: [f64; 3],
}

impl Node {
    /// Node `label` at `xyz`, coordinate systems 0, colour 0.
    pub fn new(label: i64, xyz: [f64; 3]) -> Self {
        Node {
            label,
            coordinate_system: 0,
            displacement_system: 0,
            color: 0,
            xyz,
        }
    }
}

/// Which dataset the nodes came from (its precision).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum NodeFormat {
    /// Dataset 15, single precision.
    Single15,
    /// Dataset 2411, double precision.
    Double2411,
}

/// The nodes of one 15 or 2411 dataset.
#[derive(Clone, Debug, PartialEq)]
pub struct NodeSet {
    /// The dataset.
    pub format: NodeFormat,
    /// The nodes in file order.
    pub nodes: Vec<Node>,
}

/// Dataset 164: the file's units.
#[derive(Clone, Debug, PartialEq)]
pub struct Units164 {
    /// 1 SI (m, N), 2 BG (ft, lbf), 3 MG (m, kgf), 4 BA, 5 MM (mm, mN), 6 CM, 7 IN, 8 GM, 9 user.
    pub code: i64,
    /// Description, for documentation only.
    pub description: String,
    /// 1 absolute, 2 relative.
    pub temperature_mode: i64,
    /// File length unit per metre: metres = file value / `length_factor` (1000 for mm).
    pub length_factor: f64,
    /// File force unit per newton.
    pub force_factor: f64,
    /// Temperature factor.
    pub temperature_factor: f64,
    /// Temperature offset.
    pub temperature_offset: f64,
}

impl Units164 {
    /// A length in the file's unit converted to metres.
    pub fn length_m(&self, value: f64) -> f64 {
        value / self.length_factor
    }
}

fn node_from_fields(ints: &[i64], xyz: [f64; 3]) -> Node {
    Node {
        label: ints[0],
        coordinate_system: ints[1],
        displacement_system: ints[2],
        color: ints[3],
        xyz,
    }
}

/// Four `I10` integers by their columns, or as four blank-separated fields.
fn four_ints(line: &Line) -> Option<Vec<i64>> {
    let fixed: Result<Vec<i64>, _> = (0..4)
        .map(|k| fortran::int(columns(line.text, 10 * k, 10 * k + 10)))
        .collect();
    fixed.ok().or_else(|| {
        let t: Vec<&[u8]> = line
            .text
            .split(|b| b.is_ascii_whitespace())
            .filter(|t| !t.is_empty())
            .collect();
        (t.len() == 4)
            .then(|| t.iter().map(|f| fortran::int(f).ok()).collect())
            .flatten()
    })
}

/// Dataset 15: one node per non-blank line.
pub(crate) fn parse15(lines: &[Line]) -> Result<NodeSet, UffError> {
    let mut nodes = Vec::new();
    for line in lines.iter().filter(|l| !fortran::blank(l.text)) {
        let fixed = four_ints(&Line {
            no: line.no,
            text: columns(line.text, 0, 40),
        })
        .filter(|_| line.text.len() > 40)
        .and_then(|ints| {
            let xyz: Result<Vec<f64>, _> = (0..3)
                .map(|k| fortran::real(columns(line.text, 40 + 13 * k, 53 + 13 * k)))
                .map(|r| r.map(|v| v.unwrap_or(0.0)))
                .collect();
            xyz.ok()
                .map(|x| node_from_fields(&ints, [x[0], x[1], x[2]]))
        });
        let node = fixed.or_else(|| {
            let v = fortran::scan_reals(line.text).ok()?;
            let ints: Vec<i64> = v[..4.min(v.len())]
                .iter()
                .filter(|x| x.fract() == 0.0 && x.abs() < 1e15)
                .map(|&x| x as i64)
                .collect();
            (v.len() == 7 && ints.len() == 4).then(|| node_from_fields(&ints, [v[4], v[5], v[6]]))
        });
        nodes.push(node.ok_or_else(|| {
            malformed(
                "15",
                line.no,
                "a node record 4I10,1P3E13.5 (label, coordinate systems, colour, x, y, z)",
                quote(line.text),
            )
        })?);
    }
    Ok(NodeSet {
        format: NodeFormat::Single15,
        nodes,
    })
}

/// Dataset 2411: two records per node.
pub(crate) fn parse2411(lines: &[Line]) -> Result<NodeSet, UffError> {
    let lines: Vec<Line> = lines
        .iter()
        .filter(|l| !fortran::blank(l.text))
        .copied()
        .collect();
    let mut nodes = Vec::new();
    let mut next = 0;
    while next < lines.len() {
        let r1 = lines[next];
        let ints = four_ints(&r1).ok_or_else(|| {
            malformed(
                "2411",
                r1.no,
                "record 1, 4I10 (label, export and displacement coordinate systems, colour)",
                quote(r1.text),
            )
        })?;
        next += 1;
        if next == lines.len() {
            return Err(truncated(
                "2411",
                r1.no + 1,
                format!("record 2 (x, y, z) of node {}", ints[0]),
                "the end of the dataset",
            ));
        }
        let xyz = read_reals("2411", &lines, &mut next, 3, &[25], "record 2: x, y, z")?;
        nodes.push(node_from_fields(&ints, [xyz[0], xyz[1], xyz[2]]));
    }
    Ok(NodeSet {
        format: NodeFormat::Double2411,
        nodes,
    })
}

/// Dataset 164.
pub(crate) fn parse164(lines: &[Line], id_line: usize) -> Result<Units164, UffError> {
    let Some(r1) = lines.first() else {
        return Err(truncated(
            "164",
            id_line + 1,
            "record 1 (units code, description, temperature mode)",
            "an empty dataset",
        ));
    };
    let int = |a, b, what: &str| {
        fortran::int(columns(r1.text, a, b)).map_err(|e| bad_number("164", r1.no, what, e))
    };
    let code = int(0, 10, "record 1: units code (I10)")?;
    let temperature_mode = int(30, 40, "record 1: temperature mode (I10)")?;
    let mut next = 1;
    let f = read_reals("164", lines, &mut next, 4, &[25], "record 2: unit factors")?;
    if f[0] <= 0.0 {
        return Err(malformed(
            "164",
            lines[1].no,
            "a length factor > 0",
            f[0].to_string(),
        ));
    }
    Ok(Units164 {
        code,
        description: text(columns(r1.text, 10, 30)).trim().to_string(),
        temperature_mode,
        length_factor: f[0],
        force_factor: f[1],
        temperature_factor: f[2],
        temperature_offset: f[3],
    })
}

fn coordinate(
    dataset: &str,
    v: f64,
    width: usize,
    decimals: usize,
    label: i64,
) -> Result<String, UffError> {
    e_field(v, width, decimals).ok_or_else(|| UffError::Unwritable {
        dataset: dataset.into(),
        what: format!("coordinate of node {label}"),
        detail: format!("{v} is not finite"),
    })
}

fn emit(w: &mut impl Write, dataset: &str, s: &str) -> Result<(), UffError> {
    w.write_all(s.as_bytes()).map_err(|source| UffError::Write {
        dataset: dataset.into(),
        source,
    })
}

fn node_ints(dataset: &str, n: &Node) -> Result<String, UffError> {
    Ok(format!(
        "{}{}{}{}",
        i_field(dataset, n.label, 10, "node label")?,
        i_field(dataset, n.coordinate_system, 10, "coordinate system")?,
        i_field(dataset, n.displacement_system, 10, "displacement system")?,
        i_field(dataset, n.color, 10, "colour")?,
    ))
}

/// Writes `nodes` as dataset 15 (single precision: 7 significant digits in `E13.5` columns, 6 for
/// negative values).
pub fn write_nodes15(w: &mut impl Write, nodes: &[Node]) -> Result<(), UffError> {
    let mut s = String::from("    -1\n    15\n");
    for n in nodes {
        s += &node_ints("15", n)?;
        for v in n.xyz {
            s += &coordinate("15", v, 13, 6, n.label)?;
        }
        s.push('\n');
    }
    s += "    -1\n";
    emit(w, "15", &s)
}

/// Writes `nodes` as dataset 2411 (double precision: 17 significant digits in `D25.16`
/// columns, written with `E`, which every reader takes; the round trip is exact).
pub fn write_nodes2411(w: &mut impl Write, nodes: &[Node]) -> Result<(), UffError> {
    let mut s = String::from("    -1\n  2411\n");
    for n in nodes {
        s += &node_ints("2411", n)?;
        s.push('\n');
        for v in n.xyz {
            s += &coordinate("2411", v, 25, 16, n.label)?;
        }
        s.push('\n');
    }
    s += "    -1\n";
    emit(w, "2411", &s)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::uff::{parse_uff, Dataset};

    fn nodes() -> Vec<Node> {
        vec![
            Node::new(1, [0.0, 0.0, 0.0]),
            Node::new(12, [1.234_567_890_123_456_7, -0.1, 3e-5]),
            Node {
                label: 999_999,
                coordinate_system: 2,
                displacement_system: 3,
                color: 8,
                xyz: [-1e10, std::f64::consts::PI, -std::f64::consts::E],
            },
        ]
    }

    fn read_back(bytes: &[u8]) -> NodeSet {
        match parse_uff(bytes).unwrap().datasets.remove(0) {
            Dataset::Nodes(n) => n,
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn nodes_2411_round_trip_exactly_and_15_to_single_precision() {
        let mut out = Vec::new();
        write_nodes2411(&mut out, &nodes()).unwrap();
        let back = read_back(&out);
        assert_eq!(back.format, NodeFormat::Double2411);
        assert_eq!(back.nodes, nodes());
        let mut out = Vec::new();
        write_nodes15(&mut out, &nodes()).unwrap();
        let back = read_back(&out);
        assert_eq!(back.format, NodeFormat::Single15);
        for (a, b) in back.nodes.iter().zip(nodes()) {
            assert_eq!(
                (a.label, a.coordinate_system, a.color),
                (b.label, b.coordinate_system, b.color)
            );
            for (p, q) in a.xyz.iter().zip(b.xyz) {
                assert!((p - q).abs() <= 5e-6 * q.abs(), "{p} vs {q}");
            }
        }
    }

    #[test]
    fn d_exponents_touching_fields_and_blank_separated_records_are_read() {
        let f = "    -1\n  2411\n         5         0         0         8\n-1.0000000000000000D+00-2.5000000000000000D-01 3.0000000000000000D+00\n    -1\n    -1\n    15\n7 0 0 0 1.5 -2.5 0.0\n    -1\n";
        let c = parse_uff(f.as_bytes()).unwrap();
        let n: Vec<&Node> = c.nodes().collect();
        assert_eq!(n[0].label, 5);
        assert_eq!(n[0].color, 8);
        assert_eq!(n[0].xyz, [-1.0, -0.25, 3.0]);
        assert_eq!(n[1].label, 7);
        assert_eq!(n[1].xyz, [1.5, -2.5, 0.0]);
    }

    #[test]
    fn units_164_give_the_length_factor() {
        let f = "    -1\n   164\n         5  mm (milli newton)          2\n  1.0000000000000000D+03  1.0000000000000000D+03  1.0000000000000000D+00\n  2.7314999999999998D+02\n    -1\n";
        let u = parse_uff(f.as_bytes()).unwrap().units().cloned().unwrap();
        assert_eq!(u.code, 5);
        assert_eq!(u.length_factor, 1000.0);
        assert!((u.temperature_offset - 273.15).abs() < 1e-12);
        assert_eq!(u.length_m(250.0), 0.25);
        assert_eq!(u.description, "mm (milli newton)");
    }

    #[test]
    fn broken_node_records_are_errors_with_lines() {
        let e = parse_uff(b"    -1\n  2411\n         5         0         0         8\n    -1\n")
            .unwrap_err();
        assert!(matches!(e, UffError::Truncated { line: 4, .. }), "{e}");
        let e = parse_uff(
            b"    -1\n    15\n         1         0         0         0  1.0  x\n    -1\n",
        )
        .unwrap_err();
        assert!(matches!(e, UffError::Malformed { line: 3, .. }), "{e}");
        let mut bad = nodes();
        bad[1].xyz[2] = f64::INFINITY;
        let e = write_nodes2411(&mut Vec::new(), &bad).unwrap_err();
        assert!(e.to_string().contains("node 12"), "{e}");
    }
}
