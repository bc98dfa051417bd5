//! The flags of an estimate: why a number is missing, or what qualifies one that stands. The
//! table column `flags` lists them by [`Flag::as_str`].

/// Why an estimate is missing, or what to be careful about when reading it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Flag {
    /// The band received no energy.
    NoEnergy,
    /// The record ends (no noise floor: the decay is cut off, not buried) before the band energy
    /// has fallen below the lower limit of the range.
    TooShort,
    /// The curve reaches the range, but fewer than the minimum number of frames fall inside it:
    /// the front end's frame rate is too low for this decay (use a shorter window or a filter bank).
    TooFewFrames,
    /// A noise floor sits less than 10 dB below the lower limit of the range (ISO 3382 rule).
    NoiseLimited,
    /// The fitted line does not fall.
    NoDecay,
    /// |T30/T20 − 1| exceeds the curvature limit: not a single exponential (beating, several
    /// modes, or noise).
    NonlinearDecay,
    /// The record ends less than 10 dB below the lower limit, so the end of the curve bends down.
    TruncationBias,
    /// The channel contained NaN or infinite samples (or an empty CSV cell): from the first of
    /// them on nothing more is reported (decays that ended before it stand).
    NonFiniteInput,
    /// The input ended in the middle of a sample frame or before the length its header announced.
    InputTruncated,
    /// The decay in this band is not its own: its energy is the skirt of a mode outside the
    /// band (the frequency carrying it lies outside), or no more than [`LEAKAGE_MARGIN_DB`](super::estimate::LEAKAGE_MARGIN_DB)
    /// above what the stronger bands of the same decay leak into it through the front end's
    /// skirts, or more than [`NUMERICAL_FLOOR_DB`](super::estimate::NUMERICAL_FLOOR_DB) below the strongest band. No number is given.
    Leakage,
    /// The band is narrower than the front end resolves (an STFT band narrower than one bin of
    /// the window): its energy is the neighbouring bins'. No number is given.
    BelowResolution,
    /// The fitted line does not describe the curve: r² below [`EstimateSettings::min_r2`](super::estimate::EstimateSettings::min_r2) or
    /// |C| above [`EstimateSettings::max_curvature_pct`](super::estimate::EstimateSettings::max_curvature_pct) (merged hits, noise, several modes of
    /// very different decay). No number is given.
    PoorFit,
    /// The decay holds a new hit (its band energy restarts, see [`crate::decay::restarts`]):
    /// the Schroeder curve sums several decays. No number is given; split the stream
    /// (`--retrigger-jump-db`) or cut the record.
    MergedHits,
    /// A noise floor was found; the curve was truncated at Lundeby's intersection time and its
    /// tail compensated (ISO 3382 practice).
    NoiseCompensated,
    /// The band lies (partly) above the Nyquist frequency or outside what the front end resolves.
    BandOutOfRange,
    /// The decay outlasted the buffering front end's limit (`max_decay_s`): only its first
    /// part was analysed.
    DecayTooLong,
    /// The responses carried an exponential window (FRF input, impact tests): its added
    /// damping 1/(2πfτ) was removed from the decay times and damping ratios.
    ExponentialWindowRemoved,
    /// The hit was clipped (its peak held flat: the sensor or converter saturated). The decay
    /// after it stands; its level and anything read from the first samples do not.
    ClippedHit,
    /// The decay's first samples hold a second impact, within tens of ms of the first (a
    /// hammer that bounced: [`crate::pipeline::segment::double_hit`]). The decay after it
    /// stands (the same modes ring on); its level, its first frames (EDT) and an FRF from the
    /// hit do not.
    DoubleHit,
    /// The decay is as fast as the band filter's own ringing: B·T60 below
    /// [`crate::frontend::BT60_MIN`], B the filter's bandwidth. What was measured is the filter
    /// (in an empty band: its response to the onset). No number is given; use a wider band or
    /// the STFT with a short window.
    FilterLimited,
    /// The recording's bit depth cannot show this band's decay: the band's share of the
    /// rounding noise (step² / 12 per sample of an integer recording) lies less than the
    /// range's depth plus the noise margin below its peak ([`crate::decay::quantization`]). An
    /// undithered recording shows no such floor; its band would read the loud modes' rounding
    /// error as its decay. No number is given; record louder or with more bits.
    QuantizationLimited,
    /// The analysis of this channel stopped on an internal error (a bug, reported on stderr);
    /// the other channels were analysed.
    InternalError,
}

impl Flag {
    /// True for the flags that explain a missing number (as opposed to the ones that only
    /// qualify a number that stands, such as `noise_compensated` or `nonlinear_decay`).
    pub fn withholds(&self) -> bool {
        !matches!(
            self,
            Flag::NonlinearDecay
                | Flag::TruncationBias
                | Flag::NoiseCompensated
                | Flag::DecayTooLong
                | Flag::ExponentialWindowRemoved
                | Flag::ClippedHit
                | Flag::DoubleHit
        )
    }

    /// Why a result with `flags` has no number: the first flag that withholds one (not a
    /// qualifying flag such as `noise_compensated` that happened to be raised first), else its
    /// first flag, else `no_estimate`.
    pub fn missing_reason(flags: &[Flag]) -> &'static str {
        flags
            .iter()
            .find(|f| f.withholds())
            .or(flags.first())
            .map_or("no_estimate", Flag::as_str)
    }

    /// The flag a table names `name` ([`Flag::as_str`]), or `None` for a name it does not know.
    pub fn parse(name: &str) -> Option<Flag> {
        use serde::de::IntoDeserializer;
        let de: serde::de::value::StrDeserializer<'_, serde::de::value::Error> =
            name.into_deserializer();
        serde::Deserialize::deserialize(de).ok()
    }

    /// The flag as it appears in tables.
    pub fn as_str(&self) -> &'static str {
        match self {
            Flag::NoEnergy => "no_energy",
            Flag::TooShort => "too_short",
            Flag::TooFewFrames => "too_few_frames",
            Flag::NoiseLimited => "noise_limited",
            Flag::NoDecay => "no_decay",
            Flag::NonlinearDecay => "nonlinear_decay",
            Flag::TruncationBias => "truncation_bias",
            Flag::NonFiniteInput => "non_finite_input",
            Flag::InputTruncated => "input_truncated",
            Flag::BandOutOfRange => "band_out_of_range",
            Flag::NoiseCompensated => "noise_compensated",
            Flag::Leakage => "leakage",
            Flag::BelowResolution => "below_resolution",
            Flag::PoorFit => "poor_fit",
            Flag::MergedHits => "merged_hits",
            Flag::DecayTooLong => "decay_too_long",
            Flag::ExponentialWindowRemoved => "exponential_window_removed",
            Flag::ClippedHit => "clipped_hit",
            Flag::DoubleHit => "double_hit",
            Flag::FilterLimited => "filter_limited",
            Flag::QuantizationLimited => "quantization_limited",
            Flag::InternalError => "internal_error",
        }
    }
}
