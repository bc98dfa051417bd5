//! Studies built on the analysis chain: local damping maps and the global equivalent damping
//! per band, FRF re-synthesis from it, the front-end comparison sweep, the throughput bench, and
//! the spread of many decays' results per channel and band.

pub mod bench;
pub mod compare;
pub mod demo;
pub mod maps;
pub mod resynthesis;
pub mod spread;
pub mod sweep;
