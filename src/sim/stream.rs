//! The simulator as a [`Source`]: impulse responses of any number of sensors, produced block by
//! block from a [`FactoredFrf`] so that a recording set is streamed to disk, not held.
//!
//! The inverse FFT of [`super::impulse`] is real-linear, so with the accelerance of sensor s
//! written as Σ_i w_si A_i(f), w = a + jb:
//!
//! ```text
//! h_s(t) = Σ_i a_si · IFFT(A_i)(t) + b_si · IFFT(j A_i)(t)
//! ```
//!
//! One time signal per basis vector (two when the weights are complex) is made once; each block
//! of samples is then one matrix product (sensors × vectors) · (vectors × frames). Noise is the
//! same as [`super::simulate::impulse_responses`]: per channel, σ = peak · 10^(−snr/20), seeded
//! with seed + k and drawn sample by sample, so the streamed and the held results agree.

use faer::{c64, Mat};

use super::error::SimError;
use super::factored::FactoredFrf;
use super::impulse::impulse_response;
use super::simulate::{channel_noise, check_snr_db};
use crate::source::memory::MemorySource;
use crate::source::noise::GaussianNoise;
use crate::source::{Block, SignalInfo, Source, SourceError};

/// Bytes of output one block may hold at most (sensors × frames × 8): with many sensors a
/// block is shorter than asked, as the [`Source`] contract allows.
const MAX_BLOCK_BYTES: usize = 16 << 20;

/// Frames per block for `n_sensors`: at most `wanted`, at most [`MAX_BLOCK_BYTES`], at least 1.
fn block_frames(n_sensors: usize, wanted: usize) -> usize {
    (MAX_BLOCK_BYTES / (8 * n_sensors.max(1))).clamp(1, wanted.max(1))
}

/// Impulse responses of every sensor of a simulation, served as a stream.
pub struct SimulatedSource {
    inner: Inner,
}

enum Inner {
    /// Responses already held per sensor (the direct method computes them that way).
    Held(MemorySource),
    /// Responses made per block from the basis-vector signals.
    Modal(ModalStream),
}

struct ModalStream {
    info: SignalInfo,
    /// One time signal per row: the impulse response of each basis vector (real and, for
    /// complex weights, imaginary part), (m/s²)/(N·s) per unit weight.
    signals: Mat<f64>,
    /// Sensor × signal weights.
    weights: Mat<f64>,
    /// Per channel: noise σ and its generator.
    noise: Vec<(f64, GaussianNoise)>,
    position: usize,
}

/// Bytes a streamed simulation holds besides the model: the signals, the split weights and one
/// block of output (product and channel copies) when blocks of `wanted_frames` are read.
pub fn streamed_bytes(n_sensors: usize, basis: usize, samples: usize, wanted_frames: usize) -> f64 {
    let b = block_frames(n_sensors, wanted_frames) as f64;
    let (s, m, l) = (n_sensors as f64, basis as f64, samples as f64);
    2.0 * m * l * 8.0 + s * 2.0 * m * 8.0 + 2.0 * s * b * 8.0
}

impl SimulatedSource {
    /// A source over responses already computed (channel-major, equal lengths).
    pub fn held(info: SignalInfo, channels: Vec<Vec<f64>>) -> Result<Self, SimError> {
        let src = MemorySource::new(info, channels).map_err(|e| SimError::InvalidValue {
            key: "impulse responses".into(),
            message: e.to_string(),
        })?;
        Ok(SimulatedSource {
            inner: Inner::Held(src),
        })
    }

    /// A streamed source over `frf` sampled at 0, df, …, fmax: impulse responses at
    /// fs = 2 fmax, with optional peak-SNR noise (channel k seeded with `seed + k`).
    pub fn from_factored(
        frf: &FactoredFrf,
        fmax_hz: f64,
        snr_db: Option<f64>,
        seed: u64,
    ) -> Result<Self, SimError> {
        check_snr_db(snr_db)?;
        let omega2: Vec<f64> = frf
            .frequencies_hz
            .iter()
            .map(|f| (2.0 * std::f64::consts::PI * f).powi(2))
            .collect();
        let parts: &[c64] = if frf.real_weights() {
            &[c64 { re: 1.0, im: 0.0 }]
        } else {
            &[c64 { re: 1.0, im: 0.0 }, c64 { re: 0.0, im: 1.0 }]
        };
        let m = frf.basis_size();
        let mut rows = Vec::with_capacity(m * parts.len());
        for part in parts {
            for i in 0..m {
                let acc: Vec<c64> = (0..omega2.len())
                    .map(|k| *part * frf.modal[(k, i)] * (-omega2[k]))
                    .collect();
                rows.push(impulse_response(&acc, fmax_hz)?);
            }
        }
        let samples = rows.first().map_or(0, Vec::len);
        let signals = Mat::<f64>::from_fn(rows.len(), samples, |r, t| rows[r][t]);
        drop(rows);
        let ns = frf.n_sensors();
        let weights = Mat::<f64>::from_fn(ns, m * parts.len(), |s, c| {
            let w = frf.weights[(s, c % m)];
            if c < m {
                w.re
            } else {
                w.im
            }
        });
        let info = SignalInfo {
            sample_rate_hz: 2.0 * fmax_hz,
            channel_names: frf.sensor_ids.clone(),
        };
        let mut stream = ModalStream {
            info,
            signals,
            weights,
            noise: Vec::new(),
            position: 0,
        };
        if let Some(snr) = snr_db {
            let peaks = stream.peaks();
            stream.noise = peaks
                .iter()
                .enumerate()
                .map(|(k, &p)| channel_noise(p, snr, seed, k))
                .collect();
        }
        Ok(SimulatedSource {
            inner: Inner::Modal(stream),
        })
    }
}

impl ModalStream {
    fn samples(&self) -> usize {
        self.signals.ncols()
    }

    /// Noise-free samples `start..end` of every sensor (sensor × frame).
    fn frames(&self, start: usize, end: usize) -> Mat<f64> {
        &self.weights * self.signals.subcols(start, end - start)
    }

    /// Peak |h| of every sensor over the whole response.
    fn peaks(&self) -> Vec<f64> {
        let mut peaks = vec![0.0f64; self.weights.nrows()];
        let mut start = 0;
        while start < self.samples() {
            let end = (start + block_frames(peaks.len(), 1024)).min(self.samples());
            let block = self.frames(start, end);
            for (s, p) in peaks.iter_mut().enumerate() {
                for t in 0..end - start {
                    *p = p.max(block[(s, t)].abs());
                }
            }
            start = end;
        }
        peaks
    }
}

impl Source for SimulatedSource {
    fn info(&self) -> &SignalInfo {
        match &self.inner {
            Inner::Held(s) => s.info(),
            Inner::Modal(s) => &s.info,
        }
    }

    fn duration_frames(&self) -> Option<u64> {
        match &self.inner {
            Inner::Held(s) => s.duration_frames(),
            Inner::Modal(s) => Some(s.samples() as u64),
        }
    }

    fn read_block(&mut self, max_frames: usize, block: &mut Block) -> Result<bool, SourceError> {
        let s = match &mut self.inner {
            Inner::Held(s) => return s.read_block(max_frames, block),
            Inner::Modal(s) => s,
        };
        block.channels.clear();
        if s.position >= s.samples() {
            return Ok(false);
        }
        let end = (s.position + block_frames(s.weights.nrows(), max_frames)).min(s.samples());
        let frames = s.frames(s.position, end);
        for k in 0..frames.nrows() {
            let mut ch: Vec<f64> = (0..end - s.position).map(|t| frames[(k, t)]).collect();
            if let Some((sigma, g)) = s.noise.get_mut(k) {
                ch.iter_mut().for_each(|x| *x += *sigma * g.next_gaussian());
            }
            block.channels.push(ch);
        }
        s.position = end;
        Ok(true)
    }
}
