//! FRF files as inputs: a universal file (`.uff`, `.unv`: datasets 58 FRFs or time responses,
//! 15/2411 node coordinates) or an FRF CSV (`f, <id>_re, <id>_im, …`), opened like any other
//! input and turned into impulse responses ([`super::frf`]) that stream through the pipeline.
//! The exponential window the responses carry (applied here or declared by the file) travels in
//! the returned metadata, so that the analysis removes its damping again.

use std::path::Path;

use super::frf::{is_frf_csv_header, read_frf_csv, read_frf_uff, FrfToImpulse, ImpulseSet};
use super::recording_set::{DecayKind, RecordingMeta, Sensor};
use super::{Source, SourceError};
use crate::Error;

/// File extensions read as universal files.
pub const UFF_EXTENSIONS: [&str; 3] = ["uff", "unv", "uf"];

/// An FRF file opened as impulse responses.
pub struct FrfInput {
    /// The impulse responses.
    pub source: Box<dyn Source>,
    /// Sensor positions, when the file gives one for every channel (universal files with
    /// node coordinates).
    pub sensors: Option<Vec<Sensor>>,
    /// Sample rate, kind (impulse responses), quantity/unit and the total exponential window.
    pub meta: RecordingMeta,
    /// What was done and assumed (grid, padding, windows, units), one sentence each.
    pub notes: Vec<String>,
}

/// Whether the file at `path` is an FRF CSV (its first non-comment line is an FRF header).
pub fn is_frf_csv(path: &Path) -> bool {
    use std::io::BufRead;
    // Only a regular file can be read twice: a named pipe or a process substitution
    // (`<(tool)`) read here would lose its first bytes (a whole buffer) to this look.
    if !std::fs::metadata(path).is_ok_and(|m| m.is_file()) {
        return false;
    }
    let Ok(f) = std::fs::File::open(path) else {
        return false;
    };
    std::io::BufReader::new(f)
        .lines()
        .take(20)
        .map_while(|l| l.ok())
        .find(|l| !l.trim().is_empty() && !l.trim_start().starts_with('#'))
        .is_some_and(|l| is_frf_csv_header(&l))
}

/// Whether `path` has a universal-file extension.
pub fn is_uff_path(path: &Path) -> bool {
    path.extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| UFF_EXTENSIONS.contains(&e.to_ascii_lowercase().as_str()))
}

/// A library error as a source error naming `what` (source errors pass through).
fn as_source_error(what: &str, e: Error) -> SourceError {
    match e {
        Error::Source(s) => s,
        other => SourceError::Setting {
            what: what.to_string(),
            detail: other.to_string(),
        },
    }
}

/// Opens an FRF CSV or a universal file as impulse responses (`options`: taper and window).
pub fn open_frf_file(path: &Path, options: &FrfToImpulse) -> Result<FrfInput, SourceError> {
    let what = path.display().to_string();
    let err = |e: Error| as_source_error(&what, e);
    let (impulses, sensors, mut notes, quantity) = if is_uff_path(path) {
        let m = read_frf_uff(path).map_err(err)?;
        let quantity = m
            .frf
            .as_ref()
            .and_then(|f| f.channels.first())
            .and_then(|c| c.unit.clone());
        let impulses = match (m.frf, m.impulses) {
            (Some(frf), _) => frf.impulse_responses(options).map_err(err)?,
            (None, Some(mut ir)) => {
                apply_window(&mut ir, options.exponential_window_tau_s);
                ir
            }
            (None, None) => {
                return Err(SourceError::Setting {
                    what,
                    detail: "expected FRFs (dataset 58, function type 4) or time responses (type 1), found neither".into(),
                })
            }
        };
        (impulses, m.sensors, m.notes, quantity)
    } else {
        let frf = read_frf_csv(path).map_err(err)?;
        let quantity = frf.channels.first().and_then(|c| c.unit.clone());
        let impulses = frf.impulse_responses(options).map_err(err)?;
        (impulses, Vec::new(), Vec::new(), quantity)
    };
    notes.extend(impulses.notes.iter().cloned());
    let sensors = ordered_sensors(&impulses.names, sensors);
    let meta = RecordingMeta {
        fs: Some(impulses.sample_rate_hz),
        kind: DecayKind::ImpulseResponse,
        unit: quantity,
        exponential_window_tau_s: impulses.exponential_window_tau_s,
        ..Default::default()
    };
    let source = Box::new(impulses.into_source()?);
    Ok(FrfInput {
        source,
        sensors,
        meta,
        notes,
    })
}

/// A window applied to time responses read as such (FRFs get theirs in the transform).
fn apply_window(ir: &mut ImpulseSet, tau_s: Option<f64>) {
    let Some(tau) = tau_s.filter(|t| t.is_finite() && *t > 0.0) else {
        return;
    };
    for ch in &mut ir.channels {
        super::frf::exponential_window(ch, ir.sample_rate_hz, tau);
    }
    ir.exponential_window_tau_s = super::frf::combined_tau(ir.exponential_window_tau_s, Some(tau));
    ir.notes.push(format!(
        "exponential window e^(-t/{tau} s) applied to the time responses"
    ));
}

/// The sensors in channel order, when every channel has one.
fn ordered_sensors(names: &[String], sensors: Vec<Sensor>) -> Option<Vec<Sensor>> {
    names
        .iter()
        .map(|n| sensors.iter().find(|s| &s.id == n).cloned())
        .collect()
}

/// The channels of `input` reordered to `ids` (a recording set's `sensors.csv` order): an id
/// missing from the file is an error naming it.
pub fn reorder_to_sensors(
    what: &str,
    input: FrfInput,
    ids: &[String],
) -> Result<FrfInput, SourceError> {
    let mut source = input.source;
    let names = source.info().channel_names.clone();
    let rate = source.info().sample_rate_hz;
    let channels = super::memory::read_all(source.as_mut(), usize::MAX)?;
    // A universal file numbers its nodes; one whose responses are nodes 1…n in order, none of
    // them a sensor id, holds sensor row k at node k + 1 (as dampscope writes it).
    let numbered = names.len() == ids.len()
        && !names.iter().any(|n| ids.contains(n))
        && names
            .iter()
            .enumerate()
            .all(|(k, n)| n.parse::<usize>().ok() == Some(k + 1));
    let names: Vec<String> = if numbered { ids.to_vec() } else { names };
    let mut ordered = Vec::with_capacity(ids.len());
    for id in ids {
        let Some(k) = names.iter().position(|n| n == id) else {
            return Err(SourceError::Setting {
                what: what.to_string(),
                detail: format!(
                    "sensor {id:?} of sensors.csv has no FRF column; the file has {names:?}"
                ),
            });
        };
        ordered.push(channels[k].clone());
    }
    let info = super::SignalInfo {
        sample_rate_hz: rate,
        channel_names: ids.to_vec(),
    };
    Ok(FrfInput {
        source: Box::new(super::memory::MemorySource::new(info, ordered)?),
        ..input
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frf_headers_are_told_from_time_series() {
        assert!(is_frf_csv_header("f,a_re,a_im,b_re,b_im"));
        assert!(is_frf_csv_header("freq_hz, 12_db, 12_deg"));
        assert!(!is_frf_csv_header("time,a,b"));
        assert!(!is_frf_csv_header("f"));
        assert!(!is_frf_csv_header("f,a_re,b"));
    }
}
