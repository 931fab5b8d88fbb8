//! The container both binary indexes of a tree share (`clusters.bin` and
//! `objects.bin`, docs/formats.md): a 64-byte header, a table of
//! `(offset, length)` pairs, then the sections, each at an offset that is a
//! multiple of 8 so that they can be read in place as records. One writer
//! and one reader for both, so that a truncated file, a section out of
//! bounds or a checksum that does not match is found, and said, the same
//! way for either.
//!
//! Header: magic (8 bytes), `u32` version, `u32` section count, `u32`
//! count of the file's items, a `u32` word of the file's own, the `u64`
//! length of the JSON file it was made from, then the blake3 of bytes
//! 0..32 and 64..end.

use std::path::Path;

use crate::error::{Error, Result};

/// Bytes before the section table.
pub(crate) const HEADER: usize = 64;

/// What a file of one kind holds, for the reader's checks and errors.
pub(crate) struct Layout<const N: usize> {
    pub magic: [u8; 8],
    /// What the file is, in errors: "an hdlod cluster index".
    pub what: &'static str,
    /// The same, short: "the index".
    pub short: &'static str,
    /// Each version this reader reads with its section count: a later
    /// version adds sections at the end, so the first ones keep their
    /// meaning.
    pub versions: &'static [(u32, usize)],
    pub names: [&'static str; N],
    /// The size of one record of each section.
    pub sizes: [usize; N],
    /// The sections with one record per item of the header's count.
    pub counted: &'static [usize],
    /// The header's items, in errors: "clusters".
    pub items: &'static str,
}

/// A file's header and section table, checked against its size.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Header<const N: usize> {
    pub version: u32,
    /// Bytes 20..24, the file's own.
    pub word: u32,
    /// Byte ranges; those a version does not have are empty.
    pub sections: [(usize, usize); N],
}

/// Where the sections start with `count` of them.
fn body(count: usize) -> usize {
    HEADER + 16 * count
}

/// A file of `sections` with the checksum left zero (see [`seal`]).
pub(crate) fn write(
    magic: [u8; 8],
    version: u32,
    count: u32,
    word: u32,
    json_len: u64,
    sections: &[&[u8]],
) -> Vec<u8> {
    // Sized once: the cluster index is tens of megabytes, and growing it
    // section by section copied it again at each step.
    let size = (sections.iter()).fold(body(sections.len()), |at, bytes| {
        at.next_multiple_of(8) + bytes.len()
    });
    let mut out = Vec::with_capacity(size);
    out.resize(body(sections.len()), 0);
    out[..8].copy_from_slice(&magic);
    out[8..12].copy_from_slice(&version.to_le_bytes());
    out[12..16].copy_from_slice(&(sections.len() as u32).to_le_bytes());
    out[16..20].copy_from_slice(&count.to_le_bytes());
    out[20..24].copy_from_slice(&word.to_le_bytes());
    out[24..32].copy_from_slice(&json_len.to_le_bytes());
    for (k, bytes) in sections.iter().enumerate() {
        out.resize(out.len().next_multiple_of(8), 0);
        let (at, offset) = (HEADER + 16 * k, out.len() as u64);
        out[at..at + 8].copy_from_slice(&offset.to_le_bytes());
        out[at + 8..at + 16].copy_from_slice(&(bytes.len() as u64).to_le_bytes());
        out.extend_from_slice(bytes);
    }
    out
}

/// Sets the length of the JSON file the file is made from.
pub(crate) fn set_json_len(bytes: &mut [u8], json_len: u64) {
    bytes[24..32].copy_from_slice(&json_len.to_le_bytes());
}

/// Writes the checksum into the header.
pub(crate) fn seal(bytes: &mut [u8]) {
    let sum = checksum(bytes);
    bytes[32..64].copy_from_slice(&sum);
}

/// The blake3 hash of the file but its checksum field. Hashed on every
/// core: the cluster index of the paper scene is 95 MB, read in full
/// before a server starts.
pub(crate) fn checksum(bytes: &[u8]) -> [u8; 32] {
    *blake3::Hasher::new()
        .update(&bytes[..32])
        .update_rayon(&bytes[HEADER..])
        .finalize()
        .as_bytes()
}

/// The checksum stored in the header.
pub(crate) fn stored_checksum(bytes: &[u8]) -> [u8; 32] {
    bytes[32..64].try_into().expect("32 bytes")
}

/// The length of the JSON file the file was made from.
pub(crate) fn json_len(bytes: &[u8]) -> u64 {
    u64::from_le_bytes(bytes[24..32].try_into().expect("8 bytes"))
}

/// An error unless `starts` are offsets increasing from 0 to the length of
/// `strings` and each string between two of them is UTF-8: the string
/// table both indexes keep (each string once, named by its index).
pub(crate) fn check_strings<T: Copy + Into<u64>>(
    starts: &[T],
    strings: &[u8],
    path: &Path,
) -> Result<()> {
    let at = |i: usize| starts[i].into() as usize;
    if starts.first().map(|&s| s.into()) != Some(0)
        || (1..starts.len()).any(|i| at(i - 1) > at(i))
        || starts.last().map(|&e| e.into() as usize) != Some(strings.len())
    {
        return Err(Error::invalid(
            path,
            "string_starts",
            "offsets must increase from 0 to the strings' length",
        ));
    }
    if let Some(s) =
        (1..starts.len()).position(|i| std::str::from_utf8(&strings[at(i - 1)..at(i)]).is_err())
    {
        return Err(Error::invalid(
            path,
            format!("strings[{s}]"),
            "is not UTF-8",
        ));
    }
    Ok(())
}

/// An error unless the checksum matches the contents.
pub(crate) fn check_checksum<const N: usize>(
    layout: &Layout<N>,
    bytes: &[u8],
    path: &Path,
) -> Result<()> {
    if checksum(bytes) != stored_checksum(bytes) {
        return Err(Error::invalid(
            path,
            "header.checksum",
            format!(
                "does not match the file's contents: {} is corrupt (write it again with \
                 `hdlod index TREE`)",
                layout.short
            ),
        ));
    }
    Ok(())
}

/// The header and the section table of `bytes`: the magic, a version this
/// reader reads, every section inside the file, 8-aligned, holding whole
/// records, and the counted sections one record per item.
pub(crate) fn read<const N: usize>(
    layout: &Layout<N>,
    bytes: &[u8],
    path: &Path,
) -> Result<Header<N>> {
    let bad = |at: &str, message: String| Error::invalid(path, at, message);
    let len = bytes.len();
    if len < 8 || bytes[..8] != layout.magic {
        return Err(bad(
            "header",
            format!(
                "does not start with {:?}: not {}",
                String::from_utf8_lossy(&layout.magic),
                layout.what
            ),
        ));
    }
    let u32_at = |at: usize| u32::from_le_bytes(bytes[at..at + 4].try_into().expect("4 bytes"));
    let u64_at = |at: usize| u64::from_le_bytes(bytes[at..at + 8].try_into().expect("8 bytes"));
    if len < HEADER {
        return Err(bad(
            "header",
            format!(
                "is {len} bytes, shorter than its {}-byte header (truncated)",
                body(layout.versions.iter().map(|v| v.1).max().unwrap_or(0))
            ),
        ));
    }
    let version = u32_at(8);
    let Some(&(_, count)) = layout.versions.iter().find(|v| v.0 == version) else {
        let read: Vec<String> = layout.versions.iter().map(|v| v.0.to_string()).collect();
        return Err(bad(
            "header.version",
            format!(
                "version {version}, this reader reads {} {}: write the index again with \
                 `hdlod index TREE`",
                if read.len() > 1 {
                    "versions"
                } else {
                    "version"
                },
                match read.split_last() {
                    Some((last, [])) => last.clone(),
                    Some((last, rest)) => format!("{} and {last}", rest.join(", ")),
                    None => String::new(),
                }
            ),
        ));
    };
    if len < body(count) {
        return Err(bad(
            "header",
            format!(
                "is {len} bytes, shorter than its {}-byte header (truncated)",
                body(count)
            ),
        ));
    }
    if u32_at(12) as usize != count {
        return Err(bad(
            "header.sections",
            format!("{} sections, version {version} has {count}", u32_at(12)),
        ));
    }
    let mut sections = [(body(count), body(count)); N];
    for (k, section) in sections.iter_mut().enumerate().take(count) {
        let (offset, length) = (u64_at(HEADER + 16 * k), u64_at(HEADER + 16 * k + 8));
        let name = layout.names[k];
        let Some(end) = offset.checked_add(length).filter(|&e| e <= len as u64) else {
            return Err(bad(
                &format!("sections.{name}"),
                format!(
                    "bytes {offset} to {offset}+{length} lie beyond the file's {len} bytes \
                     (truncated)"
                ),
            ));
        };
        if offset % 8 != 0 || (offset as usize) < body(count) {
            return Err(bad(
                &format!("sections.{name}"),
                format!("offset {offset} is not a multiple of 8 after the header"),
            ));
        }
        if length % layout.sizes[k] as u64 != 0 {
            return Err(bad(
                &format!("sections.{name}"),
                format!(
                    "{length} bytes is not a whole number of {}-byte records",
                    layout.sizes[k]
                ),
            ));
        }
        *section = (offset as usize, end as usize);
    }
    let n = u32_at(16) as usize;
    for &k in layout.counted {
        let records = (sections[k].1 - sections[k].0) / layout.sizes[k];
        if records != n {
            return Err(bad(
                &format!("sections.{}", layout.names[k]),
                format!("{records} records for the header's {n} {}", layout.items),
            ));
        }
    }
    Ok(Header {
        version,
        word: u32_at(20),
        sections,
    })
}
