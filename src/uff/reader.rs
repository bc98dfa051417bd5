//! Splitting a universal file into datasets (text and binary) and handing each to its parser.

use std::path::Path;

use super::fortran::{self, columns, BadField};
use super::{dataset55, dataset58, nodes, Dataset, SkippedDataset, UffContents, UffError};

/// One line of the file: its 1-based number and its bytes without the line break.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Line<'a> {
    pub no: usize,
    pub text: &'a [u8],
}

/// A position in the file's bytes that hands out lines and, for binary datasets, raw bytes.
struct Cursor<'a> {
    bytes: &'a [u8],
    pos: usize,
    line: usize,
}

impl<'a> Cursor<'a> {
    fn next_line(&mut self) -> Option<Line<'a>> {
        let rest = self.bytes.get(self.pos..).filter(|r| !r.is_empty())?;
        let (text, advance) = match rest.iter().position(|&b| b == b'\n') {
            Some(i) => (&rest[..i], i + 1),
            None => (rest, rest.len()),
        };
        self.pos += advance;
        self.line += 1;
        Some(Line {
            no: self.line,
            text: text.strip_suffix(b"\r").unwrap_or(text),
        })
    }

    fn remaining(&self) -> usize {
        self.bytes.len().saturating_sub(self.pos)
    }

    /// The next `n` bytes, or `None` when fewer remain (checked before anything is taken).
    fn take(&mut self, n: usize) -> Option<&'a [u8]> {
        if n > self.remaining() {
            return None;
        }
        let data = &self.bytes[self.pos..self.pos + n];
        self.pos += n;
        self.line += data.iter().filter(|&&b| b == b'\n').count();
        Some(data)
    }

    /// Steps over one line break (binary data is often followed by one before `-1`).
    fn skip_line_break(&mut self) {
        let rest = &self.bytes[self.pos.min(self.bytes.len())..];
        if rest.starts_with(b"\r\n") {
            self.pos += 2;
        } else if rest.starts_with(b"\n") {
            self.pos += 1;
        }
    }
}

/// Is this the `    -1` line that opens and closes every dataset?
pub(crate) fn is_delimiter(text: &[u8]) -> bool {
    text.trim_ascii() == b"-1"
}

/// A line (or field) quoted for an error message, shortened to 60 characters.
pub(crate) fn quote(text: &[u8]) -> String {
    let s = String::from_utf8_lossy(text);
    let s = s.trim_end();
    if s.chars().count() > 60 {
        format!("'{}…'", s.chars().take(60).collect::<String>())
    } else {
        format!("'{s}'")
    }
}

pub(crate) fn malformed(
    dataset: &str,
    line: usize,
    expected: impl Into<String>,
    found: impl Into<String>,
) -> UffError {
    UffError::Malformed {
        dataset: dataset.to_string(),
        line,
        expected: expected.into(),
        found: found.into(),
    }
}

pub(crate) fn truncated(
    dataset: &str,
    line: usize,
    expected: impl Into<String>,
    found: impl Into<String>,
) -> UffError {
    UffError::Truncated {
        dataset: dataset.to_string(),
        line,
        expected: expected.into(),
        found: found.into(),
    }
}

/// The error for a field that is not a number.
pub(crate) fn bad_number(dataset: &str, line: usize, what: &str, bad: BadField) -> UffError {
    malformed(
        dataset,
        line,
        format!("{what} (a number)"),
        format!("'{}'", bad.0),
    )
}

/// Reads `count` reals from `lines[*next..]`, cut at `pattern`'s widths (see
/// [`fortran::line_reals`]), advancing `*next` past the lines used. A record's values end at a
/// line end: a line that holds more than the values still wanted is an error. The vector grows
/// with the values actually present, never with the claim.
pub(crate) fn read_reals(
    dataset: &str,
    lines: &[Line],
    next: &mut usize,
    count: usize,
    pattern: &[usize],
    what: &str,
) -> Result<Vec<f64>, UffError> {
    let mut out = Vec::new();
    while out.len() < count {
        let Some(line) = lines.get(*next) else {
            let at = lines.last().map_or(0, |l| l.no + 1);
            return Err(truncated(
                dataset,
                at,
                format!("{count} values of {what}"),
                format!("{} before the dataset's end", out.len()),
            ));
        };
        *next += 1;
        let values = fortran::line_reals(line.text, pattern)
            .map_err(|b| bad_number(dataset, line.no, what, b))?;
        if out.len() + values.len() > count {
            return Err(malformed(
                dataset,
                line.no,
                format!("{} more values of {what}", count - out.len()),
                format!("{} on this line", values.len()),
            ));
        }
        out.extend(values);
    }
    Ok(out)
}

/// Reads a universal file from disk; see [`parse_uff`].
pub fn read_uff(path: impl AsRef<Path>) -> Result<UffContents, UffError> {
    let path = path.as_ref();
    let bytes = std::fs::read(path).map_err(|source| UffError::Io {
        path: path.display().to_string(),
        source,
    })?;
    parse_uff(&bytes)
}

/// Parses the bytes of a universal file: datasets 58/58b, 55, 15, 2411 and 164 are read, others
/// skipped (their numbers listed). Blank lines between datasets are allowed; anything else
/// outside a `-1 … -1` pair is an error.
pub fn parse_uff(bytes: &[u8]) -> Result<UffContents, UffError> {
    let mut cur = Cursor {
        bytes,
        pos: 0,
        line: 0,
    };
    let mut out = UffContents::default();
    while let Some(open) = cur.next_line() {
        if fortran::blank(open.text) {
            continue;
        }
        if !is_delimiter(open.text) {
            return Err(malformed(
                "none",
                open.no,
                "a line '    -1' opening a dataset",
                quote(open.text),
            ));
        }
        let Some(id) = cur.next_line() else {
            return Err(truncated(
                "none",
                open.no + 1,
                "a dataset number after '-1'",
                "the end of input",
            ));
        };
        let number = fortran::int(columns(id.text, 0, 6))
            .ok()
            .filter(|n| *n > 0)
            .ok_or_else(|| {
                malformed(
                    "none",
                    id.no,
                    "a dataset number in columns 1-6",
                    quote(id.text),
                )
            })?;
        if id
            .text
            .get(6)
            .is_some_and(|b| b.eq_ignore_ascii_case(&b'b'))
        {
            read_binary(&mut cur, number, id, &mut out)?;
            continue;
        }
        let name = number.to_string();
        let mut lines = Vec::new();
        loop {
            match cur.next_line() {
                Some(l) if is_delimiter(l.text) => break,
                Some(l) => lines.push(l),
                None => {
                    return Err(truncated(
                        &name,
                        cur.line + 1,
                        "a line '    -1' closing the dataset",
                        "the end of input",
                    ))
                }
            }
        }
        let dataset = match number {
            58 => Dataset::Function(Box::new(dataset58::parse_ascii(&lines, id.no)?)),
            55 => Dataset::ModeShape(Box::new(dataset55::parse(&lines, id.no)?)),
            15 => Dataset::Nodes(nodes::parse15(&lines)?),
            2411 => Dataset::Nodes(nodes::parse2411(&lines)?),
            164 => Dataset::Units(nodes::parse164(&lines, id.no)?),
            _ => {
                out.skipped.push(SkippedDataset {
                    number,
                    line: id.no,
                });
                continue;
            }
        };
        out.datasets.push(dataset);
    }
    Ok(out)
}

/// A binary dataset: `NNNNNNb` + byte order, float format, ASCII line count and byte count
/// (`I6,1A1,I6,I6,I12,I12,…`), then the ASCII lines, the bytes, and `-1`.
fn read_binary(
    cur: &mut Cursor,
    number: i64,
    id: Line,
    out: &mut UffContents,
) -> Result<(), UffError> {
    let name = format!("{number}b");
    let field = |a, b, what: &str| {
        fortran::int(columns(id.text, a, b)).map_err(|e| bad_number(&name, id.no, what, e))
    };
    let byte_order = field(7, 13, "byte ordering (1 little, 2 big endian)")?;
    let float_format = field(13, 19, "floating-point format (2 = IEEE 754)")?;
    let n_ascii = field(19, 31, "number of ASCII lines")?;
    let n_bytes = field(31, 43, "number of binary bytes")?;
    let expected_ascii = if number == 58 { 11 } else { n_ascii };
    if !(0..=1000).contains(&n_ascii) || n_ascii != expected_ascii {
        return Err(malformed(
            &name,
            id.no,
            format!("{expected_ascii} ASCII header lines (columns 20-31)"),
            n_ascii.to_string(),
        ));
    }
    let mut header = Vec::new();
    for _ in 0..n_ascii {
        let l = cur.next_line().ok_or_else(|| {
            truncated(
                &name,
                cur.line + 1,
                format!("{n_ascii} ASCII header lines"),
                format!("{} before the end of input", header.len()),
            )
        })?;
        header.push(l);
    }
    let data_line = cur.line + 1;
    if number != 58 {
        let n = usize::try_from(n_bytes)
            .ok()
            .filter(|&n| n <= cur.remaining());
        let Some(n) = n else {
            return Err(truncated(
                &name,
                data_line,
                format!("{n_bytes} bytes of binary data"),
                format!("{} bytes before the end of input", cur.remaining()),
            ));
        };
        cur.take(n);
        close_binary(cur, &name, n, n_bytes)?;
        out.skipped.push(SkippedDataset {
            number,
            line: id.no,
        });
        return Ok(());
    }
    let little_endian = match byte_order {
        1 => true,
        2 => false,
        other => {
            return Err(malformed(
                &name,
                id.no,
                "byte ordering 1 (little endian) or 2 (big endian) in columns 8-13",
                other.to_string(),
            ))
        }
    };
    if float_format != 2 {
        return Err(malformed(
            &name,
            id.no,
            "floating-point format 2 (IEEE 754; 1 = DEC VMS and 3 = IBM 370 are not read)",
            float_format.to_string(),
        ));
    }
    let (mut f, form) = dataset58::parse_header(&header, &name)?;
    // Record 7 says what the data is; pyuff writes the header's byte count for complex data as
    // half the truth, so record 7's count is the one used and the closing `-1` checks it.
    let size = form.binary_size(&name, data_line)?;
    let data = cur.take(size).ok_or_else(|| {
        truncated(
            &name,
            data_line,
            format!("{size} bytes of binary data ({})", form.describe()),
            format!("{} bytes before the end of input", cur.remaining()),
        )
    })?;
    dataset58::fill_binary(&mut f, &form, data, little_endian, &name, data_line)?;
    close_binary(cur, &name, size, n_bytes)?;
    out.datasets.push(Dataset::Function(Box::new(f)));
    Ok(())
}

/// After binary data: an optional line break, then `-1`.
fn close_binary(cur: &mut Cursor, name: &str, used: usize, header: i64) -> Result<(), UffError> {
    cur.skip_line_break();
    match cur.next_line() {
        Some(l) if is_delimiter(l.text) => Ok(()),
        other => {
            let note = if header == used as i64 {
                String::new()
            } else {
                format!(" (the header line claims {header} bytes)")
            };
            Err(malformed(
                name,
                other.map_or(cur.line + 1, |l| l.no),
                format!("'    -1' right after {used} bytes of binary data{note}"),
                other.map_or("the end of input".into(), |l| quote(l.text)),
            ))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const UNKNOWN_AND_NODES: &str = "    -1\n   151\nmodel name\n description\n    -1\n\n    -1\n    15\n         1         0         0         0  1.00000E+00  2.00000E+00  3.00000E+00\n    -1\n";

    #[test]
    fn unknown_datasets_are_skipped_and_listed() {
        let c = parse_uff(UNKNOWN_AND_NODES.as_bytes()).unwrap();
        assert_eq!(
            c.skipped,
            vec![SkippedDataset {
                number: 151,
                line: 2
            }]
        );
        let n: Vec<_> = c.nodes().collect();
        assert_eq!(n.len(), 1);
        assert_eq!(n[0].xyz, [1.0, 2.0, 3.0]);
    }

    #[test]
    fn junk_between_datasets_and_unclosed_datasets_are_errors_with_lines() {
        let e = parse_uff(b"    -1\n   151\nx\n    -1\nhello\n").unwrap_err();
        assert!(matches!(e, UffError::Malformed { line: 5, .. }), "{e}");
        assert!(e.to_string().contains("'hello'"), "{e}");
        let e = parse_uff(b"    -1\n    15\n         1").unwrap_err();
        assert!(matches!(e, UffError::Truncated { .. }), "{e}");
        assert!(e.to_string().contains("dataset 15"), "{e}");
        let e = parse_uff(b"    -1\n  abc\n    -1\n").unwrap_err();
        assert!(e.to_string().contains("dataset number"), "{e}");
    }

    #[test]
    fn an_unknown_binary_dataset_is_stepped_over_by_its_byte_count() {
        let mut f = b"    -1\n  2414b     1     2           1           5     0     0           0           0\nascii\n".to_vec();
        f.extend_from_slice(b"\n-1\x00\xff");
        f.extend_from_slice(b"\n    -1\n");
        let c = parse_uff(&f).unwrap();
        assert_eq!(c.skipped.len(), 1);
        assert_eq!(c.skipped[0].number, 2414);
        // A claim past the end of the input is refused before anything is taken.
        let f = b"    -1\n  2414b     1     2           0   999999999     0     0           0           0\n    -1\n";
        assert!(matches!(
            parse_uff(f).unwrap_err(),
            UffError::Truncated { .. }
        ));
    }

    /// A file with every dataset kind the reader knows, written by the writers (and a 58b and
    /// a 164 by hand).
    fn valid_file() -> Vec<u8> {
        use crate::uff::*;
        use realfft::num_complex::Complex;
        let mut out = Vec::new();
        let frf = Function58::new(
            FunctionType::FrequencyResponse,
            NodeDof::new(3, 3),
            NodeDof::new(1, 3),
            Abscissa::Even {
                start: 0.0,
                increment: 0.5,
            },
            Ordinate::Complex(
                (0..7)
                    .map(|k| Complex::new(k as f64, -1.5 * k as f64))
                    .collect(),
            ),
        );
        write_function58(&mut out, &frf).unwrap();
        let mut t = frf.clone();
        t.abscissa = Abscissa::Uneven(vec![0.0, 1.0, 2.0]);
        t.ordinate = Ordinate::Real(vec![1.0, -0.5, 0.25]);
        write_function58(&mut out, &t).unwrap();
        out.extend_from_slice(b"    -1\n    58b     1     2          11          16     0     0           0           0\nNONE\nNONE\nNONE\nNONE\nNONE\n    1         0    0         0 NONE               5   2 NONE               5   2\n         4         2         1  0.00000E+00  1.00000E-03  0.00000E+00\n");
        for _ in 0..4 {
            out.extend_from_slice(b"         0    0    0    0 NONE                 NONE\n");
        }
        out.extend_from_slice(&1.0f64.to_le_bytes());
        out.extend_from_slice(&(-2.0f64).to_le_bytes());
        out.extend_from_slice(b"\n    -1\n");
        let nodes = vec![
            Node::new(1, [0.0, 1.0, 2.0]),
            Node::new(3, [-1.0, 0.5, 0.0]),
        ];
        write_nodes15(&mut out, &nodes).unwrap();
        write_nodes2411(&mut out, &nodes).unwrap();
        let shape = ModeShape55::complex_mode(
            1,
            12.5,
            0.02,
            vec![NodeValues {
                node: 3,
                values: vec![Complex::new(1.0, 0.5); 3],
            }],
        );
        write_mode_shape55(&mut out, &shape).unwrap();
        out.extend_from_slice(b"    -1\n   164\n         1SI                           2\n  1.0D+00  1.0D+00  1.0D+00\n  2.7315D+02\n    -1\n");
        out.extend_from_slice(UNKNOWN_AND_NODES.as_bytes());
        out
    }

    #[test]
    fn the_valid_file_reads_whole() {
        let c = parse_uff(&valid_file()).unwrap();
        assert_eq!(c.functions().count(), 3);
        assert_eq!(c.nodes().count(), 5);
        assert_eq!(c.mode_shapes().count(), 1);
        assert_eq!(c.units().unwrap().length_factor, 1.0);
        assert_eq!(c.skipped.len(), 1);
    }

    /// One edit of the file: overwrite, insert or delete a byte, or cut the file.
    #[derive(Debug, Clone)]
    enum Edit {
        Set(usize, u8),
        Insert(usize, u8),
        Delete(usize),
        Cut(usize),
    }

    fn edit() -> impl proptest::strategy::Strategy<Value = Edit> {
        use proptest::prelude::*;
        let byte = prop_oneof![
            any::<u8>(),
            Just(b'\n'),
            Just(b'9'),
            Just(b'-'),
            Just(b' '),
            Just(b'b')
        ];
        prop_oneof![
            (any::<usize>(), byte.clone()).prop_map(|(i, b)| Edit::Set(i, b)),
            (any::<usize>(), byte).prop_map(|(i, b)| Edit::Insert(i, b)),
            any::<usize>().prop_map(Edit::Delete),
            any::<usize>().prop_map(Edit::Cut),
        ]
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig::with_cases(2000))]
        /// Random byte mutations of a valid file never panic: the reader answers with datasets
        /// or a typed error.
        #[test]
        fn mutations_never_panic(edits in proptest::collection::vec(edit(), 1..8)) {
            let mut f = valid_file();
            for e in edits {
                let n = f.len().max(1);
                match e {
                    Edit::Set(i, b) => { let i = i % n; if i < f.len() { f[i] = b; } }
                    Edit::Insert(i, b) => f.insert(i % (f.len() + 1), b),
                    Edit::Delete(i) => { if !f.is_empty() { f.remove(i % f.len()); } }
                    Edit::Cut(i) => f.truncate(i % n),
                }
            }
            let _ = parse_uff(&f);
        }
    }
}
