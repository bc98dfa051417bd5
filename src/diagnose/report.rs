//! The diagnosis as FORMATS.md §5 writes it (`diagnosis.json`: findings, fit before and after)
//! and in plain words: what is missing, where, how much, and why a local damping map alone
//! would not have shown it.

use std::collections::BTreeMap;
use std::fmt::Write as _;

use super::evidence::Evidence;
use super::fit::FitBeforeAfter;
use super::hypothesis::Hypothesis;
use super::regions::Region;
use crate::modal::Mode;
use crate::sim::model::Model;

/// A point on the plate, m.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Point {
    /// m.
    pub x: f64,
    /// m.
    pub y: f64,
}

/// Where an image of a finding would sit.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Image {
    /// For region kinds.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub region: Option<Region>,
    /// For point kinds.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub point: Option<Point>,
    /// For another size of a region (one the evidence could not tell from the finding's):
    /// its parameters, as the finding's. Empty (not written) for a mirror image, whose size
    /// is the finding's.
    #[serde(skip_serializing_if = "BTreeMap::is_empty")]
    pub parameters: BTreeMap<String, f64>,
}

/// The next-best explanation of the same evidence.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct RunnerUp {
    /// Its kind.
    pub kind: String,
    /// How much worse its BIC is (≥ 0; above 10 is decisive).
    pub delta_bic: f64,
}

/// One piece of missing physics (FORMATS.md §5).
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Finding {
    /// `localized_damping`, `viscoelastic_damping`, `added_mass`, `boundary_compliance`,
    /// `stiffness_change`, `damping_law` or `noise_floor`.
    pub kind: String,
    /// What, where and how much, in plain words.
    pub summary: String,
    /// The region, for region kinds.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub region: Option<Region>,
    /// The point, for point kinds.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub point: Option<Point>,
    /// The edge, for `boundary_compliance`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub edge: Option<String>,
    /// The law, for `damping_law` (`"rayleigh"` or `"structural"`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub law: Option<String>,
    /// The median channel's SNR on mean signal power, dB, for `noise_floor`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub snr_db: Option<f64>,
    /// Per channel SNR, dB (`null`: not measurable), for `noise_floor`.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub channel_snr_db: Vec<Option<f64>>,
    /// Other places the evidence cannot tell from this one (the plate's mirror images).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub images: Vec<Image>,
    /// Fitted parameters by name (`loss_factor`, `mass_kg`, `alpha`, `beta`, …).
    pub parameters: BTreeMap<String, f64>,
    /// Posterior probability of this explanation among "no change" and every family's best,
    /// from their BICs (e^(−BIC/2) weights).
    pub confidence: f64,
    /// BIC of "no change" minus this finding's.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub bic_gain: Option<f64>,
    /// The best explanation of another kind.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub runner_up: Option<RunnerUp>,
}

/// Whether `image` is a region of another width or height than `h`'s (not a mirror image).
fn other_size(h: &Hypothesis, image: &Hypothesis) -> bool {
    match (h.region(), image.region()) {
        (Some(a), Some(b)) => {
            let dims = |r: &Region| (r.x[1] - r.x[0], r.y[1] - r.y[0]);
            let (p, q) = (dims(&a), dims(&b));
            (p.0 - q.0).abs() > 1e-9 || (p.1 - q.1).abs() > 1e-9
        }
        _ => false,
    }
}

impl Finding {
    /// The finding for a hypothesis of the model `model` (the model before it), with its
    /// unsettled images.
    pub fn of(h: &Hypothesis, images: &[Hypothesis], model: &Model) -> Finding {
        let mut f = Finding {
            kind: h.kind().into(),
            summary: String::new(),
            region: h.region(),
            point: None,
            edge: None,
            law: None,
            snr_db: None,
            channel_snr_db: Vec::new(),
            images: images
                .iter()
                .map(|i| Image {
                    region: i.region(),
                    point: match i {
                        Hypothesis::AddedMass { x_m, y_m, .. } => Some(Point { x: *x_m, y: *y_m }),
                        _ => None,
                    },
                    parameters: if other_size(h, i) {
                        Finding::of(i, &[], model).parameters
                    } else {
                        BTreeMap::new()
                    },
                })
                .collect(),
            parameters: BTreeMap::new(),
            confidence: 0.0,
            bic_gain: None,
            runner_up: None,
        };
        let mat = &model.material;
        let g0 = mat.loss_factor;
        let at = |r: &Region| {
            format!(
                "x {:.2}–{:.2} m, y {:.2}–{:.2} m",
                r.x[0], r.x[1], r.y[0], r.y[1]
            )
        };
        let p = &mut f.parameters;
        f.summary = match h {
            Hypothesis::AddedMass { x_m, y_m, mass_kg } => {
                f.point = Some(Point { x: *x_m, y: *y_m });
                p.insert("mass_kg".into(), *mass_kg);
                format!(
                    "A mass of {mass_kg:.2} kg that the model lacks sits near ({x_m:.2}, \
                     {y_m:.2}) m: it lowers the modes with an antinode there and leaves those \
                     with a nodal line through it."
                )
            }
            Hypothesis::StiffnessChange {
                region,
                youngs_factor,
            } => {
                p.insert("youngs_modulus".into(), mat.youngs_modulus * youngs_factor);
                p.insert("youngs_factor".into(), *youngs_factor);
                format!(
                    "The region {} is {} than modelled: Young's modulus {:.3e} Pa ({:+.0} %), \
                     or the thickness {:+.1} %. The modes that bend it there move ({}), the others \
                     hardly; the damping is unchanged.",
                    at(region),
                    if *youngs_factor > 1.0 {
                        "stiffer"
                    } else {
                        "softer"
                    },
                    mat.youngs_modulus * youngs_factor,
                    100.0 * (youngs_factor - 1.0),
                    100.0 * (youngs_factor.cbrt() - 1.0),
                    if *youngs_factor > 1.0 { "up" } else { "down" },
                )
            }
            Hypothesis::BoundaryCompliance {
                edge,
                stiffness_per_length,
                was_pinned,
            } => {
                f.edge = Some(edge.name().into());
                p.insert("stiffness_per_length".into(), *stiffness_per_length);
                if *was_pinned {
                    format!(
                        "The edge {} is not pinned but held elastically, {:.3e} N/m per metre: \
                         the modes that move it are lower than modelled, and their damping too \
                         (the support stores energy without losing it).",
                        edge.name(),
                        stiffness_per_length
                    )
                } else {
                    format!(
                        "The free edge {} is held by a support of {:.3e} N/m per metre that the \
                         model lacks: the modes that move it are higher than modelled.",
                        edge.name(),
                        stiffness_per_length
                    )
                }
            }
            Hypothesis::LocalizedDamping { region, delta_g } => {
                p.insert("loss_factor".into(), g0 + delta_g);
                p.insert("delta_g".into(), *delta_g);
                format!(
                    "The region {} dissipates more than modelled: loss factor {:.3} instead of \
                     {g0:.3}. Each mode's extra damping follows its share of strain energy there.",
                    at(region),
                    g0 + delta_g
                )
            }
            Hypothesis::ViscoelasticDamping {
                region,
                sls,
                peak_loss,
                peak_hz,
                density_factor,
            } => {
                p.insert("peak_loss_factor".into(), *peak_loss);
                p.insert("peak_frequency_hz".into(), *peak_hz);
                p.insert("sls_e".into(), sls.e);
                p.insert("sls_e_inf".into(), sls.e_inf);
                p.insert("sls_eta".into(), sls.eta);
                p.insert("density_factor".into(), *density_factor);
                format!(
                    "The region {} is viscoelastic: its loss factor peaks at {peak_loss:.3} near \
                     {peak_hz:.0} Hz and falls off on both sides (a standard linear solid), so \
                     the modes that strain it near that frequency gain the most damping{}.",
                    at(region),
                    if *density_factor > 1.0 {
                        format!(
                            "; it also adds mass ({:+.0} % density there, as a damping layer does)",
                            100.0 * (density_factor - 1.0)
                        )
                    } else {
                        String::new()
                    }
                )
            }
            Hypothesis::DampingLaw {
                loss_factor,
                alpha,
                beta,
            } => {
                p.insert("loss_factor".into(), *loss_factor);
                if *alpha > 0.0 || *beta > 0.0 {
                    f.law = Some("rayleigh".into());
                    p.insert("alpha".into(), *alpha);
                    p.insert("beta".into(), *beta);
                    format!(
                        "The damping follows another law than modelled: Rayleigh damping α = \
                         {alpha:.3} 1/s, β = {beta:.3e} s (damping ratio α/(2ω) + βω/2) with a \
                         loss factor {loss_factor:.4} instead of {g0:.4}."
                    )
                } else {
                    f.law = Some("structural".into());
                    format!(
                        "The whole plate's loss factor is {loss_factor:.4}, not {g0:.4}: every \
                         mode's damping differs alike."
                    )
                }
            }
        };
        f
    }

    /// The `noise_floor` finding for per-channel SNRs (median `median_db`).
    pub fn noise_floor(median_db: f64, channels: Vec<Option<f64>>) -> Finding {
        let min = channels
            .iter()
            .flatten()
            .copied()
            .fold(f64::INFINITY, f64::min);
        Finding {
            kind: "noise_floor".into(),
            summary: format!(
                "The recordings carry measurement noise {median_db:.1} dB below the mean signal \
                 power (median channel; worst {min:.1} dB). It limits how far each decay can be \
                 followed and is accounted for in every mode's uncertainty; it is not damping."
            ),
            region: None,
            point: None,
            edge: None,
            law: None,
            snr_db: Some(median_db),
            parameters: BTreeMap::from([
                ("snr_db".to_string(), median_db),
                ("snr_db_min".to_string(), min),
            ]),
            channel_snr_db: channels,
            images: Vec::new(),
            confidence: 1.0,
            bic_gain: None,
            runner_up: None,
        }
    }
}

/// Every family's best explanation in one round of the search, for the report.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct FamilyScore {
    /// Round (0: against the model as given).
    pub round: usize,
    /// The kind.
    pub kind: String,
    /// BIC of "no change" minus the family's best.
    pub bic_gain: f64,
}

/// Everything [`super::procedure::diagnose`] concludes.
#[derive(Clone, Debug)]
pub struct Diagnosis {
    /// The findings, strongest first (empty or only `noise_floor`: no missing physics).
    pub findings: Vec<Finding>,
    /// Fit before and after.
    pub fit: FitBeforeAfter,
    /// The model with every finding applied.
    pub updated_model: Model,
    /// The evidence against the model as given.
    pub evidence: Evidence,
    /// The evidence against the updated model.
    pub evidence_after: Evidence,
    /// The identified modes.
    pub modes: Vec<Mode>,
    /// Each family's best per round.
    pub families: Vec<FamilyScore>,
    /// FRF overlays at a few sensors (for the figures), when the FRF error was computed.
    pub frf: Option<super::fit::FrfOverlay>,
    /// The recordings' sensor positions (channel order).
    pub sensor_positions: Vec<crate::sim::model::SensorPosition>,
}

impl Diagnosis {
    /// Whether no missing physics was found (findings empty or only `noise_floor`).
    pub fn is_clean(&self) -> bool {
        self.findings.iter().all(|f| f.kind == "noise_floor")
    }

    /// The shape residual per sensor against the model as given: for each paired mode, both
    /// shapes normalised, the model's scaled by the best complex factor, the squared difference
    /// at the sensor; the square root of its mean over the pairs. Where a finding bends the
    /// modes (a mass, a soft edge) or makes them complex (a lossy region) the residual grows.
    pub fn shape_residual(&self) -> Vec<f64> {
        let n = self.modes.first().map_or(0, |m| m.shape.len());
        let mut acc = vec![0.0; n];
        let mut count = 0usize;
        for p in &self.evidence.pairs {
            let phi = &self.modes[p.measured].shape;
            let psi = &self.evidence.model[p.model].shape;
            if phi.len() != n || psi.len() != n {
                continue;
            }
            let nphi = phi.iter().map(|z| z.norm_sqr()).sum::<f64>().sqrt();
            let npsi = psi.iter().map(|v| v * v).sum::<f64>().sqrt();
            if nphi == 0.0 || npsi == 0.0 {
                continue;
            }
            let alpha = phi
                .iter()
                .zip(psi)
                .fold(faer::c64::new(0.0, 0.0), |a, (z, v)| a + z * (v / npsi))
                / nphi;
            for s in 0..n {
                acc[s] += (phi[s] / nphi - alpha * (psi[s] / npsi)).norm_sqr();
            }
            count += 1;
        }
        acc.iter()
            .map(|v| (v / count.max(1) as f64).sqrt())
            .collect()
    }

    /// The findings and the fit in a few lines.
    pub fn summary(&self) -> String {
        let mut out = String::new();
        let _ = writeln!(
            out,
            "{} modes identified, {} paired with the model (model form: frequencies {:+.2} % in the median, scatter {:.2} %)",
            self.modes.len(),
            self.evidence.pairs.len(),
            self.evidence
                .calibration
                .map_or(0.0, |c| 100.0 * c.log_frequency_ratio.exp_m1()),
            self.evidence
                .calibration
                .map_or(0.0, |c| 100.0 * c.frequency_sigma_rel),
        );
        let rejected = self.families.iter().find_map(|f| {
            let worse = "the model updated with it fits the recordings worse";
            let no_size = "refitted through the re-solved model, its size came to no change";
            (f.kind.strip_suffix(REJECTED_FITS_WORSE).map(|k| (k, worse)))
                .or_else(|| f.kind.strip_suffix(REJECTED_NO_SIZE).map(|k| (k, no_size)))
                .or_else(|| {
                    let why = "through the re-solved model it explains too little";
                    f.kind
                        .strip_suffix(REJECTED_NOT_BORNE_OUT)
                        .map(|k| (k, why))
                })
                .or_else(|| {
                    let why = "a kept finding's own kind, scanned again, explains as much (the \
                               kept finding a little off its place or size)";
                    f.kind
                        .strip_suffix(REJECTED_KEPT_KIND_EXPLAINS)
                        .map(|k| (k, why))
                })
        });
        match (self.is_clean(), rejected) {
            (true, None) => {
                let _ = writeln!(out, "verdict: no missing physics");
            }
            (true, Some((kind, why))) => {
                let _ = writeln!(
                    out,
                    "verdict: no missing physics that the model could be updated with: the best candidate, {kind}, was rejected because {why} (the mismatch below stays unexplained)"
                );
            }
            (false, Some((kind, why))) => {
                let _ = writeln!(
                    out,
                    "note: a further candidate, {kind}, was rejected: {why}"
                );
            }
            (false, None) => {}
        }
        for f in &self.findings {
            let _ = writeln!(
                out,
                "finding: {} (confidence {:.2}): {}",
                f.kind, f.confidence, f.summary
            );
        }
        let (b, a) = (self.fit.before, self.fit.after);
        let frf = match (b.frf_error, a.frf_error) {
            (Some(b), Some(a)) => format!(", FRF error {b:.3} → {a:.3}"),
            _ => String::new(),
        };
        let _ = writeln!(
            out,
            "fit: damping RMS {:.5} → {:.5}, frequency RMS {:.3} → {:.3} Hz (calibrated {:.3} → {:.3} Hz){frf}",
            b.damping_rms,
            a.damping_rms,
            b.frequency_rms_hz,
            a.frequency_rms_hz,
            b.frequency_rms_calibrated_hz,
            a.frequency_rms_calibrated_hz
        );
        out
    }
}

/// What a [`FamilyScore`]'s kind ends with when the round's best candidate was rejected because
/// the model updated with it fits the recordings worse.
pub const REJECTED_FITS_WORSE: &str = " (rejected: fits worse)";

/// What a [`FamilyScore`]'s kind ends with when the round's best candidate, refitted through the
/// re-solved model, came to no change at all (a mass of 0 kg, a loss of 0).
pub const REJECTED_NO_SIZE: &str = " (rejected: no size left)";

/// What a [`FamilyScore`]'s kind ends with when the round's best candidate, through the
/// re-solved model, no longer beats "no change" by [`super::procedure::MIN_BIC_GAIN`]; the
/// row's gain is then the re-solved one.
pub const REJECTED_NOT_BORNE_OUT: &str = " (rejected: not borne out once re-solved)";

/// What a [`FamilyScore`]'s kind ends with when the round's best candidate does not beat, by
/// [`super::procedure::MIN_BIC_GAIN`], what a kept finding's own kind scanned again explains of
/// the same residual (the kept finding a little off its place or size); the row's gain is what
/// the candidate adds on top of that.
pub const REJECTED_KEPT_KIND_EXPLAINS: &str =
    " (rejected: a kept finding's own kind, scanned again, explains it)";

/// Why a local damping map alone would not show a finding of this kind.
pub fn why_maps_miss(kind: &str) -> &'static str {
    match kind {
        "localized_damping" | "viscoelastic_damping" => {
            "A local damping map (D per sensor and band) does not show this region: each \
             sensor's decay in a band is dominated by the beating of close modes and by nodal \
             lines, which swing the local D by more than the patch changes it. The modes \
             identified from all sensors at once do show it, in the modes that strain the region."
        }
        "added_mass" | "stiffness_change" | "boundary_compliance" => {
            "A damping map would not show this at all: it moves the frequencies (and with them the \
             mode shapes), not the decay rates of a band — except a soft edge, which lowers the \
             damping of every mode alike and would read as a smaller loss factor."
        }
        "damping_law" => {
            "A damping map shows every band's D but cannot say whether the difference is the law \
             or a region; the modes' damping against their frequency, across the whole plate, can."
        }
        _ => "",
    }
}
