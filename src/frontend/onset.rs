//! Decay onset detection.
