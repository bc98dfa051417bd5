//! Results as universal files (UFF), the format modal test systems and their post-processors
//! read: FRFs as dataset 58 with the sensor nodes as dataset 2411 (`simulate --format uff`), mode
//! shapes as dataset 55 (`modal --out`). Node `k + 1` is sensor row `k`; the excitation, when
//! known, is the node after the sensors. Coordinates in metres, FRFs as accelerance
//! (m/s² per N), directions +Z. Files appear whole or not at all ([`super::atomic`]).

use std::io::Write;
use std::path::Path;

use rustfft::num_complex::Complex;

use crate::error::{Error, Result};
use crate::source::recording_set::{Excitation, Sensor};
use crate::uff::{
    write_function58, write_mode_shape55, write_nodes2411, Abscissa, AxisInfo, Function58,
    FunctionType, ModeShape55, Node, NodeDof, NodeValues, Ordinate,
};

/// UFF direction code of +Z.
const PLUS_Z: i64 = 3;
/// UFF specific data types of record 8/9: frequency, acceleration, excitation force.
const FREQUENCY: i64 = 18;
const ACCELERATION: i64 = 12;
const FORCE: i64 = 13;

/// The sensors (labels 1…n) and the excitation (label n + 1) as nodes.
fn nodes(sensors: &[Sensor], excitation: Option<&Excitation>) -> Vec<Node> {
    let mut nodes: Vec<Node> = sensors
        .iter()
        .enumerate()
        .map(|(k, s)| Node::new(k as i64 + 1, [s.x_m, s.y_m, s.z_m.unwrap_or(0.0)]))
        .collect();
    if let Some(e) = excitation {
        nodes.push(Node::new(sensors.len() as i64 + 1, [e.x_m, e.y_m, 0.0]));
    }
    nodes
}

/// Writes FRFs (accelerance, m/s² per N, one per sensor, on the grid 0, df, …) with the sensor
/// and excitation nodes to `path`. ID line 1 of each function names its sensor id.
pub fn write_frf_uff(
    path: &Path,
    df_hz: f64,
    frfs: &[Vec<Complex<f64>>],
    sensors: &[Sensor],
    excitation: Option<&Excitation>,
) -> Result<()> {
    super::atomic::write_file(path, |w| {
        write_frf_datasets(w, df_hz, frfs, sensors, excitation)
            .map_err(|e| std::io::Error::other(format!("{}: {e}", path.display())))
    })
    .map_err(|e| Error::Output(e.to_string()))
}

/// [`write_frf_uff`] to any writer (a recording set's `responses.uff`).
pub fn write_frf_datasets(
    w: &mut dyn Write,
    df_hz: f64,
    frfs: &[Vec<Complex<f64>>],
    sensors: &[Sensor],
    excitation: Option<&Excitation>,
) -> std::io::Result<()> {
    if frfs.len() != sensors.len() {
        return Err(std::io::Error::other(format!(
            "expected one FRF per sensor ({}), got {}",
            sensors.len(),
            frfs.len()
        )));
    }
    let err = |e: crate::uff::UffError| std::io::Error::other(e.to_string());
    let reference = NodeDof::new(sensors.len() as i64 + 1, PLUS_Z);
    let mut w = w;
    write_nodes2411(&mut w, &nodes(sensors, excitation)).map_err(err)?;
    for (k, (h, s)) in frfs.iter().zip(sensors).enumerate() {
        let mut f = Function58::new(
            FunctionType::FrequencyResponse,
            NodeDof::new(k as i64 + 1, PLUS_Z),
            reference.clone(),
            Abscissa::Even {
                start: 0.0,
                increment: df_hz,
            },
            Ordinate::Complex(h.clone()),
        );
        f.id_lines[0] = format!("dampscope accelerance sensor {}", s.id);
        f.id_lines[1] = "simulated: dampscope finite-element plate".into();
        f.function_id = k as i64 + 1;
        f.abscissa_axis = AxisInfo::new(FREQUENCY, "Frequency", "Hz");
        f.ordinate_axis = AxisInfo::new(ACCELERATION, "Acceleration", "m/s^2");
        f.denominator_axis = AxisInfo::new(FORCE, "Force", "N");
        write_function58(&mut w, &f).map_err(err)?;
    }
    w.flush()
}

/// One identified mode for [`write_mode_shapes_uff`]: frequency, damping ratio and the complex
/// shape value per sensor (+Z).
#[derive(Clone, Debug, PartialEq)]
pub struct ModeShapeRecord {
    /// Damped natural frequency, Hz.
    pub frequency_hz: f64,
    /// Damping ratio (fraction).
    pub damping_ratio: f64,
    /// Shape value at each sensor, in sensor order.
    pub shape: Vec<Complex<f64>>,
}

/// Writes the sensor nodes (2411) and one complex-eigenvalue dataset 55 per mode to `path`.
pub fn write_mode_shapes_uff(
    path: &Path,
    modes: &[ModeShapeRecord],
    sensors: &[Sensor],
) -> Result<()> {
    super::atomic::write_file(path, |w| {
        let err =
            |e: crate::uff::UffError| std::io::Error::other(format!("{}: {e}", path.display()));
        write_nodes2411(w, &nodes(sensors, None)).map_err(err)?;
        for (m, mode) in modes.iter().enumerate() {
            let values: Vec<NodeValues> = mode
                .shape
                .iter()
                .enumerate()
                .map(|(k, v)| NodeValues {
                    node: k as i64 + 1,
                    values: vec![Complex::new(0.0, 0.0), Complex::new(0.0, 0.0), *v],
                })
                .collect();
            let shape = ModeShape55::complex_mode(
                m as i64 + 1,
                mode.frequency_hz,
                mode.damping_ratio,
                values,
            );
            write_mode_shape55(w, &shape).map_err(err)?;
        }
        w.flush()
    })
    .map_err(|e| Error::Output(e.to_string()))
}
