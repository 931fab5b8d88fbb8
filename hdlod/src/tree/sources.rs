//! `sources.bin` (`hdlod-sources/1`, docs/formats.md): per scene object, in
//! scene order, a digest of what its leaves are made of (its mesh,
//! placement, colour and motion). The builder writes it; a later build of
//! an edited scene compares it with the new scene's to find the objects
//! whose geometry changed (`build::local`). Optional: a tree without it
//! loads, and is rebuilt in full rather than updated.
//!
//! Layout, little-endian: the magic `HDLODSRC`, a `u32` version (1), a
//! `u32` count, then `count` digests of 16 bytes.

use std::path::Path;

use crate::error::{Error, Result};

/// One object's digest: the first 16 bytes of a blake3 hash.
pub type Digest = [u8; 16];

const MAGIC: &[u8; 8] = b"HDLODSRC";
const VERSION: u32 = 1;
const HEADER: usize = 16;

pub fn encode(digests: &[Digest]) -> Vec<u8> {
    let mut out = Vec::with_capacity(HEADER + digests.len() * 16);
    out.extend_from_slice(MAGIC);
    out.extend_from_slice(&VERSION.to_le_bytes());
    out.extend_from_slice(&(digests.len() as u32).to_le_bytes());
    for d in digests {
        out.extend_from_slice(d);
    }
    out
}

/// The digests of `bytes`, read from `file` (named in errors).
pub fn decode(bytes: &[u8], file: &Path) -> Result<Vec<Digest>> {
    let invalid = |at: &str, message: String| Error::invalid(file, at, message);
    if bytes.len() < HEADER || &bytes[..8] != MAGIC {
        return Err(invalid("header", "not an hdlod sources file".into()));
    }
    let word = |at: usize| u32::from_le_bytes(bytes[at..at + 4].try_into().expect("4 bytes"));
    let version = word(8);
    if version != VERSION {
        return Err(invalid(
            "header.version",
            format!("version {version}: this build reads version {VERSION}"),
        ));
    }
    let count = word(12) as usize;
    let body = &bytes[HEADER..];
    if body.len() != count * 16 {
        return Err(invalid(
            "header.count",
            format!(
                "{count} digests need {} bytes, the file has {}",
                count * 16,
                body.len()
            ),
        ));
    }
    Ok(body
        .chunks_exact(16)
        .map(|c| c.try_into().expect("16 bytes"))
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip_and_damage() {
        let digests = vec![[1u8; 16], [7u8; 16]];
        let bytes = encode(&digests);
        let file = Path::new("sources.bin");
        assert_eq!(decode(&bytes, file).unwrap(), digests);
        let short = decode(&bytes[..bytes.len() - 1], file).unwrap_err();
        assert!(short.to_string().contains("header.count"), "{short}");
        let mut newer = bytes.clone();
        newer[8] = 2;
        let newer = decode(&newer, file).unwrap_err();
        assert!(newer.to_string().contains("version 2"), "{newer}");
        assert!(decode(b"not a sources file", file).is_err());
    }
}
