//! `objects.json`, written as `serde_json::to_writer` writes the objects
//! record, byte for byte, with a newline: the object records serialised in
//! chunks on every core, and the rest of the record (its format, tasks,
//! dates and appearance) once, which is also the last section of
//! `objects.bin`. Serialised whole, through one writer, the tens of
//! megabytes of object records were one core's work, the last of an
//! update's writes to finish (`table.rs` does the same for
//! `clusters.json`).

use std::path::Path;

use memchr::memmem;
use rayon::prelude::*;

use super::objects::ObjectTables;
use crate::error::{Error, Result};
use crate::time::TimeSpan;

/// Where the object records go in the record without them.
const OBJECTS: &[u8] = b"\"objects\":[";

/// The file's bytes in pieces.
pub(super) struct ObjectsJson {
    /// The record with no objects: `{"format":…,"objects":[],…}`.
    rest: Vec<u8>,
    /// Where in `rest` the objects go: after `"objects":[`.
    at: usize,
    /// The object records in order, in chunks, without the commas between
    /// the chunks.
    chunks: Vec<Vec<u8>>,
}

impl ObjectsJson {
    pub(super) fn of(tables: &ObjectTables, time: &TimeSpan, path: &Path) -> Result<ObjectsJson> {
        Self::in_chunks(tables, time, path, 2048)
    }

    fn in_chunks(
        tables: &ObjectTables,
        time: &TimeSpan,
        path: &Path,
        chunk: u32,
    ) -> Result<ObjectsJson> {
        let bad = |e: serde_json::Error| Error::invalid(path, "", e.to_string());
        let rest = serde_json::to_vec(&tables.to_record_without_objects(time)).map_err(bad)?;
        // The format comes first, and names no objects.
        let at =
            memmem::find(&rest, OBJECTS).expect("the record names its objects") + OBJECTS.len();
        let n = tables.rows().len() as u32;
        let chunks = (0..n.div_ceil(chunk))
            .into_par_iter()
            .map(|k| {
                let mut out = Vec::new();
                for i in k * chunk..((k + 1) * chunk).min(n) {
                    if i > k * chunk {
                        out.push(b',');
                    }
                    serde_json::to_writer(&mut out, &tables.object_record(i))?;
                }
                Ok(out)
            })
            .collect::<std::result::Result<_, serde_json::Error>>()
            .map_err(bad)?;
        Ok(ObjectsJson { rest, at, chunks })
    }

    /// The record without its objects, as `objects.bin` keeps it.
    pub(super) fn rest(&self) -> &[u8] {
        &self.rest
    }

    fn pieces(&self) -> impl Iterator<Item = &[u8]> {
        let objects = self.chunks.iter().enumerate().flat_map(|(k, chunk)| {
            let comma: &[u8] = if k > 0 { b"," } else { b"" };
            [comma, chunk]
        });
        std::iter::once(&self.rest[..self.at])
            .chain(objects)
            .chain([&self.rest[self.at..], b"\n"])
    }

    /// The file's length in bytes.
    pub(super) fn len(&self) -> u64 {
        self.pieces().map(|p| p.len() as u64).sum()
    }

    /// Whether `bytes` are this file's.
    pub(super) fn is(&self, bytes: &[u8]) -> bool {
        let mut at = 0;
        self.len() == bytes.len() as u64
            && self.pieces().all(|piece| {
                let same = bytes[at..at + piece.len()] == *piece;
                at += piece.len();
                same
            })
    }

    pub(super) fn write(&self, path: &Path) -> Result<()> {
        super::sections::write_pieces(path, self.pieces())
    }
}

#[cfg(test)]
mod tests {
    use std::collections::BTreeMap;

    use super::*;
    use crate::scene::status::{Actual, Dates, TaskDates};
    use crate::scene::{Class, TaskType, Visibility};
    use crate::tree::objects::{ObjectEntry, TaskEntry};

    /// Five objects, their names and properties in need of escapes, one
    /// present from a date on (an open interval), under two tasks.
    fn tables() -> ObjectTables {
        let object = |k: u32| ObjectEntry {
            id: format!("E\"{k}"),
            name: k.is_multiple_of(2).then(|| format!("wall é{k}")),
            class: Some("IfcWall".into()),
            properties: BTreeMap::from([("storey".into(), format!("L{k}\n"))]),
            visibility_class: Class::PseudoDynamic,
            tasks: vec![k % 2],
            presence: if k == 3 {
                Visibility::from_intervals(vec![(4.0, f64::INFINITY)])
            } else {
                Visibility::always()
            },
            clusters: vec![k],
        };
        let task = |k: u32| TaskEntry {
            id: format!("T{k}"),
            name: Some(format!("Task {k}")),
            kind: TaskType::Construct,
            ifc_type: None,
            dates: TaskDates {
                start: f64::from(k),
                finish: f64::from(k) + 10.0,
                actual: Actual::default(),
                baseline: None,
            },
            parent: None,
            predecessors: Vec::new(),
            objects: (0..5).filter(|o| o % 2 == k).collect(),
        };
        ObjectTables::new(
            (0..5).map(object).collect(),
            vec![task(0), task(1)],
            Dates::Planned,
            None,
        )
    }

    #[test]
    fn the_pieces_are_the_record_serialised_whole() {
        let tables = tables();
        let time = TimeSpan {
            start: chrono::DateTime::UNIX_EPOCH,
            seconds: 100.0,
        };
        let mut whole = serde_json::to_vec(&tables.to_record(&time)).expect("serialises");
        whole.push(b'\n');
        for chunk in [1, 2, 5, 2048] {
            let json = ObjectsJson::in_chunks(&tables, &time, Path::new("objects.json"), chunk)
                .expect("serialises");
            let pieces: Vec<u8> = json.pieces().flatten().copied().collect();
            assert_eq!(
                String::from_utf8_lossy(&pieces),
                String::from_utf8_lossy(&whole),
                "in chunks of {chunk}"
            );
            assert_eq!(json.len(), whole.len() as u64);
            assert!(json.is(&whole));
            let mut other = whole.clone();
            other[json.at + 3] ^= 1;
            assert!(!json.is(&other));
            assert!(!json.is(&whole[1..]));
        }
    }
}
