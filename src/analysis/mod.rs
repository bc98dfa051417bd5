//! Studies built on the analysis chain (the front-end comparison sweep).

pub mod sweep;
