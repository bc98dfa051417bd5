//! Studies built on the analysis chain: local damping maps and the global equivalent damping
//! per band, and the front-end comparison sweep.

pub mod maps;
pub mod sweep;
