//! Input files: where a path named inside another file may lead, and what
//! may be read at all. A scene's `scene.json` names its models and a glTF
//! file its buffers; such a path stays inside the naming file's directory
//! unless the process allows more ([`Limits::outside`]), so that a scene
//! handed over by someone else reads nothing else on the machine. Every
//! input, named on the command line or in a file, is a regular file (a
//! device such as `/dev/zero` never ends, a FIFO blocks) of at most
//! [`Limits::max_bytes`], so that no input makes a run hang or grow without
//! bound (docs/formats.md, "Inputs").
//!
//! The limits are the process's, set once from the command line before any
//! input is read (like a ulimit): every reader, from the scene loader to
//! the schedule importers, obeys the same ones without each signature
//! carrying them.

use std::fs::File;
use std::io::Read;
use std::path::{Component, Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};

use crate::error::{Error, Result};

/// The default cap on one input file: 2 GiB, above any model, schedule or
/// scene file we know of (a paper-scale scene's GLB is a few hundred MB),
/// and well within the machine's memory.
pub const DEFAULT_MAX_BYTES: u64 = 2 << 30;

static MAX_BYTES: AtomicU64 = AtomicU64::new(DEFAULT_MAX_BYTES);
static OUTSIDE: AtomicBool = AtomicBool::new(false);

/// What the process may read.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Limits {
    /// The largest input file, in bytes.
    pub max_bytes: u64,
    /// Whether a path named inside a file may lead outside that file's
    /// directory (absolute, through `..` or a symbolic link).
    pub outside: bool,
}

impl Default for Limits {
    fn default() -> Self {
        Limits {
            max_bytes: DEFAULT_MAX_BYTES,
            outside: false,
        }
    }
}

/// Sets the process's limits; the command line calls it once, first.
pub fn set_limits(limits: Limits) {
    MAX_BYTES.store(limits.max_bytes, Ordering::Relaxed);
    OUTSIDE.store(limits.outside, Ordering::Relaxed);
}

/// The process's limits.
pub fn limits() -> Limits {
    Limits {
        max_bytes: MAX_BYTES.load(Ordering::Relaxed),
        outside: OUTSIDE.load(Ordering::Relaxed),
    }
}

/// `dir/name` when `name`, named inside a file of `dir`, stays inside `dir`
/// (or the limits allow more); else why not. A path that does not exist
/// yet passes: reading it names the error.
pub fn inside(dir: &Path, name: &str) -> std::result::Result<PathBuf, String> {
    let path = dir.join(name);
    if limits().outside {
        return Ok(path);
    }
    let mut depth = 0usize;
    for part in Path::new(name).components() {
        match part {
            Component::Normal(_) => depth += 1,
            Component::CurDir => {}
            Component::ParentDir if depth > 0 => depth -= 1,
            Component::ParentDir | Component::RootDir | Component::Prefix(_) => {
                return Err(format!(
                    "{} leads outside {} (allow it with --allow-outside-paths)",
                    quote(name),
                    dir.display()
                ));
            }
        }
    }
    // A symbolic link inside may still point out.
    if let (Ok(real_dir), Ok(real)) = (dir.canonicalize(), path.canonicalize())
        && !real.starts_with(&real_dir)
    {
        return Err(format!(
            "{} leads outside {} through a symbolic link, to {} (allow it with \
             --allow-outside-paths)",
            quote(name),
            dir.display(),
            real.display()
        ));
    }
    Ok(path)
}

/// Checks what `path` is before and after it is opened: a regular file
/// within the cap. The look before keeps a FIFO from blocking the open;
/// the look after at the open file itself, which may have been replaced in
/// between.
fn check(path: &Path, meta: &std::fs::Metadata) -> Result<()> {
    if !meta.is_file() {
        let what = if meta.is_dir() {
            "a directory"
        } else {
            "not a regular file (a device, FIFO or socket)"
        };
        return Err(Error::file(path, format!("is {what}: not read")));
    }
    let cap = limits().max_bytes;
    if meta.len() > cap {
        return Err(too_large(path, meta.len(), cap));
    }
    Ok(())
}

fn too_large(path: &Path, len: u64, cap: u64) -> Error {
    Error::file(
        path,
        format!("is {len} bytes, over the cap of {cap} bytes on an input file (--max-input-bytes)"),
    )
}

/// Opens an input file: a regular file within the cap.
pub fn open(path: &Path) -> Result<File> {
    let meta = std::fs::metadata(path).map_err(|e| Error::io(path, e))?;
    check(path, &meta)?;
    let file = File::open(path).map_err(|e| Error::io(path, e))?;
    check(path, &file.metadata().map_err(|e| Error::io(path, e))?)?;
    Ok(file)
}

/// Reads an input file whole: a regular file within the cap, read no
/// further than the cap even when it grows meanwhile.
pub fn read(path: &Path) -> Result<Vec<u8>> {
    let file = open(path)?;
    let cap = limits().max_bytes;
    let len = file.metadata().map(|m| m.len()).unwrap_or(0);
    let mut bytes = Vec::with_capacity(len.min(cap) as usize);
    file.take(cap.saturating_add(1))
        .read_to_end(&mut bytes)
        .map_err(|e| Error::io(path, e))?;
    if bytes.len() as u64 > cap {
        return Err(too_large(path, bytes.len() as u64, cap));
    }
    Ok(bytes)
}

/// Reads an input file whole as UTF-8 text.
pub fn read_to_string(path: &Path) -> Result<String> {
    String::from_utf8(read(path)?).map_err(|e| {
        Error::io(
            path,
            std::io::Error::new(std::io::ErrorKind::InvalidData, e.utf8_error()),
        )
    })
}

/// At most about 100 characters of `text` in quotes, for messages that
/// echo input: the rest is counted, not repeated.
pub fn quote(text: &str) -> String {
    const KEEP: usize = 100;
    match text.char_indices().nth(KEEP) {
        None => format!("{text:?}"),
        Some((cut, _)) => format!(
            "{:?}... ({} more characters)",
            &text[..cut],
            text[cut..].chars().count()
        ),
    }
}
