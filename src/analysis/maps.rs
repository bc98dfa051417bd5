//! Local damping maps and the global equivalent damping per band (report sections 3 and 4.2).
//!
//! A [`BandMap`] holds, for one band, every sensor of the set with its position and its local
//! damping ratio D_local(f_n, x) — or the reason there is none. The global equivalent damping of
//! the band is the spatial mean over the sensors that have an estimate (report eq. 4.3,
//! D_global(f_n) = mean(D_local(f_n, {x}))); sensors without one are counted and listed by
//! reason, never filled in. [`BandMap::sensors_needed`] repeats the mean with every k-th sensor
//! (report section 4.2.1: about 120 of 1089 points give the same mean).

use std::collections::BTreeMap;

use crate::decay::Flag;
use crate::frontend::Band;
use crate::pipeline::ResultRow;
use crate::source::Sensor;

/// Why a sensor has no local damping ratio when the analysis produced no row for it at all
/// (no onset found: e.g. a sensor on a pinned edge, which does not move).
pub const NO_DECAY_FOUND: &str = "no_decay_found";

/// One sensor of a band map.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct MapNode {
    /// Sensor id (channel name).
    pub id: String,
    /// Position along x, m.
    pub x_m: f64,
    /// Position along y, m.
    pub y_m: f64,
    /// Local damping ratio D = 1.1/(T60 f_center) (fraction), `None` when not estimated.
    pub damping_ratio: Option<f64>,
    /// Local damping ratio corrected with the dominant frequency (eq. 3.2), fraction.
    pub damping_ratio_corrected: Option<f64>,
    /// Flags of the estimate (empty when the sensor had no row).
    pub flags: Vec<Flag>,
    /// Why `damping_ratio` is missing: [`crate::decay::DecayEstimate::missing_reason`], or [`NO_DECAY_FOUND`].
    pub missing_reason: Option<String>,
}

/// The local damping map of one band.
#[derive(Clone, Debug, PartialEq)]
pub struct BandMap {
    /// The band.
    pub band: Band,
    /// Every sensor, in the order of the sensor list.
    pub nodes: Vec<MapNode>,
}

/// Summary statistics of the local damping ratios of a band (fractions).
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct GlobalDamping {
    /// Band lower edge, Hz.
    pub f_lo_hz: f64,
    /// Band upper edge, Hz.
    pub f_hi_hz: f64,
    /// Band centre, Hz.
    pub f_center_hz: f64,
    /// Sensors in the map.
    pub n_nodes: usize,
    /// Sensors with a local damping ratio.
    pub n_estimated: usize,
    /// Global equivalent damping ratio: mean of the local ones (eq. 4.3); `None` without any.
    pub mean_d: Option<f64>,
    /// Mean of the frequency-corrected local ratios, over the sensors that have one.
    pub mean_d_corrected: Option<f64>,
    /// Median of the local ratios.
    pub median_d: Option<f64>,
    /// Sample standard deviation of the local ratios (`None` below 2 estimates).
    pub std_d: Option<f64>,
    /// Smallest local ratio.
    pub min_d: Option<f64>,
    /// Largest local ratio.
    pub max_d: Option<f64>,
    /// Sensors without an estimate, by reason (`flag:count;…`, sorted by flag).
    pub missing: String,
}

/// The global mean recomputed from every k-th sensor (report section 4.2.1).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct SubsetMean {
    /// Step k: sensors 0, k, 2k, … of the sensor list.
    pub step: usize,
    /// Sensors in the subset.
    pub n_nodes: usize,
    /// Of those, sensors with an estimate.
    pub n_estimated: usize,
    /// Mean local damping ratio of the subset.
    pub mean_d: Option<f64>,
    /// (mean of the subset − mean of all) / mean of all.
    pub rel_change: Option<f64>,
}

/// Errors of map building.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum MapError {
    /// The sensor list is empty.
    #[error("no sensors: a damping map needs sensor positions (a recording set or a sensor file)")]
    NoSensors,
    /// A sensor id appears twice.
    #[error("sensor id {0:?} appears twice in the sensor list")]
    DuplicateSensor(String),
    /// Result rows name channels that are not sensors.
    #[error("{count} result channel(s) have no sensor position, e.g. {example:?}: expected one sensor per channel")]
    UnknownChannels {
        /// How many channels are unknown.
        count: usize,
        /// One of them.
        example: String,
    },
}

/// Builds one map per band from the analysis rows of decay number `decay` of each channel (0:
/// the first decay) and the sensor positions. Bands are taken in the order they first appear.
pub fn band_maps(
    rows: &[ResultRow],
    sensors: &[Sensor],
    decay: usize,
) -> Result<Vec<BandMap>, MapError> {
    if sensors.is_empty() {
        return Err(MapError::NoSensors);
    }
    let mut index = BTreeMap::new();
    for (i, s) in sensors.iter().enumerate() {
        if index.insert(s.id.as_str(), i).is_some() {
            return Err(MapError::DuplicateSensor(s.id.clone()));
        }
    }
    let unknown: Vec<&str> = rows
        .iter()
        .map(|r| r.channel.as_str())
        .filter(|c| !index.contains_key(c))
        .collect();
    if let Some(example) = unknown.first() {
        return Err(MapError::UnknownChannels {
            count: {
                let mut u = unknown.clone();
                u.sort_unstable();
                u.dedup();
                u.len()
            },
            example: example.to_string(),
        });
    }
    let mut bands: Vec<Band> = Vec::new();
    for r in rows {
        if !bands.contains(&r.band) {
            bands.push(r.band);
        }
    }
    Ok(bands
        .into_iter()
        .map(|band| {
            let mut nodes: Vec<MapNode> = sensors
                .iter()
                .map(|s| MapNode {
                    id: s.id.clone(),
                    x_m: s.x_m,
                    y_m: s.y_m,
                    damping_ratio: None,
                    damping_ratio_corrected: None,
                    flags: Vec::new(),
                    missing_reason: Some(NO_DECAY_FOUND.to_string()),
                })
                .collect();
            for r in rows.iter().filter(|r| r.band == band && r.decay == decay) {
                let node = &mut nodes[index[r.channel.as_str()]];
                let e = &r.estimate;
                node.damping_ratio = e.damping_ratio;
                node.damping_ratio_corrected = e.damping_ratio_corrected;
                node.flags = e.flags.clone();
                node.missing_reason = e.missing_reason().map(str::to_string);
            }
            BandMap { band, nodes }
        })
        .collect())
}

fn mean(v: &[f64]) -> Option<f64> {
    (!v.is_empty()).then(|| v.iter().sum::<f64>() / v.len() as f64)
}

impl BandMap {
    /// The band's global equivalent damping and the spread of the local values.
    pub fn global(&self) -> GlobalDamping {
        let mut d: Vec<f64> = self.nodes.iter().filter_map(|n| n.damping_ratio).collect();
        let dc: Vec<f64> = self
            .nodes
            .iter()
            .filter_map(|n| n.damping_ratio_corrected)
            .collect();
        d.sort_by(f64::total_cmp);
        let m = mean(&d);
        let median = match d.len() {
            0 => None,
            n if n % 2 == 1 => Some(d[n / 2]),
            n => Some(0.5 * (d[n / 2 - 1] + d[n / 2])),
        };
        let std = m.filter(|_| d.len() >= 2).map(|m| {
            (d.iter().map(|x| (x - m) * (x - m)).sum::<f64>() / (d.len() - 1) as f64).sqrt()
        });
        let mut missing: BTreeMap<&str, usize> = BTreeMap::new();
        for n in &self.nodes {
            if let Some(r) = &n.missing_reason {
                *missing.entry(r.as_str()).or_default() += 1;
            }
        }
        GlobalDamping {
            f_lo_hz: self.band.lo_hz,
            f_hi_hz: self.band.hi_hz,
            f_center_hz: self.band.center_hz,
            n_nodes: self.nodes.len(),
            n_estimated: d.len(),
            mean_d: m,
            mean_d_corrected: mean(&dc),
            median_d: median,
            std_d: std,
            min_d: d.first().copied(),
            max_d: d.last().copied(),
            missing: missing
                .iter()
                .map(|(k, v)| format!("{k}:{v}"))
                .collect::<Vec<_>>()
                .join(";"),
        }
    }

    /// The global mean from sensors 0, k, 2k, … for k = 1 … `max_step` (steps that leave no
    /// sensor are skipped).
    pub fn sensors_needed(&self, max_step: usize) -> Vec<SubsetMean> {
        let all = self.global().mean_d;
        (1..=max_step.min(self.nodes.len()))
            .map(|step| {
                let subset: Vec<&MapNode> = self.nodes.iter().step_by(step).collect();
                let d: Vec<f64> = subset.iter().filter_map(|n| n.damping_ratio).collect();
                let m = mean(&d);
                SubsetMean {
                    step,
                    n_nodes: subset.len(),
                    n_estimated: d.len(),
                    mean_d: m,
                    rel_change: m.zip(all).map(|(m, a)| (m - a) / a),
                }
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::decay::{DecayEstimate, EvaluationRange};

    fn sensor(id: &str, x: f64, y: f64) -> Sensor {
        Sensor {
            id: id.into(),
            x_m: x,
            y_m: y,
            z_m: None,
            dir: "z".into(),
        }
    }

    fn row(ch: &str, band: Band, decay: usize, d: Option<f64>, flags: Vec<Flag>) -> ResultRow {
        ResultRow {
            position_sample: 0,
            channel: ch.into(),
            decay,
            onset_s: Some(0.0),
            front_end: "stft",
            band,
            range: EvaluationRange::T30,
            estimate: DecayEstimate {
                damping_ratio: d,
                damping_ratio_corrected: d.map(|d| 0.9 * d),
                flags,
                ..Default::default()
            },
        }
    }

    #[test]
    fn global_mean_uses_estimates_only_and_counts_the_rest() {
        let b1 = Band::new(50.0, 60.0).unwrap();
        let b2 = Band::new(90.0, 110.0).unwrap();
        let sensors: Vec<Sensor> = (0..5)
            .map(|i| sensor(&format!("s{i}"), i as f64, 0.0))
            .collect();
        let rows = vec![
            row("s0", b1, 0, Some(0.01), vec![]),
            row("s1", b1, 0, Some(0.03), vec![Flag::NonlinearDecay]),
            row("s2", b1, 0, None, vec![Flag::TooFewFrames]),
            row("s3", b1, 0, Some(0.02), vec![]),
            // The reason is the withholding flag, not a qualifying one raised before it.
            row(
                "s4",
                b1,
                0,
                None,
                vec![Flag::NoiseCompensated, Flag::Leakage],
            ),
            // A second decay of s3 is not the map's decay 0.
            row("s3", b1, 1, Some(0.5), vec![]),
            row("s0", b2, 0, Some(0.02), vec![]),
        ];
        let maps = band_maps(&rows, &sensors, 0).unwrap();
        assert_eq!(maps.len(), 2);
        let g = maps[0].global();
        assert_eq!((g.n_nodes, g.n_estimated), (5, 3));
        assert_eq!(maps[0].nodes[4].missing_reason.as_deref(), Some("leakage"));
        assert!((g.mean_d.unwrap() - 0.02).abs() < 1e-15);
        assert!((g.mean_d_corrected.unwrap() - 0.018).abs() < 1e-15);
        assert_eq!(g.median_d, Some(0.02));
        assert!((g.std_d.unwrap() - 0.01).abs() < 1e-15);
        assert_eq!((g.min_d, g.max_d), (Some(0.01), Some(0.03)));
        assert_eq!(g.missing, "leakage:1;too_few_frames:1");
        let g2 = maps[1].global();
        assert_eq!((g2.n_estimated, g2.mean_d), (1, Some(0.02)));
        assert_eq!(g2.std_d, None);
        assert_eq!(g2.missing, "no_decay_found:4");
        // Decay 1: only s3.
        let later = band_maps(&rows, &sensors, 1).unwrap();
        assert_eq!(later[0].global().mean_d, Some(0.5));
    }

    #[test]
    fn every_kth_sensor() {
        let band = Band::new(50.0, 60.0).unwrap();
        let sensors: Vec<Sensor> = (0..10)
            .map(|i| sensor(&format!("s{i}"), i as f64, 1.0))
            .collect();
        let rows: Vec<ResultRow> = (0..10)
            .map(|i| {
                row(
                    &format!("s{i}"),
                    band,
                    0,
                    Some(0.01 * (i + 1) as f64),
                    vec![],
                )
            })
            .collect();
        let maps = band_maps(&rows, &sensors, 0).unwrap();
        let s = maps[0].sensors_needed(20);
        assert_eq!(s.len(), 10);
        assert_eq!((s[0].step, s[0].n_nodes), (1, 10));
        assert_eq!(s[0].rel_change, Some(0.0));
        // k = 3: sensors 0, 3, 6, 9 → D 1, 4, 7, 10 % → mean 5.5 %, as for all.
        assert_eq!((s[2].n_nodes, s[2].n_estimated), (4, 4));
        assert!((s[2].mean_d.unwrap() - 0.055).abs() < 1e-15);
        // k = 4: 0, 4, 8 → 1, 5, 9 % → 5 %: −9.1 %.
        assert!((s[3].rel_change.unwrap() + 0.5 / 5.5).abs() < 1e-12);
    }

    #[test]
    fn bad_sensor_lists_are_errors() {
        let band = Band::new(50.0, 60.0).unwrap();
        let rows = vec![row("a", band, 0, Some(0.01), vec![])];
        assert_eq!(band_maps(&rows, &[], 0), Err(MapError::NoSensors));
        let dup = [sensor("a", 0.0, 0.0), sensor("a", 1.0, 0.0)];
        assert_eq!(
            band_maps(&rows, &dup, 0),
            Err(MapError::DuplicateSensor("a".into()))
        );
        match band_maps(&rows, &[sensor("b", 0.0, 0.0)], 0) {
            Err(MapError::UnknownChannels { count: 1, example }) => assert_eq!(example, "a"),
            other => panic!("{other:?}"),
        }
    }
}
