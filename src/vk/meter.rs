//! What a process holds at once, counted where memory is taken and given
//! back, not estimated: device memory of live buffers and images (counted
//! by `Context::allocate` and `Context::free`), and, for a binary that
//! installs [`MeteredAlloc`] as its global allocator (a test), the Rust
//! heap, with the largest sum of the two seen at any allocation. On
//! lavapipe device memory is host memory, so the sum bounds what a run
//! holds (device bytes count from allocation: an upper bound on what is
//! resident). `tests/memory_bound.rs` asserts issue 21's bound with it.

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicU64, Ordering::Relaxed};

static DEVICE: AtomicU64 = AtomicU64::new(0);
static HEAP: AtomicU64 = AtomicU64::new(0);
static PEAK: AtomicU64 = AtomicU64::new(0);

/// Bytes of device memory held by live buffers and images, over every
/// context of the process.
pub fn device_bytes_live() -> u64 {
    DEVICE.load(Relaxed)
}

/// Bytes of the Rust heap in use (0 unless [`MeteredAlloc`] is installed).
pub fn heap_bytes_live() -> u64 {
    HEAP.load(Relaxed)
}

/// The largest heap + device bytes seen since the last [`reset_peak`].
pub fn peak_bytes() -> u64 {
    PEAK.load(Relaxed).max(heap_bytes_live() + device_bytes_live())
}

/// Starts a new peak from what is held now.
pub fn reset_peak() {
    PEAK.store(heap_bytes_live() + device_bytes_live(), Relaxed);
}

pub(crate) fn device_allocated(bytes: u64) {
    let now = DEVICE.fetch_add(bytes, Relaxed) + bytes;
    PEAK.fetch_max(now + heap_bytes_live(), Relaxed);
}

pub(crate) fn device_freed(bytes: u64) {
    DEVICE.fetch_sub(bytes, Relaxed);
}

fn heap_grew(bytes: usize) {
    let now = HEAP.fetch_add(bytes as u64, Relaxed) + bytes as u64;
    PEAK.fetch_max(now + device_bytes_live(), Relaxed);
}

fn heap_shrank(bytes: usize) {
    HEAP.fetch_sub(bytes as u64, Relaxed);
}

/// The system allocator, counting the heap bytes in use and the peak of
/// heap + device bytes. Install with
/// `#[global_allocator] static A: volbench::vk::MeteredAlloc = volbench::vk::MeteredAlloc;`.
pub struct MeteredAlloc;

// SAFETY: every call is forwarded unchanged to `System`, which upholds
// `GlobalAlloc`'s contract; the counting touches only atomics (it never
// allocates, so it cannot recurse).
unsafe impl GlobalAlloc for MeteredAlloc {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        // SAFETY: forwarded with the caller's layout (non-zero size, per the contract).
        let p = unsafe { System.alloc(layout) };
        if !p.is_null() {
            heap_grew(layout.size());
        }
        p
    }

    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        // SAFETY: as `alloc`.
        let p = unsafe { System.alloc_zeroed(layout) };
        if !p.is_null() {
            heap_grew(layout.size());
        }
        p
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: `ptr` was allocated by this allocator (so by `System`) with `layout`.
        unsafe { System.dealloc(ptr, layout) };
        heap_shrank(layout.size());
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        // SAFETY: `ptr` was allocated by `System` with `layout`; `new_size` as the caller's contract.
        let p = unsafe { System.realloc(ptr, layout, new_size) };
        if !p.is_null() {
            if new_size >= layout.size() {
                heap_grew(new_size - layout.size());
            } else {
                heap_shrank(layout.size() - new_size);
            }
        }
        p
    }
}
