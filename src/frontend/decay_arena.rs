//! Decay buffers on huge pages: where the input's length is known, a worker maps one region
//! for the decays of all its channels, with transparent huge pages asked for, and each buffering
//! bank's decay takes a slot of it sized to the input instead of its own allocation.
//!
//! The buffers of a 64-channel, 10 s stream are 10 MB of fresh memory, all alive at once at
//! the input's end: 2600 page faults of 4 kB and one unmapping per buffer at the end, each
//! interrupting the other core to flush its TLB. On 2 MB pages the same memory is a few faults
//! and one unmapping: the process's page faults 4836 → 2186 and its time 25.2–26.7 → 21.4–22.3
//! ms (octave bank at 4096 Hz, minimum and median of 40 runs). Where the length is unknown (a pipe), a slot would be too
//! small, or the system has no such pages, buffers come from the allocator as before; a slot
//! that fills up moves its samples to the allocator and goes on there.

use std::cell::RefCell;
use std::sync::Arc;

/// Bytes of a transparent huge page on x86-64 and aarch64 with 4 kB pages.
pub(crate) const HUGE_PAGE_BYTES: usize = 2 << 20;

/// Smallest arena worth mapping: below it (short or few channels) the allocator serves.
const MIN_ARENA_BYTES: usize = HUGE_PAGE_BYTES;

/// Address space an arena keeps per channel beyond the input's length, in samples: room for a
/// bank's pre-roll (the Goyder bank has none, the octave bank a fraction of a second). Address
/// space only: pages are mapped where slots are written.
const LEAD_ROOM_SAMPLES: usize = 1 << 20;

/// Input frames an arena makes room for per channel at most (256 MB of f32): a long input's
/// decays are cut at the banks' `max_decay_s` anyway, and more address space buys nothing.
const MAX_CHANNEL_SAMPLES: usize = 1 << 26;

/// Samples a slot is rounded up to (a cache line of f32), so slots never share a line.
const SLOT_ALIGN_SAMPLES: usize = 16;

/// One anonymous private mapping, unmapped when the last slot and arena handle let go of it.
struct Region {
    base: *mut std::ffi::c_void,
    map_len: usize,
    /// The usable part: from the first huge-page boundary on.
    start: *mut f32,
    len_samples: usize,
}

// SAFETY: the region is plain memory; every slot owns a disjoint part of it and hands out
// references only through `&self` / `&mut self` of that slot.
unsafe impl Send for Region {}
unsafe impl Sync for Region {}

impl Region {
    /// Maps `samples` f32 of address space (not reserved against swap) aligned to a huge page,
    /// with huge pages asked for; `None` where the system refuses.
    #[cfg(target_os = "linux")]
    fn map(samples: usize) -> Option<Region> {
        let bytes = samples.checked_mul(4)?;
        let map_len = bytes.checked_add(HUGE_PAGE_BYTES)?;
        // SAFETY: a fresh anonymous private mapping; failure is reported as MAP_FAILED.
        let base = unsafe {
            libc::mmap(
                std::ptr::null_mut(),
                map_len,
                libc::PROT_READ | libc::PROT_WRITE,
                libc::MAP_PRIVATE | libc::MAP_ANONYMOUS | libc::MAP_NORESERVE,
                -1,
                0,
            )
        };
        if base == libc::MAP_FAILED {
            return None;
        }
        let skip = (HUGE_PAGE_BYTES - base as usize % HUGE_PAGE_BYTES) % HUGE_PAGE_BYTES;
        // SAFETY: `skip < HUGE_PAGE_BYTES`, inside the mapping.
        let start = unsafe { (base as *mut u8).add(skip) };
        // A refusal (huge pages disabled) leaves ordinary pages: still correct.
        // SAFETY: advice on a range of our own mapping.
        unsafe {
            libc::madvise(start.cast(), bytes, libc::MADV_HUGEPAGE);
        }
        Some(Region {
            base,
            map_len,
            start: start.cast(),
            len_samples: samples,
        })
    }

    #[cfg(not(target_os = "linux"))]
    fn map(_samples: usize) -> Option<Region> {
        None
    }
}

impl Drop for Region {
    fn drop(&mut self) {
        #[cfg(target_os = "linux")]
        // SAFETY: exactly what mmap returned; no slot is alive (each holds an `Arc` of this).
        unsafe {
            libc::munmap(self.base, self.map_len);
        }
    }
}

/// This thread's arena: the region, how much of it slots took, and the input's length.
struct Arena {
    region: Arc<Region>,
    used_samples: usize,
    input_frames: usize,
}

thread_local! {
    static ARENA: RefCell<Option<Arena>> = const { RefCell::new(None) };
}

/// Removes this thread's arena when dropped (the slots taken keep their memory).
pub(crate) struct ArenaGuard(());

impl Drop for ArenaGuard {
    fn drop(&mut self) {
        ARENA.with(|a| a.borrow_mut().take());
    }
}

/// Gives this thread an arena for the decays of `channels` channels of an input of
/// `input_frames` frames (`None`: unknown length, no arena), until the guard is dropped.
pub(crate) fn install(channels: usize, input_frames: Option<usize>) -> ArenaGuard {
    let region = input_frames
        .filter(|&n| channels.saturating_mul(n).saturating_mul(4) >= MIN_ARENA_BYTES)
        .and_then(|n| {
            let per_channel = n.min(MAX_CHANNEL_SAMPLES) + LEAD_ROOM_SAMPLES;
            Region::map(per_channel.checked_mul(channels)?)
        });
    ARENA.with(|a| {
        *a.borrow_mut() = region
            .zip(input_frames)
            .map(|(region, input_frames)| Arena {
                region: Arc::new(region),
                used_samples: 0,
                input_frames,
            })
    });
    ArenaGuard(())
}

/// A slot of this thread's arena for a decay of at most `capacity` samples that starts with
/// `lead` samples before the input's own (a pre-roll): `lead + input` samples, at most
/// `capacity`. `None` without an arena or when it is full.
pub(crate) fn take_slot(lead: usize, capacity: usize) -> Option<Slot> {
    ARENA.with(|a| {
        let mut a = a.borrow_mut();
        let arena = a.as_mut()?;
        let want = lead
            .saturating_add(arena.input_frames)
            .min(capacity)
            .checked_next_multiple_of(SLOT_ALIGN_SAMPLES)?;
        let end = arena.used_samples.checked_add(want)?;
        if want == 0 || end > arena.region.len_samples {
            return None;
        }
        #[cfg(test)]
        SLOTS_TAKEN.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        // SAFETY: `used_samples + want ≤ len_samples`: inside the region, and past every slot
        // handed out before.
        let ptr = unsafe { arena.region.start.add(arena.used_samples) };
        arena.used_samples = end;
        Some(Slot {
            _region: arena.region.clone(),
            ptr,
            len: 0,
            capacity: want,
        })
    })
}

/// Slots handed out by every thread so far (tests check that a run used its arena).
#[cfg(test)]
pub(crate) static SLOTS_TAKEN: std::sync::atomic::AtomicUsize =
    std::sync::atomic::AtomicUsize::new(0);

/// Single-precision samples in a slot of an arena: `capacity` of them at `ptr`, the first `len`
/// held. The memory is the mapping's (zero until written), this slot's alone.
pub(crate) struct Slot {
    _region: Arc<Region>,
    ptr: *mut f32,
    len: usize,
    capacity: usize,
}

impl std::fmt::Debug for Slot {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Slot")
            .field("len", &self.len)
            .field("capacity", &self.capacity)
            .finish()
    }
}

// SAFETY: the slot owns its range of the region exclusively (see `Region`).
unsafe impl Send for Slot {}
unsafe impl Sync for Slot {}

impl Slot {
    /// The samples held.
    pub(crate) fn as_slice(&self) -> &[f32] {
        // SAFETY: `len ≤ capacity` values of this slot's range, initialised (zero-filled pages
        // or written).
        unsafe { std::slice::from_raw_parts(self.ptr, self.len) }
    }

    /// Samples it can hold.
    pub(crate) fn capacity(&self) -> usize {
        self.capacity
    }

    /// Empties it (the memory stays its own).
    pub(crate) fn clear(&mut self) {
        self.len = 0;
    }

    /// Appends `xs` rounded to f32 when they fit; false (nothing appended) when they do not.
    pub(crate) fn try_extend(&mut self, xs: &[f64]) -> bool {
        if xs.len() > self.capacity - self.len {
            return false;
        }
        // SAFETY: `len + xs.len() ≤ capacity`: this slot's range, initialised memory.
        let room = unsafe { std::slice::from_raw_parts_mut(self.ptr.add(self.len), xs.len()) };
        crate::frontend::simd::in_wide_vectors(|| {
            for (r, &x) in room.iter_mut().zip(xs) {
                *r = x as f32;
            }
        });
        self.len += xs.len();
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Slots are disjoint, sized `lead + input` (at most the capacity), keep what is written,
    /// refuse what does not fit, outlive the arena's guard; no arena for an unknown or a short
    /// input.
    #[test]
    fn slots_are_disjoint_sized_and_outlive_their_arena() {
        if !cfg!(target_os = "linux") {
            return;
        }
        let frames = 100_000;
        let guard = install(16, Some(frames));
        let mut a = take_slot(300, usize::MAX).expect("an arena for 16 × 100000 frames");
        let mut b = take_slot(0, 50_000).expect("room for a second slot");
        assert_eq!(
            a.capacity(),
            (frames + 300).next_multiple_of(SLOT_ALIGN_SAMPLES)
        );
        assert_eq!(b.capacity(), 50_000);
        let xs: Vec<f64> = (0..40_000).map(|k| k as f64 * 0.5 - 3.25).collect();
        assert!(a.try_extend(&xs) && b.try_extend(&[9.5; 7]));
        assert!(a.try_extend(&xs[..1000]));
        drop(guard);
        // Both slots still hold their own values after the arena is gone.
        let mut want: Vec<f32> = xs.iter().map(|&x| x as f32).collect();
        want.extend(xs[..1000].iter().map(|&x| x as f32));
        assert_eq!(a.as_slice(), &want[..]);
        assert_eq!(b.as_slice(), &[9.5; 7]);
        assert!(
            !b.try_extend(&vec![1.0; 50_000 - 6]),
            "more than its capacity"
        );
        assert_eq!(b.as_slice().len(), 7);
        b.clear();
        assert!(b.try_extend(&vec![2.0; 50_000]) && b.as_slice().iter().all(|&x| x == 2.0));
        assert!(take_slot(0, 10).is_none(), "no arena after its guard");
        // Unknown length, or too little to be worth a mapping.
        let _g = install(64, None);
        assert!(take_slot(0, 10).is_none());
        let _g = install(2, Some(1000));
        assert!(take_slot(0, 10).is_none());
    }

    /// An arena fills up: the slot that does not fit is refused, not cut.
    #[test]
    fn a_full_arena_refuses_slots() {
        if !cfg!(target_os = "linux") {
            return;
        }
        let frames = 1 << 20;
        let _g = install(1, Some(frames));
        let room = frames + LEAD_ROOM_SAMPLES;
        // A slot of the whole room but 64 samples (a lead as long as the room's margin).
        let big = take_slot(LEAD_ROOM_SAMPLES, room - 64).expect("the first slot fits");
        assert_eq!(big.capacity(), room - 64);
        assert!(take_slot(0, 128).is_none());
        assert_eq!(take_slot(0, 64).map(|s| s.capacity()), Some(64));
        assert!(take_slot(0, 1).is_none());
    }
}
