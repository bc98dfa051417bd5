//! FRFs, time responses and sensor positions from a universal file: the bridge from
//! [`super`]'s datasets to `crate::source::frf` (re-exported there).

use std::collections::HashMap;
use std::path::Path;

use super::{direction_label, Abscissa, AxisInfo, Function58, FunctionType, Ordinate, UffContents};
use crate::source::frf::{declared_tau, malformed, FrfChannel, FrfSet, ImpulseSet};
use crate::source::Sensor;
use crate::Result;

/// What a universal file holds for dampscope: FRFs (function type 4) and/or time responses
/// (type 1, used directly as impulse responses), and sensor positions of their response nodes.
#[derive(Clone, Debug, PartialEq)]
pub struct UffMeasurement {
    /// The FRFs, if the file holds any.
    pub frf: Option<FrfSet>,
    /// The time responses as impulse responses, if the file holds any.
    pub impulses: Option<ImpulseSet>,
    /// One sensor per channel whose response node has coordinates (dataset 15/2411), in metres.
    pub sensors: Vec<Sensor>,
    /// What was assumed (units, ids) and skipped.
    pub notes: Vec<String>,
}

/// Reads a universal file from disk; see [`measurement_from_uff`].
pub fn read_frf_uff(path: &Path) -> Result<UffMeasurement> {
    let what = path.display().to_string();
    let contents = super::read_uff(path).map_err(|e| malformed(&what, "uff", e.to_string()))?;
    measurement_from_uff(&contents, &what)
}

/// Channel ids: the node number when every response has the same direction, else
/// `{node}{dir}` (`12+Z`); `…:{ref node}{ref dir}` appended when responses repeat over
/// references.
fn channel_ids(f: &[&Function58]) -> Vec<String> {
    let same_dir = f
        .iter()
        .all(|g| g.response.direction == f[0].response.direction);
    let ids: Vec<String> = f
        .iter()
        .map(|g| {
            if same_dir {
                g.response.node.to_string()
            } else {
                format!(
                    "{}{}",
                    g.response.node,
                    direction_label(g.response.direction)
                )
            }
        })
        .collect();
    let unique = ids.iter().collect::<std::collections::HashSet<_>>().len() == ids.len();
    if unique {
        return ids;
    }
    ids.iter()
        .zip(f)
        .map(|(id, g)| {
            format!(
                "{id}:{}{}",
                g.reference.node,
                direction_label(g.reference.direction)
            )
        })
        .collect()
}

fn quantity(a: &AxisInfo) -> Option<String> {
    let by_type = match a.specific_data_type {
        8 => Some("displacement"),
        11 => Some("velocity"),
        12 => Some("acceleration"),
        13 => Some("force"),
        _ => None,
    };
    let label = (!a.label.is_empty() && a.label != "NONE").then(|| a.label.to_lowercase());
    label.or(by_type.map(str::to_string))
}

/// The window τ the functions' ID lines declare (`exponential_window_tau_s=τ`), if any; two
/// different values are an error.
fn declared_window(contents: &UffContents, what: &str) -> Result<Option<f64>> {
    let mut tau: Option<f64> = None;
    for (k, f) in contents.functions().enumerate() {
        for line in &f.id_lines {
            let detail = match declared_tau(line) {
                None => continue,
                Some(Ok(t)) if tau.is_none_or(|u| u == t) => {
                    tau = Some(t);
                    continue;
                }
                Some(Ok(t)) => {
                    format!("declares exponential_window_tau_s = {t} s, another {tau:?} s")
                }
                Some(Err(bad)) => {
                    format!(
                        "ID line {line:?}: expected exponential_window_tau_s=τ > 0, got {bad:?}"
                    )
                }
            };
            return Err(malformed(
                what,
                "uff",
                format!("function {}: {detail}", k + 1),
            ));
        }
    }
    Ok(tau)
}

/// The common even abscissa (start, increment, points) of a group of functions, or an error
/// naming the first that differs.
fn common_grid(group: &[&Function58], kind: &str, what: &str) -> Result<(f64, f64, usize)> {
    let name = |k: usize| format!("{kind} {} ({})", k + 1, group[k].id_lines[0]);
    let (start0, inc0) = match group[0].abscissa {
        Abscissa::Even { start, increment } => (start, increment),
        Abscissa::Uneven(_) => {
            let detail = "expected an even abscissa, found uneven spacing (resample it first)";
            return Err(malformed(what, "uff", format!("{}: {detail}", name(0))));
        }
    };
    let n0 = group[0].ordinate.len();
    let near = |a: f64, b: f64| (a - b).abs() <= 1e-9 * inc0.abs();
    for (k, g) in group.iter().enumerate() {
        let same = match g.abscissa {
            Abscissa::Even { start, increment } => near(start, start0) && near(increment, inc0),
            Abscissa::Uneven(_) => false,
        };
        if !same || g.ordinate.len() != n0 {
            let detail = format!(
                "expected the abscissa of the first ({n0} points from {start0} by {inc0}), \
                 found {:?} with {} points",
                g.abscissa,
                g.ordinate.len()
            );
            return Err(malformed(what, "uff", format!("{}: {detail}", name(k))));
        }
    }
    Ok((start0, inc0, n0))
}

/// FRFs, time responses and sensors from a parsed universal file (`what` names it in errors).
/// All FRFs must share one even abscissa (and all time responses one), or it is an error naming
/// the function. A window the test system applied is read from an ID line holding
/// `exponential_window_tau_s=τ` (dampscope's convention; the UFF has no field for it).
/// Coordinates are taken in the file's length unit divided by dataset 164's length factor, and
/// as metres when there is no 164.
pub fn measurement_from_uff(contents: &UffContents, what: &str) -> Result<UffMeasurement> {
    let mut notes = Vec::new();
    let tau = declared_window(contents, what)?;
    let pick = |t: FunctionType| {
        contents
            .functions()
            .filter(|f| f.function_type == t)
            .collect::<Vec<_>>()
    };
    let (frfs, times) = (
        pick(FunctionType::FrequencyResponse),
        pick(FunctionType::TimeResponse),
    );
    let others = contents.functions().count() - frfs.len() - times.len();
    if others > 0 {
        notes.push(format!(
            "{others} functions of other types (spectra, coherence, …) skipped"
        ));
    }
    if frfs.is_empty() && times.is_empty() {
        return Err(malformed(
            what,
            "uff",
            "expected dataset 58 functions of type 4 (FRF) or 1 (time response), found none".into(),
        ));
    }
    let grid = |group: &[&Function58], kind: &str| common_grid(group, kind, what);
    let mut ids_all = Vec::new();
    let frf = if frfs.is_empty() {
        None
    } else {
        let (start, inc, n) = grid(&frfs, "FRF")?;
        let ids = channel_ids(&frfs);
        ids_all.extend(
            ids.iter()
                .cloned()
                .zip(frfs.iter().map(|f| (f.response.node, f.response.direction))),
        );
        let channels = frfs
            .iter()
            .zip(ids)
            .map(|(f, id)| {
                let units = [
                    &f.ordinate_axis.units_label,
                    &f.denominator_axis.units_label,
                ];
                let named = |s: &&String| !s.is_empty() && s.as_str() != "NONE";
                FrfChannel {
                    values: f.ordinate.to_complex(),
                    response_node: Some(f.response.node),
                    response_dir: Some(f.response.direction),
                    reference_node: Some(f.reference.node),
                    reference_dir: Some(f.reference.direction),
                    quantity: quantity(&f.ordinate_axis),
                    unit: named(&units[0]).then(|| {
                        if named(&units[1]) {
                            format!("{}/{}", units[0], units[1])
                        } else {
                            units[0].clone()
                        }
                    }),
                    id,
                }
            })
            .collect();
        Some(FrfSet {
            freq_hz: (0..n).map(|k| start + k as f64 * inc).collect(),
            channels,
            exponential_window_tau_s: tau,
        })
    };
    let impulses = if times.is_empty() {
        None
    } else {
        let (_, dt, _) = grid(&times, "time response")?;
        if dt <= 0.0 {
            return Err(malformed(
                what,
                "uff",
                format!("time response 1: expected an abscissa increment > 0 s, found {dt}"),
            ));
        }
        // The abscissa has 6-7 digits (E13.5): a rate within them of a whole number of Hz is that.
        let raw = 1.0 / dt;
        let fs = if (raw - raw.round()).abs() <= 5e-6 * raw {
            raw.round()
        } else {
            raw
        };
        let ids = channel_ids(&times);
        ids_all.extend(
            ids.iter().cloned().zip(
                times
                    .iter()
                    .map(|f| (f.response.node, f.response.direction)),
            ),
        );
        let mut channels = Vec::new();
        for (k, f) in times.iter().enumerate() {
            match &f.ordinate {
                Ordinate::Real(v) => channels.push(v.clone()),
                Ordinate::Complex(_) => {
                    return Err(malformed(
                        what,
                        "uff",
                        format!(
                            "time response {}: expected real values, found complex",
                            k + 1
                        ),
                    ))
                }
            }
        }
        Some(ImpulseSet {
            sample_rate_hz: fs,
            names: ids,
            channels,
            exponential_window_tau_s: tau,
            notes: vec![format!(
                "time responses used as impulse responses, fs = 1/Δt = {fs} Hz"
            )],
        })
    };
    let scale = contents.units().map(|u| {
        (
            u.length_factor,
            format!(
                "dataset 164 (units code {}, length ÷ {})",
                u.code, u.length_factor
            ),
        )
    });
    let (factor, source) = scale.unwrap_or((
        1.0,
        "no dataset 164: coordinates taken as metres".to_string(),
    ));
    let positions: HashMap<i64, [f64; 3]> = contents.nodes().map(|n| (n.label, n.xyz)).collect();
    let mut sensors = Vec::new();
    for (id, (node, dir)) in ids_all {
        if let Some(p) = positions.get(&node) {
            let d = direction_label(dir).to_lowercase();
            sensors.push(Sensor {
                id,
                x_m: p[0] / factor,
                y_m: p[1] / factor,
                z_m: Some(p[2] / factor),
                dir: d.strip_prefix('+').unwrap_or(&d).to_string(),
            });
        }
    }
    if !sensors.is_empty() {
        notes.push(format!("sensor positions from node coordinates; {source}"));
    }
    Ok(UffMeasurement {
        frf,
        impulses,
        sensors,
        notes,
    })
}
