//! The object rows of a tree's object tables in binary (`objects.bin`,
//! `hdlod-objects-index/1`, docs/formats.md): fixed-size records, flat
//! arrays for their lists, the strings once each, the rows in id order and
//! their lower-cased search text; the tasks, which are few, as JSON. The
//! same layout serves the tables a build makes (in memory) and those a
//! server maps from disk, so a server starts without parsing the object
//! rows of `objects.json` and reads only the pages its requests need.
//!
//! `objects.json` stays the primary form; this file is derived from it in
//! the tree's atomic write (or by `hdlod index TREE`). The loader checks
//! the header, the section table and a blake3 checksum, then every
//! invariant the rows' accessors rely on: no access panics on a file that
//! loaded.

use std::collections::BTreeMap;

use rustc_hash::FxHashMap;
use std::fs::File;
use std::path::Path;
use std::sync::Arc;

use bytemuck::{Pod, Zeroable};
use memmap2::Mmap;

use super::index::NONE;
use super::objects::{ObjectEntry, Page, open_presence, push_lowercase, search_rows};
use super::sections::{self, HEADER, Layout};
use crate::error::{Error, Result};
use crate::scene::{Class, Visibility};

/// The first eight bytes of the file.
pub const MAGIC: [u8; 8] = *b"HDLODOBJ";
/// The layout's version; a reader refuses any other.
pub const VERSION: u32 = 1;
/// The header (`sections::HEADER`: its 20..24 word is reserved, 0) and
/// the section table.
const SECTIONS: usize = 11;
const BODY: usize = HEADER + SECTIONS * 16;

/// The sections, in file order.
const ROWS: usize = 0;
const PROPERTIES: usize = 1;
const TASKS: usize = 2;
const PRESENCE: usize = 3;
const CLUSTERS: usize = 4;
const BY_ID: usize = 5;
const TEXT_ENDS: usize = 6;
const TEXT: usize = 7;
const STRING_STARTS: usize = 8;
const STRINGS: usize = 9;
/// The tasks, the dates and the appearance profile, as JSON.
pub(crate) const REST: usize = 10;
const SECTION_NAMES: [&str; SECTIONS] = [
    "rows",
    "properties",
    "tasks",
    "presence",
    "clusters",
    "by_id",
    "text_ends",
    "text",
    "string_starts",
    "strings",
    "rest",
];
const SIZES: [usize; SECTIONS] = [size_of::<Row>(), 8, 4, 16, 4, 4, 8, 1, 8, 1, 1];
const LAYOUT: Layout<SECTIONS> = Layout {
    magic: MAGIC,
    what: "an hdlod object index",
    short: "the object index",
    versions: &[(VERSION, SECTIONS)],
    names: SECTION_NAMES,
    sizes: SIZES,
    counted: &[ROWS, BY_ID, TEXT_ENDS],
    items: "objects",
};

/// One object; lists are ranges of the flat sections, strings indices of
/// the string table ([`NONE`]: no name, no class).
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable)]
#[repr(C)]
struct Row {
    id: u32,
    name: u32,
    class: u32,
    /// `Class` as its index in `Class::ALL`.
    visibility_class: u32,
    first_property: u32,
    property_count: u32,
    first_task: u32,
    task_count: u32,
    first_interval: u32,
    interval_count: u32,
    first_cluster: u32,
    cluster_count: u32,
}

/// The file's bytes: made in memory (8-aligned, as the sections need) or
/// mapped.
#[derive(Clone)]
enum Bytes {
    Owned(Arc<Vec<u64>>, usize),
    Mapped(Arc<Mmap>),
}

impl std::ops::Deref for Bytes {
    type Target = [u8];

    fn deref(&self) -> &[u8] {
        match self {
            Bytes::Owned(words, len) => &bytemuck::cast_slice(words.as_slice())[..*len],
            Bytes::Mapped(map) => map,
        }
    }
}

/// The object rows, checked.
#[derive(Clone)]
pub struct ObjectRows {
    bytes: Bytes,
    sections: [(usize, usize); SECTIONS],
}

impl std::fmt::Debug for ObjectRows {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ObjectRows")
            .field("objects", &self.len())
            .finish()
    }
}

/// Rows are equal when their bytes are (the encoding is deterministic),
/// but for the header and the JSON section, which only a file has.
impl PartialEq for ObjectRows {
    fn eq(&self, other: &Self) -> bool {
        fn rows(r: &ObjectRows) -> (&[(usize, usize)], &[u8]) {
            (&r.sections[..REST], &r.bytes[BODY..r.sections[REST].0])
        }
        rows(self) == rows(other)
    }
}

/// The rows of `objects`, as the file's bytes with an empty `rest` and the
/// header's JSON length and checksum zero ([`file`] sets them).
pub(crate) fn rows_of<'a>(objects: &'a [ObjectEntry]) -> ObjectRows {
    let mut rows = Vec::with_capacity(objects.len());
    let mut properties: Vec<[u32; 2]> = Vec::new();
    let mut tasks: Vec<u32> = Vec::new();
    let mut presence: Vec<[f64; 2]> = Vec::new();
    let mut clusters: Vec<u32> = Vec::new();
    let mut text_ends: Vec<u64> = Vec::with_capacity(objects.len());
    let mut text = String::new();
    let mut string_starts: Vec<u64> = vec![0];
    let mut strings: Vec<u8> = Vec::new();
    let mut string_ids: FxHashMap<&str, u32> = FxHashMap::default();
    let mut string = |s: &'a str| -> u32 {
        *string_ids.entry(s).or_insert_with_key(|s| {
            strings.extend_from_slice(s.as_bytes());
            string_starts.push(strings.len() as u64);
            string_starts.len() as u32 - 2
        })
    };
    let range = |first: usize, end: usize| (first as u32, (end - first) as u32);
    for o in objects {
        let id = string(&o.id);
        let name = o.name.as_deref().map_or(NONE, &mut string);
        let class = o.class.as_deref().map_or(NONE, &mut string);
        let first = properties.len();
        for (k, v) in &o.properties {
            properties.push([string(k), string(v)]);
        }
        let (first_property, property_count) = range(first, properties.len());
        let first = tasks.len();
        tasks.extend(&o.tasks);
        let (first_task, task_count) = range(first, tasks.len());
        let first = presence.len();
        presence.extend(o.presence.intervals().iter().map(|&(a, b)| [a, b]));
        let (first_interval, interval_count) = range(first, presence.len());
        let first = clusters.len();
        clusters.extend(&o.clusters);
        let (first_cluster, cluster_count) = range(first, clusters.len());
        rows.push(Row {
            id,
            name,
            class,
            visibility_class: Class::ALL
                .iter()
                .position(|&c| c == o.visibility_class)
                .expect("every class is in ALL") as u32,
            first_property,
            property_count,
            first_task,
            task_count,
            first_interval,
            interval_count,
            first_cluster,
            cluster_count,
        });
        // A separator no query holds (`search` matches nothing for one
        // that does), so that no match spans two fields.
        let fields = [o.id.as_str(), o.name.as_deref().unwrap_or_default()]
            .into_iter()
            .chain(o.properties.values().map(String::as_str));
        for field in fields {
            text.push('\0');
            push_lowercase(&mut text, field);
        }
        text_ends.push(text.len() as u64);
    }
    let mut by_id: Vec<u32> = (0..objects.len() as u32).collect();
    by_id.sort_unstable_by(|&a, &b| {
        objects[a as usize]
            .id
            .cmp(&objects[b as usize].id)
            .then(a.cmp(&b))
    });
    let sections: [&[u8]; SECTIONS] = [
        bytemuck::cast_slice(&rows),
        bytemuck::cast_slice(&properties),
        bytemuck::cast_slice(&tasks),
        bytemuck::cast_slice(&presence),
        bytemuck::cast_slice(&clusters),
        bytemuck::cast_slice(&by_id),
        bytemuck::cast_slice(&text_ends),
        text.as_bytes(),
        bytemuck::cast_slice(&string_starts),
        &strings,
        &[],
    ];
    let (words, len) =
        sections::Parts::new(MAGIC, VERSION, objects.len() as u32, 0, &sections).to_words();
    ObjectRows::parse(Bytes::Owned(Arc::new(words), len), Path::new(""))
        .expect("encoded rows are well formed")
}

/// The file of `rows` with `rest` as its last section, the length of the
/// `objects.json` written beside it and the checksum set.
pub(crate) fn file<'a>(rows: &'a ObjectRows, rest: &'a [u8], json_len: u64) -> IndexFile<'a> {
    let mut body: [u8; BODY] = rows.bytes[..BODY].try_into().expect("a header and table");
    let at = HEADER + 16 * REST;
    body[at + 8..at + 16].copy_from_slice(&(rest.len() as u64).to_le_bytes());
    sections::set_json_len(&mut body, json_len);
    let rows = &rows.bytes[BODY..rows.sections[REST].0];
    let header = body[..HEADER].try_into().expect("a header");
    let sum = sections::checksum_of(header, [&body[HEADER..], rows, rest]);
    body[32..64].copy_from_slice(&sum);
    IndexFile { body, rows, rest }
}

/// An object index file ([`file`]), written from where its rows are
/// rather than copied beside its last section first.
pub(crate) struct IndexFile<'a> {
    body: [u8; BODY],
    rows: &'a [u8],
    rest: &'a [u8],
}

impl IndexFile<'_> {
    /// The file's bytes in order.
    pub(crate) fn pieces(&self) -> [&[u8]; 3] {
        [&self.body, self.rows, self.rest]
    }

    pub(crate) fn to_vec(&self) -> Vec<u8> {
        self.pieces().concat()
    }
}

impl ObjectRows {
    /// The rows with each cluster `c` they name renamed `new_id(c)`, which
    /// must keep the clusters' order (a renumbering that drops some).
    pub(crate) fn renumbered(&self, new_id: impl Fn(u32) -> u32) -> ObjectRows {
        let len = self.bytes.len();
        let mut words = vec![0u64; len.div_ceil(8)];
        let bytes = &mut bytemuck::cast_slice_mut::<u64, u8>(&mut words)[..len];
        bytes.copy_from_slice(&self.bytes);
        let (a, b) = self.sections[CLUSTERS];
        for c in bytemuck::cast_slice_mut::<u8, u32>(&mut bytes[a..b]) {
            *c = new_id(*c);
        }
        ObjectRows {
            bytes: Bytes::Owned(Arc::new(words), len),
            sections: self.sections,
        }
    }

    /// Maps `path` and checks its header, sections and checksum and every
    /// invariant of the rows; what they say of the tasks and clusters is
    /// checked with the tables ([`super::ObjectTables::validate`]).
    pub fn open(path: &Path) -> Result<ObjectRows> {
        let file = File::open(path).map_err(|e| Error::io(path, e))?;
        // SAFETY: the mapping is read-only, and trees are replaced by
        // renaming a new directory or file into place, never rewritten in
        // place (as the cluster index, `index::map`).
        let map = unsafe { Mmap::map(&file) }.map_err(|e| Error::io(path, e))?;
        let rows = ObjectRows::parse(Bytes::Mapped(Arc::new(map)), path)?;
        sections::check_checksum(&LAYOUT, &rows.bytes, path)?;
        rows.validate(path)?;
        Ok(rows)
    }

    /// The header and the section table, checked against the file's size.
    fn parse(bytes: Bytes, path: &Path) -> Result<ObjectRows> {
        let header = sections::read(&LAYOUT, &bytes, path)?;
        Ok(ObjectRows {
            bytes,
            sections: header.sections,
        })
    }

    /// Every invariant the accessors rely on: ranges within their
    /// sections, strings that are UTF-8, presence intervals in order, the
    /// id order a sorted permutation.
    fn validate(&self, path: &Path) -> Result<()> {
        let bad = |at: String, message: String| Error::invalid(path, at, message);
        let starts = self.section::<u64>(STRING_STARTS);
        let strings = self.section::<u8>(STRINGS);
        sections::check_strings(starts, strings, path)?;
        let ends = self.section::<u64>(TEXT_ENDS);
        let text = self.section::<u8>(TEXT);
        if ends.windows(2).any(|w| w[0] > w[1])
            || ends.last().map_or(0, |&e| e as usize) != text.len()
        {
            return Err(bad(
                "text_ends".into(),
                "must increase to the search text's length".into(),
            ));
        }
        let mut start = 0;
        for (i, &end) in ends.iter().enumerate() {
            if std::str::from_utf8(&text[start..end as usize]).is_err() {
                return Err(bad(format!("text[{i}]"), "is not UTF-8".into()));
            }
            start = end as usize;
        }
        let strings = starts.len() - 1;
        let string_ok = |s: u32| (s as usize) < strings;
        let within = |first: u32, count: u32, k: usize| {
            (first as usize)
                .checked_add(count as usize)
                .is_some_and(|end| end <= self.count(k))
        };
        let properties = self.section::<[u32; 2]>(PROPERTIES);
        let presence = self.section::<[f64; 2]>(PRESENCE);
        for (i, r) in self.rows().iter().enumerate() {
            let at = |field: &str| format!("objects[{i}].{field}");
            if !string_ok(r.id)
                || (r.name != NONE && !string_ok(r.name))
                || (r.class != NONE && !string_ok(r.class))
            {
                return Err(bad(at("id"), "names a string that is not there".into()));
            }
            if r.visibility_class as usize >= Class::ALL.len() {
                return Err(bad(
                    at("visibility_class"),
                    format!("{} is no class", r.visibility_class),
                ));
            }
            if !within(r.first_property, r.property_count, PROPERTIES)
                || !properties[r.first_property as usize..][..r.property_count as usize]
                    .iter()
                    .all(|&[k, v]| string_ok(k) && string_ok(v))
            {
                return Err(bad(
                    at("properties"),
                    "lie outside the properties or name a string that is not there".into(),
                ));
            }
            if !within(r.first_task, r.task_count, TASKS) {
                return Err(bad(at("tasks"), "lie outside the task lists".into()));
            }
            if !within(r.first_cluster, r.cluster_count, CLUSTERS) {
                return Err(bad(at("clusters"), "lie outside the cluster lists".into()));
            }
            if !within(r.first_interval, r.interval_count, PRESENCE) {
                return Err(bad(at("presence"), "lies outside the intervals".into()));
            }
            let own = &presence[r.first_interval as usize..][..r.interval_count as usize];
            if Visibility::from_normalised(own.iter().map(|&[a, b]| (a, b)).collect()).is_none() {
                return Err(bad(
                    at("presence"),
                    "intervals must be non-empty, sorted and apart".into(),
                ));
            }
        }
        let by_id = self.section::<u32>(BY_ID);
        let n = self.len();
        let mut seen = vec![false; n];
        for &r in by_id {
            if (r as usize) >= n || std::mem::replace(&mut seen[r as usize], true) {
                return Err(bad("by_id".into(), "must hold every object once".into()));
            }
        }
        if let Some(w) = by_id
            .windows(2)
            .find(|w| (self.id(w[0]), w[0]) > (self.id(w[1]), w[1]))
        {
            return Err(bad(
                "by_id".into(),
                format!("objects {} and {} are out of id order", w[0], w[1]),
            ));
        }
        Ok(())
    }

    /// The stored checksum of the file but that field.
    pub fn checksum(&self) -> [u8; 32] {
        sections::stored_checksum(&self.bytes)
    }

    /// The length of the `objects.json` the file was made from.
    pub fn json_len(&self) -> u64 {
        sections::json_len(&self.bytes)
    }

    /// Whether the rows are mapped from a file.
    pub fn is_mapped(&self) -> bool {
        matches!(self.bytes, Bytes::Mapped(_))
    }

    fn section<T: Pod>(&self, k: usize) -> &[T] {
        let (a, b) = self.sections[k];
        bytemuck::cast_slice(&self.bytes[a..b])
    }

    fn count(&self, k: usize) -> usize {
        (self.sections[k].1 - self.sections[k].0) / SIZES[k]
    }

    fn rows(&self) -> &[Row] {
        self.section(ROWS)
    }

    pub(crate) fn rest(&self) -> &[u8] {
        self.section(REST)
    }

    pub fn len(&self) -> usize {
        self.rows().len()
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    fn string(&self, s: u32) -> &str {
        let starts = self.section::<u64>(STRING_STARTS);
        let bytes = &self.section::<u8>(STRINGS)
            [starts[s as usize] as usize..starts[s as usize + 1] as usize];
        std::str::from_utf8(bytes).expect("checked at open")
    }

    fn optional(&self, s: u32) -> Option<&str> {
        (s != NONE).then(|| self.string(s))
    }

    pub fn id(&self, i: u32) -> &str {
        self.string(self.rows()[i as usize].id)
    }

    pub fn name(&self, i: u32) -> Option<&str> {
        self.optional(self.rows()[i as usize].name)
    }

    pub fn class(&self, i: u32) -> Option<&str> {
        self.optional(self.rows()[i as usize].class)
    }

    pub fn visibility_class(&self, i: u32) -> Class {
        Class::ALL[self.rows()[i as usize].visibility_class as usize]
    }

    /// Its properties, in key order.
    pub fn properties(&self, i: u32) -> impl ExactSizeIterator<Item = (&str, &str)> + '_ {
        let r = &self.rows()[i as usize];
        self.section::<[u32; 2]>(PROPERTIES)[r.first_property as usize..]
            [..r.property_count as usize]
            .iter()
            .map(|&[k, v]| (self.string(k), self.string(v)))
    }

    /// The value of property `key`.
    pub fn property(&self, i: u32, key: &str) -> Option<&str> {
        self.properties(i).find(|&(k, _)| k == key).map(|(_, v)| v)
    }

    pub fn tasks(&self, i: u32) -> &[u32] {
        let r = &self.rows()[i as usize];
        &self.section::<u32>(TASKS)[r.first_task as usize..][..r.task_count as usize]
    }

    pub fn clusters(&self, i: u32) -> &[u32] {
        let r = &self.rows()[i as usize];
        &self.section::<u32>(CLUSTERS)[r.first_cluster as usize..][..r.cluster_count as usize]
    }

    /// Its presence intervals `[start, end)`, infinite for an open end.
    pub fn presence(&self, i: u32) -> &[[f64; 2]] {
        let r = &self.rows()[i as usize];
        &self.section::<[f64; 2]>(PRESENCE)[r.first_interval as usize..]
            [..r.interval_count as usize]
    }

    /// Its presence as the files and the API write it: `[start, end)`,
    /// `None` for an open end.
    pub fn open_presence(&self, i: u32) -> Vec<[Option<f64>; 2]> {
        open_presence(self.presence(i).iter().copied())
    }

    /// Object `i` decoded.
    pub fn entry(&self, i: u32) -> ObjectEntry {
        ObjectEntry {
            id: self.id(i).to_owned(),
            name: self.name(i).map(str::to_owned),
            class: self.class(i).map(str::to_owned),
            properties: self
                .properties(i)
                .map(|(k, v)| (k.to_owned(), v.to_owned()))
                .collect::<BTreeMap<_, _>>(),
            visibility_class: self.visibility_class(i),
            tasks: self.tasks(i).to_vec(),
            presence: Visibility::from_normalised(
                self.presence(i).iter().map(|&[a, b]| (a, b)).collect(),
            )
            .expect("checked at open"),
            clusters: self.clusters(i).to_vec(),
        }
    }

    /// The first object with this id: a binary search of the id order.
    pub fn find(&self, id: &str) -> Option<u32> {
        let by_id = self.section::<u32>(BY_ID);
        let k = by_id.partition_point(|&r| self.id(r) < id);
        by_id.get(k).copied().filter(|&r| self.id(r) == id)
    }

    /// An object whose id an earlier object in id order has, and that one.
    pub fn duplicate(&self) -> Option<(u32, u32)> {
        self.section::<u32>(BY_ID)
            .windows(2)
            .find(|w| self.id(w[0]) == self.id(w[1]))
            .map(|w| (w[1], w[0]))
    }

    /// Objects whose id, name or any property value contains `query`
    /// (lower-cased by the caller), as `ObjectTables::search_objects`.
    pub fn search(&self, query: &str, from: usize, limit: usize) -> Page {
        let ends = self.section::<u64>(TEXT_ENDS);
        // Checked once per search, not per row: each row was checked to
        // be UTF-8 at open, so the rows' ends are character boundaries.
        let text = std::str::from_utf8(self.section::<u8>(TEXT)).expect("checked at open");
        let row = |i: usize| {
            let start = if i == 0 { 0 } else { ends[i - 1] as usize };
            &text[start..ends[i] as usize]
        };
        search_rows(ends.len(), row, query, from, limit)
    }
}
