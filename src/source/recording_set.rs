//! Recording sets (FORMATS.md §1): a directory holding one decay per sensor
//! (`responses.wav` or `responses.csv`), the sensor positions (`sensors.csv`), optionally the
//! excitation (`excitation.csv`) and metadata (`meta.json`).
//!
//! Reading is tolerant where the contract allows it (unknown `meta.json` keys, extra CSV
//! columns, any WAV hound reads) and strict where a mistake would silently mislabel data (channel
//! count vs sensor rows, non-numeric coordinates).

use std::fs::File;
use std::io::BufReader;
use std::path::Path;

use super::csv::CsvSource;
use super::wav::WavSource;
use super::{Source, SourceError};

/// FRF files a recording set may hold instead of time responses, looked for in this order.
pub const FRF_RESPONSE_FILES: [&str; 3] = ["responses.uff", "responses.unv", "frf.csv"];

/// Whether the responses are impulse responses or free decays.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum DecayKind {
    /// Response to a force impulse at t = 0 (the default).
    #[default]
    ImpulseResponse,
    /// A free decay after the excitation stopped.
    FreeDecay,
}

/// A sensor: id and position in plate coordinates.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Sensor {
    /// Sensor id (the channel name).
    pub id: String,
    /// Position along x, metres.
    pub x_m: f64,
    /// Position along y, metres.
    pub y_m: f64,
    /// Height, metres; `None` = mid-plane.
    pub z_m: Option<f64>,
    /// Measured direction (`z` by default).
    pub dir: String,
}

/// Where and how hard the structure was excited.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Excitation {
    /// Position along x, metres.
    pub x_m: f64,
    /// Position along y, metres.
    pub y_m: f64,
    /// Direction of the force (`z` usually).
    pub dir: String,
    /// Force (impulse) amplitude, newtons.
    pub force_n: f64,
}

/// The `meta.json` of a recording set. Unknown keys are ignored; every field is optional.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default)]
pub struct RecordingMeta {
    /// Sample rate in Hz (the WAV header wins when there is a WAV; needed for a CSV without time).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub fs: Option<f64>,
    /// Impulse responses or free decays (`diagnose` computes no FRF error for free decays).
    pub kind: DecayKind,
    /// Measured quantity: `acceleration` (assumed when absent), `velocity` or `displacement`;
    /// `diagnose` differentiates the responses accordingly before comparing them with the
    /// model's accelerance ([`RecordingMeta::derivatives_to_acceleration`]).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub quantity: Option<String>,
    /// Unit of the samples, informative.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub unit: Option<String>,
    /// Signal-to-noise ratio in dB, informative only.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub snr_db: Option<f64>,
    /// Time constant τ of an exponential window e^(−t/τ) the acquisition applied to every
    /// response, s (a dampscope extension of FORMATS.md §1: impact testing's response window).
    /// `dampscope modal` subtracts its decay rate 1/τ from every pole.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub exponential_window_tau_s: Option<f64>,
    /// Physical units per count of an integer WAV (instead of scaling to [-1, 1)).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub scale: Option<f64>,
}

impl RecordingMeta {
    /// How many times the responses must be differentiated to be accelerations, the quantity
    /// a model's accelerance compares with: 0 for `acceleration` (and when no quantity is
    /// given), 1 for `velocity`, 2 for `displacement`. `Err` says why the responses cannot be
    /// compared as impulse responses at all: free decays (their amplitudes and phases are set
    /// by the excitation before them, not by the structure's response to a unit impulse), or
    /// a quantity not known.
    pub fn derivatives_to_acceleration(&self) -> Result<u32, String> {
        if self.kind == DecayKind::FreeDecay {
            return Err(
                "the responses are free decays (kind free_decay), not impulse responses".into(),
            );
        }
        match self
            .quantity
            .as_deref()
            .map(|q| q.trim().to_ascii_lowercase())
        {
            None => Ok(0),
            Some(q) if q == "acceleration" => Ok(0),
            Some(q) if q == "velocity" => Ok(1),
            Some(q) if q == "displacement" => Ok(2),
            Some(q) => Err(format!(
                "the quantity {q:?} is none of acceleration, velocity, displacement"
            )),
        }
    }
}

/// An opened recording set: metadata, sensors and a streaming source of the responses whose
/// channel names are the sensor ids, in `sensors.csv` row order.
pub struct RecordingSet {
    /// The metadata (defaults when `meta.json` is absent).
    pub meta: RecordingMeta,
    /// One sensor per channel.
    pub sensors: Vec<Sensor>,
    /// Excitations (empty when `excitation.csv` is absent).
    pub excitation: Vec<Excitation>,
    /// The responses.
    pub source: Box<dyn Source>,
    /// What was read differently from what the files say, for the user (e.g. a `meta.json`
    /// rate that the WAV header overrides).
    pub warnings: Vec<String>,
}

pub(crate) fn io_err(path: &Path, e: std::io::Error) -> SourceError {
    SourceError::Io {
        what: path.display().to_string(),
        source: e,
    }
}

fn malformed(path: &Path, format: &'static str, detail: String) -> SourceError {
    SourceError::Malformed {
        what: path.display().to_string(),
        format,
        detail,
    }
}

/// A small CSV table: lower-cased header, rows with their line numbers.
type Table = (Vec<String>, Vec<(u64, Vec<String>)>);

/// Reads a small CSV table: returns the lower-cased header and the rows with their line numbers.
/// No line is a comment: FORMATS.md §1 defines none, and sensor ids may start with `#`.
fn read_table(path: &Path) -> Result<Table, SourceError> {
    let file = File::open(path).map_err(|e| io_err(path, e))?;
    let mut r = ::csv::ReaderBuilder::new()
        .trim(::csv::Trim::All)
        .flexible(true)
        .from_reader(BufReader::new(file));
    let header: Vec<String> = r
        .headers()
        .map_err(|e| malformed(path, "csv", e.to_string()))?
        .iter()
        .map(str::to_ascii_lowercase)
        .collect();
    let mut rows = Vec::new();
    for rec in r.records() {
        let rec = rec.map_err(|e| malformed(path, "csv", e.to_string()))?;
        let line = rec.position().map_or(0, |p| p.line());
        if rec.iter().all(str::is_empty) {
            continue;
        }
        if rec.len() != header.len() {
            return Err(malformed(
                path,
                "csv",
                format!(
                    "line {line}: expected {} columns, got {}",
                    header.len(),
                    rec.len()
                ),
            ));
        }
        rows.push((line, rec.iter().map(str::to_string).collect()));
    }
    Ok((header, rows))
}

/// Column index of `name`, or a `Malformed` error naming the header found.
fn column(path: &Path, header: &[String], name: &str) -> Result<usize, SourceError> {
    header.iter().position(|h| h == name).ok_or_else(|| {
        malformed(
            path,
            "csv",
            format!("expected a column {name:?} in the header, got {header:?}"),
        )
    })
}

fn number(path: &Path, line: u64, col: &str, text: &str) -> Result<f64, SourceError> {
    text.parse::<f64>()
        .ok()
        .filter(|v| v.is_finite())
        .ok_or_else(|| {
            malformed(
                path,
                "csv",
                format!("line {line}, column {col}: expected a finite number, got {text:?}"),
            )
        })
}

/// Reads `sensors.csv`: `id,x,y` with optional `z` and `dir`.
pub fn read_sensors(path: &Path) -> Result<Vec<Sensor>, SourceError> {
    let (header, rows) = read_table(path)?;
    let (ci, cx, cy) = (
        column(path, &header, "id")?,
        column(path, &header, "x")?,
        column(path, &header, "y")?,
    );
    let cz = header.iter().position(|h| h == "z");
    let cd = header.iter().position(|h| h == "dir");
    let mut seen = std::collections::HashMap::new();
    for (line, r) in &rows {
        if let Some(first) = seen.insert(r[ci].clone(), *line) {
            return Err(malformed(
                path,
                "csv",
                format!(
                    "line {line}: expected unique sensor ids, got {:?} again (first on line {first})",
                    r[ci]
                ),
            ));
        }
    }
    rows.iter()
        .map(|(line, r)| {
            Ok(Sensor {
                id: r[ci].clone(),
                x_m: number(path, *line, "x", &r[cx])?,
                y_m: number(path, *line, "y", &r[cy])?,
                z_m: match cz.map(|c| r[c].as_str()) {
                    None | Some("") => None,
                    Some(t) => Some(number(path, *line, "z", t)?),
                },
                dir: cd
                    .map(|c| r[c].clone())
                    .filter(|d| !d.is_empty())
                    .unwrap_or_else(|| "z".into()),
            })
        })
        .collect()
}

/// Reads `excitation.csv`: `x,y,dir,force`.
pub fn read_excitation(path: &Path) -> Result<Vec<Excitation>, SourceError> {
    let (header, rows) = read_table(path)?;
    let (cx, cy, cd, cf) = (
        column(path, &header, "x")?,
        column(path, &header, "y")?,
        column(path, &header, "dir")?,
        column(path, &header, "force")?,
    );
    rows.iter()
        .map(|(line, r)| {
            Ok(Excitation {
                x_m: number(path, *line, "x", &r[cx])?,
                y_m: number(path, *line, "y", &r[cy])?,
                dir: r[cd].clone(),
                force_n: number(path, *line, "force", &r[cf])?,
            })
        })
        .collect()
}

/// Reads `meta.json` as other tools write it: a UTF-8 byte-order mark is skipped, a key given
/// twice keeps its last value, `null` means absent, and the keys read leniently (`snr_db`,
/// `quantity`, `unit`) are dropped with a warning when they are not what they should be; an
/// error names the key.
fn read_meta(path: &Path, warnings: &mut Vec<String>) -> Result<RecordingMeta, SourceError> {
    let bytes = std::fs::read(path).map_err(|e| io_err(path, e))?;
    let text = bytes.strip_prefix(b"\xef\xbb\xbf").unwrap_or(&bytes);
    let value: serde_json::Value =
        serde_json::from_slice(text).map_err(|e| malformed(path, "json", e.to_string()))?;
    let serde_json::Value::Object(mut keys) = value else {
        return Err(malformed(
            path,
            "json",
            format!("expected an object of keys, got {value}"),
        ));
    };
    keys.retain(|_, v| !v.is_null());
    for informative in ["snr_db", "quantity", "unit"] {
        let Some(v) = keys.get(informative) else {
            continue;
        };
        let fits = if informative == "snr_db" {
            v.is_number()
        } else {
            v.is_string()
        };
        if !fits {
            warnings.push(format!(
                "{}: {informative} = {v} ignored ({})",
                path.display(),
                match informative {
                    "snr_db" => "informative only; expected a number of dB",
                    "quantity" =>
                        "expected acceleration, velocity or displacement as a string; \
                                   acceleration is assumed",
                    _ => "informative only; expected a string",
                }
            ));
            keys.remove(informative);
        }
    }
    serde_json::from_value(serde_json::Value::Object(keys.clone())).map_err(|e| {
        // serde's message names the type, not the key: the key is the one that fails alone.
        let key = keys.iter().find(|(k, v)| {
            let alone = serde_json::Map::from_iter([((*k).clone(), (*v).clone())]);
            serde_json::from_value::<RecordingMeta>(serde_json::Value::Object(alone)).is_err()
        });
        let detail = match key {
            Some((k, _)) => format!("{k}: {e}"),
            None => e.to_string(),
        };
        malformed(path, "json", detail)
    })
}

/// Opens the recording set in `dir`. `responses.wav` wins over `responses.csv`; `meta.json` and
/// `excitation.csv` are optional. Errors: `ChannelCount` when the responses do not have one
/// channel per `sensors.csv` row, `Setting` when neither response file exists.
pub fn open_recording_set(dir: &Path) -> Result<RecordingSet, SourceError> {
    open_recording_set_with(dir, &Default::default())
}

/// [`open_recording_set`], with `frf` saying how FRF responses (`responses.uff`, `frf.csv`)
/// become impulse responses (taper, exponential window).
pub fn open_recording_set_with(
    dir: &Path,
    frf: &super::frf::FrfToImpulse,
) -> Result<RecordingSet, SourceError> {
    let meta_path = dir.join("meta.json");
    let mut warnings = Vec::new();
    let meta = if meta_path.exists() {
        read_meta(&meta_path, &mut warnings)?
    } else {
        RecordingMeta::default()
    };
    let sensors = read_sensors(&dir.join("sensors.csv"))?;
    let exc_path = dir.join("excitation.csv");
    let excitation = if exc_path.exists() {
        read_excitation(&exc_path)?
    } else {
        Vec::new()
    };
    let ids: Vec<String> = sensors.iter().map(|s| s.id.clone()).collect();
    let wav = dir.join("responses.wav");
    let csv = dir.join("responses.csv");
    let (what, got, source): (String, usize, Box<dyn Source>) = if wav.exists() {
        let what = wav.display().to_string();
        let f = File::open(&wav).map_err(|e| io_err(&wav, e))?;
        let mut s = WavSource::from_file(f, what.clone())?;
        if let Some(scale) = meta.scale {
            s = s.with_int_scale(scale);
        }
        let got = s.header().channels;
        // FORMATS.md §1: the WAV header's rate is the truth (a header holds whole hertz; a
        // meta.json may state the exact rate, or describe a responses.csv the WAV overrides).
        let header_fs = f64::from(s.header().sample_rate_hz);
        if let Some(fs) = meta.fs {
            if (fs / header_fs - 1.0).abs() > 1e-9 {
                warnings.push(format!(
                    "{what}: the WAV header says {header_fs} Hz, meta.json says fs = {fs} Hz: the header's rate is used (docs/FORMATS.md §1)"
                ));
            }
        }
        (what, got, Box::new(s))
    } else if csv.exists() {
        let what = csv.display().to_string();
        let f = File::open(&csv).map_err(|e| io_err(&csv, e))?;
        let s = CsvSource::with_channel_ids(BufReader::new(f), what.clone(), meta.fs, &ids)?
            .in_channel_order(&ids);
        (what, s.info().channels(), Box::new(s))
    } else if let Some(path) = FRF_RESPONSE_FILES
        .iter()
        .map(|name| dir.join(name))
        .find(|p| p.exists())
    {
        // FRFs: impulse responses by inverse FFT, columns matched to sensors.csv by id.
        let what = path.display().to_string();
        let frf = super::frf_input::open_frf_file(&path, frf)?;
        let frf = super::frf_input::reorder_to_sensors(&what, frf, &ids)?;
        let meta = RecordingMeta {
            fs: frf.meta.fs,
            exponential_window_tau_s: frf
                .meta
                .exponential_window_tau_s
                .or(meta.exponential_window_tau_s),
            ..meta
        };
        return Ok(RecordingSet {
            meta,
            sensors,
            excitation,
            source: frf.source,
            warnings,
        });
    } else {
        return Err(SourceError::Setting {
            what: dir.display().to_string(),
            detail: format!(
                "recording set: expected responses.wav, responses.csv or FRFs ({}), found none",
                FRF_RESPONSE_FILES.join(", ")
            ),
        });
    };
    if got != ids.len() {
        return Err(SourceError::ChannelCount {
            what: format!("{what} (vs {} sensors in sensors.csv)", ids.len()),
            expected: ids.len(),
            got,
        });
    }
    let source = rename(source, ids);
    Ok(RecordingSet {
        meta,
        sensors,
        excitation,
        source,
        warnings,
    })
}

/// Wraps a source so that its channels carry the given names (same count, checked by caller).
fn rename(inner: Box<dyn Source>, names: Vec<String>) -> Box<dyn Source> {
    struct Renamed {
        inner: Box<dyn Source>,
        info: super::SignalInfo,
    }
    impl Source for Renamed {
        fn duration_frames(&self) -> Option<u64> {
            self.inner.duration_frames()
        }

        fn expected_frames(&self) -> Option<u64> {
            self.inner.expected_frames()
        }

        fn quantization_step(&self) -> Option<f64> {
            self.inner.quantization_step()
        }

        fn paused(&self) -> bool {
            self.inner.paused()
        }

        fn info(&self) -> &super::SignalInfo {
            &self.info
        }
        fn read_block(
            &mut self,
            max_frames: usize,
            block: &mut super::Block,
        ) -> Result<bool, SourceError> {
            self.inner.read_block(max_frames, block)
        }
        fn read_encoded_block(
            &mut self,
            max_frames: usize,
            out: &mut super::encoded::EncodedFrames,
        ) -> Option<Result<bool, SourceError>> {
            self.inner.read_encoded_block(max_frames, out)
        }
        fn allow_block_bytes(&mut self, bytes: usize) {
            self.inner.allow_block_bytes(bytes)
        }
    }
    let info = super::SignalInfo {
        sample_rate_hz: inner.info().sample_rate_hz,
        channel_names: names,
    };
    Box::new(Renamed { inner, info })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `quantity` and `kind` say how a recording set's responses compare with a model's
    /// accelerance: found by the contract probe, where displacement responses were compared as
    /// accelerations and free decays as impulse responses.
    #[test]
    fn quantity_and_kind_say_how_responses_become_accelerances() {
        let meta = |kind, quantity: Option<&str>| RecordingMeta {
            kind,
            quantity: quantity.map(String::from),
            ..Default::default()
        };
        use DecayKind::{FreeDecay, ImpulseResponse};
        assert_eq!(
            meta(ImpulseResponse, None).derivatives_to_acceleration(),
            Ok(0)
        );
        assert_eq!(
            meta(ImpulseResponse, Some("acceleration")).derivatives_to_acceleration(),
            Ok(0)
        );
        assert_eq!(
            meta(ImpulseResponse, Some(" Velocity")).derivatives_to_acceleration(),
            Ok(1)
        );
        assert_eq!(
            meta(ImpulseResponse, Some("displacement")).derivatives_to_acceleration(),
            Ok(2)
        );
        let strain = meta(ImpulseResponse, Some("strain")).derivatives_to_acceleration();
        assert!(strain.unwrap_err().contains("\"strain\""));
        let free = meta(FreeDecay, Some("acceleration")).derivatives_to_acceleration();
        assert!(free.unwrap_err().contains("free decays"));
    }
}
