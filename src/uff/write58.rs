//! Writing dataset 58 (ASCII, double precision); see `dataset58.rs` for the layout.

use std::io::Write;

use super::dataset58::{Abscissa, AxisInfo, Function58, Ordinate};
use super::fortran::{self, e_field};
use super::UffError;

fn unwritable(what: &str, detail: impl Into<String>) -> UffError {
    UffError::Unwritable {
        dataset: "58".into(),
        what: what.into(),
        detail: detail.into(),
    }
}

/// An integer in `width` columns, or an error naming the field.
pub(crate) fn i_field(dataset: &str, v: i64, width: usize, what: &str) -> Result<String, UffError> {
    let s = format!("{v:>width$}");
    if s.len() == width {
        Ok(s)
    } else {
        Err(UffError::Unwritable {
            dataset: dataset.into(),
            what: what.into(),
            detail: format!("{v} does not fit in {width} columns"),
        })
    }
}

fn e(v: f64, width: usize, decimals: usize, what: &str) -> Result<String, UffError> {
    e_field(v, width, decimals).ok_or_else(|| unwritable(what, format!("{v} is not finite")))
}

fn text_field(s: &str, width: usize, what: &str) -> Result<String, UffError> {
    let s = if s.trim().is_empty() { "NONE" } else { s };
    a_field(s, width, what)
}

fn a_field(s: &str, width: usize, what: &str) -> Result<String, UffError> {
    fortran::a_field(s, width).ok_or_else(|| {
        unwritable(
            what,
            format!("{s:?} is not ASCII text of at most {width} characters on one line"),
        )
    })
}

fn axis_record(a: &AxisInfo, what: &str) -> Result<String, UffError> {
    Ok(format!(
        "{}{}{}{} {} {}\n",
        i_field("58", a.specific_data_type, 10, what)?,
        i_field("58", a.length_exponent, 5, what)?,
        i_field("58", a.force_exponent, 5, what)?,
        i_field("58", a.temperature_exponent, 5, what)?,
        text_field(&a.label, 20, what)?,
        text_field(&a.units_label, 20, what)?,
    ))
}

/// Writes `f` as an ASCII dataset 58 in double precision (ordinate type 4 or 6, `4E20.12`
/// data, 13 significant digits, 12 for negative values beyond 1e±99; the abscissa in `E13.5`
/// columns with 7 digits, 6 when negative). The
/// whole dataset is checked before the first byte is written: an ID line over 80 characters, a
/// label over 20, a number too wide for its columns, a non-finite value or an uneven abscissa
/// of another length than the ordinate is an [`UffError::Unwritable`].
pub fn write_function58(w: &mut impl Write, f: &Function58) -> Result<(), UffError> {
    let n = f.ordinate.len();
    if n == 0 {
        return Err(unwritable("ordinate", "no points"));
    }
    let mut s = String::from("    -1\n    58\n");
    for (i, id) in f.id_lines.iter().enumerate() {
        s += &text_field(id, 80, &format!("ID line {}", i + 1))?;
        s = s.trim_end().to_string() + "\n";
    }
    let (r, q) = (&f.response, &f.reference);
    s += &format!(
        "{}{}{}{} {}{}{} {}{}{}\n",
        i_field("58", f.function_type.code(), 5, "function type")?,
        i_field("58", f.function_id, 10, "function id")?,
        i_field("58", f.version, 5, "version")?,
        i_field("58", f.load_case, 10, "load case")?,
        text_field(&r.entity, 10, "response entity")?,
        i_field("58", r.node, 10, "response node")?,
        i_field("58", r.direction, 4, "response direction")?,
        text_field(&q.entity, 10, "reference entity")?,
        i_field("58", q.node, 10, "reference node")?,
        i_field("58", q.direction, 4, "reference direction")?,
    );
    let complex = matches!(f.ordinate, Ordinate::Complex(_));
    let (even, start, inc) = match &f.abscissa {
        Abscissa::Even { start, increment } => (true, *start, *increment),
        Abscissa::Uneven(x) if x.len() == n => (false, 0.0, 0.0),
        Abscissa::Uneven(x) => {
            return Err(unwritable(
                "uneven abscissa",
                format!("{} values for {n} ordinate points", x.len()),
            ))
        }
    };
    s += &format!(
        "{}{}{}{}{}{}\n",
        i_field("58", if complex { 6 } else { 4 }, 10, "ordinate type")?,
        i_field("58", n as i64, 10, "number of points")?,
        i_field("58", i64::from(even), 10, "spacing")?,
        e(start, 13, 6, "abscissa minimum")?,
        e(inc, 13, 6, "abscissa increment")?,
        e(f.z_axis_value, 13, 6, "z-axis value")?,
    );
    s += &axis_record(&f.abscissa_axis, "record 8")?;
    s += &axis_record(&f.ordinate_axis, "record 9")?;
    s += &axis_record(&f.denominator_axis, "record 10")?;
    s += &axis_record(&f.z_axis, "record 11")?;
    let values = f.ordinate.to_complex();
    let y = |k: usize, part: f64| e(part, 20, 12, &format!("ordinate value {}", k + 1));
    match (&f.abscissa, complex) {
        (Abscissa::Even { .. }, _) => {
            let flat: Vec<f64> = if complex {
                values.iter().flat_map(|z| [z.re, z.im]).collect()
            } else {
                values.iter().map(|z| z.re).collect()
            };
            let per_value = if complex { 2 } else { 1 };
            for (row, chunk) in flat.chunks(4).enumerate() {
                for (j, v) in chunk.iter().enumerate() {
                    s += &y((row * 4 + j) / per_value, *v)?;
                }
                s.push('\n');
            }
        }
        (Abscissa::Uneven(x), false) => {
            for (row, pair) in x.chunks(2).zip(values.chunks(2)).enumerate() {
                for (j, (xv, z)) in pair.0.iter().zip(pair.1).enumerate() {
                    s += &e(*xv, 13, 6, &format!("abscissa value {}", row * 2 + j + 1))?;
                    s += &y(row * 2 + j, z.re)?;
                }
                s.push('\n');
            }
        }
        (Abscissa::Uneven(x), true) => {
            for (k, (xv, z)) in x.iter().zip(&values).enumerate() {
                s += &e(*xv, 13, 6, &format!("abscissa value {}", k + 1))?;
                s += &y(k, z.re)?;
                s += &y(k, z.im)?;
                s.push('\n');
            }
        }
    }
    s += "    -1\n";
    w.write_all(s.as_bytes()).map_err(|source| UffError::Write {
        dataset: "58".into(),
        source,
    })
}
