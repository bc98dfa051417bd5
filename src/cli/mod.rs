//! The `dampscope` command line.

pub mod modes;
