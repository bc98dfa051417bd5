//! CLI (pending).
