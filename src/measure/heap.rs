//! A counting global allocator: the bytes the process has allocated on the heap now, and the
//! most it has held since the last [`reset_peak`]. `bench` uses it to report what a stage
//! *allocates* at its peak, which the resident-set figure (`VmHWM`) cannot separate from fixed
//! runtime costs: code pages faulted in on first use, thread stacks, per-thread malloc arenas.
//! On small clouds those fixed costs weigh as much as the data, and they do not grow with it.
//!
//! Counting is off until [`enable`] (only `bench` turns it on), so every other command's
//! allocations, the renderers' worker threads included, pay one relaxed load of a flag that
//! never changes under them, not a contended `fetch_max`. The binary installs it (`main.rs`);
//! library users and tests that do not see counters of zero.

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicBool, AtomicIsize, Ordering::Relaxed};

static ENABLED: AtomicBool = AtomicBool::new(false);
// Signed: blocks allocated before `enable` are freed after it, so the count of bytes
// allocated since then may go below zero; differences and peaks stay right.
static CURRENT: AtomicIsize = AtomicIsize::new(0);
static PEAK: AtomicIsize = AtomicIsize::new(0);

/// The system allocator, counted.
pub struct Counting;

fn grew(by: usize) {
    if ENABLED.load(Relaxed) {
        let by = by as isize;
        let now = CURRENT.fetch_add(by, Relaxed) + by;
        PEAK.fetch_max(now, Relaxed);
    }
}

fn shrank(by: usize) {
    if ENABLED.load(Relaxed) {
        CURRENT.fetch_sub(by as isize, Relaxed);
    }
}

// SAFETY: every method forwards to `System` with the caller's arguments unchanged, so the
// `GlobalAlloc` contract is `System`'s; the counters only observe sizes.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        // SAFETY: forwarded unchanged (see the impl's note).
        let p = unsafe { System.alloc(layout) };
        if !p.is_null() {
            grew(layout.size());
        }
        p
    }

    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        // SAFETY: forwarded unchanged (see the impl's note).
        let p = unsafe { System.alloc_zeroed(layout) };
        if !p.is_null() {
            grew(layout.size());
        }
        p
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: forwarded unchanged (see the impl's note).
        unsafe { System.dealloc(ptr, layout) };
        shrank(layout.size());
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        // SAFETY: forwarded unchanged (see the impl's note).
        let p = unsafe { System.realloc(ptr, layout, new_size) };
        if !p.is_null() {
            if new_size >= layout.size() {
                grew(new_size - layout.size());
            } else {
                shrank(layout.size() - new_size);
            }
        }
        p
    }
}

/// Start counting (from zero bytes): what follows is measured by [`current`] and [`peak`].
pub fn enable() {
    ENABLED.store(true, Relaxed);
}

/// Heap bytes allocated since [`enable`], net of those freed (0 when [`Counting`] is not the
/// global allocator or counting is off).
pub fn current() -> isize {
    CURRENT.load(Relaxed)
}

/// The most of [`current`] at once since the last [`reset_peak`].
pub fn peak() -> isize {
    PEAK.load(Relaxed)
}

/// Start a new peak from what is allocated now.
pub fn reset_peak() {
    PEAK.store(CURRENT.load(Relaxed), Relaxed);
}
