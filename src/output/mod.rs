//! Result tables (FORMATS.md §4): CSV with a header row, or the same rows as JSON lines.
//!
//! A missing estimate is an empty CSV cell (`null` in JSON), never a made-up number. Flags are
//! joined with `;`. Rows are flushed as they are written, so a reader downstream of a pipe sees
//! each decay's results as soon as it ends.

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

/// The columns, in order.
pub const COLUMNS: [&str; 21] = [
    "channel",
    "decay",
    "onset_s",
    "front_end",
    "f_lo",
    "f_hi",
    "f_center",
    "f_nominal",
    "range",
    "edt_s",
    "t20_s",
    "t30_s",
    "t60_s",
    "damping_ratio",
    "damping_ratio_corrected",
    "f_dominant",
    "r2",
    "dynamic_range_db",
    "n_points",
    "curvature_pct",
    "flags",
];

fn num(v: Option<f64>) -> String {
    match v {
        Some(x) if x.is_finite() => format!("{x:.6}"),
        _ => String::new(),
    }
}

fn json_num(v: Option<f64>) -> serde_json::Value {
    match v {
        Some(x) if x.is_finite() => serde_json::json!(x),
        _ => serde_json::Value::Null,
    }
}

/// The cells of one row, as text, in [`COLUMNS`] order.
pub fn row_cells(r: &ResultRow) -> Vec<String> {
    let e = &r.estimate;
    let flags: Vec<&str> = e.flags.iter().map(|f| f.as_str()).collect();
    vec![
        r.channel.clone(),
        r.decay.to_string(),
        num(r.onset_s),
        r.front_end.to_string(),
        num(Some(r.band.lo_hz)),
        num(Some(r.band.hi_hz)),
        num(Some(r.band.center_hz)),
        num(Some(r.band.nominal_hz)),
        r.range.to_string(),
        num(e.edt_s),
        num(e.t20_s),
        num(e.t30_s),
        num(e.t60_s),
        num(e.damping_ratio),
        num(e.damping_ratio_corrected),
        num(e.f_dominant_hz),
        num(e.r2),
        num(e.dynamic_range_db),
        e.n_points.to_string(),
        num(e.curvature_pct),
        flags.join(";"),
    ]
}

fn row_json(r: &ResultRow) -> serde_json::Value {
    let e = &r.estimate;
    let flags: Vec<&str> = e.flags.iter().map(|f| f.as_str()).collect();
    serde_json::json!({
        "channel": r.channel,
        "decay": r.decay,
        "onset_s": json_num(r.onset_s),
        "front_end": r.front_end,
        "f_lo": r.band.lo_hz,
        "f_hi": r.band.hi_hz,
        "f_center": r.band.center_hz,
        "f_nominal": r.band.nominal_hz,
        "range": r.range.to_string(),
        "edt_s": json_num(e.edt_s),
        "t20_s": json_num(e.t20_s),
        "t30_s": json_num(e.t30_s),
        "t60_s": json_num(e.t60_s),
        "damping_ratio": json_num(e.damping_ratio),
        "damping_ratio_corrected": json_num(e.damping_ratio_corrected),
        "f_dominant": json_num(e.f_dominant_hz),
        "r2": json_num(e.r2),
        "dynamic_range_db": json_num(e.dynamic_range_db),
        "n_points": e.n_points,
        "curvature_pct": json_num(e.curvature_pct),
        "flags": flags,
    })
}

/// Writes result rows to any writer, flushing after each batch.
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

    /// Writes the CSV header (once); called automatically by [`TableWriter::write_rows`].
    pub fn write_header(&mut self) -> Result<()> {
        if !self.header_done && self.format == TableFormat::Csv {
            writeln!(self.out, "{}", COLUMNS.join(",")).map_err(io_err)?;
        }
        self.header_done = true;
        Ok(())
    }

    /// Writes a batch of rows and flushes.
    pub fn write_rows(&mut self, rows: &[ResultRow]) -> Result<()> {
        self.write_header()?;
        for r in rows {
            match self.format {
                TableFormat::Csv => {
                    let cells: Vec<String> = row_cells(r).into_iter().map(csv_escape).collect();
                    writeln!(self.out, "{}", cells.join(",")).map_err(io_err)?;
                }
                TableFormat::Jsonl => {
                    writeln!(self.out, "{}", row_json(r)).map_err(io_err)?;
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

fn csv_escape(cell: String) -> String {
    if cell.contains([',', '"', '\n', '\r']) {
        format!("\"{}\"", cell.replace('"', "\"\""))
    } else {
        cell
    }
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
/// an error names the file.
pub fn write_csv_file<T: serde::Serialize>(
    path: &std::path::Path,
    rows: impl IntoIterator<Item = T>,
) -> Result<()> {
    let failed = |e: csv::Error| Error::Output(format!("{}: {e}", path.display()));
    let mut w = csv::Writer::from_path(path).map_err(failed)?;
    for r in rows {
        w.serialize(r).map_err(failed)?;
    }
    w.flush()
        .map_err(|e| Error::Output(format!("{}: {e}", path.display())))
}
