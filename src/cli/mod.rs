//! The `dampscope` command line.
pub mod synth;
