//! The `dampscope` command line.
