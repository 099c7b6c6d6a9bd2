//! A counting global allocator: live and peak bytes per worker slot, and a hard bound.
//!
//! Each fuzz worker runs its mutants on one thread whose slot is set by [`enter_slot`];
//! every allocation there is counted against that slot. A request that would take the
//! slot's live bytes over [`BOUND_BYTES`] is refused (null) after printing the mutant's
//! recipe, so an over-allocating mutant is named even when the refusal aborts the process.
//! Slot 0 (the harness's own threads) is not counted.

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, AtomicI64, Ordering::Relaxed};

/// Number of slots: slot 0 is the harness, the rest are workers (a hung worker's slot is
/// retired, so this also bounds the hangs one run survives).
pub const MAX_SLOTS: usize = 64;

/// Live bytes a single mutant may hold at once.
pub const BOUND_BYTES: i64 = 1 << 30;

/// The allocator: the system allocator with per-slot accounting.
pub struct Counting;

static LIVE: [AtomicI64; MAX_SLOTS] = [const { AtomicI64::new(0) }; MAX_SLOTS];
static PEAK: [AtomicI64; MAX_SLOTS] = [const { AtomicI64::new(0) }; MAX_SLOTS];
static REFUSED: [AtomicBool; MAX_SLOTS] = [const { AtomicBool::new(false) }; MAX_SLOTS];
static RECIPE: [Mutex<String>; MAX_SLOTS] = [const { Mutex::new(String::new()) }; MAX_SLOTS];

thread_local! {
    // const-initialised without a destructor: safe to read from inside the allocator.
    static SLOT: Cell<usize> = const { Cell::new(0) };
}

/// Counts this thread's allocations against `slot` from now on.
pub fn enter_slot(slot: usize) {
    SLOT.with(|s| s.set(slot));
}

/// Starts a mutant on `slot`: clears its counters and remembers its recipe for messages.
pub fn begin(slot: usize, recipe: String) {
    LIVE[slot].store(0, Relaxed);
    PEAK[slot].store(0, Relaxed);
    REFUSED[slot].store(false, Relaxed);
    *RECIPE[slot].lock().unwrap_or_else(|e| e.into_inner()) = recipe;
}

/// The peak of live bytes on `slot` since [`begin`], and whether a request over the
/// bound was refused.
pub fn peak(slot: usize) -> (i64, bool) {
    (PEAK[slot].load(Relaxed), REFUSED[slot].load(Relaxed))
}

fn current_slot() -> usize {
    SLOT.try_with(Cell::get).unwrap_or(0)
}

/// Counts `bytes` more on the current slot; false (and nothing counted) when that would
/// pass the bound.
fn grow(bytes: usize) -> bool {
    let slot = current_slot();
    if slot == 0 {
        return true;
    }
    let bytes = bytes as i64;
    let live = LIVE[slot].fetch_add(bytes, Relaxed) + bytes;
    if live > BOUND_BYTES {
        LIVE[slot].fetch_sub(bytes, Relaxed);
        REFUSED[slot].store(true, Relaxed);
        // Uncounted from here, so the message's own allocations do not recurse.
        SLOT.with(|s| s.set(0));
        let recipe = RECIPE[slot]
            .lock()
            .map(|r| r.clone())
            .unwrap_or_else(|e| e.into_inner().clone());
        eprintln!(
            "fuzz: OVER-ALLOCATION: {recipe}: asked for {bytes} bytes with {} live (bound {BOUND_BYTES}); refused",
            live - bytes
        );
        SLOT.with(|s| s.set(slot));
        return false;
    }
    PEAK[slot].fetch_max(live, Relaxed);
    true
}

fn shrink(bytes: usize) {
    let slot = current_slot();
    if slot != 0 {
        LIVE[slot].fetch_sub(bytes as i64, Relaxed);
    }
}

// SAFETY: every call forwards to `System` with the caller's layout; the accounting only
// touches atomics and a const thread-local.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        if !grow(layout.size()) {
            return std::ptr::null_mut();
        }
        // SAFETY: forwarded unchanged.
        let p = unsafe { System.alloc(layout) };
        if p.is_null() {
            shrink(layout.size());
        }
        p
    }

    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        if !grow(layout.size()) {
            return std::ptr::null_mut();
        }
        // SAFETY: forwarded unchanged.
        let p = unsafe { System.alloc_zeroed(layout) };
        if p.is_null() {
            shrink(layout.size());
        }
        p
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        shrink(layout.size());
        // SAFETY: forwarded unchanged.
        unsafe { System.dealloc(ptr, layout) }
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        let old = layout.size();
        if new_size > old && !grow(new_size - old) {
            return std::ptr::null_mut();
        }
        // SAFETY: forwarded unchanged.
        let p = unsafe { System.realloc(ptr, layout, new_size) };
        if p.is_null() {
            if new_size > old {
                shrink(new_size - old);
            }
        } else if new_size < old {
            shrink(old - new_size);
        }
        p
    }
}
