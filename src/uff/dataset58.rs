//! Dataset 58 (and 58b): a function at a nodal DOF — an FRF, a time response, a spectrum.
//!
//! Records 1–5 are ID lines (80A1). Record 6 (`2(I5,I10),2(1X,10A1,I10,I4)`): function type,
//! function id, version, load case, response entity/node/direction, reference
//! entity/node/direction. Record 7 (`3I10,3E13.5`): ordinate data type (2 real single, 4 real
//! double, 5 complex single, 6 complex double), number of points, spacing (1 even, 0 uneven),
//! abscissa minimum, increment, z-axis value. Records 8–11 (`I10,3I5,2(1X,20A1)`): specific
//! data type, length/force/temperature exponents, axis label and units label of the abscissa,
//! ordinate numerator, ordinate denominator and z axis. Then the data: `6E13.5` for single
//! precision; `4E20.12` (even), `2(E13.5,E20.12)` (uneven real) or `E13.5,2E20.12` (uneven
//! complex) for double; uneven data interleave the abscissa value before each ordinate. In 58b
//! the same values follow as raw IEEE numbers, all of the ordinate's precision (as pyuff writes
//! and reads them).

use realfft::num_complex::Complex;

use super::fortran::{self, columns, text};
use super::reader::{bad_number, malformed, quote, read_reals, truncated, Line};
use super::UffError;

/// Record 6 field 1: what the function is. Codes other than 1 and 4 are kept as their number
/// (0 general, 2 auto spectrum, 3 cross spectrum, 6 coherence, …).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FunctionType {
    /// 1: a time response (for dampscope: an impulse response or free decay).
    TimeResponse,
    /// 4: a frequency response function.
    FrequencyResponse,
    /// Any other code.
    Other(i64),
}

impl FunctionType {
    /// The UFF code.
    pub fn code(self) -> i64 {
        match self {
            FunctionType::TimeResponse => 1,
            FunctionType::FrequencyResponse => 4,
            FunctionType::Other(c) => c,
        }
    }

    /// The type of a UFF code.
    pub fn from_code(code: i64) -> Self {
        match code {
            1 => FunctionType::TimeResponse,
            4 => FunctionType::FrequencyResponse,
            c => FunctionType::Other(c),
        }
    }
}

/// A node and direction (record 6): where a response was measured or the excitation applied.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct NodeDof {
    /// Entity name, at most 10 characters (`NONE` if unused).
    pub entity: String,
    /// Node label.
    pub node: i64,
    /// Direction code: ±1…±3 translation X/Y/Z, ±4…±6 rotation, 0 scalar (see
    /// [`super::direction_label`]).
    pub direction: i64,
}

impl NodeDof {
    /// Node `node` in direction `direction`, entity `NONE`.
    pub fn new(node: i64, direction: i64) -> Self {
        NodeDof {
            entity: "NONE".into(),
            node,
            direction,
        }
    }
}

/// The abscissa (frequency in Hz or time in s, as the abscissa axis says).
#[derive(Clone, Debug, PartialEq)]
pub enum Abscissa {
    /// Even spacing: value k is `start + k·increment`.
    Even {
        /// First value.
        start: f64,
        /// Spacing.
        increment: f64,
    },
    /// Uneven spacing: one value per point.
    Uneven(Vec<f64>),
}

impl Abscissa {
    /// The first `n` abscissa values.
    pub fn values(&self, n: usize) -> Vec<f64> {
        match self {
            Abscissa::Even { start, increment } => {
                (0..n).map(|k| start + k as f64 * increment).collect()
            }
            Abscissa::Uneven(v) => v.iter().copied().take(n).collect(),
        }
    }
}

/// The ordinate values: real or complex.
#[derive(Clone, Debug, PartialEq)]
pub enum Ordinate {
    /// Real values (data types 2 and 4).
    Real(Vec<f64>),
    /// Complex values (data types 5 and 6).
    Complex(Vec<Complex<f64>>),
}

impl Ordinate {
    /// Number of points.
    pub fn len(&self) -> usize {
        match self {
            Ordinate::Real(v) => v.len(),
            Ordinate::Complex(v) => v.len(),
        }
    }

    /// No points at all.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The values as complex numbers (real ones with zero imaginary part).
    pub fn to_complex(&self) -> Vec<Complex<f64>> {
        match self {
            Ordinate::Real(v) => v.iter().map(|&x| Complex::new(x, 0.0)).collect(),
            Ordinate::Complex(v) => v.clone(),
        }
    }
}

/// Records 8–11: what an axis holds.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct AxisInfo {
    /// Specific data type: 0 unknown, 1 general, 8 displacement, 11 velocity, 12 acceleration,
    /// 13 excitation force, 17 time, 18 frequency, …
    pub specific_data_type: i64,
    /// Length units exponent (relevant for type 1, general).
    pub length_exponent: i64,
    /// Force units exponent.
    pub force_exponent: i64,
    /// Temperature units exponent.
    pub temperature_exponent: i64,
    /// Axis label, at most 20 characters (`NONE` if unused).
    pub label: String,
    /// Axis units label, at most 20 characters (`NONE` if unused).
    pub units_label: String,
}

impl AxisInfo {
    /// An axis of `specific_data_type` with a label and units label, exponents 0.
    pub fn new(specific_data_type: i64, label: &str, units_label: &str) -> Self {
        AxisInfo {
            specific_data_type,
            length_exponent: 0,
            force_exponent: 0,
            temperature_exponent: 0,
            label: label.into(),
            units_label: units_label.into(),
        }
    }
}

impl Default for AxisInfo {
    fn default() -> Self {
        AxisInfo::new(0, "NONE", "NONE")
    }
}

/// One dataset 58: a function of frequency or time at a response DOF for a reference DOF.
#[derive(Clone, Debug, PartialEq)]
pub struct Function58 {
    /// Records 1–5 (trailing blanks removed; `NONE` when unused).
    pub id_lines: [String; 5],
    /// Record 6 field 1.
    pub function_type: FunctionType,
    /// Function identification number.
    pub function_id: i64,
    /// Version or sequence number.
    pub version: i64,
    /// Load case (0 = single point excitation).
    pub load_case: i64,
    /// Response DOF.
    pub response: NodeDof,
    /// Reference (excitation) DOF.
    pub reference: NodeDof,
    /// Abscissa values.
    pub abscissa: Abscissa,
    /// Ordinate values.
    pub ordinate: Ordinate,
    /// The file stored the ordinate in double precision (types 4, 6). Informative: the writer
    /// always writes double precision.
    pub double_precision: bool,
    /// The function came from a binary 58b dataset. Informative: the writer writes ASCII.
    pub binary: bool,
    /// Record 7 field 6.
    pub z_axis_value: f64,
    /// Record 8.
    pub abscissa_axis: AxisInfo,
    /// Record 9 (ordinate numerator).
    pub ordinate_axis: AxisInfo,
    /// Record 10 (ordinate denominator).
    pub denominator_axis: AxisInfo,
    /// Record 11.
    pub z_axis: AxisInfo,
}

impl Function58 {
    /// A function with ID lines and axes set to `NONE`/unknown, double precision.
    pub fn new(
        function_type: FunctionType,
        response: NodeDof,
        reference: NodeDof,
        abscissa: Abscissa,
        ordinate: Ordinate,
    ) -> Self {
        Function58 {
            id_lines: std::array::from_fn(|_| "NONE".to_string()),
            function_type,
            function_id: 0,
            version: 0,
            load_case: 0,
            response,
            reference,
            abscissa,
            ordinate,
            double_precision: true,
            binary: false,
            z_axis_value: 0.0,
            abscissa_axis: AxisInfo::default(),
            ordinate_axis: AxisInfo::default(),
            denominator_axis: AxisInfo::default(),
            z_axis: AxisInfo::default(),
        }
    }

    /// The abscissa value of every point.
    pub fn abscissa_values(&self) -> Vec<f64> {
        self.abscissa.values(self.ordinate.len())
    }
}

/// Record 7: how the data is stored.
pub(crate) struct DataForm {
    ordinate_type: i64,
    n_points: usize,
    even: bool,
}

impl DataForm {
    fn complex(&self) -> bool {
        matches!(self.ordinate_type, 5 | 6)
    }

    fn double(&self) -> bool {
        matches!(self.ordinate_type, 4 | 6)
    }

    fn values_per_point(&self) -> usize {
        1 + usize::from(self.complex()) + usize::from(!self.even)
    }

    /// Column widths of an ASCII data line, repeated (the spec's Addendum B).
    fn pattern(&self) -> &'static [usize] {
        match (self.double(), self.complex(), self.even) {
            (false, _, _) => &[13],
            (true, _, true) => &[20],
            (true, false, false) => &[13, 20],
            (true, true, false) => &[13, 20, 20],
        }
    }

    /// "N points, complex double, even" for messages.
    pub(crate) fn describe(&self) -> String {
        format!(
            "record 7: {} points, type {}, {} spacing",
            self.n_points,
            self.ordinate_type,
            if self.even { "even" } else { "uneven" }
        )
    }

    fn n_values(&self, dataset: &str, line: usize) -> Result<usize, UffError> {
        self.n_points
            .checked_mul(self.values_per_point())
            .ok_or_else(|| {
                malformed(
                    dataset,
                    line,
                    "a number of points that fits",
                    self.describe(),
                )
            })
    }

    /// Bytes of 58b data record 7 implies.
    pub(crate) fn binary_size(&self, dataset: &str, line: usize) -> Result<usize, UffError> {
        let width = if self.double() { 8 } else { 4 };
        self.n_values(dataset, line)?
            .checked_mul(width)
            .ok_or_else(|| {
                malformed(
                    dataset,
                    line,
                    "a number of points that fits",
                    self.describe(),
                )
            })
    }
}

fn axis(dataset: &str, line: &Line, record: &str) -> Result<AxisInfo, UffError> {
    let int = |a, b, what: &str| {
        fortran::int(columns(line.text, a, b))
            .map_err(|e| bad_number(dataset, line.no, &format!("{record}: {what}"), e))
    };
    Ok(AxisInfo {
        specific_data_type: int(0, 10, "specific data type (I10)")?,
        length_exponent: int(10, 15, "length units exponent (I5)")?,
        force_exponent: int(15, 20, "force units exponent (I5)")?,
        temperature_exponent: int(20, 25, "temperature units exponent (I5)")?,
        label: text(columns(line.text, 26, 46)).trim().to_string(),
        units_label: text(columns(line.text, 47, 67)).trim().to_string(),
    })
}

/// Record 6 by its columns, or (a writer with other widths) as ten blank-separated fields.
fn record6(dataset: &str, line: &Line) -> Result<(Vec<i64>, String, String), UffError> {
    let cols = [
        (0, 5),
        (5, 15),
        (15, 20),
        (20, 30),
        (41, 51),
        (51, 55),
        (66, 76),
        (76, 80),
    ];
    let fixed: Result<Vec<i64>, _> = cols
        .iter()
        .map(|&(a, b)| fortran::int(columns(line.text, a, b)))
        .collect();
    if let Ok(ints) = fixed {
        let rsp = text(columns(line.text, 31, 41)).trim().to_string();
        let refe = text(columns(line.text, 56, 66)).trim().to_string();
        return Ok((ints, rsp, refe));
    }
    let tokens: Vec<&[u8]> = line
        .text
        .split(|b| b.is_ascii_whitespace())
        .filter(|t| !t.is_empty())
        .collect();
    let ints: Option<Vec<i64>> = (tokens.len() == 10)
        .then(|| {
            [0, 1, 2, 3, 5, 6, 8, 9]
                .iter()
                .map(|&i| fortran::int(tokens[i]).ok())
                .collect()
        })
        .flatten();
    match ints {
        Some(ints) => Ok((ints, text(tokens[4]), text(tokens[7]))),
        None => Err(malformed(
            dataset,
            line.no,
            "record 6: 2(I5,I10),2(1X,10A1,I10,I4) (function type, id, version, load case, \
             response name/node/direction, reference name/node/direction)",
            quote(line.text),
        )),
    }
}

/// Records 1–11 of a 58 or 58b dataset (`header` holds at least those 11 lines): the function
/// without its data, and the data form of record 7.
pub(crate) fn parse_header(
    header: &[Line],
    dataset: &str,
) -> Result<(Function58, DataForm), UffError> {
    if header.len() < 11 {
        return Err(truncated(
            dataset,
            header.last().map_or(0, |l| l.no + 1),
            "11 header records",
            format!("{} lines", header.len()),
        ));
    }
    let (r6, rsp_entity, ref_entity) = record6(dataset, &header[5])?;
    let l7 = &header[6];
    let int7 = |a, b, what: &str| {
        fortran::int(columns(l7.text, a, b))
            .map_err(|e| bad_number(dataset, l7.no, &format!("record 7: {what}"), e))
    };
    let real7 = |a, b, what: &str| {
        fortran::real(columns(l7.text, a, b))
            .map(|v| v.unwrap_or(0.0))
            .map_err(|e| bad_number(dataset, l7.no, &format!("record 7: {what}"), e))
    };
    let ordinate_type = int7(0, 10, "ordinate data type (I10)")?;
    if !matches!(ordinate_type, 2 | 4 | 5 | 6) {
        return Err(malformed(
            dataset,
            l7.no,
            "ordinate data type 2, 4, 5 or 6 in columns 1-10",
            ordinate_type.to_string(),
        ));
    }
    let n = int7(10, 20, "number of points (I10)")?;
    let n_points = usize::try_from(n).ok().filter(|&n| n >= 1).ok_or_else(|| {
        malformed(
            dataset,
            l7.no,
            "a number of points ≥ 1 in columns 11-20",
            n.to_string(),
        )
    })?;
    let even = match int7(20, 30, "abscissa spacing (I10)")? {
        0 => false,
        1 => true,
        s => {
            return Err(malformed(
                dataset,
                l7.no,
                "abscissa spacing 0 (uneven) or 1 (even) in columns 21-30",
                s.to_string(),
            ))
        }
    };
    let start = real7(30, 43, "abscissa minimum (E13.5)")?;
    let increment = real7(43, 56, "abscissa increment (E13.5)")?;
    let z_axis_value = real7(56, 69, "z-axis value (E13.5)")?;
    let mut f = Function58::new(
        FunctionType::from_code(r6[0]),
        NodeDof {
            entity: rsp_entity,
            node: r6[4],
            direction: r6[5],
        },
        NodeDof {
            entity: ref_entity,
            node: r6[6],
            direction: r6[7],
        },
        if even {
            Abscissa::Even { start, increment }
        } else {
            Abscissa::Uneven(Vec::new())
        },
        Ordinate::Real(Vec::new()),
    );
    f.id_lines = std::array::from_fn(|i| text(header[i].text));
    (f.function_id, f.version, f.load_case) = (r6[1], r6[2], r6[3]);
    f.z_axis_value = z_axis_value;
    f.abscissa_axis = axis(dataset, &header[7], "record 8")?;
    f.ordinate_axis = axis(dataset, &header[8], "record 9")?;
    f.denominator_axis = axis(dataset, &header[9], "record 10")?;
    f.z_axis = axis(dataset, &header[10], "record 11")?;
    let form = DataForm {
        ordinate_type,
        n_points,
        even,
    };
    f.double_precision = form.double();
    Ok((f, form))
}

/// Splits the data values (in file order) into abscissa and ordinate.
fn assemble(f: &mut Function58, form: &DataForm, v: &[f64]) {
    let k = form.values_per_point();
    let x = (!form.even).then(|| v.iter().step_by(k).copied().collect());
    let o = usize::from(!form.even);
    f.ordinate = if form.complex() {
        Ordinate::Complex(
            v.chunks_exact(k)
                .map(|c| Complex::new(c[o], c[o + 1]))
                .collect(),
        )
    } else {
        Ordinate::Real(v.iter().skip(o).step_by(k).copied().collect())
    };
    if let Some(x) = x {
        f.abscissa = Abscissa::Uneven(x);
    }
}

/// An ASCII dataset 58 (`lines` = everything between the number line and the closing `-1`).
pub(crate) fn parse_ascii(lines: &[Line], id_line: usize) -> Result<Function58, UffError> {
    let ds = "58";
    if lines.len() < 11 {
        return Err(truncated(
            ds,
            lines.last().map_or(id_line + 1, |l| l.no + 1),
            "11 header records before the data",
            format!("{} lines", lines.len()),
        ));
    }
    let (mut f, form) = parse_header(&lines[..11], ds)?;
    let data = &lines[11..];
    let count = form.n_values(ds, lines[6].no)?;
    // The claim against the bytes present, before anything is read: every value needs a
    // character and a separator at least.
    let available: usize = data.iter().map(|l| l.text.len() + 1).sum();
    if count > available {
        return Err(truncated(
            ds,
            data.first().map_or(lines[10].no + 1, |l| l.no),
            format!("{count} data values ({})", form.describe()),
            format!("{available} bytes of data lines"),
        ));
    }
    let mut next = 0;
    let values = read_reals(ds, data, &mut next, count, form.pattern(), "data")?;
    if let Some(extra) = data[next..].iter().find(|l| !fortran::blank(l.text)) {
        return Err(malformed(
            ds,
            extra.no,
            format!(
                "the end of the dataset after {count} values ({})",
                form.describe()
            ),
            quote(extra.text),
        ));
    }
    assemble(&mut f, &form, &values);
    Ok(f)
}

/// The data of a 58b dataset from its bytes (exactly `form.binary_size()` of them).
pub(crate) fn fill_binary(
    f: &mut Function58,
    form: &DataForm,
    data: &[u8],
    little_endian: bool,
    dataset: &str,
    line: usize,
) -> Result<(), UffError> {
    let values: Vec<f64> = if form.double() {
        data.chunks_exact(8)
            .map(|c| {
                let b: [u8; 8] = c.try_into().expect("chunks of 8");
                if little_endian {
                    f64::from_le_bytes(b)
                } else {
                    f64::from_be_bytes(b)
                }
            })
            .collect()
    } else {
        data.chunks_exact(4)
            .map(|c| {
                let b: [u8; 4] = c.try_into().expect("chunks of 4");
                f64::from(if little_endian {
                    f32::from_le_bytes(b)
                } else {
                    f32::from_be_bytes(b)
                })
            })
            .collect()
    };
    if let Some(k) = values.iter().position(|v| !v.is_finite()) {
        return Err(malformed(
            dataset,
            line,
            "finite IEEE numbers in the binary data",
            format!("{} as value {} of {}", values[k], k + 1, values.len()),
        ));
    }
    f.binary = true;
    assemble(f, form, &values);
    Ok(())
}

#[cfg(test)]
#[path = "dataset58_tests.rs"]
mod tests;
