//! Valgrind client requests for counted runs (`volbench run --count`): the
//! callgrind requests that start and stop instrumentation and dump the
//! instruction counts at a phase boundary, and the check whether the
//! process runs under valgrind at all. The requests are valgrind's
//! documented magic sequence (`valgrind.h`, amd64): a no-op on a real CPU,
//! so every call is harmless outside valgrind, and each request is sent
//! only while a counted section is open (`start`..`stop`).
//!
//! It lives under `vk/` because the sequence is inline assembly: every
//! `unsafe` of volbench stays in this layer.

use std::sync::atomic::{AtomicBool, Ordering};

/// valgrind.h: `VG_USERREQ__RUNNING_ON_VALGRIND`.
const RUNNING_ON_VALGRIND: usize = 0x1001;
/// callgrind.h: `VG_USERREQ_TOOL_BASE('C','T')` and the requests after it.
const CALLGRIND_BASE: usize = (b'C' as usize) << 24 | (b'T' as usize) << 16;
const ZERO_STATS: usize = CALLGRIND_BASE + 1;
const DUMP_STATS_AT: usize = CALLGRIND_BASE + 3;
const START_INSTRUMENTATION: usize = CALLGRIND_BASE + 4;
const STOP_INSTRUMENTATION: usize = CALLGRIND_BASE + 5;

/// A counted section is open: `mark` dumps.
static OPEN: AtomicBool = AtomicBool::new(false);

#[cfg(target_arch = "x86_64")]
fn request(code: usize, a1: usize) -> usize {
    let args: [usize; 6] = [code, a1, 0, 0, 0, 0];
    let mut result: usize = 0;
    // SAFETY: valgrind.h's amd64 client-request sequence. The four rotations
    // of rdi add up to 128 bits (rdi is unchanged); `xchg rbx, rbx` is a
    // no-op on a real CPU, and under valgrind marks the request. rax points
    // at `args`, which outlives the asm block; valgrind writes only rdx (the
    // result, `0` when not under valgrind) and may read the C string that
    // `a1` points at for DUMP_STATS_AT.
    unsafe {
        std::arch::asm!(
            "rol rdi, 3", "rol rdi, 13", "rol rdi, 61", "rol rdi, 51", "xchg rbx, rbx",
            in("rax") args.as_ptr(),
            inout("rdx") result,
            options(nostack, preserves_flags),
        );
    }
    result
}

/// Other architectures: no requests (a counted run refuses to start there,
/// see `harness::count`).
#[cfg(not(target_arch = "x86_64"))]
fn request(_code: usize, _a1: usize) -> usize {
    0
}

/// Whether client requests work on this architecture.
pub const SUPPORTED: bool = cfg!(target_arch = "x86_64");

/// Whether this process runs under valgrind.
pub fn running_on_valgrind() -> bool {
    request(RUNNING_ON_VALGRIND, 0) != 0
}

/// Open a counted section: instrumentation on (callgrind runs with
/// `--instr-atstart=no`, so nothing before this is counted) and the counters
/// zeroed.
pub fn start() {
    if running_on_valgrind() {
        request(START_INSTRUMENTATION, 0);
        request(ZERO_STATS, 0);
        OPEN.store(true, Ordering::SeqCst);
    }
}

/// Dump the instructions every thread executed since the last dump (or
/// `start`) under `label`, and zero the counters. Nothing outside a counted
/// section.
pub fn mark(label: &str) {
    if OPEN.load(Ordering::SeqCst) {
        // A label with a NUL byte cannot be sent; the phase names are ours.
        if let Ok(c) = std::ffi::CString::new(label) {
            request(DUMP_STATS_AT, c.as_ptr() as usize);
        }
    }
}

/// Close the counted section: instrumentation off.
pub fn stop() {
    if OPEN.swap(false, Ordering::SeqCst) {
        request(STOP_INSTRUMENTATION, 0);
    }
}

/// Whether a counted section is open.
pub fn counting() -> bool {
    OPEN.load(Ordering::SeqCst)
}
