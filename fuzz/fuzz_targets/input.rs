//! What every target shares: the input as a file (the readers take paths),
//! in a directory of the process's own, under the input cap the command
//! line would set.

#![allow(dead_code)] // Each target takes what it needs of it.

use std::path::PathBuf;
use std::sync::OnceLock;

/// The fuzzing process's directory. A static is never dropped and
/// libFuzzer ends the process with `exit`, so it stays: `scripts/fuzz`
/// points `TMPDIR` at a directory it empties.
pub fn dir() -> &'static std::path::Path {
    static DIR: OnceLock<tempfile::TempDir> = OnceLock::new();
    DIR.get_or_init(|| {
        // Well under libFuzzer's -malloc_limit_mb: a reader that trusts a
        // size field must still be stopped by the cap.
        hdlod::input::set_limits(hdlod::input::Limits {
            max_bytes: 16 << 20,
            outside: false,
        });
        tempfile::tempdir().expect("a temporary directory")
    })
    .path()
}

/// `data` written to `name` in [`dir`].
pub fn file(name: &str, data: &[u8]) -> PathBuf {
    let path = dir().join(name);
    std::fs::write(&path, data).expect("the temporary directory is writable");
    path
}
