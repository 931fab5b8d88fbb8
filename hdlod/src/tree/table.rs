//! `clusters.json`, written as `serde_json::to_writer` writes the clusters
//! record, byte for byte, with a newline: the clusters serialised in chunks
//! on every core.
//!
//! An update replaces a tree whose records are mostly unchanged, and
//! formatting the floats of 180,000 records again was most of its write at
//! paper scale. Given the tree it replaces ([`Previous`]), the writer copies
//! each unchanged record's bytes from the old file instead, writing afresh
//! only the ids, which an update renumbers. Whether a record is unchanged
//! is decided here, field by field against the old cluster, not taken on
//! the caller's word; the caller only says which old cluster each new one
//! came from.

use std::fs;
use std::ops::Range;
use std::path::Path;

use memchr::memmem;
use memmap2::{Mmap, MmapOptions};
use rayon::prelude::*;

use super::{Match, Tree};
use crate::error::{Error, Result};

/// The tree a write replaces ([`super::TreeWriter::finish_replacing`]):
/// its unchanged records are copied from its `clusters.json`, and its
/// object tables linked when the new ones are the same.
pub struct Previous<'a> {
    /// The old tree, as loaded from `dir`.
    pub tree: &'a Tree,
    pub dir: &'a Path,
    /// Per cluster of the new tree, the old cluster it was made from, if
    /// any; a record is copied only when its content is that cluster's.
    pub origin: &'a [Option<u32>],
    /// Its `clusters.json`, opened ahead ([`OldTable::open`]) where the
    /// caller had a core to spare; else the writer opens it.
    pub table: Option<&'a OldTable>,
}

/// The table's bytes in chunks, in order.
pub(super) struct ClustersJson<'a> {
    chunks: Vec<Chunk>,
    /// The previous table, which `Piece::Old` ranges are of.
    old: Option<Table<'a>>,
    /// How many records were copied from the previous table.
    pub(super) copied: usize,
}

/// Consecutive records of the table, without the commas before and after.
#[derive(Default)]
struct Chunk {
    /// The bytes made afresh: whole records, and the ids of records
    /// otherwise copied.
    new: Vec<u8>,
    pieces: Vec<Piece>,
    copied: usize,
}

/// A run of the chunk's bytes: of its own, or of the previous table. A
/// record copied under new ids is its ids made afresh and the rest of its
/// bytes where they are in the old file, written from there: copying
/// 150 MB of records into buffers first was most of an update's table.
enum Piece {
    New(Range<usize>),
    Old(Range<usize>),
}

impl Chunk {
    /// Appends what `write` writes to the chunk's own bytes.
    fn push_new(&mut self, write: impl FnOnce(&mut Vec<u8>)) {
        let start = self.new.len();
        write(&mut self.new);
        let end = self.new.len();
        match self.pieces.last_mut() {
            Some(Piece::New(run)) if run.end == start => run.end = end,
            _ => self.pieces.push(Piece::New(start..end)),
        }
    }

    /// Appends the previous table's bytes at `range`: a run of them goes on
    /// where the last one ended.
    fn push_old(&mut self, range: Range<usize>) {
        match self.pieces.last_mut() {
            Some(Piece::Old(run)) if run.end == range.start => run.end = range.end,
            _ => self.pieces.push(Piece::Old(range)),
        }
    }

    fn len(&self) -> usize {
        (self.pieces.iter())
            .map(|p| match p {
                Piece::New(range) | Piece::Old(range) => range.len(),
            })
            .sum()
    }
}

const OPEN: &[u8] = b"{\"clusters\":[";
const CLOSE: &[u8] = b"]}\n";
const RECORD: &[u8] = b"{\"id\":";
const LEVEL: &[u8] = b",\"level\":";
const MOTION_FROM: &[u8] = b",\"motion_from\":";

/// The previous table, opened by the writer or given.
enum Table<'a> {
    Opened(Box<OldTable>),
    Given(&'a OldTable),
}

impl std::ops::Deref for Table<'_> {
    type Target = OldTable;

    fn deref(&self) -> &OldTable {
        match self {
            Table::Opened(table) => table,
            Table::Given(table) => table,
        }
    }
}

impl<'a> ClustersJson<'a> {
    /// The table of `tree`, written to `path` later; `previous`: the tree
    /// it replaces, if any.
    pub(super) fn of(tree: &Tree, path: &Path, previous: Option<&Previous<'a>>) -> Result<Self> {
        const CHUNK: u32 = 4096;
        let old = previous.and_then(|p| {
            let table = match p.table {
                Some(table) => Table::Given(table),
                None => Table::Opened(Box::new(OldTable::open(p.tree, p.dir)?)),
            };
            Some((table, p))
        });
        let n = tree.cluster_count() as u32;
        let chunks = (0..n.div_ceil(CHUNK))
            .into_par_iter()
            .map(|k| {
                let mut chunk = Chunk::default();
                for id in k * CHUNK..((k + 1) * CHUNK).min(n) {
                    let first = id == k * CHUNK;
                    let copied = old
                        .as_ref()
                        .is_some_and(|(table, p)| table.copy(tree, p, id, &mut chunk, first));
                    if copied {
                        chunk.copied += 1;
                        continue;
                    }
                    let mut record = Ok(());
                    chunk.push_new(|out| {
                        if !first {
                            out.push(b',');
                        }
                        record = serde_json::to_writer(out, &tree.cluster_record(id));
                    });
                    record?;
                }
                Ok(chunk)
            })
            .collect::<std::result::Result<Vec<_>, serde_json::Error>>()
            .map_err(|e| Error::invalid(path, "", e.to_string()))?;
        Ok(ClustersJson {
            copied: chunks.iter().map(|c| c.copied).sum(),
            chunks,
            old: old.map(|(table, _)| table),
        })
    }

    /// The file's length in bytes.
    pub(super) fn len(&self) -> u64 {
        let commas = self.chunks.len().saturating_sub(1);
        (OPEN.len() + self.chunks.iter().map(Chunk::len).sum::<usize>() + commas + CLOSE.len())
            as u64
    }

    pub(super) fn write(&self, path: &Path) -> Result<()> {
        let old: &[u8] = self.old.as_ref().map_or(&[], |old| &old.map);
        let mut slices: Vec<&[u8]> = vec![OPEN];
        for (i, chunk) in self.chunks.iter().enumerate() {
            if i > 0 {
                slices.push(b",");
            }
            slices.extend(chunk.pieces.iter().map(|piece| match piece {
                Piece::New(range) => &chunk.new[range.clone()],
                Piece::Old(range) => &old[range.clone()],
            }));
        }
        slices.push(CLOSE);
        super::sections::write_pieces(path, slices)
    }
}

/// The old tree's `clusters.json`, mapped, and where each record starts.
pub struct OldTable {
    map: Mmap,
    /// Per old cluster, its record's first byte; one more, the end of the
    /// last record.
    starts: Vec<usize>,
    level: memmem::Finder<'static>,
    motion_from: memmem::Finder<'static>,
}

impl OldTable {
    /// The old table, when it is laid out as this writer writes it: one
    /// record per cluster, in order of id. `None` otherwise (a table written
    /// by hand, or by another writer), and nothing is copied.
    pub fn open(tree: &Tree, dir: &Path) -> Option<OldTable> {
        let path = dir.join(super::format::CLUSTERS_FILE);
        let file = fs::File::open(&path).ok()?;
        // Populated: read whole and at once, rather than a fault per page.
        // SAFETY: trees are replaced by renaming a new directory into place,
        // never rewritten in place, so the mapped bytes do not change while
        // the new table is made from them.
        let map = unsafe { MmapOptions::new().populate().map(&file) }.ok()?;
        let bytes: &[u8] = &map;
        if !bytes.starts_with(OPEN) || !bytes.ends_with(CLOSE) {
            return None;
        }
        let starts = record_starts(bytes);
        let n = tree.cluster_count();
        if starts.len() != n {
            return None;
        }
        // Each record names its id first, in order, and is followed by a
        // comma or, the last, by the table's end.
        let numbered = starts.par_iter().enumerate().all(|(i, &s)| {
            let digits = &bytes[s + RECORD.len()..];
            let mut id = itoa::Buffer::new();
            let id = id.format(i).as_bytes();
            digits.starts_with(id) && digits.get(id.len()) == Some(&b',')
        });
        let separated = starts[1..].iter().all(|&s| bytes[s - 1] == b',');
        if !numbered || !separated {
            return None;
        }
        let mut starts = starts;
        starts.push(bytes.len() - CLOSE.len() + 1);
        Some(OldTable {
            map,
            starts,
            level: memmem::Finder::new(LEVEL),
            motion_from: memmem::Finder::new(MOTION_FROM),
        })
    }

    /// Appends to `chunk` (after a comma unless `first`) the record of
    /// cluster `id` of `tree` copied from the old one it came from: as it
    /// was where its ids are the same, else with its ids written afresh.
    /// False, having appended nothing, when it did not come from one or its
    /// content changed.
    fn copy(
        &self,
        tree: &Tree,
        previous: &Previous,
        id: u32,
        chunk: &mut Chunk,
        first: bool,
    ) -> bool {
        let Some(&Some(from)) = previous.origin.get(id as usize) else {
            return false;
        };
        if from as usize >= previous.tree.cluster_count() {
            return false;
        }
        let new = tree.cluster(id);
        let motion_from = tree.motion_source(id).filter(|&s| s != id);
        let same_ids = match previous.tree.compare(from, &new, motion_from) {
            Match::Differs => return false,
            // Same ids: the new cluster's id is the old one's.
            Match::Same => true,
            Match::SameButIds => false,
        };
        // The record but its trailing comma.
        let range = self.starts[from as usize]..self.starts[from as usize + 1] - 1;
        let record = &self.map[range.clone()];
        // Where the record names the top of its chain, if it does: as the
        // new tree names it, or the record is made afresh (a chain's
        // keyframes stored otherwise by an earlier writer).
        let named = if new.motion.is_some() {
            self.motion_from.find(record)
        } else {
            None
        };
        if named.is_some() != motion_from.is_some() {
            return false;
        }
        if same_ids {
            // After the comma that ends the record before it in the old
            // file, where there is one: consecutive records make one run.
            if first {
                chunk.push_old(range);
            } else if from > 0 {
                chunk.push_old(range.start - 1..range.end);
            } else {
                chunk.push_new(|out| out.push(b','));
                chunk.push_old(range);
            }
            return true;
        }
        // Ids, parents and children are digits, commas and brackets: the
        // first `,"level":` ends them.
        let Some(level) = self.level.find(record) else {
            return false;
        };
        // In the old file: the record's bytes from `level` on, but the
        // digits of `motion_from` where it names one.
        let at = range.start;
        let (before, after) = match named {
            None => (at + level..range.end, range.end..range.end),
            Some(named) => {
                let digits = &record[named + MOTION_FROM.len()..];
                let len = digits.iter().take_while(|b| b.is_ascii_digit()).count();
                (
                    at + level..at + named,
                    at + named + MOTION_FROM.len() + len..range.end,
                )
            }
        };
        let mut ids = itoa::Buffer::new();
        chunk.push_new(|out| {
            if !first {
                out.push(b',');
            }
            out.extend_from_slice(RECORD);
            out.extend_from_slice(ids.format(id).as_bytes());
            out.extend_from_slice(b",\"parent\":");
            match new.parent {
                Some(p) => out.extend_from_slice(ids.format(p).as_bytes()),
                None => out.extend_from_slice(b"null"),
            }
            out.extend_from_slice(b",\"children\":[");
            for (i, &k) in new.children.iter().enumerate() {
                if i > 0 {
                    out.push(b',');
                }
                out.extend_from_slice(ids.format(k).as_bytes());
            }
            out.push(b']');
        });
        chunk.push_old(before);
        if let Some(source) = motion_from {
            chunk.push_new(|out| {
                out.extend_from_slice(MOTION_FROM);
                out.extend_from_slice(ids.format(source).as_bytes());
            });
        }
        if !after.is_empty() {
            chunk.push_old(after);
        }
        true
    }
}

/// Where each `{"id":` of `bytes` starts, found on every core. Outside the
/// records' starts it cannot occur: a string's quotes inside it are
/// escaped, and no other object of the table has an `id`.
fn record_starts(bytes: &[u8]) -> Vec<usize> {
    const PIECE: usize = 1 << 22;
    let finder = memmem::Finder::new(RECORD);
    (0..bytes.len().div_ceil(PIECE))
        .into_par_iter()
        .flat_map_iter(|k| {
            let from = k * PIECE;
            // Far enough past the piece for a start at its last byte.
            let to = (from + PIECE + RECORD.len() - 1).min(bytes.len());
            finder
                .find_iter(&bytes[from..to])
                .map(move |at| from + at)
                .filter(move |&at| at < from + PIECE)
                .collect::<Vec<_>>()
        })
        .collect()
}
