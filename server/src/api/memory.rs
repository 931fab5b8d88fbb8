//! Freed memory back to the system after loading trees and after a burst of
//! streams. Each stream holds its buffers (tungstenite's, the cut's, the
//! diff's: some hundreds of kilobytes) and frees them when it closes; the
//! allocator (mimalloc, `main.rs`) keeps freed pages for reuse and returns
//! them to the system only as the thread that freed them allocates again.
//! After rounds of 300 streams an idle server then held whatever the last
//! round left, 32 to 67 MB from round to round (`scripts/memory-bursts`,
//! the tiny site); collected when the last stream closes, 27 to 34 MB over
//! thirty rounds, with no growth (docs/benchmarks.md, "Memory after bursts
//! of streams").

/// Hands the pages freed after loading trees (the JSON read, the checks'
/// scratch) back: a server starts at the size of what it keeps.
pub fn loaded() {
    collect();
}

/// Called when the last open stream has closed.
pub fn streams_idle() {
    tokio::task::spawn_blocking(collect);
}

fn collect() {
    // SAFETY: `mi_collect` only walks the allocator's own free lists and
    // is thread-safe.
    unsafe { libmimalloc_sys::mi_collect(true) }
}
