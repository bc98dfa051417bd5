//! Universal File Format (UFF, "universal files", `.uff`/`.unv`): how modal test systems hand
//! over frequency response functions, mode shapes and node coordinates.
//!
//! A file is a sequence of datasets, each between two lines holding `-1` in columns 1–6; the
//! first line of a dataset holds its number in columns 1–6 (and `b` in column 7 for a binary
//! dataset, 58b). Records are Fortran fixed-width formats (see `fortran.rs`).
//!
//! | dataset | what | read | written |
//! |---|---|---|---|
//! | 58 / 58b | function at a nodal DOF (FRF, time response, …), ASCII or binary | yes | ASCII, double precision |
//! | 55 | data at nodes: mode shapes (normal mode, complex eigenvalue) | yes | yes |
//! | 15 | nodes, single precision (`4I10,1P3E13.5`) | yes | yes |
//! | 2411 | nodes, double precision (`4I10` then `1P3D25.16`) | yes | yes |
//! | 164 | units (length factor for node coordinates) | yes | no |
//!
//! Every other dataset is skipped (listed in [`UffContents::skipped`]). The layouts follow the
//! SDRC/UC-SDRL dataset descriptions (as quoted in pyuff's `datasets/dataset_*.py`). Errors name
//! the dataset, the line and what was expected against what was found; no input makes the reader
//! panic or allocate more than a small multiple of the input's size (a claimed point count is
//! checked against the bytes present first).
//!
//! Precision: the spec stores the abscissa (start, increment, or uneven values) in single
//! precision `E13.5` columns; the writer puts 7 significant digits there (6 for negative values). Ordinates written
//! by [`write_function58`] are double precision (`4E20.12`, 13 significant digits).

mod dataset55;
mod dataset58;
mod fortran;
pub mod import;
mod nodes;
mod reader;
mod write58;

pub use dataset55::{write_mode_shape55, ModeShape55, NodeValues, ShapeAnalysis};
pub use dataset58::{Abscissa, AxisInfo, Function58, FunctionType, NodeDof, Ordinate};
pub use nodes::{write_nodes15, write_nodes2411, Node, NodeFormat, NodeSet, Units164};
pub use reader::{parse_uff, read_uff};
pub use write58::write_function58;

/// Why a universal file could not be read or written. Every variant names the dataset (`58`,
/// `58b`, `2411`, … or `none` between datasets) and, when reading, the 1-based line.
#[derive(Debug, thiserror::Error)]
pub enum UffError {
    /// The file could not be opened or read.
    #[error("cannot read {path}: {source}")]
    Io {
        /// The path.
        path: String,
        /// The operating system's error.
        #[source]
        source: std::io::Error,
    },
    /// A record does not hold what its dataset's layout says it must.
    #[error("UFF dataset {dataset}, line {line}: expected {expected}, found {found}")]
    Malformed {
        /// Dataset number (`58b` for binary 58), or `none` outside a dataset.
        dataset: String,
        /// 1-based line of the file (for binary data: the line where the data starts).
        line: usize,
        /// What the layout requires there.
        expected: String,
        /// What the file holds (quoted, shortened).
        found: String,
    },
    /// The input ends (or the dataset closes) before the dataset is complete.
    #[error(
        "UFF dataset {dataset}, line {line}: input ends early: expected {expected}, found {found}"
    )]
    Truncated {
        /// Dataset number.
        dataset: String,
        /// 1-based line where more was expected.
        line: usize,
        /// What was still to come.
        expected: String,
        /// What there was instead.
        found: String,
    },
    /// A value handed to a writer cannot be represented in the dataset's fixed-width layout.
    #[error("UFF dataset {dataset}: cannot write {what}: {detail}")]
    Unwritable {
        /// Dataset number.
        dataset: String,
        /// Which field.
        what: String,
        /// Why (too long, not finite, sizes that disagree, …).
        detail: String,
    },
    /// The writer's sink failed.
    #[error("cannot write UFF dataset {dataset}: {source}")]
    Write {
        /// Dataset number.
        dataset: String,
        /// The underlying error.
        #[source]
        source: std::io::Error,
    },
}

/// One dataset the reader understood.
#[derive(Clone, Debug, PartialEq)]
pub enum Dataset {
    /// Dataset 58 or 58b: one function at a nodal DOF.
    Function(Box<Function58>),
    /// Dataset 15 or 2411: node coordinates.
    Nodes(NodeSet),
    /// Dataset 55: data at nodes (a mode shape).
    ModeShape(Box<ModeShape55>),
    /// Dataset 164: the file's units.
    Units(Units164),
}

/// A dataset the reader does not interpret and stepped over.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SkippedDataset {
    /// Its number (`2412`, `151`, …).
    pub number: i64,
    /// 1-based line of its number.
    pub line: usize,
}

/// What a universal file holds, in file order.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct UffContents {
    /// The datasets read, in file order.
    pub datasets: Vec<Dataset>,
    /// Datasets of other numbers, skipped.
    pub skipped: Vec<SkippedDataset>,
}

impl UffContents {
    /// The 58/58b functions, in file order.
    pub fn functions(&self) -> impl Iterator<Item = &Function58> {
        self.datasets.iter().filter_map(|d| match d {
            Dataset::Function(f) => Some(f.as_ref()),
            _ => None,
        })
    }

    /// Every node of every 15/2411 dataset, in file order.
    pub fn nodes(&self) -> impl Iterator<Item = &Node> {
        self.datasets
            .iter()
            .filter_map(|d| match d {
                Dataset::Nodes(n) => Some(n.nodes.iter()),
                _ => None,
            })
            .flatten()
    }

    /// The 55 datasets (mode shapes), in file order.
    pub fn mode_shapes(&self) -> impl Iterator<Item = &ModeShape55> {
        self.datasets.iter().filter_map(|d| match d {
            Dataset::ModeShape(m) => Some(m.as_ref()),
            _ => None,
        })
    }

    /// The first 164 dataset (units), if any.
    pub fn units(&self) -> Option<&Units164> {
        self.datasets.iter().find_map(|d| match d {
            Dataset::Units(u) => Some(u),
            _ => None,
        })
    }
}

/// A UFF direction code as text: `+X`, `-Z`, `+RY` (rotations 4–6), `scalar` (0); other codes
/// as their number. Used for channel ids (`12+Z`).
pub fn direction_label(code: i64) -> String {
    let axis = ["X", "Y", "Z"];
    let sign = if code < 0 { "-" } else { "+" };
    match code.unsigned_abs() {
        0 => "scalar".to_string(),
        a @ 1..=3 => format!("{sign}{}", axis[a as usize - 1]),
        a @ 4..=6 => format!("{sign}R{}", axis[a as usize - 4]),
        _ => code.to_string(),
    }
}

#[cfg(test)]
mod tests {
    use super::direction_label;

    #[test]
    fn direction_codes_read_as_axis_labels() {
        assert_eq!(direction_label(3), "+Z");
        assert_eq!(direction_label(-1), "-X");
        assert_eq!(direction_label(5), "+RY");
        assert_eq!(direction_label(0), "scalar");
        assert_eq!(direction_label(9), "9");
    }
}
