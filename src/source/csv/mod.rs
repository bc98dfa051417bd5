//! Streaming CSV text source: one row per sample, one column per channel.
//!
//! Accepted layouts (FORMATS.md §1–2):
//! - a header row, then numbers. A first column named `time` or `t` (any case) is the time in
//!   seconds: the sample rate comes from its spacing, which must be uniform within 1e-6
//!   relative. Every other column is a channel named by its header;
//! - no header (the first row is numeric): every column is a channel, named `ch0`, `ch1`, …
//!   ([`CsvSource::with_channel_ids`]: unless it holds the known channel names).
//!
//! A field may be quoted (RFC 4180: `"Acc, top"`, or every number quoted).
//!
//! Lines starting with `#` are comments; `# fs=51200` (or `# fs: 51200`, anything may follow
//! the number) gives the sample rate. Every rate the input states (the caller's, the comment,
//! the time column's mean step over the first rows) must agree, within 1e-6 or what the time
//! column's printed precision allows; a contradiction is [`SourceError::Setting`]. The time
//! column's steps are always checked. Channel names must be unique.
//! Separators: `,`, else `;`, else tab (detected on the first row). `NaN`/`inf` are passed through
//! and an empty cell is read as NaN (the pipeline flags that channel only); text that is not a
//! number is [`SourceError::Malformed`] with the line number. Rows before a bad row are always
//! delivered first.

use std::io::{BufRead, Read};

use super::raw::check_fs;
use super::{Block, SignalInfo, Source, SourceError};
use text::{
    detect_delim, is_time_header, names_the_channels, parse_fs_comment, printed_resolution,
    split_fields,
};

mod text;
mod time_column;

/// Longest accepted line, in bytes; longer lines are malformed (guards memory on binary input).
const MAX_LINE_BYTES: u64 = 1 << 20;

/// What the next call to `next_line` found.
enum Line {
    /// A data line (trimmed), with whether it ended in a newline.
    Data(String, bool),
    /// End of the stream.
    End,
    /// The writer paused with rows of this block already read ([`CsvSource::waking_on_pause`]).
    Paused,
}

/// A [`Source`] streaming CSV text row by row (never the whole file in memory).
pub struct CsvSource<R: BufRead + Send> {
    reader: R,
    what: String,
    info: SignalInfo,
    delim: char,
    time_column: bool,
    /// Check the time column's spacing (whenever there is a time column).
    check_time: bool,
    /// The step of the last printed decimal of the last row's time, s (0 for an integer).
    row_time_resolution_s: f64,
    /// The same for the previous row's time.
    last_time_resolution_s: f64,
    /// The rate's relative uncertainty from the time column's printing (0 without one).
    rate_uncertainty: f64,
    /// Columns per row, including the time column.
    n_cols: usize,
    /// Channel k's column among the channel columns (None: in the file's order).
    column_of_channel: Option<Vec<usize>>,
    line_no: usize,
    /// Comment-given sample rate seen while reading (first one wins).
    comment_fs: Option<f64>,
    /// Rows already read (while finding the rate) and not yet delivered.
    queued: std::collections::VecDeque<Vec<f64>>,
    last_time: Option<f64>,
    pending: Option<SourceError>,
    /// An error met while reading ahead, due once the queued rows before it are delivered.
    pending_after_queue: Option<SourceError>,
    frames_read: u64,
    done: bool,
    buf: Vec<u8>,
    /// `buf` holds the start of a line whose rest had not arrived when the writer paused.
    partial: bool,
    /// Set while a pause would hand out what was read ([`CsvSource::waking_on_pause`]).
    pause_armed: Option<std::sync::Arc<std::sync::atomic::AtomicBool>>,
    /// The last read returned early: the writer paused ([`Source::paused`]).
    paused: bool,
    /// A pause was reported and no line arrived since: the next read waits for one.
    pause_told: bool,
}

impl<R: BufRead + Send> CsvSource<R> {
    /// Reads the header (and, when the rate comes from the time column, the first two rows).
    /// `fs_hz` is an explicit sample rate that wins over the file's; `what` names the input.
    ///
    /// Errors: `Empty` without any data row, `Setting` when no sample rate can be found,
    /// `Malformed` for bad rows or non-uniform time.
    pub fn new(
        reader: R,
        what: impl Into<String>,
        fs_hz: Option<f64>,
    ) -> Result<Self, SourceError> {
        Self::open(reader, what.into(), fs_hz, &[], None)
    }

    /// [`CsvSource::new`] for a stream read through a [`super::pipe::PausingReader`] whose flag
    /// is `armed`: when the writer pauses, the rows read so far are handed out in a block not
    /// yet full (and the rate is taken from the rows at hand), as raw and WAV streams do.
    pub(crate) fn waking_on_pause(
        reader: R,
        what: impl Into<String>,
        fs_hz: Option<f64>,
        armed: std::sync::Arc<std::sync::atomic::AtomicBool>,
    ) -> Result<Self, SourceError> {
        Self::open(reader, what.into(), fs_hz, &[], Some(armed))
    }

    /// [`CsvSource::new`] for input whose channels are known by name: a first line holding
    /// exactly these names (after an optional `time`/`t` column, in any order) is the header
    /// even when they read as numbers. A recording set's `responses.csv` names its columns by
    /// sensor id (FORMATS.md §1), and ids such as `1001` made a numeric header that detection
    /// read as a first sample of 1001.
    pub fn with_channel_ids(
        reader: R,
        what: impl Into<String>,
        fs_hz: Option<f64>,
        ids: &[String],
    ) -> Result<Self, SourceError> {
        Self::open(reader, what.into(), fs_hz, ids, None)
    }

    fn open(
        reader: R,
        what: String,
        fs_hz: Option<f64>,
        ids: &[String],
        pause_armed: Option<std::sync::Arc<std::sync::atomic::AtomicBool>>,
    ) -> Result<Self, SourceError> {
        if let Some(fs) = fs_hz {
            check_fs(&what, fs)?;
        }
        let mut s = Self {
            reader,
            what,
            info: SignalInfo {
                sample_rate_hz: 0.0,
                channel_names: Vec::new(),
            },
            delim: ',',
            time_column: false,
            check_time: false,
            row_time_resolution_s: 0.0,
            last_time_resolution_s: 0.0,
            rate_uncertainty: 0.0,
            n_cols: 0,
            column_of_channel: None,
            line_no: 0,
            comment_fs: None,
            queued: Default::default(),
            last_time: None,
            pending: None,
            pending_after_queue: None,
            frames_read: 0,
            done: false,
            buf: Vec::new(),
            partial: false,
            pause_armed,
            paused: false,
            pause_told: false,
        };
        let first = match s.next_line()? {
            Line::Data(l, _) => l,
            Line::End | Line::Paused => return Err(SourceError::Empty { what: s.what }),
        };
        s.delim = detect_delim(&first);
        let mut fields = split_fields(&first, s.delim);
        // A separator ending every line (`time,s0,s1,`) closes the last field; it does not
        // open a nameless channel of empty cells.
        if fields.len() > 1 && fields.last().is_some_and(|f| f.is_empty()) {
            fields.pop();
        }
        s.n_cols = fields.len();
        let numeric = fields.iter().all(|f| f.parse::<f64>().is_ok());
        if numeric && !names_the_channels(&fields, ids) {
            s.info.channel_names = (0..s.n_cols).map(|k| format!("ch{k}")).collect();
            let row = s.parse_row(&first, true)?;
            s.queued.push_back(row);
            s.check_orientation()?;
        } else {
            let names: Vec<String> = fields.iter().map(|f| f.to_string()).collect();
            s.time_column = is_time_header(&names[0]);
            let skip = usize::from(s.time_column);
            s.info.channel_names = names[skip..].to_vec();
            if s.info.channel_names.is_empty() {
                return Err(SourceError::Malformed {
                    what: s.what,
                    format: "csv",
                    detail: format!(
                        "line {}: expected at least one channel column, got only {:?}",
                        s.line_no, names[0]
                    ),
                });
            }
        }
        super::check_unique_names(&s.what, &s.info.channel_names)?;
        // Every rate the input states must agree: a contradiction changes every number.
        let from_time = if s.time_column {
            Some(s.fs_from_time()?)
        } else {
            None
        };
        let stated = [
            (fs_hz, "the given sample rate"),
            (s.comment_fs, "the `# fs=` comment"),
            (from_time, "the time column"),
        ];
        let mut known = stated.iter().filter_map(|&(fs, by)| fs.map(|f| (f, by)));
        let Some((fs, by)) = known.next() else {
            return Err(SourceError::Setting {
                what: s.what,
                detail: "sample rate unknown: expected a `time` column, a `# fs=HZ` comment or an explicit fs".into(),
            });
        };
        let tolerance = if s.time_column {
            s.rate_uncertainty.max(FS_AGREEMENT)
        } else {
            FS_AGREEMENT
        };
        for (other, other_by) in known {
            if ((other / fs) - 1.0).abs() > tolerance {
                return Err(SourceError::Setting {
                    what: s.what,
                    detail: format!(
                        "contradictory sample rates: {by} says {fs} Hz, {other_by} says {other} Hz"
                    ),
                });
            }
        }
        s.info.sample_rate_hz = check_fs(&s.what, fs)?;
        Ok(s)
    }

    /// A CSV without a header holding fewer rows than columns is a table laid out one channel
    /// per *row* (pyrato's and numpy's layout, e.g. 2 × 16384): read as it stands it would be
    /// thousands of channels of a few samples each, so it is refused. Reads ahead (queued) until
    /// the rows reach the columns, the input ends, or [`TIME_FIT_CELLS`] cells are held (then the
    /// orientation is taken as given). A header names its channels, so it settles the question.
    fn check_orientation(&mut self) -> Result<(), SourceError> {
        if self.n_cols < 2 {
            return Ok(());
        }
        while self.queued.len() < self.n_cols && self.queued.len() * self.n_cols < TIME_FIT_CELLS {
            match self.next_line() {
                Ok(Line::Data(l, nl)) => match self.parse_row(&l, nl) {
                    Ok(row) => self.queued.push_back(row),
                    Err(e) => {
                        self.pending_after_queue = Some(e);
                        return Ok(());
                    }
                },
                Ok(Line::Paused) => return Ok(()),
                Ok(Line::End) => {
                    return Err(self.malformed(format!(
                        "{} rows of {} columns without a header: dampscope reads one sample per row and one channel per column, so this looks transposed ({} channels of {} samples?); transpose it or add a header naming the channels (docs/FORMATS.md §1)",
                        self.queued.len(),
                        self.n_cols,
                        self.queued.len(),
                        self.n_cols
                    )));
                }
                Err(e) => {
                    self.pending_after_queue = Some(e);
                    return Ok(());
                }
            }
        }
        Ok(())
    }

    /// Replaces the channel names (for example by sensor ids). Errors when the count differs.
    pub fn with_channel_names(mut self, names: Vec<String>) -> Result<Self, SourceError> {
        if names.len() != self.info.channel_names.len() {
            return Err(SourceError::ChannelCount {
                what: self.what.clone(),
                expected: names.len(),
                got: self.info.channel_names.len(),
            });
        }
        self.info.channel_names = names;
        Ok(self)
    }

    /// Takes the channels in the order of `names` when the header names exactly those channels
    /// in another order (a recording set's columns are named by sensor id, FORMATS.md §1, and
    /// its channels follow `sensors.csv`); otherwise leaves the order as it is.
    pub fn in_channel_order(mut self, names: &[String]) -> Self {
        let header = &self.info.channel_names;
        if header.len() != names.len() || header == names {
            return self;
        }
        let columns: Option<Vec<usize>> = names
            .iter()
            .map(|n| header.iter().position(|h| h == n))
            .collect();
        if let Some(columns) = columns {
            self.info.channel_names = names.to_vec();
            self.column_of_channel = Some(columns);
        }
        self
    }

    fn arm_pause(&self, on: bool) {
        if let Some(a) = &self.pause_armed {
            a.store(on, std::sync::atomic::Ordering::Relaxed);
        }
    }

    fn malformed(&self, detail: String) -> SourceError {
        SourceError::Malformed {
            what: self.what.clone(),
            format: "csv",
            detail,
        }
    }

    /// The next non-blank, non-comment line (comments are scanned for `fs=`).
    fn next_line(&mut self) -> Result<Line, SourceError> {
        loop {
            if !self.partial {
                self.buf.clear();
            }
            self.partial = false;
            let room = MAX_LINE_BYTES.saturating_sub(self.buf.len() as u64);
            let read = (&mut self.reader)
                .take(room)
                .read_until(b'\n', &mut self.buf);
            let n = match read {
                Ok(n) => n,
                Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => {
                    self.partial = !self.buf.is_empty();
                    return Ok(Line::Paused);
                }
                Err(e) => {
                    return Err(SourceError::Io {
                        what: self.what.clone(),
                        source: e,
                    })
                }
            };
            if self.buf.is_empty() {
                return Ok(Line::End);
            }
            self.line_no += 1;
            let newline = self.buf.last() == Some(&b'\n');
            if !newline && n as u64 == room {
                return Err(self.malformed(format!(
                    "line {}: expected a line of at most {MAX_LINE_BYTES} bytes, got a longer one",
                    self.line_no
                )));
            }
            let text = std::str::from_utf8(&self.buf).map_err(|e| {
                self.malformed(format!(
                    "line {}: expected UTF-8 text, got an invalid byte at column {}",
                    self.line_no,
                    e.valid_up_to() + 1
                ))
            })?;
            let t = text.trim_start_matches('\u{feff}').trim();
            if t.is_empty() {
                continue;
            }
            if t.starts_with('#') {
                if self.comment_fs.is_none() {
                    self.comment_fs = parse_fs_comment(t);
                }
                continue;
            }
            return Ok(Line::Data(t.to_string(), newline));
        }
    }

    /// Parses one data row into its numbers (time first when there is a time column).
    fn parse_row(&mut self, line: &str, newline: bool) -> Result<Vec<f64>, SourceError> {
        let mut row = Vec::with_capacity(self.n_cols);
        let mut fields = split_fields(line, self.delim);
        if fields.len() == self.n_cols + 1 && fields.last().is_some_and(|f| f.is_empty()) {
            fields.pop();
        }
        for (k, field) in fields.iter().enumerate() {
            let f: &str = field;
            let is_channel = !(self.time_column && k == 0);
            if !is_channel {
                self.row_time_resolution_s = printed_resolution(f);
            }
            match f.parse::<f64>() {
                Ok(v) => row.push(v),
                // An empty cell is a missing sample of that channel only (as NaN would be).
                Err(_) if f.is_empty() && is_channel => row.push(f64::NAN),
                Err(_) => {
                    let col = if self.time_column && k == 0 {
                        "time".to_string()
                    } else {
                        let c = k - usize::from(self.time_column);
                        self.info
                            .channel_names
                            .get(c)
                            .cloned()
                            .unwrap_or_else(|| format!("column {}", k + 1))
                    };
                    return Err(self.malformed(format!(
                        "line {}, {col}: expected a number, got {f:?}",
                        self.line_no
                    )));
                }
            }
        }
        if row.len() != self.n_cols {
            if !newline && row.len() < self.n_cols {
                return Err(SourceError::Truncated {
                    what: self.what.clone(),
                    expected: format!("line {} with {} columns", self.line_no, self.n_cols),
                    got: format!("{} columns before the end of the input", row.len()),
                });
            }
            return Err(self.malformed(format!(
                "line {}: expected {} columns, got {}",
                self.line_no,
                self.n_cols,
                row.len()
            )));
        }
        Ok(row)
    }
}

/// Relative tolerance within which two stated sample rates agree (the time column's own
/// spacing tolerance), unless the time column's printing is coarser.
const FS_AGREEMENT: f64 = 1e-6;

/// Rows read ahead to take the rate from the time column (bounded by [`TIME_FIT_CELLS`]).
const TIME_FIT_ROWS: usize = 4096;

/// Cells (rows × columns) read ahead at most for the rate from the time column.
const TIME_FIT_CELLS: usize = 1 << 20;

impl<R: BufRead + Send> Source for CsvSource<R> {
    fn info(&self) -> &SignalInfo {
        &self.info
    }

    fn read_block(&mut self, max_frames: usize, block: &mut Block) -> Result<bool, SourceError> {
        let n_ch = self.info.channel_names.len();
        let skip = usize::from(self.time_column);
        block.channels.resize_with(n_ch, Vec::new);
        for ch in &mut block.channels {
            ch.clear();
        }
        if let Some(e) = self.pending.take() {
            return Err(e);
        }
        let max_frames = max_frames.max(1);
        let mut got = 0;
        self.paused = false;
        while got < max_frames {
            let row = if let Some(r) = self.queued.pop_front() {
                r
            } else {
                if let Some(e) = self.pending_after_queue.take() {
                    self.done = true;
                    self.pending = Some(e);
                    break;
                }
                if self.done {
                    break;
                }
                // With rows in hand, or none but a pause not yet reported (told then with an
                // empty block).
                self.arm_pause(got > 0 || !self.pause_told);
                let parsed = match self.next_line() {
                    Ok(Line::Data(l, nl)) => {
                        self.pause_told = false;
                        self.parse_row(&l, nl).and_then(|row| {
                            if self.check_time {
                                self.check_spacing(row[0])?;
                            }
                            Ok(row)
                        })
                    }
                    Ok(Line::End) => {
                        self.done = true;
                        break;
                    }
                    Ok(Line::Paused) => {
                        self.paused = true;
                        self.pause_told = true;
                        break;
                    }
                    Err(e) => Err(e),
                };
                match parsed {
                    Ok(r) => r,
                    Err(e) => {
                        self.done = true;
                        self.pending = Some(e);
                        break;
                    }
                }
            };
            match &self.column_of_channel {
                None => {
                    for (ch, v) in block.channels.iter_mut().zip(&row[skip..]) {
                        ch.push(*v);
                    }
                }
                Some(columns) => {
                    for (ch, &c) in block.channels.iter_mut().zip(columns) {
                        ch.push(row[skip + c]);
                    }
                }
            }
            got += 1;
        }
        self.arm_pause(false);
        self.frames_read += got as u64;
        if got == 0 && !self.paused {
            return super::end_of_input(&mut self.pending, self.frames_read, &self.what);
        }
        Ok(true)
    }

    fn paused(&self) -> bool {
        self.paused
    }
}
