//! The plate model file (FORMATS.md §3): TOML → [`Model`], then validation of every value.
//!
//! Parsing rejects unknown keys (`deny_unknown_fields`); [`Model::validate`] rejects impossible
//! values with a [`SimError::InvalidValue`] naming the TOML key, e.g.
//! `plate.thickness: must be > 0, got -0.02`.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use super::error::{invalid, SimError};
pub use super::system::Sls;

/// A complete plate model: the nominal structure a user simulates.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Model {
    /// Plate geometry.
    pub plate: Plate,
    /// Structured hexahedral mesh.
    pub mesh: MeshSpec,
    /// Base material of the plate.
    pub material: Material,
    /// Pinned edges (none: a free plate).
    #[serde(default)]
    pub supports: Supports,
    /// The point load.
    pub excitation: Excitation,
    /// Frequency range, resolution and sensors.
    pub output: Output,
    /// Regions with other material properties (`[[patch]]`).
    #[serde(default, rename = "patch")]
    pub patches: Vec<Patch>,
    /// Lumped masses (`[[point_mass]]`).
    #[serde(default, rename = "point_mass")]
    pub point_masses: Vec<PointMass>,
    /// Elastic line supports in z (`[[edge_spring]]`).
    #[serde(default, rename = "edge_spring")]
    pub edge_springs: Vec<EdgeSpring>,
    /// Optional global viscous damping.
    #[serde(default)]
    pub damping: Option<Damping>,
    /// Directory of the model file, for relative paths such as `output.sensors.file`.
    #[serde(skip)]
    pub base_dir: Option<PathBuf>,
}

/// `[plate]`: a rectangular plate 0..lx × 0..ly, thickness centred on z = 0… thickness.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Plate {
    /// Length along x, m.
    pub lx: f64,
    /// Length along y, m.
    pub ly: f64,
    /// Thickness along z, m.
    pub thickness: f64,
}

/// `[mesh]`: number of 8-node hexahedra along x, y and through the thickness.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MeshSpec {
    /// Elements along x.
    pub nx: usize,
    /// Elements along y.
    pub ny: usize,
    /// Elements through the thickness.
    pub nz: usize,
}

/// `[material]`: isotropic linear-elastic material with structural damping.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Material {
    /// Young's modulus, Pa.
    pub youngs_modulus: f64,
    /// Poisson's ratio, dimensionless, in (-1, 0.5).
    pub poisson: f64,
    /// Density, kg/m³.
    pub density: f64,
    /// Structural loss factor g: K(1 + j g); critical damping ratio D = g/2.
    #[serde(default)]
    pub loss_factor: f64,
}

/// `[supports]`.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Supports {
    /// Names of pinned edges (`x0`, `x1`, `y0`, `y1`): the mid-plane line of each has
    /// ux = uy = uz = 0.
    #[serde(default)]
    pub pinned_edges: Vec<String>,
}

/// One plate edge.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Edge {
    /// The edge x = 0.
    X0,
    /// The edge x = lx.
    X1,
    /// The edge y = 0.
    Y0,
    /// The edge y = ly.
    Y1,
}

impl Edge {
    /// Parses `x0`, `x1`, `y0` or `y1`; `key` names the TOML key for the error.
    pub fn parse(name: &str, key: &str) -> Result<Edge, SimError> {
        match name {
            "x0" => Ok(Edge::X0),
            "x1" => Ok(Edge::X1),
            "y0" => Ok(Edge::Y0),
            "y1" => Ok(Edge::Y1),
            other => Err(invalid(
                key,
                format!("unknown edge {other:?}, expected one of x0, x1, y0, y1"),
            )),
        }
    }

    /// The TOML name of the edge.
    pub fn name(self) -> &'static str {
        match self {
            Edge::X0 => "x0",
            Edge::X1 => "x1",
            Edge::Y0 => "y0",
            Edge::Y1 => "y1",
        }
    }
}

/// `[excitation]`: a point force on the mid-plane.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Excitation {
    /// Position, m.
    pub x: f64,
    /// Position, m.
    pub y: f64,
    /// Direction: `x`, `y` or `z`.
    #[serde(default = "default_dir")]
    pub dir: String,
    /// Amplitude, N.
    #[serde(default = "default_force")]
    pub force: f64,
}

fn default_dir() -> String {
    "z".to_string()
}

fn default_force() -> f64 {
    1.0
}

/// `[output]`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Output {
    /// Highest frequency, Hz; the impulse responses' time step is 1/(2 fmax).
    pub fmax: f64,
    /// Frequency step, Hz; the impulse responses' length is 1/df.
    pub df: f64,
    /// Where the sensors are.
    pub sensors: SensorSpec,
}

/// `output.sensors`: a regular grid or a `sensors.csv` file (FORMATS.md §1).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(untagged, try_from = "SensorSpecKeys")]
pub enum SensorSpec {
    /// `{ nx, ny }`: nx × ny sensors spanning the plate edge to edge.
    Grid {
        /// Sensors along x.
        nx: usize,
        /// Sensors along y.
        ny: usize,
    },
    /// `{ file = "sensors.csv" }`: header `id,x,y`, relative to the model file.
    File {
        /// Path of the CSV file.
        file: PathBuf,
    },
}

/// `output.sensors` as written, before it is one of [`SensorSpec`]'s forms: the untagged enum
/// answered `{ nx = 3 }`, `{ nx = 3.0, ny = 3 }` or `{ files = "s.csv" }` with "data did not
/// match any variant", and took `{ nx, ny, file }` as a grid, ignoring the file.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct SensorSpecKeys {
    nx: Option<usize>,
    ny: Option<usize>,
    file: Option<PathBuf>,
}

impl TryFrom<SensorSpecKeys> for SensorSpec {
    type Error = String;

    fn try_from(k: SensorSpecKeys) -> Result<Self, String> {
        match (k.nx, k.ny, k.file) {
            (Some(nx), Some(ny), None) => Ok(SensorSpec::Grid { nx, ny }),
            (None, None, Some(file)) => Ok(SensorSpec::File { file }),
            (nx, ny, file) => Err(format!(
                "expected either {{ nx = N, ny = N }} (a grid, whole numbers) or {{ file = \"sensors.csv\" }}, got{}{}{}",
                nx.map_or(String::new(), |v| format!(" nx = {v}")),
                ny.map_or(String::new(), |v| format!(" ny = {v}")),
                file.map_or(String::new(), |f| format!(" file = {f:?}")),
            )),
        }
    }
}

/// One sensor position.
#[derive(Clone, Debug, PartialEq)]
pub struct SensorPosition {
    /// Sensor id (channel name).
    pub id: String,
    /// Position, m.
    pub x_m: f64,
    /// Position, m.
    pub y_m: f64,
}

/// `[[patch]]`: a rectangle x × y (through the whole thickness) with other properties.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Patch {
    /// `[x_min, x_max]`, m.
    pub x: [f64; 2],
    /// `[y_min, y_max]`, m.
    pub y: [f64; 2],
    /// Young's modulus, Pa (default: the plate's).
    pub youngs_modulus: Option<f64>,
    /// Poisson's ratio (default: the plate's).
    pub poisson: Option<f64>,
    /// Density, kg/m³ (default: the plate's).
    pub density: Option<f64>,
    /// Structural loss factor (default: the plate's).
    pub loss_factor: Option<f64>,
    /// Viscoelastic standard linear solid; the region is assembled with modulus `sls.e_inf`.
    pub sls: Option<Sls>,
}

/// `[[point_mass]]`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PointMass {
    /// Position, m.
    pub x: f64,
    /// Position, m.
    pub y: f64,
    /// Mass, kg.
    pub mass: f64,
}

/// `[[edge_spring]]`: distributed z springs along an edge's mid-plane line.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EdgeSpring {
    /// Edge name (`x0`, `x1`, `y0`, `y1`).
    pub edge: String,
    /// Stiffness per metre of edge, N/m².
    pub stiffness_per_length: f64,
}

/// `[damping]`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Damping {
    /// Rayleigh damping C = alpha M + beta K₀.
    pub rayleigh: Rayleigh,
}

/// Rayleigh coefficients.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Rayleigh {
    /// Mass-proportional coefficient, 1/s.
    pub alpha: f64,
    /// Stiffness-proportional coefficient, s.
    pub beta: f64,
}

/// The effective material of one region (plate or patch), patch overrides applied.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RegionMaterial {
    /// Modulus the stiffness is assembled with, Pa (`sls.e_inf` for an SLS region).
    pub youngs_modulus: f64,
    /// Poisson's ratio.
    pub poisson: f64,
    /// Density, kg/m³.
    pub density: f64,
    /// Structural loss factor.
    pub loss_factor: f64,
    /// Viscoelastic law, if any.
    pub sls: Option<Sls>,
}

/// The reference plate of the report (FORMATS.md §3), as TOML.
pub const REFERENCE_PLATE_TOML: &str = r#"
[plate]
lx = 2.0
ly = 3.0
thickness = 0.02

[mesh]
nx = 32
ny = 48
nz = 2

[material]
youngs_modulus = 7.0e10
poisson = 0.34
density = 2700.0
loss_factor = 0.05

[supports]
pinned_edges = ["y0", "y1"]

[excitation]
x = 0.0625
y = 0.0625
dir = "z"
force = 1.0

[output]
fmax = 2000.0
df = 0.25
sensors = { nx = 33, ny = 49 }
"#;

impl Model {
    /// The report's reference plate (2 × 3 × 0.02 m aluminium, 32 × 48 × 2 hexahedra, edges y0
    /// and y1 pinned), so that tests and `dampscope modes` need no file.
    pub fn reference_plate() -> Model {
        // The constant is part of the crate and is tested to parse and validate.
        Model::from_toml_str(REFERENCE_PLATE_TOML).expect("reference plate TOML is valid")
    }

    /// Parses and validates a model from TOML text (relative paths resolve against the
    /// current directory).
    pub fn from_toml_str(text: &str) -> Result<Model, SimError> {
        let model: Model = toml::from_str(text).map_err(|e| SimError::Toml(e.to_string()))?;
        model.validate()?;
        Ok(model)
    }

    /// The model in `path`, or the reference plate when none is given (what `simulate`,
    /// `modes` and `resynth` do without `--model`).
    pub fn load_or_reference(path: Option<&Path>) -> Result<Model, SimError> {
        path.map_or_else(|| Ok(Model::reference_plate()), Model::load)
    }

    /// Reads, parses and validates a model file; relative paths inside resolve against its
    /// directory.
    pub fn load(path: &Path) -> Result<Model, SimError> {
        let text = std::fs::read_to_string(path).map_err(|e| SimError::Io {
            path: path.to_path_buf(),
            message: e.to_string(),
        })?;
        let mut model: Model = toml::from_str(&text)
            .map_err(|e| SimError::Toml(format!("{}: {e}", path.display())))?;
        model.base_dir = path.parent().map(Path::to_path_buf);
        model.validate()?;
        Ok(model)
    }

    /// The plate's own material as a [`RegionMaterial`].
    pub fn material_of_plate(&self) -> RegionMaterial {
        let m = &self.material;
        RegionMaterial {
            youngs_modulus: m.youngs_modulus,
            poisson: m.poisson,
            density: m.density,
            loss_factor: m.loss_factor,
            sls: None,
        }
    }

    /// A patch's material: the plate's with the patch's overrides; an SLS patch's modulus is
    /// `sls.e_inf` (the relaxed modulus the stiffness is assembled with).
    pub fn material_of_patch(&self, p: &Patch) -> RegionMaterial {
        let base = self.material_of_plate();
        RegionMaterial {
            youngs_modulus: p
                .sls
                .map(|s| s.e_inf)
                .or(p.youngs_modulus)
                .unwrap_or(base.youngs_modulus),
            poisson: p.poisson.unwrap_or(base.poisson),
            density: p.density.unwrap_or(base.density),
            loss_factor: p.loss_factor.unwrap_or(base.loss_factor),
            sls: p.sls,
        }
    }

    /// The parsed pinned edges (validated, so no error is expected after [`Model::validate`]).
    pub fn pinned_edges(&self) -> Result<Vec<Edge>, SimError> {
        self.supports
            .pinned_edges
            .iter()
            .enumerate()
            .map(|(i, n)| Edge::parse(n, &format!("supports.pinned_edges[{i}]")))
            .collect()
    }

    /// The sensor positions: the grid (ids `x{ix}y{iy}`, spanning the plate edge to edge, x
    /// fastest) or the rows of the sensors file (checked to lie on the plate).
    pub fn sensor_positions(&self) -> Result<Vec<SensorPosition>, SimError> {
        match &self.output.sensors {
            SensorSpec::Grid { nx, ny } => {
                let coord = |i: usize, n: usize, len: f64| {
                    if n == 1 {
                        0.5 * len
                    } else {
                        len * i as f64 / (n - 1) as f64
                    }
                };
                let mut out = Vec::with_capacity(nx * ny);
                for iy in 0..*ny {
                    for ix in 0..*nx {
                        out.push(SensorPosition {
                            id: format!("x{ix}y{iy}"),
                            x_m: coord(ix, *nx, self.plate.lx),
                            y_m: coord(iy, *ny, self.plate.ly),
                        });
                    }
                }
                Ok(out)
            }
            SensorSpec::File { file } => {
                let path = match &self.base_dir {
                    Some(dir) if file.is_relative() => dir.join(file),
                    _ => file.clone(),
                };
                let sensors = read_sensors_csv(&path)?;
                for (i, s) in sensors.iter().enumerate() {
                    self.inside(
                        &format!("output.sensors.file row {} (id {})", i + 1, s.id),
                        s.x_m,
                        s.y_m,
                    )?;
                }
                Ok(sensors)
            }
        }
    }
}

/// Reads a `sensors.csv` (header `id,x,y`, optional further columns ignored).
fn read_sensors_csv(path: &Path) -> Result<Vec<SensorPosition>, SimError> {
    let key = "output.sensors.file";
    let mut rdr = csv::ReaderBuilder::new()
        .trim(csv::Trim::All)
        .from_path(path)
        .map_err(|e| invalid(key, format!("cannot read {}: {e}", path.display())))?;
    let headers = rdr
        .headers()
        .map_err(|e| invalid(key, format!("{}: {e}", path.display())))?
        .clone();
    let col = |name: &str| {
        headers.iter().position(|h| h == name).ok_or_else(|| {
            invalid(
                key,
                format!(
                    "{}: expected a column {name:?} in header id,x,y",
                    path.display()
                ),
            )
        })
    };
    let (ci, cx, cy) = (col("id")?, col("x")?, col("y")?);
    let mut out = Vec::new();
    for (row, rec) in rdr.records().enumerate() {
        let rec = rec.map_err(|e| invalid(key, format!("{}: {e}", path.display())))?;
        let field = |c: usize, name: &str| -> Result<f64, SimError> {
            let s = rec.get(c).unwrap_or("");
            s.parse::<f64>().map_err(|_| {
                invalid(
                    key,
                    format!(
                        "{} row {}: column {name} expected a number, got {s:?}",
                        path.display(),
                        row + 1
                    ),
                )
            })
        };
        out.push(SensorPosition {
            id: rec.get(ci).unwrap_or("").to_string(),
            x_m: field(cx, "x")?,
            y_m: field(cy, "y")?,
        });
    }
    if out.is_empty() {
        return Err(invalid(key, format!("{}: no sensor rows", path.display())));
    }
    Ok(out)
}
