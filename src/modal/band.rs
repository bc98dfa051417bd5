//! One sub-band from baseband samples to validated modes: poles over the orders, the
//! stabilisation diagram read automatically, refinement, residues on every channel, and the
//! rejection of what the refined fit shows to be no mode (a shape as incoherent as noise, a
//! damping ratio out of the physical range). Rejected poles leave the model and the rest is
//! refitted, so no spurious exponential distorts its neighbours.

use faer::c64;

use super::baseband::{Baseband, SubBand};
use super::stabilise::{classify, select_modes, Cluster, StabilityCriteria};
use super::subspace::mac;
use super::subspace::{compress, poles_by_order, HankelPlan};
use super::{refine, shapes, DiagramPole, ModalSettings, Mode};

/// Most refit rounds after rejections (each removes one pole).
const MAX_REFITS: usize = 24;
/// Poles are modelled out to this many filter half-widths from the sub-band's centre: 2, the
/// decimated Nyquist frequency, i.e. every pole the baseband holds. The order-12 low-pass
/// attenuates 3 dB at one half-width, 42 dB at 1.5, 63 dB at 1.83 and 72 dB at 2: a strong
/// mode just beyond the band is still there, and left out of the model (1.8 half-widths
/// before) it pulled the band's poles (D off by 2–3 %) or was fitted by a pole of its own
/// inside the band (test `regression_a_strong_mode_beyond_the_top_band_pulled_the_band_modes`).
const MODELLED_HALF_WIDTHS: f64 = 2.0;
/// Most candidate clusters tried per sub-band.
const MAX_CANDIDATES: usize = 6;
/// A candidate (a cluster stable at too few orders to be a mode by itself) is added when its
/// modal SNR reaches this, dB. Poles fitted to noise reach 6–8.4 dB after selection
/// (99 channels at 35 dB, 8 seeds), the weakest true mode 11.5 dB.
const CANDIDATE_MIN_SNR_DB: f64 = 12.0;
/// Every mode's modal SNR reaches this, dB. A pole fitted to white noise sits near 0 dB and
/// the noisiest that survive selection reach 6–8.4 dB; poles fitted to a noise-free record's
/// deterministic residual (filter transients, modes beyond the band) sit below 0 dB; the
/// weakest true mode at 35 dB has 11.5 dB (99 channels, 8 seeds).
const MODE_MIN_SNR_DB: f64 = 3.0;
/// Sensor groups of the jackknife uncertainty (channel c belongs to group c mod G).
pub const JACKKNIFE_GROUPS: usize = 4;
/// A candidate's refined damping ratio stays within this fraction of its cluster's median.
const CANDIDATE_DAMPING_REL: f64 = 0.5;
/// A candidate's shape has a MAC below this with every other mode of the band (a split of one
/// mode into two poles gives two near-equal shapes; the 0.77 Hz pair at 57 Hz has MAC < 0.1).
const CANDIDATE_MAX_MAC: f64 = 0.5;
/// Two refined modes closer than this fraction of the frequency tolerance, with matching
/// shapes, are one pole.
const DUPLICATE_FREQUENCY_FRACTION: f64 = 0.25;

/// The modes of one sub-band (those inside `sub.lo_hz..sub.hi_hz`) and its diagram poles, or
/// why the band gives nothing.
pub fn identify_band(
    band: &Baseband,
    sub: &SubBand,
    plan: &HankelPlan,
    settings: &ModalSettings,
) -> Result<(Vec<Mode>, Vec<DiagramPole>), String> {
    let too_short = || {
        format!(
            "{} decimated samples are too few for {} block rows, or a factorisation failed",
            band.data.ncols(),
            plan.block_rows
        )
    };
    let compressed =
        compress(band.data.as_ref(), plan.compressed_channels).ok_or_else(too_short)?;
    let by_order = poles_by_order(
        band,
        compressed.as_ref(),
        plan,
        settings.min_order..=settings.max_order,
    )
    .ok_or_else(too_short)?;
    // Modes are modelled wherever the baseband holds them, the filter's skirt included (a
    // mode at the cutoff is only 3 dB down, and left out of the model it pulls its
    // neighbours' poles), and kept where the sub-band accepts them.
    let criteria = &settings.stability;
    let reach_hz = MODELLED_HALF_WIDTHS * sub.half_width_hz();
    let classes = classify(
        &by_order,
        sub.center_hz() - reach_hz,
        sub.center_hz() + reach_hz,
        criteria,
    );
    let mut diagram = Vec::new();
    for (poles, class) in by_order.iter().zip(&classes) {
        for (p, k) in poles.iter().zip(class) {
            if p.f_hz >= sub.lo_hz && p.f_hz < sub.hi_hz {
                diagram.push(DiagramPole {
                    order: p.order,
                    f_hz: p.f_hz,
                    damping_ratio: p.damping_ratio,
                    class: *k,
                });
            }
        }
    }
    let (modes, candidates) = select_modes(&by_order, &classes, criteria);
    let fitter = Fitter {
        band,
        compressed: compressed.as_ref(),
        criteria,
        noise_mpc: criteria.noise_mpc(band.data.nrows()),
    };
    let mut model = fitter.settle(modes);
    // Candidates inside the band, most persistent first, each kept when the refitted model
    // stays valid and the new mode stands clear of the noise.
    let mut candidates: Vec<Cluster> = candidates
        .into_iter()
        .filter(|c| {
            let f = c.median(|p| p.f_hz);
            f >= sub.lo_hz && f < sub.hi_hz
        })
        .collect();
    candidates.sort_by_key(|c| std::cmp::Reverse(c.poles.len()));
    for cand in candidates.into_iter().take(MAX_CANDIDATES) {
        if !fitter.worth_refining(&model, &cand) {
            continue;
        }
        let mut clusters = model.clusters.clone();
        clusters.push(cand);
        let trial = fitter.fit(clusters);
        if fitter.valid(&trial).iter().all(|v| *v) && fitter.candidate_holds(&trial) {
            model = trial;
        }
    }
    let in_band: Vec<usize> = (0..model.modes.len())
        .filter(|&i| {
            let f = model.modes[i].frequency_hz;
            f >= sub.lo_hz && f < sub.hi_hz
        })
        .collect();
    let spread = if in_band.is_empty() {
        Vec::new()
    } else {
        fitter.sensor_jackknife(&model, settings.compressed_channels)
    };
    let modes = in_band
        .into_iter()
        .map(|i| {
            let mut m = model.modes[i].clone();
            if let Some(&(f_std, d_std)) = spread.get(i) {
                m.frequency_sensor_std_hz = f_std;
                m.damping_sensor_std = d_std;
            }
            m.frequency_std_hz = m.frequency_order_std_hz.hypot(m.frequency_sensor_std_hz);
            m.damping_std = m.damping_order_std.hypot(m.damping_sensor_std);
            m
        })
        .collect();
    Ok((modes, diagram))
}

/// Clusters and their refined modes, aligned.
struct Model {
    clusters: Vec<Cluster>,
    /// The refined poles (decimated z-plane).
    z: Vec<c64>,
    modes: Vec<Mode>,
    /// Whether the residue fit succeeded (without it no shape can be judged).
    has_shapes: bool,
}

/// Fits and judges models of one band.
struct Fitter<'a> {
    band: &'a Baseband,
    compressed: faer::MatRef<'a, c64>,
    criteria: &'a StabilityCriteria,
    noise_mpc: f64,
}

impl Fitter<'_> {
    /// Refines the clusters' poles together and fits the residues on every channel.
    fn fit(&self, clusters: Vec<Cluster>) -> Model {
        let z0: Vec<c64> = clusters.iter().map(|c| c.representative().z).collect();
        let z = refine::refine_poles(self.compressed, &z0);
        let fit = shapes::fit_residues(self.band.data.as_ref(), &z);
        let modes = clusters
            .iter()
            .enumerate()
            .map(|(r, cl)| mode_of(self.band, cl, z[r], fit.as_ref(), r))
            .collect();
        Model {
            clusters,
            z,
            modes,
            has_shapes: fit.is_some(),
        }
    }

    /// Which modes of `model` are modes: a physical damping ratio, a shape more collinear than
    /// noise, more energy than a pole fitted to noise, and not the same pole as a more persistent mode (refinement can pull two
    /// clusters onto one pole).
    fn valid(&self, model: &Model) -> Vec<bool> {
        let c = self.criteria;
        let modes = &model.modes;
        (0..modes.len())
            .map(|i| {
                let m = &modes[i];
                let duplicate = (0..modes.len()).any(|j| {
                    j != i
                        && (modes[j].frequency_hz - m.frequency_hz).abs()
                            <= DUPLICATE_FREQUENCY_FRACTION * c.frequency_rel * m.frequency_hz
                        && (!model.has_shapes || mac(&modes[j].shape, &m.shape) >= c.mac_min)
                        && (model.clusters[j].poles.len(), j) > (model.clusters[i].poles.len(), i)
                });
                m.damping_ratio > 0.0
                    && m.damping_ratio < c.damping_max
                    && (!model.has_shapes
                        || (m.mpc >= self.noise_mpc && m.modal_snr_db >= MODE_MIN_SNR_DB))
                    && !duplicate
            })
            .collect()
    }

    /// A cheap screen before a candidate is refined: with every pole held where it is, the
    /// candidate's residues must already look like a mode (shape above the noise MPC, modal
    /// SNR above [`CANDIDATE_MIN_SNR_DB`]). Noise candidates, the great majority, stop here.
    fn worth_refining(&self, model: &Model, cand: &Cluster) -> bool {
        let mut z = model.z.clone();
        z.push(cand.representative().z);
        let Some(fit) = shapes::fit_residues(self.band.data.as_ref(), &z) else {
            return false;
        };
        let r = z.len() - 1;
        let shape: Vec<c64> = (0..fit.residues.ncols())
            .map(|c| fit.residues[(r, c)])
            .collect();
        shapes::mpc(&shape) >= self.noise_mpc && fit.modal_snr_db[r] >= CANDIDATE_MIN_SNR_DB
    }

    /// Whether the candidate just added (the last mode of `trial`) is a mode of its own: it
    /// stands clear of the noise, it stayed where the diagram saw it (refinement did not pull
    /// it onto another mode's residual or far away), and its shape is not a neighbour's.
    fn candidate_holds(&self, trial: &Model) -> bool {
        let (Some(new), Some(cl)) = (trial.modes.last(), trial.clusters.last()) else {
            return false;
        };
        let (f_seen, d_seen) = (cl.median(|p| p.f_hz), cl.median(|p| p.damping_ratio));
        let others = &trial.modes[..trial.modes.len() - 1];
        new.modal_snr_db >= CANDIDATE_MIN_SNR_DB
            && (new.frequency_hz - f_seen).abs() <= self.criteria.frequency_rel * f_seen
            && (new.damping_ratio - d_seen).abs() <= CANDIDATE_DAMPING_REL * d_seen
            && others
                .iter()
                .all(|m| mac(&m.shape, &new.shape) < CANDIDATE_MAX_MAC)
    }

    /// Delete-a-group jackknife over sensor groups: the model's poles refitted with every
    /// [`JACKKNIFE_GROUPS`]-th channel left out in turn; the spread of f and D over the refits,
    /// scaled by (G − 1)/G, estimates what the noise at the sensors does to each mode (per mode
    /// of `model`, Hz and damping ratio; 0 with fewer than two channels).
    fn sensor_jackknife(&self, model: &Model, compressed_channels: usize) -> Vec<(f64, f64)> {
        let channels = self.band.data.nrows();
        let groups = JACKKNIFE_GROUPS.min(channels);
        if groups < 2 || model.z.is_empty() {
            return vec![(0.0, 0.0); model.z.len()];
        }
        let mut estimates: Vec<Vec<(f64, f64)>> = Vec::with_capacity(groups);
        for g in 0..groups {
            let kept: Vec<usize> = (0..channels).filter(|c| c % groups != g).collect();
            let data = faer::Mat::<c64>::from_fn(kept.len(), self.band.data.ncols(), |r, t| {
                self.band.data[(kept[r], t)]
            });
            let Some(y) = compress(data.as_ref(), compressed_channels) else {
                continue;
            };
            let z = refine::refine_poles(y.as_ref(), &model.z);
            estimates.push(
                z.iter()
                    .map(|&p| self.band.frequency_and_damping(p))
                    .collect(),
            );
        }
        let n = estimates.len() as f64;
        (0..model.z.len())
            .map(|r| {
                if estimates.len() < 2 {
                    return (0.0, 0.0);
                }
                let spread = |pick: fn(&(f64, f64)) -> f64| {
                    let mean = estimates.iter().map(|e| pick(&e[r])).sum::<f64>() / n;
                    let ss: f64 = estimates.iter().map(|e| (pick(&e[r]) - mean).powi(2)).sum();
                    ((n - 1.0) / n * ss).sqrt()
                };
                (spread(|e| e.0), spread(|e| e.1))
            })
            .collect()
    }

    /// Drops, before any refinement, the clusters whose unrefined poles carry less energy than
    /// [`MODE_MIN_SNR_DB`] on all channels (weakest first, residues refitted after each; one
    /// least-squares solve per step). A noise-free record's deterministic residual gives many
    /// such stable clusters, and every one of them would cost a refinement.
    fn screen(&self, mut clusters: Vec<Cluster>) -> Vec<Cluster> {
        while !clusters.is_empty() {
            let z: Vec<c64> = clusters.iter().map(|c| c.representative().z).collect();
            let Some(fit) = shapes::fit_residues(self.band.data.as_ref(), &z) else {
                break;
            };
            let weakest = (0..z.len())
                .min_by(|&a, &b| fit.modal_snr_db[a].total_cmp(&fit.modal_snr_db[b]))
                .expect("clusters are not empty");
            if fit.modal_snr_db[weakest] >= MODE_MIN_SNR_DB {
                break;
            }
            clusters.remove(weakest);
        }
        clusters
    }

    /// Fits `clusters`, drops what is no mode, refits, until every mode is valid.
    fn settle(&self, clusters: Vec<Cluster>) -> Model {
        let mut clusters = self.screen(clusters);
        for _ in 0..MAX_REFITS {
            let model = self.fit(clusters);
            let valid = self.valid(&model);
            if valid.iter().all(|v| *v) {
                return model;
            }
            // One bad pole can spoil its neighbours' fit: drop only the least persistent
            // invalid one and refit.
            let worst = (0..valid.len())
                .filter(|&i| !valid[i])
                .min_by_key(|&i| model.clusters[i].poles.len())
                .expect("some mode is invalid");
            clusters = model.clusters;
            clusters.remove(worst);
        }
        self.fit(Vec::new())
    }
}

/// The mode of cluster `cl` at the refined pole `z` (row `r` of the residue fit).
fn mode_of(
    band: &Baseband,
    cl: &Cluster,
    z: c64,
    fit: Option<&shapes::ResidueFit>,
    r: usize,
) -> Mode {
    let (frequency_hz, damping_ratio) = band.frequency_and_damping(z);
    let shape = fit
        .map(|f| {
            let a = &f.residues;
            shapes::normalised(&(0..a.ncols()).map(|c| a[(r, c)]).collect::<Vec<_>>())
        })
        .unwrap_or_default();
    let (f_order, d_order) = (cl.std(|p| p.f_hz), cl.std(|p| p.damping_ratio));
    Mode {
        frequency_hz,
        damping_ratio,
        frequency_std_hz: f_order,
        damping_std: d_order,
        frequency_order_std_hz: f_order,
        damping_order_std: d_order,
        frequency_sensor_std_hz: 0.0,
        damping_sensor_std: 0.0,
        mpc: shapes::mpc(&shape),
        n_stable: cl.poles.len(),
        modal_snr_db: fit.map_or(f64::NAN, |f| f.modal_snr_db[r]),
        shape,
    }
}
