//! STFT front end.
