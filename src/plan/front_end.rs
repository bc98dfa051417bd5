//! Which front end, with which settings: the one factory of front ends.
//!
//! A [`FrontEndSpec`] holds what every front end needs (the STFT's window, the banks' direction,
//! order and frame period); [`FrontEndSpec::build`] makes the kind it names for given bands.
//! `analyze`, `map`, `compare`, `demo` and the built-in sweep all build their front ends here.

use std::str::FromStr;
use std::sync::Arc;

use crate::error::{Error, Result};
use crate::frontend::goyder::{GoyderFrontEnd, GoyderSettings};
use crate::frontend::octave_bank::{OctaveBankFrontEnd, OctaveBankSettings};
use crate::frontend::stft::{StftFrontEnd, StftSettings};
use crate::frontend::{Band, FilterDirection, FrontEnd};
use crate::pipeline::FrontEndFactory;

/// The three time-frequency front ends.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum FrontEndKind {
    /// Short-time Fourier transform (Hann window).
    Stft,
    /// Goyder-style bank: narrow complex band-pass filters, by default on the reversed decay.
    Goyder,
    /// IEC 61260 Butterworth band-pass bank (biquads), forward or time-reversed.
    Octave,
}

impl FrontEndKind {
    /// Every kind, in the order tables list them.
    pub const ALL: [FrontEndKind; 3] = [
        FrontEndKind::Stft,
        FrontEndKind::Goyder,
        FrontEndKind::Octave,
    ];

    /// The name used in tables and settings (`stft`, `goyder`, `octave`).
    pub fn name(self) -> &'static str {
        match self {
            FrontEndKind::Stft => "stft",
            FrontEndKind::Goyder => "goyder",
            FrontEndKind::Octave => "octave",
        }
    }
}

impl FromStr for FrontEndKind {
    type Err = Error;

    fn from_str(text: &str) -> Result<Self> {
        FrontEndKind::ALL
            .into_iter()
            .find(|k| k.name() == text.trim())
            .ok_or_else(|| {
                Error::setting(
                    "front_end",
                    format!("expected stft, goyder or octave, got '{text}'"),
                )
            })
    }
}

/// A front end and its settings, before the bands and the sample rate are known.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct FrontEndSpec {
    /// Which front end.
    pub kind: FrontEndKind,
    /// The STFT's window, overlap and zero padding.
    pub stft: StftSettings,
    /// Time direction of the filter banks (reversed by default: the decay rate is preserved).
    pub direction: FilterDirection,
    /// Order of the banks' low-pass prototype (`None`: each bank's default).
    pub filter_order: Option<usize>,
    /// Frame period of the banks, ms (`None`: each bank's default).
    pub frame_period_ms: Option<f64>,
}

impl Default for FrontEndSpec {
    /// The STFT with its default window; the banks' own defaults.
    fn default() -> Self {
        FrontEndSpec {
            kind: FrontEndKind::Stft,
            stft: StftSettings::default(),
            direction: FilterDirection::default(),
            filter_order: None,
            frame_period_ms: None,
        }
    }
}

impl FrontEndSpec {
    /// The same settings for another kind of front end (`compare` runs several side by side).
    pub fn with_kind(&self, kind: FrontEndKind) -> FrontEndSpec {
        FrontEndSpec { kind, ..*self }
    }

    /// The Goyder bank's settings: its defaults with the direction, order and frame period given.
    pub fn goyder_settings(&self) -> GoyderSettings {
        let d = GoyderSettings::default();
        GoyderSettings {
            direction: self.direction,
            order: self.filter_order.unwrap_or(d.order),
            frame_period_ms: self.frame_period_ms.unwrap_or(d.frame_period_ms),
            ..d
        }
    }

    /// The octave bank's settings: its defaults with the direction, order and frame period given.
    pub fn octave_settings(&self) -> OctaveBankSettings {
        let d = OctaveBankSettings::default();
        OctaveBankSettings {
            direction: self.direction,
            order: self.filter_order.unwrap_or(d.order),
            frame_period_ms: self.frame_period_ms.unwrap_or(d.frame_period_ms),
            ..d
        }
    }

    /// The frame period this spec gives its kind, ms (the STFT's hop).
    pub fn frame_period_ms(&self) -> f64 {
        match self.kind {
            FrontEndKind::Stft => self.stft.window_ms * (1.0 - self.stft.overlap),
            FrontEndKind::Goyder => self.goyder_settings().frame_period_ms,
            FrontEndKind::Octave => self.octave_settings().frame_period_ms,
        }
    }

    /// Builds one front end over `bands` at `fs_hz`. Errors name the setting that is wrong.
    pub fn build(&self, fs_hz: f64, bands: &[Band]) -> Result<Box<dyn FrontEnd>> {
        Ok(match self.kind {
            FrontEndKind::Stft => Box::new(StftFrontEnd::new(self.stft, fs_hz, bands)?),
            FrontEndKind::Goyder => {
                Box::new(GoyderFrontEnd::new(self.goyder_settings(), fs_hz, bands)?)
            }
            FrontEndKind::Octave => Box::new(OctaveBankFrontEnd::new(
                self.octave_settings(),
                fs_hz,
                bands,
            )?),
        })
    }

    /// A factory of identical front ends (one per channel: front ends are stateful). One is
    /// built here, so that bad settings fail before any thread starts, and the factory hands
    /// out fresh copies of it: building each anew repeated the banks' filter design (complex
    /// roots, group delays) for every channel, a tenth of a short 64-channel run.
    pub fn factory(&self, fs_hz: f64, bands: Vec<Band>) -> Result<FrontEndFactory> {
        Ok(match self.kind {
            FrontEndKind::Stft => copies_of(StftFrontEnd::new(self.stft, fs_hz, &bands)?),
            FrontEndKind::Goyder => {
                copies_of(GoyderFrontEnd::new(self.goyder_settings(), fs_hz, &bands)?)
            }
            FrontEndKind::Octave => copies_of(OctaveBankFrontEnd::new(
                self.octave_settings(),
                fs_hz,
                &bands,
            )?),
        })
    }
}

/// A factory of copies of `prototype`, a front end that has seen no sample.
fn copies_of<F: FrontEnd + Clone + Send + Sync + 'static>(prototype: F) -> FrontEndFactory {
    Arc::new(move || Ok(Box::new(prototype.clone())))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip_and_a_wrong_one_is_named() {
        for k in FrontEndKind::ALL {
            assert_eq!(k.name().parse::<FrontEndKind>().unwrap(), k);
        }
        let e = "fft".parse::<FrontEndKind>().unwrap_err().to_string();
        assert!(e.contains("front_end") && e.contains("'fft'"), "{e}");
    }

    #[test]
    fn builds_each_kind_with_its_name_and_settings() {
        let band = Band::new(90.0, 110.0).unwrap();
        let spec = FrontEndSpec {
            frame_period_ms: Some(4.0),
            ..Default::default()
        };
        for k in FrontEndKind::ALL {
            let fe = spec.with_kind(k).build(4000.0, &[band]).unwrap();
            assert_eq!(fe.name(), k.name());
            if k != FrontEndKind::Stft {
                assert!((fe.resolution().frame_period_s - 4e-3).abs() < 1e-12);
            }
        }
        let bad = FrontEndSpec {
            kind: FrontEndKind::Goyder,
            filter_order: Some(3),
            ..Default::default()
        };
        assert!(bad.build(4000.0, &[band]).is_err());
    }

    /// The factory's front ends are copies of one prototype: each gives, bit for bit, the frames
    /// of a front end built anew, also after another copy has run (no state is shared, and the
    /// prototype stays fresh), for every kind and both bank directions.
    #[test]
    fn factory_copies_act_as_front_ends_built_anew() {
        let fs = 4000.0;
        let bands = [
            Band::new(90.0, 180.0).unwrap(),
            Band::new(180.0, 360.0).unwrap(),
        ];
        use crate::frontend::test_frames::{decay_frame_bits as frames, decaying_sine};
        let signal = |f: f64, n: usize| decaying_sine(fs, f, 4.0, n);
        for direction in [FilterDirection::Reversed, FilterDirection::Forward] {
            for k in FrontEndKind::ALL {
                let spec = FrontEndSpec {
                    kind: k,
                    direction,
                    ..Default::default()
                };
                let factory = spec.factory(fs, bands.to_vec()).unwrap();
                let (a, b) = (signal(120.0, 6000), signal(250.0, 5000));
                let mut first = factory().unwrap();
                let got_a = frames(first.as_mut(), &a);
                let mut second = factory().unwrap();
                let got_b = frames(second.as_mut(), &b);
                let want_a = frames(spec.build(fs, &bands).unwrap().as_mut(), &a);
                let want_b = frames(spec.build(fs, &bands).unwrap().as_mut(), &b);
                assert!(
                    !want_a.is_empty() && want_a != want_b,
                    "{k:?} {direction:?}"
                );
                assert_eq!(got_a, want_a, "{k:?} {direction:?}");
                assert_eq!(got_b, want_b, "{k:?} {direction:?}");
            }
        }
    }
}
