//! Buffers an evaluation of the objective borrows and gives back, per thread. The
//! matrix, the per-light column sums and the band Jacobians are each larger than glibc's
//! per-thread cache takes (1 KiB); allocating and freeing them every evaluation was part
//! of the 5 % of a noise-aware search spent in the allocator. Their contents are written
//! before they are read, so an evaluation's bits do not depend on what a buffer held.

use std::cell::RefCell;

/// How many buffers a thread keeps: one evaluation gives back at most 4 + 2·K.
const KEPT: usize = 16;

thread_local! {
    static FREE: RefCell<Vec<Vec<f64>>> = const { RefCell::new(Vec::new()) };
}

/// An empty buffer, with whatever capacity it was given back with.
pub(in crate::fit::parametric) fn take() -> Vec<f64> {
    let mut buffer = FREE
        .try_with(|free| free.borrow_mut().pop())
        .ok()
        .flatten()
        .unwrap_or_default();
    buffer.clear();
    buffer
}

/// `n` zeros in a buffer given back earlier where there is one.
pub(in crate::fit::parametric) fn zeros(n: usize) -> Vec<f64> {
    let mut buffer = take();
    buffer.resize(n, 0.0);
    buffer
}

/// Keeps `buffer` for this thread's next evaluation.
pub(in crate::fit::parametric) fn give_back(buffer: Vec<f64>) {
    let _ = FREE.try_with(|free| {
        let mut free = free.borrow_mut();
        if free.len() < KEPT {
            free.push(buffer);
        }
    });
}
