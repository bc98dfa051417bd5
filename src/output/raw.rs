//! Raw samples as standard input takes them (`--raw f32`): interleaved little-endian f32.

/// Appends `channels` (all of the same length) to `out` as interleaved little-endian f32
/// frames: sample 0 of every channel, then sample 1, ….
pub fn append_interleaved_f32_le(channels: &[Vec<f64>], out: &mut Vec<u8>) {
    let frames = channels.first().map_or(0, Vec::len);
    out.reserve(frames * channels.len() * 4);
    for i in 0..frames {
        for ch in channels {
            out.extend_from_slice(&(ch[i] as f32).to_le_bytes());
        }
    }
}
