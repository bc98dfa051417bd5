//! Result tables (FORMATS.md §4): CSV with a header row, or the same rows as JSON lines.
//!
//! A missing estimate is an empty CSV cell (`null` in JSON), never a made-up number. Flags are
//! joined with `;`. Rows are flushed as they are written, so a reader downstream of a pipe sees
//! each decay's results as soon as it ends.

pub mod atomic;
pub mod fixed6;
pub mod raw;
pub mod recording_set;
pub mod uff;
pub mod wav;

pub use recording_set::{
    write_recording_set, write_recording_set_streamed, write_recording_set_uff,
};
pub use wav::{write_wav_f32, WavStreamWriter};

use std::io::Write;

use crate::error::{Error, Result};
use crate::pipeline::ResultRow;

/// Table format.
#[derive(
    Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum, serde::Serialize, serde::Deserialize,
)]
pub enum TableFormat {
    /// Comma-separated values with a header row.
    Csv,
    /// One JSON object per line.
    Jsonl,
}

/// A number cell: finite values only (a missing or non-finite estimate is an empty CSV cell,
/// `null` in JSON). In CSV six decimals, in JSON the value as computed.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Num(pub Option<f64>);

impl serde::Serialize for Num {
    fn serialize<S: serde::Serializer>(&self, s: S) -> std::result::Result<S::Ok, S::Error> {
        match self.0 {
            Some(x) if x.is_finite() => s.serialize_f64(x),
            _ => s.serialize_none(),
        }
    }
}

/// A number cell of the CSV table: six decimals, empty when missing.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Fixed6(pub Option<f64>);

impl serde::Serialize for Fixed6 {
    fn serialize<S: serde::Serializer>(&self, s: S) -> std::result::Result<S::Ok, S::Error> {
        thread_local! {
            /// The cell's text (one buffer per thread instead of a string per cell).
            static CELL: std::cell::RefCell<String> = const { std::cell::RefCell::new(String::new()) };
        }
        match self.0 {
            Some(x) if x.is_finite() => CELL.with(|cell| match cell.try_borrow_mut() {
                Ok(mut text) => {
                    text.clear();
                    fixed6::write_fixed6(x, &mut text);
                    s.serialize_str(&text)
                }
                Err(_) => {
                    let mut text = String::new();
                    fixed6::write_fixed6(x, &mut text);
                    s.serialize_str(&text)
                }
            }),
            _ => s.serialize_none(),
        }
    }
}

/// One row of the result table (FORMATS.md §4): the one place its columns are listed. `N` is
/// the number cell ([`Fixed6`] for CSV, [`Num`] for JSON), `F` the flags (joined with `;` in
/// CSV, a list in JSON).
#[derive(Clone, Debug, serde::Serialize)]
pub struct TableRow<'a, N, F> {
    /// Channel (sensor id).
    pub channel: &'a str,
    /// Index of the decay in the channel's stream.
    pub decay: usize,
    /// Onset of the decay, s from the start.
    pub onset_s: N,
    /// Front end.
    pub front_end: &'a str,
    /// Band edges, centre and nominal frequency, Hz.
    pub f_lo: N,
    /// Upper band edge, Hz.
    pub f_hi: N,
    /// Band centre, Hz.
    pub f_center: N,
    /// Nominal band frequency, Hz.
    pub f_nominal: N,
    /// Evaluation range of `t60_s` and the damping ratios.
    pub range: String,
    /// Early decay time, s.
    pub edt_s: N,
    /// T20, s.
    pub t20_s: N,
    /// T30, s.
    pub t30_s: N,
    /// T60 from the evaluation range, s.
    pub t60_s: N,
    /// Damping ratio D = 1.1 / (T60 f).
    pub damping_ratio: N,
    /// D with the band's dominant frequency in place of its centre.
    pub damping_ratio_corrected: N,
    /// Dominant frequency, Hz.
    pub f_dominant: N,
    /// r² of the fit.
    pub r2: N,
    /// Dynamic range of the decay, dB.
    pub dynamic_range_db: N,
    /// Frames in the fit.
    pub n_points: usize,
    /// Curvature C = 100 (T30/T20 − 1), %.
    pub curvature_pct: N,
    /// Flags.
    pub flags: F,
}

/// The table row of a result, with number cells made by `num` and flags by `flags`.
pub fn table_row<'a, N, F>(
    r: &'a ResultRow,
    num: impl Fn(Option<f64>) -> N,
    flags: impl Fn(Vec<&'static str>) -> F,
) -> TableRow<'a, N, F> {
    let e = &r.estimate;
    TableRow {
        channel: &r.channel,
        decay: r.decay,
        onset_s: num(r.onset_s),
        front_end: r.front_end,
        f_lo: num(Some(r.band.lo_hz)),
        f_hi: num(Some(r.band.hi_hz)),
        f_center: num(Some(r.band.center_hz)),
        f_nominal: num(Some(r.band.nominal_hz)),
        range: r.range.to_string(),
        edt_s: num(e.edt_s),
        t20_s: num(e.t20_s),
        t30_s: num(e.t30_s),
        t60_s: num(e.t60_s),
        damping_ratio: num(e.damping_ratio),
        damping_ratio_corrected: num(e.damping_ratio_corrected),
        f_dominant: num(e.f_dominant_hz),
        r2: num(e.r2),
        dynamic_range_db: num(e.dynamic_range_db),
        n_points: e.n_points,
        curvature_pct: num(e.curvature_pct),
        flags: flags(e.flags.iter().map(|f| f.as_str()).collect()),
    }
}

/// Writes result rows to any writer, flushing after each batch (CSV through the `csv` crate,
/// JSON lines through `serde_json`: quoting and escaping are theirs).
pub struct TableWriter<W: Write> {
    out: W,
    format: TableFormat,
    header_done: bool,
}

fn io_err(e: impl std::fmt::Display) -> Error {
    Error::Output(e.to_string())
}

impl<W: Write> TableWriter<W> {
    /// A writer in `format` to `out`.
    pub fn new(out: W, format: TableFormat) -> Self {
        TableWriter {
            out,
            format,
            header_done: false,
        }
    }

    fn csv(&mut self) -> csv::Writer<&mut W> {
        csv::WriterBuilder::new()
            .has_headers(false)
            .from_writer(&mut self.out)
    }

    /// Writes the CSV header (once); called automatically by [`TableWriter::write_rows`].
    pub fn write_header(&mut self) -> Result<()> {
        if !self.header_done && self.format == TableFormat::Csv {
            let mut w = self.csv();
            w.write_record(columns()).map_err(io_err)?;
            w.flush().map_err(io_err)?;
        }
        self.header_done = true;
        Ok(())
    }

    /// Writes a batch of rows and flushes.
    pub fn write_rows(&mut self, rows: &[ResultRow]) -> Result<()> {
        self.write_header()?;
        match self.format {
            TableFormat::Csv => {
                let mut w = self.csv();
                for r in rows {
                    w.serialize(table_row(r, Fixed6, |f| f.join(";")))
                        .map_err(io_err)?;
                }
                w.flush().map_err(io_err)?;
            }
            TableFormat::Jsonl => {
                for r in rows {
                    serde_json::to_writer(&mut self.out, &table_row(r, Num, |f| f))
                        .map_err(io_err)?;
                    self.out.write_all(b"\n").map_err(io_err)?;
                }
            }
        }
        self.out.flush().map_err(io_err)
    }

    /// Gives the writer back.
    pub fn into_inner(self) -> W {
        self.out
    }
}

/// The column names, in order: the field names of [`TableRow`].
pub fn columns() -> Vec<String> {
    let mut names = csv::WriterBuilder::new().from_writer(Vec::new());
    let row = ResultRow {
        channel: String::new(),
        position_sample: 0,
        decay: 0,
        onset_s: None,
        front_end: "",
        band: crate::frontend::Band {
            lo_hz: 0.0,
            hi_hz: 1.0,
            center_hz: 0.5,
            nominal_hz: 0.5,
        },
        range: crate::decay::EvaluationRange::T30,
        estimate: Default::default(),
    };
    // The csv crate writes the header from the struct's field names.
    let _ = names.serialize(table_row(&row, Fixed6, |f| f.join(";")));
    let text = String::from_utf8(names.into_inner().unwrap_or_default()).unwrap_or_default();
    text.lines()
        .next()
        .unwrap_or_default()
        .split(',')
        .map(String::from)
        .collect()
}

/// Reads a results CSV written by [`TableWriter`] back into header-keyed records (for tests and
/// for the `map`/`compare` tools).
pub fn read_table(text: &str) -> Result<Vec<std::collections::HashMap<String, String>>> {
    let mut rdr = csv::ReaderBuilder::new().from_reader(text.as_bytes());
    let headers = rdr.headers().map_err(io_err)?.clone();
    let mut rows = Vec::new();
    for rec in rdr.records() {
        let rec = rec.map_err(io_err)?;
        rows.push(
            headers
                .iter()
                .zip(rec.iter())
                .map(|(h, v)| (h.to_string(), v.to_string()))
                .collect(),
        );
    }
    Ok(rows)
}

/// Writes `rows` to `path` as CSV with a header row (the `csv` crate: quoting and escaping are
/// its own). The one writer of every table file (`global.csv`, `modes.csv`, `sweep.csv`, …);
/// the file appears whole or not at all ([`atomic`]); an error names the file.
pub fn write_csv_file<T: serde::Serialize>(
    path: &std::path::Path,
    rows: impl IntoIterator<Item = T>,
) -> Result<()> {
    atomic::write_file(path, |f| {
        let mut w = csv::Writer::from_writer(f);
        for r in rows {
            w.serialize(r).map_err(std::io::Error::other)?;
        }
        w.flush()
    })
    .map_err(|e| Error::Output(e.to_string()))
}

/// Writes `text` to `path`, whole or not at all ([`atomic`]); an error names the file.
pub fn write_text_file(path: &std::path::Path, text: &str) -> Result<()> {
    atomic::write_file(path, |f| f.write_all(text.as_bytes()))
        .map_err(|e| Error::Output(e.to_string()))
}
