//! A source over samples already in memory: for inputs that must be read whole first
//! (mode-centred `--bands auto` needs the spectrum before the bands exist) and for tests.

use super::{Block, SignalInfo, Source, SourceError};

/// Channel-major samples served block by block.
pub struct MemorySource {
    info: SignalInfo,
    channels: Vec<Vec<f64>>,
    position: usize,
}

impl MemorySource {
    /// A source over `channels` (equal lengths) named and timed by `info`.
    pub fn new(info: SignalInfo, channels: Vec<Vec<f64>>) -> Result<Self, SourceError> {
        if channels.len() != info.channels() {
            return Err(SourceError::ChannelCount {
                what: "memory source".into(),
                expected: info.channels(),
                got: channels.len(),
            });
        }
        let n = channels.first().map_or(0, Vec::len);
        if let Some(bad) = channels.iter().position(|c| c.len() != n) {
            return Err(SourceError::Setting {
                what: "memory source".into(),
                detail: format!(
                    "channel {bad} holds {} samples, expected {n}",
                    channels[bad].len()
                ),
            });
        }
        Ok(MemorySource {
            info,
            channels,
            position: 0,
        })
    }
}

impl Source for MemorySource {
    fn duration_frames(&self) -> Option<u64> {
        self.channels.first().map(|c| c.len() as u64)
    }

    fn info(&self) -> &SignalInfo {
        &self.info
    }

    fn read_block(&mut self, max_frames: usize, block: &mut Block) -> Result<bool, SourceError> {
        let n = self.channels.first().map_or(0, Vec::len);
        block.channels.clear();
        if self.position >= n {
            return Ok(false);
        }
        let end = (self.position + max_frames.max(1)).min(n);
        block
            .channels
            .extend(self.channels.iter().map(|c| c[self.position..end].to_vec()));
        self.position = end;
        Ok(true)
    }
}

/// The most samples per channel any input is read whole (2^27: 47 min at 48 kHz, 1 GiB per
/// channel as f64): mode-centred bands and `compare` read their input whole, bounded by this.
pub const MAX_WHOLE_SAMPLES: usize = 1 << 27;

/// Reads every sample of `source` into memory, refusing more than `max_frames` per channel.
pub fn read_all(source: &mut dyn Source, max_frames: usize) -> Result<Vec<Vec<f64>>, SourceError> {
    let mut data: Vec<Vec<f64>> = vec![Vec::new(); source.info().channels()];
    let mut block = Block::default();
    while source.read_block(1 << 16, &mut block)? {
        for (d, c) in data.iter_mut().zip(&block.channels) {
            d.extend_from_slice(c);
        }
        let got = data.first().map_or(0, Vec::len);
        if got > max_frames {
            return Err(SourceError::Setting {
                what: "input".into(),
                detail: format!(
                    "longer than {max_frames} samples per channel, the most that can be read whole"
                ),
            });
        }
    }
    Ok(data)
}
