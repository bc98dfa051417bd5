//! Fortran fixed-width fields: reading numbers the way a Fortran `READ` with an `E`, `D` or `I`
//! edit descriptor does, and writing `E` fields that such a reader accepts.
//!
//! UFF records are Fortran formats (`3I10,3E13.5`, `4E20.12`, `1P3D25.16`). Two things make
//! whitespace splitting wrong: fields may touch (`-1.0000E+00-2.0000E+00` in two `E11.4`
//! columns) and exponents may be written with `D` or without a letter (`1.5-03`). The readers
//! here cut a line at the spec's column widths first and fall back to a sign-aware scan only when
//! a column does not hold a number (a writer that used other widths).

/// One field could not be read as a number: its text (trimmed, at most 40 characters).
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct BadField(pub String);

impl BadField {
    fn of(bytes: &[u8]) -> Self {
        let text = String::from_utf8_lossy(bytes);
        let t = text.trim();
        BadField(if t.chars().count() > 40 {
            format!("{}…", t.chars().take(40).collect::<String>())
        } else {
            t.to_string()
        })
    }
}

/// The bytes of columns `start..end` (0-based, end exclusive) of `line`, clipped to its length.
pub(crate) fn columns(line: &[u8], start: usize, end: usize) -> &[u8] {
    let s = start.min(line.len());
    &line[s..end.min(line.len()).max(s)]
}

/// Text of a field (lossy UTF-8, trailing blanks removed): for ID lines, labels and names.
pub(crate) fn text(field: &[u8]) -> String {
    String::from_utf8_lossy(field).trim_end().to_string()
}

fn is_blank(field: &[u8]) -> bool {
    field.iter().all(|b| b.is_ascii_whitespace())
}

/// A Fortran real: blanks around, `E`/`D` (any case) or no exponent letter (`1.5-03`).
/// `Ok(None)` for a blank field (Fortran reads it as zero; the caller decides), `Err` for
/// anything else that is not a finite number (`nan` and `inf` are refused: UFF has no such
/// values and a reader that took them would pass garbage on).
pub(crate) fn real(field: &[u8]) -> Result<Option<f64>, BadField> {
    let t = field.trim_ascii();
    if t.is_empty() {
        return Ok(None);
    }
    let mut s = String::with_capacity(t.len() + 1);
    let mut has_exp = false;
    for (i, &b) in t.iter().enumerate() {
        match b {
            b'0'..=b'9' | b'.' => s.push(b as char),
            b'E' | b'e' | b'D' | b'd' if !has_exp => {
                has_exp = true;
                s.push('E');
            }
            b'+' | b'-' if i == 0 || s.ends_with('E') => s.push(b as char),
            // A sign after the mantissa is Fortran's exponent without a letter: 1.5-03.
            b'+' | b'-' if !has_exp && (t[i - 1].is_ascii_digit() || t[i - 1] == b'.') => {
                has_exp = true;
                s.push('E');
                s.push(b as char);
            }
            _ => return Err(BadField::of(field)),
        }
    }
    match s.parse::<f64>() {
        Ok(v) if v.is_finite() => Ok(Some(v)),
        _ => Err(BadField::of(field)),
    }
}

/// A Fortran integer field: blank reads as 0 (Fortran's blank = zero).
pub(crate) fn int(field: &[u8]) -> Result<i64, BadField> {
    let t = field.trim_ascii();
    if t.is_empty() {
        return Ok(0);
    }
    std::str::from_utf8(t)
        .ok()
        .and_then(|s| s.parse::<i64>().ok())
        .ok_or_else(|| BadField::of(field))
}

/// Reals of one line cut at the widths of `pattern`, repeated (`[13, 20]` for
/// `2(E13.5,E20.12)`). Trailing blanks end the line; a blank field before the last number is
/// an error (a writer with other widths), as is a field that is not a number.
pub(crate) fn fixed_reals(line: &[u8], pattern: &[usize]) -> Result<Vec<f64>, BadField> {
    let line = line.trim_ascii_end();
    let mut out = Vec::new();
    let mut pos = 0;
    let mut k = 0;
    while pos < line.len() {
        let w = pattern[k % pattern.len()].max(1);
        let field = columns(line, pos, pos + w);
        match real(field)? {
            Some(v) => out.push(v),
            None => return Err(BadField::of(field)),
        }
        pos += w;
        k += 1;
    }
    Ok(out)
}

/// Reals of one line found by scanning: separated by blanks, or touching where a sign follows
/// a digit or a point (`-1.0E+00-2.0E+00`). The fallback for lines not in the spec's widths.
pub(crate) fn scan_reals(line: &[u8]) -> Result<Vec<f64>, BadField> {
    let mut out = Vec::new();
    for token in line.split(|b| b.is_ascii_whitespace()) {
        let mut start = 0;
        for i in 1..token.len() {
            let sign = token[i] == b'+' || token[i] == b'-';
            if sign && (token[i - 1].is_ascii_digit() || token[i - 1] == b'.') {
                out.extend(real(&token[start..i])?);
                start = i;
            }
        }
        if start < token.len() {
            out.extend(real(&token[start..])?);
        }
    }
    Ok(out)
}

/// Reals of a data line: the spec's columns, else the scan (see the module note).
pub(crate) fn line_reals(line: &[u8], pattern: &[usize]) -> Result<Vec<f64>, BadField> {
    fixed_reals(line, pattern).or_else(|first| scan_reals(line).map_err(|_| first))
}

/// `value` as a Fortran `E` field of `width` characters with at most `decimals` digits after
/// the point, and fewer when the exponent needs the room: always at least one leading blank, so
/// that readers that split on whitespace read it too. `None` for a non-finite value.
pub(crate) fn e_field(value: f64, width: usize, decimals: usize) -> Option<String> {
    if !value.is_finite() {
        return None;
    }
    for d in (0..=decimals).rev() {
        let s = format!("{value:.d$E}");
        let (mantissa, exp) = s.split_once('E')?;
        let exp: i32 = exp.parse().ok()?;
        let sign = if exp < 0 { '-' } else { '+' };
        let f = format!("{mantissa}E{sign}{:02}", exp.abs());
        if f.len() < width {
            return Some(format!("{f:>width$}"));
        }
    }
    None
}

/// `text` left-aligned and padded to `width`, or `None` when it is longer or holds a line
/// break (a fixed-width record cannot carry it).
pub(crate) fn a_field(text: &str, width: usize) -> Option<String> {
    (text.len() <= width && !text.contains(['\n', '\r']) && text.is_ascii())
        .then(|| format!("{text:<width$}"))
}

/// Is every byte of `line` blank?
pub(crate) fn blank(line: &[u8]) -> bool {
    is_blank(line)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn r(s: &str) -> Option<f64> {
        real(s.as_bytes()).unwrap()
    }

    #[test]
    fn fortran_reals_with_e_d_and_letterless_exponents() {
        assert_eq!(r(" 1.23456E+02"), Some(123.456));
        assert_eq!(r("1.5D-03"), Some(1.5e-3));
        assert_eq!(r("-2.5d+01"), Some(-25.0));
        assert_eq!(r("1.5-03"), Some(1.5e-3));
        assert_eq!(r("  -7.  "), Some(-7.0));
        assert_eq!(r("   "), None);
        for bad in [
            "nan", "inf", "1.0E+400", "1..2", "1.0E", "E5", "12a", "--1", "1e5e5",
        ] {
            assert!(real(bad.as_bytes()).is_err(), "{bad} accepted");
        }
    }

    #[test]
    fn touching_fields_are_cut_at_the_spec_columns() {
        // 6E13.5 with a 3-digit exponent fills the column: no blank between fields.
        let line = b"-1.23456E-100-2.00000E+00 3.00000E+00";
        assert_eq!(
            fixed_reals(line, &[13]).unwrap(),
            vec![-1.23456e-100, -2.0, 3.0]
        );
        // A 20-wide field followed by 13-wide ones.
        let line = b"  1.000000000000E+00-2.00000E+00";
        assert_eq!(fixed_reals(line, &[20, 13]).unwrap(), vec![1.0, -2.0]);
    }

    #[test]
    fn the_scan_separates_touching_numbers_by_their_signs() {
        assert_eq!(
            scan_reals(b"-1.0000E+00-2.0000E+00  3.5D-1").unwrap(),
            vec![-1.0, -2.0, 0.35]
        );
        // A line in other widths than the spec's: the columns fail, the scan reads it.
        let line = b"   1.0000000000000000E+00   2.0000000000000000E+00";
        assert_eq!(line_reals(line, &[20]).unwrap(), vec![1.0, 2.0]);
        assert!(line_reals(b" 1.0 x", &[13]).is_err());
    }

    #[test]
    fn integers_blank_is_zero_and_garbage_is_refused() {
        assert_eq!(int(b"   42").unwrap(), 42);
        assert_eq!(int(b"  +7 ").unwrap(), 7);
        assert_eq!(int(b"     ").unwrap(), 0);
        assert!(int(b" 4.5").is_err());
        assert!(int(b"99999999999999999999999").is_err());
    }

    #[test]
    fn e_fields_fit_their_width_with_a_leading_blank_and_read_back() {
        for (v, w, d) in [
            (123.456, 13, 5),
            (-1.0e-100, 13, 5),
            (0.0, 20, 12),
            (-9.99999999999999e99, 20, 12),
            (std::f64::consts::PI, 20, 12),
        ] {
            let f = e_field(v, w, d).unwrap();
            assert_eq!(f.len(), w, "{f:?}");
            assert!(f.starts_with(' '), "{f:?}");
            let back = r(&f).unwrap();
            assert!((back - v).abs() <= 1e-5 * v.abs(), "{v} → {f} → {back}");
        }
        let pi = e_field(std::f64::consts::PI, 20, 12).unwrap();
        assert_eq!(pi, "  3.141592653590E+00");
        assert_eq!(e_field(-1.0e-100, 13, 5).unwrap(), " -1.0000E-100");
        assert!(e_field(f64::NAN, 13, 5).is_none());
        assert_eq!(a_field("NONE", 6).unwrap(), "NONE  ");
        assert!(a_field("too long", 4).is_none());
        assert!(a_field("a\nb", 10).is_none());
    }
}
