//! Temporaries that interrupted writes leave behind. A tree or a scene is
//! written into a hidden directory beside its target, `.NAME.tmp-PID-N` or
//! `.NAME.tmp-PID` (and `.NAME.old-PID-N` or `.NAME.tmp-PID.old` while a
//! replacement swaps them), then renamed into place; a process killed
//! before the rename (`kill -9`, a power cut) leaves its temporary, tens of
//! megabytes, that nothing else would remove. The next write to the same
//! target removes those whose process is gone.
//!
//! A process is known gone when `/proc/PID` does not exist (Linux). Where
//! there is no `/proc`, nothing is removed: a live build's temporary must
//! never be. A PID that a new process has taken keeps its debris until that
//! process ends, which errs on the safe side.

use std::fs;
use std::path::Path;

/// Removes the temporaries of `target` left by processes that are gone;
/// returns how many. Errors are ignored: this is housekeeping, and a write
/// must not fail for it.
pub fn remove_stale(target: &Path) -> usize {
    let Some(leaf) = target.file_name().map(|n| n.to_string_lossy().into_owned()) else {
        return 0;
    };
    let parent = match target.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    if !Path::new("/proc/self").exists() {
        return 0;
    }
    let Ok(entries) = fs::read_dir(parent) else {
        return 0;
    };
    let prefix = format!(".{leaf}.");
    let mut removed = 0;
    for entry in entries.flatten() {
        let name = entry.file_name().to_string_lossy().into_owned();
        let Some(pid) = name.strip_prefix(&prefix).and_then(owner) else {
            continue;
        };
        if pid == std::process::id() || Path::new("/proc").join(pid.to_string()).exists() {
            continue;
        }
        if entry.file_type().is_ok_and(|t| t.is_dir()) && fs::remove_dir_all(entry.path()).is_ok() {
            removed += 1;
        }
    }
    removed
}

/// The PID in `tmp-PID`, `tmp-PID-N`, `old-PID-N` or `tmp-PID.old`.
fn owner(rest: &str) -> Option<u32> {
    let rest = rest.strip_suffix(".old").unwrap_or(rest);
    let numbers = rest
        .strip_prefix("tmp-")
        .or_else(|| rest.strip_prefix("old-"))?;
    let mut parts = numbers.split('-');
    let pid = parts.next()?.parse().ok()?;
    match (parts.next(), parts.next()) {
        (None, _) => Some(pid),
        (Some(n), None) if n.parse::<u64>().is_ok() => Some(pid),
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_the_owner_of_each_kind_of_temporary() {
        assert_eq!(owner("tmp-123-4"), Some(123));
        assert_eq!(owner("tmp-123"), Some(123));
        assert_eq!(owner("old-123-0"), Some(123));
        assert_eq!(owner("tmp-123.old"), Some(123));
        assert_eq!(owner("tmp-x-4"), None);
        assert_eq!(owner("tmp-1-2-3"), None);
        assert_eq!(owner("backup"), None);
    }
}
