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

/// A file's header and section table, and its sections where they are:
/// written to a file piece by piece ([`Parts::write`]) and sealed there
/// ([`Parts::sealed_header`]), rather than copied into one buffer of the
/// file's size first (the cluster index of the paper scene is 67 MB,
/// whose pages were faulted in for a copy that the write makes again).
pub(crate) struct Parts<'a> {
    /// The header (its JSON length and checksum zero) and the table.
    body: Vec<u8>,
    sections: &'a [&'a [u8]],
}

/// Zeros that pad a section to a multiple of 8 bytes.
const PADDING: [u8; 8] = [0; 8];

impl<'a> Parts<'a> {
    pub(crate) fn new(
        magic: [u8; 8],
        version: u32,
        count: u32,
        word: u32,
        sections: &'a [&'a [u8]],
    ) -> Parts<'a> {
        let mut body = vec![0; self::body(sections.len())];
        body[..8].copy_from_slice(&magic);
        body[8..12].copy_from_slice(&version.to_le_bytes());
        body[12..16].copy_from_slice(&(sections.len() as u32).to_le_bytes());
        body[16..20].copy_from_slice(&count.to_le_bytes());
        body[20..24].copy_from_slice(&word.to_le_bytes());
        let mut offset = body.len();
        for (k, bytes) in sections.iter().enumerate() {
            offset = offset.next_multiple_of(8);
            let at = HEADER + 16 * k;
            body[at..at + 8].copy_from_slice(&(offset as u64).to_le_bytes());
            body[at + 8..at + 16].copy_from_slice(&(bytes.len() as u64).to_le_bytes());
            offset += bytes.len();
        }
        Parts { body, sections }
    }

    /// The file's bytes in order: the body, then each section after the
    /// zeros that align it.
    fn pieces(&self) -> impl Iterator<Item = &[u8]> {
        let mut at = self.body.len();
        std::iter::once(&self.body[..]).chain(self.sections.iter().flat_map(move |&bytes| {
            let pad = at.next_multiple_of(8) - at;
            at += pad + bytes.len();
            [&PADDING[..pad], bytes]
        }))
    }

    /// The whole file, its checksum zero.
    pub(crate) fn to_vec(&self) -> Vec<u8> {
        let mut out = Vec::with_capacity(self.pieces().map(<[u8]>::len).sum());
        self.pieces().for_each(|piece| out.extend_from_slice(piece));
        out
    }

    /// The whole file, its checksum zero, in words (8-aligned, as reading
    /// its sections in place needs), and its length in bytes.
    pub(crate) fn to_words(&self) -> (Vec<u64>, usize) {
        let len: usize = self.pieces().map(<[u8]>::len).sum();
        let mut words = vec![0u64; len.div_ceil(8)];
        let mut at = 0;
        let bytes = bytemuck::cast_slice_mut::<u64, u8>(&mut words);
        for piece in self.pieces() {
            bytes[at..at + piece.len()].copy_from_slice(piece);
            at += piece.len();
        }
        (words, len)
    }

    /// Writes the file, its JSON length and checksum zero, to `file`.
    pub(crate) fn write(&self, file: &mut std::fs::File) -> std::io::Result<()> {
        let mut slices: Vec<std::io::IoSlice> = self.pieces().map(std::io::IoSlice::new).collect();
        write_all_vectored(file, &mut slices)
    }

    /// The header of the file with `json_len` set and sealed, as [`seal`]
    /// seals the whole file: for the first [`HEADER`] bytes of a file
    /// [`Parts::write`] wrote.
    pub(crate) fn sealed_header(&self, json_len: u64) -> [u8; HEADER] {
        let mut header: [u8; HEADER] = self.body[..HEADER].try_into().expect("a header");
        set_json_len(&mut header, json_len);
        let body = &self.body[HEADER..];
        let sum = checksum_of(&header, std::iter::once(body).chain(self.pieces().skip(1)));
        header[32..64].copy_from_slice(&sum);
        header
    }
}

/// Writes `pieces`, in order, to a new file at `path`, synced: in a few
/// vectored writes from where the pieces are, rather than copied into one
/// buffer first.
pub(crate) fn write_pieces<'a>(
    path: &std::path::Path,
    pieces: impl IntoIterator<Item = &'a [u8]>,
) -> Result<()> {
    let mut slices: Vec<std::io::IoSlice> = pieces.into_iter().map(std::io::IoSlice::new).collect();
    let mut file = std::fs::File::create(path).map_err(|e| Error::io(path, e))?;
    write_all_vectored(&mut file, &mut slices)
        .and_then(|()| file.sync_all())
        .map_err(|e| Error::io(path, e))
}

/// `Write::write_all_vectored`, which is not stable: a few calls for
/// pieces that would take a call each.
fn write_all_vectored(
    file: &mut std::fs::File,
    mut slices: &mut [std::io::IoSlice<'_>],
) -> std::io::Result<()> {
    use std::io::Write;
    // Linux takes at most 1,024 slices a call (`IOV_MAX`).
    const MOST: usize = 1024;
    while !slices.is_empty() {
        let take = slices.len().min(MOST);
        match file.write_vectored(&slices[..take]) {
            Ok(0) => return Err(std::io::ErrorKind::WriteZero.into()),
            Ok(n) => std::io::IoSlice::advance_slices(&mut slices, n),
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e),
        }
    }
    Ok(())
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

/// [`checksum`] of the file of `header` followed by `rest`, in pieces.
pub(crate) fn checksum_of<'a>(
    header: &[u8; HEADER],
    rest: impl IntoIterator<Item = &'a [u8]>,
) -> [u8; 32] {
    let mut hasher = blake3::Hasher::new();
    hasher.update(&header[..32]);
    for piece in rest {
        hasher.update_rayon(piece);
    }
    *hasher.finalize().as_bytes()
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
