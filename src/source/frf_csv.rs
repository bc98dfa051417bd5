//! FRFs from CSV: `f, <id>_re, <id>_im, …` (or `_db/_deg`, `_mag/_deg`), with an optional
//! `# exponential_window_tau_s=τ` comment (see [`super::frf`] for what is done with them).

use std::collections::HashMap;
use std::path::Path;

use realfft::num_complex::Complex;

use super::frf::{declared_tau, malformed, FrfChannel, FrfSet};
use super::SourceError;
use crate::Result;

/// Whether a CSV header line names FRF columns: first `f`/`freq`/`freq_hz`, then columns ending
/// in `_re`/`_im`, `_db`/`_deg` or `_mag`/`_deg` (how an input is told from a time series).
pub fn is_frf_csv_header(line: &str) -> bool {
    let mut cells = line.split(',').map(|c| c.trim().to_ascii_lowercase());
    let Some(first) = cells.next() else {
        return false;
    };
    if !matches!(first.as_str(), "f" | "freq" | "freq_hz" | "frequency_hz") {
        return false;
    }
    let rest: Vec<String> = cells.collect();
    !rest.is_empty()
        && rest.iter().all(|c| {
            ["_re", "_im", "_db", "_deg", "_mag"]
                .iter()
                .any(|s| c.ends_with(s))
        })
}

/// Reads an FRF CSV file; see [`parse_frf_csv`].
pub fn read_frf_csv(path: &Path) -> Result<FrfSet> {
    let text = std::fs::read_to_string(path).map_err(|source| SourceError::Io {
        what: path.display().to_string(),
        source,
    })?;
    parse_frf_csv(&text, &path.display().to_string())
}

/// What one FRF column holds.
#[derive(Clone, Copy, PartialEq, Eq, Hash, Debug)]
enum Part {
    Re,
    Im,
    Db,
    Mag,
    Deg,
}

/// FRFs from CSV text (`what` names it in errors). Header: first column `f`, `freq` or
/// `freq_hz` (Hz); then per sensor id two columns, `<id>_re, <id>_im` (real and imaginary
/// parts), `<id>_db, <id>_deg` (magnitude in dB re 1 and phase in degrees) or `<id>_mag,
/// <id>_deg`. Lines starting with `#` are comments; `# exponential_window_tau_s=0.5` declares
/// a window the test system applied. Errors name the column and the row (1 = first data row).
pub fn parse_frf_csv(text: &str, what: &str) -> Result<FrfSet> {
    let mut tau = None;
    for line in text.lines().filter(|l| l.trim_start().starts_with('#')) {
        match declared_tau(line) {
            Some(Ok(t)) => tau = Some(t),
            Some(Err(bad)) => {
                return Err(malformed(
                    what,
                    "csv",
                    format!(
                        "comment {line:?}: expected exponential_window_tau_s=τ > 0 s, got {bad:?}"
                    ),
                ))
            }
            None => {}
        }
    }
    let mut rdr = csv::ReaderBuilder::new()
        .comment(Some(b'#'))
        .trim(csv::Trim::All)
        .from_reader(text.as_bytes());
    let header: Vec<String> = rdr
        .headers()
        .map_err(|e| malformed(what, "csv", format!("header: {e}")))?
        .iter()
        .map(str::to_string)
        .collect();
    let first = header
        .first()
        .map(|h| h.to_ascii_lowercase())
        .unwrap_or_default();
    if !matches!(first.as_str(), "f" | "freq" | "freq_hz") {
        return Err(malformed(
            what,
            "csv",
            format!(
                "column 1: expected 'f', 'freq' or 'freq_hz', found {:?}",
                header.first().map_or("", |s| s.as_str())
            ),
        ));
    }
    // Per id: the column of each part, in order of first appearance.
    let mut ids: Vec<(String, HashMap<Part, usize>)> = Vec::new();
    for (c, name) in header.iter().enumerate().skip(1) {
        let bad = |why: &str| malformed(what, "csv", format!("column {} {name:?}: {why}", c + 1));
        let (id, suffix) = name
            .rsplit_once('_')
            .ok_or_else(|| bad("expected <id>_re/_im/_db/_mag/_deg"))?;
        let part = match suffix.to_ascii_lowercase().as_str() {
            "re" => Part::Re,
            "im" => Part::Im,
            "db" => Part::Db,
            "mag" => Part::Mag,
            "deg" => Part::Deg,
            _ => return Err(bad("expected the suffix _re, _im, _db, _mag or _deg")),
        };
        if id.is_empty() {
            return Err(bad("expected a sensor id before the suffix"));
        }
        let k = match ids.iter().position(|(i, _)| i == id) {
            Some(k) => k,
            None => {
                ids.push((id.to_string(), HashMap::new()));
                ids.len() - 1
            }
        };
        if ids[k].1.insert(part, c).is_some() {
            return Err(bad("repeats a column of the same sensor"));
        }
    }
    if ids.is_empty() {
        return Err(malformed(
            what,
            "csv",
            "expected at least one FRF column pair after the frequency".into(),
        ));
    }
    let mut pairs = Vec::new();
    for (id, parts) in &ids {
        let has = |p| parts.contains_key(&p);
        let pair = match parts.len() {
            2 if has(Part::Re) && has(Part::Im) => (Part::Re, parts[&Part::Re], parts[&Part::Im]),
            2 if has(Part::Db) && has(Part::Deg) => (Part::Db, parts[&Part::Db], parts[&Part::Deg]),
            2 if has(Part::Mag) && has(Part::Deg) => {
                (Part::Mag, parts[&Part::Mag], parts[&Part::Deg])
            }
            _ => {
                let mut got: Vec<String> = parts
                    .iter()
                    .map(|(p, c)| format!("{p:?} in column {}", c + 1))
                    .collect();
                got.sort();
                return Err(malformed(
                    what,
                    "csv",
                    format!(
                        "sensor {id:?}: expected one pair _re/_im, _db/_deg or _mag/_deg, found {}",
                        got.join(", ")
                    ),
                ));
            }
        };
        pairs.push(pair);
    }
    let mut freq_hz = Vec::new();
    let mut values: Vec<Vec<Complex<f64>>> = vec![Vec::new(); ids.len()];
    for (row, record) in rdr.records().enumerate() {
        let record = record.map_err(|e| malformed(what, "csv", format!("row {}: {e}", row + 1)))?;
        let cell = |c: usize| -> Result<f64> {
            let s = record.get(c).unwrap_or("");
            s.parse::<f64>()
                .ok()
                .filter(|v| v.is_finite())
                .ok_or_else(|| {
                    malformed(
                        what,
                        "csv",
                        format!(
                            "column {} {:?}, row {}: expected a finite number, found {s:?}",
                            c + 1,
                            header[c],
                            row + 1
                        ),
                    )
                })
        };
        freq_hz.push(cell(0)?);
        for (k, &(kind, a, b)) in pairs.iter().enumerate() {
            let (x, y) = (cell(a)?, cell(b)?);
            values[k].push(match kind {
                Part::Re => Complex::new(x, y),
                Part::Db => Complex::from_polar(10f64.powf(x / 20.0), y.to_radians()),
                _ => Complex::from_polar(x, y.to_radians()),
            });
        }
    }
    let channels = ids
        .into_iter()
        .zip(values)
        .map(|((id, _), v)| FrfChannel::new(id, v))
        .collect();
    Ok(FrfSet {
        freq_hz,
        channels,
        exponential_window_tau_s: tau,
    })
}
