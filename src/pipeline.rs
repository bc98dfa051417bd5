//! Threads and channels: reader → workers (channel groups) → writer.
