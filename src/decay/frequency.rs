//! How a front end hands over the frequency present in each frame.
//!
//! The octave bank knows a frame's frequency as a cosine, c = cos 2πf/fs (from the band
//! signal's lag-one autocorrelation), and f = acos(c)·fs/2π costs an arccosine. An estimate
//! reads the frequencies of its fitted frames only, a few hundred of the 5000 that a 10 s decay
//! has per band at 2 ms frames; so the bank may hand over the cosines as they are and the
//! estimator decodes the frames it reads (the arccosines of every frame were a twentieth of a
//! 64-channel octave-bank run at 4096 Hz). The decoded value is bit for bit the one the bank
//! would have computed.

use std::borrow::Cow;

/// The coding of a run of per-frame frequency values.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum FrequencyCoding {
    /// Frequencies in Hz (NaN where unknown).
    #[default]
    Hz,
    /// Values c = cos(2πf/fs) in [−1, 1] for the sample rate fs given, in Hz (NaN where
    /// unknown).
    Cosine {
        /// fs, Hz.
        sample_rate_hz: f64,
    },
}

impl FrequencyCoding {
    /// The frequency in Hz of one value so coded.
    #[inline]
    pub fn to_hz(self, value: f64) -> f64 {
        match self {
            FrequencyCoding::Hz => value,
            FrequencyCoding::Cosine { sample_rate_hz } => {
                crate::frontend::lane_acos::acos_scaled(value, cosine_scale(sample_rate_hz))
            }
        }
    }

    /// The frequencies in Hz of `values` so coded: borrowed when they are in Hz already.
    pub fn decode(self, values: &[f64]) -> Cow<'_, [f64]> {
        match self {
            FrequencyCoding::Hz => Cow::Borrowed(values),
            FrequencyCoding::Cosine { .. } => {
                let mut hz = values.to_vec();
                self.decode_in_place(&mut hz);
                Cow::Owned(hz)
            }
        }
    }

    /// Replaces values so coded by their frequencies in Hz, many at once.
    pub fn decode_in_place(self, values: &mut [f64]) {
        if let FrequencyCoding::Cosine { sample_rate_hz } = self {
            crate::frontend::lane_acos::acos_scaled_in_place(
                crate::frontend::simd::Isa::detect(),
                values,
                cosine_scale(sample_rate_hz),
            );
        }
    }
}

/// Hz per radian of the angle 2πf/fs.
fn cosine_scale(sample_rate_hz: f64) -> f64 {
    sample_rate_hz / (2.0 * std::f64::consts::PI)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_at_a_time_and_many_at_once_decode_alike() {
        let coding = FrequencyCoding::Cosine {
            sample_rate_hz: 4096.0,
        };
        let values: Vec<f64> = (0..=400)
            .map(|k| -1.0 + k as f64 / 200.0)
            .chain([f64::NAN, 0.5, -0.5, 1.0, -1.0])
            .collect();
        let many = coding.decode(&values);
        for (&c, &f) in values.iter().zip(many.iter()) {
            assert_eq!(coding.to_hz(c).to_bits(), f.to_bits(), "cos {c}");
        }
        // Inside (0, fs/2), monotone falling in the cosine, ends at 0 and fs/2.
        assert_eq!(coding.to_hz(1.0), 0.0);
        assert!((coding.to_hz(-1.0) - 2048.0).abs() < 1e-9);
        assert!((coding.to_hz(0.0) - 1024.0).abs() < 1e-9);
        assert!(coding.to_hz(f64::NAN).is_nan());
        assert!(matches!(
            FrequencyCoding::Hz.decode(&values),
            Cow::Borrowed(_)
        ));
        assert_eq!(FrequencyCoding::Hz.to_hz(123.0), 123.0);
    }
}
