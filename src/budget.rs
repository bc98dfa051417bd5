//! Memory budget: every large allocation is estimated from the settings and the input's declared
//! size *before* it is made, and refused with the estimate and the limit when it would not fit.
//!
//! Why: a 2.6 MB WAV header may declare 65 535 channels, `--channels 1e9` arrives with 400 bytes,
//! a window may be set to hours; allocating first and failing later takes the machine down.
//! The limit is `--max-memory`, by default half of the memory the machine has available.

use crate::error::{Error, Result};

/// Fraction of the machine's available memory that the default limit allows.
pub const DEFAULT_MEMORY_FRACTION: f64 = 0.5;

/// Limit used when the machine's available memory cannot be read, bytes (4 GiB).
pub const FALLBACK_LIMIT_BYTES: u64 = 4 << 30;

/// A memory limit for one run.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct MemoryBudget {
    /// Largest estimated footprint allowed, bytes.
    pub limit_bytes: u64,
}

impl MemoryBudget {
    /// A budget of `limit_bytes`.
    pub fn new(limit_bytes: u64) -> Self {
        MemoryBudget { limit_bytes }
    }

    /// [`DEFAULT_MEMORY_FRACTION`] of `MemAvailable` (Linux `/proc/meminfo`), else
    /// [`FALLBACK_LIMIT_BYTES`].
    pub fn from_machine() -> Self {
        let available = std::fs::read_to_string("/proc/meminfo")
            .ok()
            .and_then(|t| {
                t.lines()
                    .find(|l| l.starts_with("MemAvailable:"))
                    .and_then(|l| l.split_whitespace().nth(1))
                    .and_then(|kb| kb.parse::<u64>().ok())
            })
            .map(|kb| kb.saturating_mul(1024));
        MemoryBudget::new(available.map_or(FALLBACK_LIMIT_BYTES, |b| {
            (b as f64 * DEFAULT_MEMORY_FRACTION) as u64
        }))
    }

    /// Refuses `what` when its estimate exceeds the limit.
    pub fn check(&self, what: &str, estimate_bytes: f64) -> Result<()> {
        if estimate_bytes.is_finite() && estimate_bytes <= self.limit_bytes as f64 {
            return Ok(());
        }
        Err(Error::MemoryLimit {
            what: what.to_string(),
            estimate: human(estimate_bytes),
            limit: human(self.limit_bytes as f64),
        })
    }
}

impl Default for MemoryBudget {
    fn default() -> Self {
        MemoryBudget::from_machine()
    }
}

/// The process-wide limit in bytes; 0 means "not set": [`MemoryBudget::from_machine`].
static PROCESS_LIMIT_BYTES: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);

/// Sets the limit that [`check`] applies everywhere in this process (`--max-memory`).
pub fn set_process_limit(limit_bytes: u64) {
    PROCESS_LIMIT_BYTES.store(limit_bytes, std::sync::atomic::Ordering::Relaxed);
}

/// The machine's budget ([`MemoryBudget::from_machine`]), read once per process: every front
/// end checks its size when it is built, and reading `/proc/meminfo` for each of 64 channels
/// was 7 % of a short 64-channel run.
fn machine_budget() -> MemoryBudget {
    static MACHINE: std::sync::OnceLock<MemoryBudget> = std::sync::OnceLock::new();
    *MACHINE.get_or_init(MemoryBudget::from_machine)
}

/// The process-wide budget: the one set by [`set_process_limit`], else the machine's (as it
/// was when the process first asked).
pub fn process_budget() -> MemoryBudget {
    match PROCESS_LIMIT_BYTES.load(std::sync::atomic::Ordering::Relaxed) {
        0 => machine_budget(),
        b => MemoryBudget::new(b),
    }
}

/// Refuses `what` when its estimate exceeds the process-wide budget. Constructors that
/// allocate in proportion to a setting call this first.
pub fn check(what: &str, estimate_bytes: f64) -> Result<()> {
    process_budget().check(what, estimate_bytes)
}

/// Bytes in a readable unit.
pub fn human(bytes: f64) -> String {
    if !bytes.is_finite() {
        return "an unbounded amount".into();
    }
    let units = ["B", "kB", "MB", "GB", "TB", "PB"];
    let mut v = bytes;
    let mut u = 0;
    while v >= 1000.0 && u + 1 < units.len() {
        v /= 1000.0;
        u += 1;
    }
    format!("{v:.1} {}", units[u])
}

/// Parses a size such as `200M`, `1.5G`, `512k` or a plain number of bytes.
pub fn parse_size(text: &str) -> std::result::Result<u64, String> {
    let t = text.trim();
    let (num, mult) = match t.char_indices().last() {
        Some((i, c)) if c.is_ascii_alphabetic() => {
            let m = match c.to_ascii_uppercase() {
                'K' => 1e3,
                'M' => 1e6,
                'G' => 1e9,
                'T' => 1e12,
                _ => return Err(format!("expected a size such as 200M or 2G, got {text:?}")),
            };
            (&t[..i], m)
        }
        _ => (t, 1.0),
    };
    let v: f64 = num
        .parse()
        .map_err(|_| format!("expected a size such as 200M or 2G, got {text:?}"))?;
    if !(v.is_finite() && v > 0.0) {
        return Err(format!("expected a positive size, got {text:?}"));
    }
    Ok((v * mult) as u64)
}

/// Peak resident memory of this process, KiB (Linux `/proc/self/status` VmHWM).
pub fn peak_memory_kib() -> Option<u64> {
    peak_memory_kib_of("self")
}

/// Peak resident memory of process `pid` ("self" or a number), KiB (Linux VmHWM); `None`
/// where /proc is not available.
pub fn peak_memory_kib_of(pid: &str) -> Option<u64> {
    let status = std::fs::read_to_string(format!("/proc/{pid}/status")).ok()?;
    status
        .lines()
        .find(|l| l.starts_with("VmHWM:"))?
        .split_whitespace()
        .nth(1)?
        .parse()
        .ok()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_parse_and_the_limit_refuses_with_both_figures() {
        assert_eq!(parse_size("200M"), Ok(200_000_000));
        assert_eq!(parse_size("1.5g"), Ok(1_500_000_000));
        assert_eq!(parse_size("4096"), Ok(4096));
        assert!(parse_size("-1M").is_err() && parse_size("lots").is_err());
        let b = MemoryBudget::new(200_000_000);
        assert!(b.check("x", 1.9e8).is_ok());
        let e = b.check("65535 channels", 3.1e9).unwrap_err().to_string();
        assert!(
            e.contains("3.1 GB") && e.contains("200.0 MB") && e.contains("65535"),
            "{e}"
        );
        assert!(b.check("x", f64::INFINITY).is_err());
        assert!(MemoryBudget::from_machine().limit_bytes > 0);
    }
}
