//! Freed memory back to the system after a burst of streams. Each stream
//! holds its buffers (tungstenite's, the cut's, the diff's: some hundreds
//! of kilobytes) and frees them when it closes; glibc keeps freed memory in
//! per-thread arenas for reuse, so after rounds of hundreds of streams the
//! server's resident size rose round after round as the arenas fragmented
//! (`scripts/memory-bursts`: 55 MB idle, 131 MB after the first round of
//! 300, 146 MB after twelve; with one arena it stays at 116 MB: no leak).
//! When the last stream closes, `malloc_trim` hands the free pages of every
//! arena back: the rounds then come back to 44 MB, yet still crept up
//! 0.3 MB a round (two arenas: 0.2 MB), the fragments the arenas keep
//! between live allocations. With one arena, thirty rounds of 300 streams
//! stay at 39.7 MB. The price, every thread taking the one arena's lock,
//! is small beside a cut: the server allocates little per request.

/// Caps glibc's arenas ([`ARENAS`]); called once, before the runtime's
/// threads start.
pub fn limit_arenas() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: mallopt changes a setting of the allocator, before any other
    // thread allocates.
    unsafe {
        libc::mallopt(libc::M_ARENA_MAX, ARENAS);
    }
}

/// The arenas the server's threads share.
#[cfg(all(target_os = "linux", target_env = "gnu"))]
const ARENAS: libc::c_int = 1;

/// Hands the pages freed after loading trees (the JSON read, the checks'
/// scratch) back: a server starts at the size of what it keeps.
pub fn loaded() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: as in `streams_idle`.
    unsafe {
        libc::malloc_trim(0);
    }
}

/// Called when the last open stream has closed.
pub fn streams_idle() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    tokio::task::spawn_blocking(|| {
        // SAFETY: malloc_trim only walks the allocator's own free lists; it
        // is thread-safe in glibc.
        unsafe {
            libc::malloc_trim(0);
        }
    });
}
