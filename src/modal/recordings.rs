//! The input of modal identification: every channel's samples in memory, and the noise model
//! the acceptance tests use (white noise on mean signal power).

/// Multichannel recordings of one test: impulse responses or free decays, one per sensor, all
/// starting at the same instant.
#[derive(Clone, Debug)]
pub struct Recordings {
    /// Sample rate, Hz.
    pub fs_hz: f64,
    /// Channel names (sensor ids).
    pub names: Vec<String>,
    /// Samples, one vector per channel, equal lengths.
    pub channels: Vec<Vec<f64>>,
}

impl Recordings {
    /// Reads every sample of `source` (at most `max_frames` per channel) into recordings.
    pub fn from_source(
        source: &mut dyn crate::source::Source,
        max_frames: usize,
    ) -> Result<Self, crate::source::SourceError> {
        let info = source.info().clone();
        let channels = crate::source::memory::read_all(source, max_frames)?;
        Ok(Recordings {
            fs_hz: info.sample_rate_hz,
            names: info.channel_names,
            channels,
        })
    }

    /// Adds white Gaussian noise to every channel at `snr_db` **on mean signal power**: the
    /// noise variance is the mean over channels of each channel's power over the whole record,
    /// divided by 10^(snr/10) (far harsher on decays than a peak SNR). Seeded; channel `k` gets
    /// its own stream.
    pub fn add_noise_mean_power(&mut self, snr_db: f64, seed: u64) {
        let n = self.channels.first().map_or(0, Vec::len).max(1) as f64;
        let power = self
            .channels
            .iter()
            .map(|x| x.iter().map(|v| v * v).sum::<f64>() / n)
            .sum::<f64>()
            / self.channels.len().max(1) as f64;
        let sigma = (power / 10f64.powf(snr_db / 10.0)).sqrt();
        for (k, x) in self.channels.iter_mut().enumerate() {
            let mut g = crate::source::noise::GaussianNoise::new(
                seed.wrapping_mul(0x9E37_79B9_7F4A_7C15)
                    .wrapping_add(k as u64),
            );
            for v in x.iter_mut() {
                *v += sigma * g.next_gaussian();
            }
        }
    }

    /// The recordings as a source (to write them, or to analyse them like any input).
    pub fn into_source(
        self,
    ) -> Result<crate::source::memory::MemorySource, crate::source::SourceError> {
        crate::source::memory::MemorySource::new(
            crate::source::SignalInfo {
                sample_rate_hz: self.fs_hz,
                channel_names: self.names,
            },
            self.channels,
        )
    }

    /// The channels' summed power spectrum, (f in Hz, dB), for the stabilisation diagram's
    /// background.
    pub fn mean_power_spectrum_db(&self) -> Vec<(f64, f64)> {
        use realfft::RealFftPlanner;
        let n = self.channels.first().map_or(0, Vec::len);
        if n < 2 {
            return Vec::new();
        }
        let fft = RealFftPlanner::<f64>::new().plan_fft_forward(n);
        let mut power = vec![0.0; n / 2 + 1];
        let mut spectrum = fft.make_output_vec();
        let mut input = fft.make_input_vec();
        for x in &self.channels {
            input.copy_from_slice(x);
            if fft.process(&mut input, &mut spectrum).is_ok() {
                for (p, s) in power.iter_mut().zip(&spectrum) {
                    *p += s.norm_sqr();
                }
            }
        }
        power
            .iter()
            .enumerate()
            .map(|(k, p)| {
                (
                    k as f64 * self.fs_hz / n as f64,
                    10.0 * p.max(1e-300).log10(),
                )
            })
            .collect()
    }
}
