//! The time column of CSV input: the sample rate from its mean step over the first rows, and
//! every later step checked against it.

use super::{CsvSource, Line, SourceError, TIME_FIT_CELLS, TIME_FIT_ROWS};
use std::io::BufRead;

impl<R: BufRead + Send> CsvSource<R> {
    /// Reads up to [`TIME_FIT_ROWS`] rows ahead (keeping them queued) and returns the rate from
    /// the time column's mean step over them (a rate from two printed times alone would carry
    /// their rounding). A bad row or step among them ends the read-ahead: the rows before it are
    /// delivered, then its error.
    pub(super) fn fs_from_time(&mut self) -> Result<f64, SourceError> {
        let ahead = (TIME_FIT_CELLS / self.n_cols.max(1)).clamp(2, TIME_FIT_ROWS);
        let mut res = Vec::new();
        let mut stop = None;
        while self.queued.len() < ahead {
            // Two rows give a rate: a writer that pauses after them is not kept waiting.
            self.arm_pause(self.queued.len() >= 2);
            match self.next_line() {
                Ok(Line::Data(l, nl)) => match self.parse_row(&l, nl) {
                    Ok(row) => {
                        self.queued.push_back(row);
                        res.push(self.row_time_resolution_s);
                    }
                    Err(e) => {
                        stop = Some(e);
                        break;
                    }
                },
                Ok(Line::End | Line::Paused) => break,
                Err(e) => {
                    stop = Some(e);
                    break;
                }
            }
        }
        self.arm_pause(false);
        let first_line = self.line_no + 1 - self.queued.len() - usize::from(stop.is_some());
        if self.queued.len() >= 2 {
            let (t0, t1) = (self.queued[0][0], self.queued[1][0]);
            if !(t1 - t0 > 0.0 && (t1 - t0).is_finite()) {
                return Err(self.malformed(format!(
                    "time column: expected increasing times, got {t0} then {t1}"
                )));
            }
        }
        for k in 2..self.queued.len() {
            // The mean step over the rows before checks the next one.
            let dt = (self.queued[k - 1][0] - self.queued[0][0]) / (k - 1) as f64;
            let uncertain = 0.5 * (res[0] + res[k - 1]) / (k - 1) as f64;
            let (prev, t) = (self.queued[k - 1][0], self.queued[k][0]);
            let printed = res[k - 1] + res[k];
            if let Err(e) = self.check_step(prev, t, dt, printed, uncertain, first_line + k) {
                self.queued.truncate(k);
                res.truncate(k);
                stop = Some(e);
                break;
            }
        }
        let n = self.queued.len();
        match (n, stop) {
            (0, None) => {
                return Err(SourceError::Empty {
                    what: self.what.clone(),
                })
            }
            (0 | 1, Some(e)) => return Err(e),
            (1, None) => {
                return Err(SourceError::Setting {
                    what: self.what.clone(),
                    detail: "sample rate unknown: the time column needs at least 2 rows, got 1"
                        .into(),
                })
            }
            (_, Some(e)) => {
                self.pending_after_queue = Some(e);
            }
            _ => {}
        }
        let (t0, t1) = (self.queued[0][0], self.queued[n - 1][0]);
        let dt = (t1 - t0) / (n - 1) as f64;
        if !(dt.is_finite() && dt > 0.0) {
            return Err(self.malformed(format!(
                "time column: expected increasing times, got {t0} then {t1}"
            )));
        }
        self.check_time = true;
        self.last_time = Some(t1);
        self.last_time_resolution_s = res[n - 1];
        self.rate_uncertainty = (res[0] + res[n - 1]) / (t1 - t0);
        Ok(1.0 / dt)
    }

    /// Checks the spacing of a new time value against the rate.
    pub(super) fn check_spacing(&mut self, t: f64) -> Result<(), SourceError> {
        let res = self.row_time_resolution_s;
        if let Some(prev) = self.last_time {
            let printed = self.last_time_resolution_s + res;
            self.check_step(
                prev,
                t,
                1.0 / self.info.sample_rate_hz,
                printed,
                0.0,
                self.line_no,
            )?;
        }
        self.last_time = Some(t);
        self.last_time_resolution_s = res;
        Ok(())
    }

    /// One step of the time column against `dt`: equal within 1e-6 relative, plus half the
    /// printed step of each of the two times (`printed_s` is their sum) and `dt`'s own
    /// uncertainty `dt_uncertainty_s`.
    fn check_step(
        &self,
        prev: f64,
        t: f64,
        dt: f64,
        printed_s: f64,
        dt_uncertainty_s: f64,
        line: usize,
    ) -> Result<(), SourceError> {
        let tol = 1e-6 * dt
            + 0.5 * printed_s * (1.0 + 1e-9)
            + dt_uncertainty_s
            + 8.0 * f64::EPSILON * t.abs().max(prev.abs());
        if !((t - prev) - dt).abs().le(&tol) {
            return Err(self.malformed(format!(
                "line {line}: time column not uniform: expected a step of {dt:e} s (within 1e-6 relative or the printed precision), got {:e} s",
                t - prev
            )));
        }
        Ok(())
    }
}
