//! The binary serving index of a tree, `clusters.bin` (`hdlod-index/3`,
//! docs/formats.md): the clusters as fixed-size little-endian records and
//! flat arrays for their variable parts, and the tree's counts and
//! baseline, memory-mapped. The cut reads its node records in place, so a
//! server touches the pages its cuts need and nothing else, and starts
//! without parsing the JSON cluster table or going over every cluster.
//!
//! `clusters.json` stays the primary form; this file is derived from it in
//! the same atomic write (or by `hdlod index TREE` for a tree written
//! without it, or with an earlier version of it). The loader checks the
//! header, the section table (`sections.rs`, shared with `objects.bin`), a
//! blake3 checksum of the whole file and every invariant the JSON loader
//! checks, on a mapping it then drops: the mapping served afterwards starts
//! with no page resident.

use rustc_hash::FxHashMap;
use std::fs::File;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use bytemuck::{Pod, Zeroable};
use glam::{Quat, Vec3};
use memmap2::Mmap;

use super::baseline::{Baseline, Present};
use super::nodes::{Node, Nodes, Step, triangle_count};
use super::sections::{self, Layout};
use super::{
    Aabb, Cluster, ClusterClass, Clusters, LevelSummary, Steps, Tree, TreeSummary, keyframe_bits,
    step_bits,
};
use crate::error::{Error, Result};
use crate::scene::{Keyframe, Motion, keys_until};

/// The first eight bytes of the file.
pub const MAGIC: [u8; 8] = *b"HDLODIDX";
/// The layout's version. Version 2 adds the tree's counts and baseline
/// (the last three sections); version 3 the clusters' triangles to the node
/// records (their padding before). A reader reads versions 1 and 2 too,
/// and derives what they lack from the clusters.
pub const VERSION: u32 = 3;
/// The sections of the newest version; version 1 has the first ten.
const SECTIONS: usize = 13;
/// The value of a `u32` field that names nothing.
pub(crate) const NONE: u32 = u32::MAX;

/// The sections, in file order.
const NODES: usize = 0;
const NODE_OF: usize = 1;
const ORDER: usize = 2;
const STEPS: usize = 3;
const CLUSTERS: usize = 4;
const KEYFRAMES: usize = 5;
const HASHES: usize = 6;
const OBJECTS: usize = 7;
const STRING_STARTS: usize = 8;
const STRINGS: usize = 9;
const COUNTS: usize = 10;
const LEVELS: usize = 11;
const BASELINE: usize = 12;
/// The header's 20..24 word is the root's id, its count the clusters.
const LAYOUT: Layout<SECTIONS> = Layout {
    magic: MAGIC,
    what: "an hdlod cluster index",
    short: "the index",
    versions: &[(1, 10), (2, SECTIONS), (VERSION, SECTIONS)],
    names: [
        "nodes",
        "node_of",
        "order",
        "steps",
        "clusters",
        "keyframes",
        "hashes",
        "objects",
        "string_starts",
        "strings",
        "counts",
        "levels",
        "baseline",
    ],
    sizes: [
        size_of::<Node>(),
        4,
        4,
        size_of::<Step>(),
        size_of::<Record>(),
        size_of::<Key>(),
        32,
        4,
        4,
        1,
        size_of::<Counts>(),
        size_of::<Level>(),
        size_of::<Change>(),
    ],
    counted: &[NODES, NODE_OF, ORDER, CLUSTERS],
    items: "clusters",
};

/// The tree's counts ([`TreeSummary`] but its levels).
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable)]
#[repr(C)]
struct Counts {
    leaves: u64,
    leaf_triangles: u64,
    /// Clusters per class, in the order of `ClusterClass::ALL`.
    classes: [u64; 4],
}

/// A [`LevelSummary`].
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable)]
#[repr(C)]
struct Level {
    level: u32,
    _pad: u32,
    clusters: u64,
    triangles: u64,
    max_eps: f64,
    max_gamma: f64,
}

/// One step of the [`Baseline`]: what is present from `t` on.
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable)]
#[repr(C)]
struct Change {
    t: f64,
    triangles: u64,
    objects: u64,
    draws: u64,
}

/// What a cluster has beside its node record, by id.
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable)]
#[repr(C)]
pub(crate) struct Record {
    triangles: u64,
    gamma: f64,
    /// [`NONE`] on the root.
    parent: u32,
    level: u32,
    /// `ClusterClass` as 0 root, 1 static, 2 pseudo-dynamic, 3 dynamic.
    class: u32,
    /// Index in the hashes, [`NONE`] on the root.
    geometry: u32,
    first_key: u32,
    key_count: u32,
    first_object: u32,
    object_count: u32,
}

#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable)]
#[repr(C)]
struct Key {
    t: f64,
    translation: [f32; 3],
    rotation: [f32; 4],
    scale: [f32; 3],
}

impl Key {
    fn keyframe(&self) -> Keyframe {
        Keyframe {
            t: self.t,
            translation: Vec3::from_array(self.translation),
            rotation: Quat::from_array(self.rotation),
            scale: Vec3::from_array(self.scale),
        }
    }
}

fn class_code(class: ClusterClass) -> u32 {
    match class {
        ClusterClass::Root => 0,
        ClusterClass::Static => 1,
        ClusterClass::PseudoDynamic => 2,
        ClusterClass::Dynamic => 3,
    }
}

fn class_of(code: u32) -> Option<ClusterClass> {
    ClusterClass::ALL.get(code as usize).copied()
}

/// A blake3 hex hash (64 lowercase digits) as its 32 bytes.
pub(crate) fn hash_bytes(hex: &str) -> Option<[u8; 32]> {
    // Each byte's digit value, 16 where it is none: a table rather than a
    // match, as an update compares every cluster's hash this way.
    const DIGIT: [u8; 256] = {
        let mut table = [16u8; 256];
        let mut d = 0;
        while d < 10 {
            table[b'0' as usize + d] = d as u8;
            d += 1;
        }
        let mut d = 0;
        while d < 6 {
            table[b'a' as usize + d] = 10 + d as u8;
            d += 1;
        }
        table
    };
    let hex = hex.as_bytes();
    if hex.len() != 64 {
        return None;
    }
    let mut out = [0u8; 32];
    let mut bad = 0;
    for (byte, pair) in out.iter_mut().zip(hex.chunks_exact(2)) {
        let (hi, lo) = (DIGIT[usize::from(pair[0])], DIGIT[usize::from(pair[1])]);
        bad |= hi | lo;
        *byte = hi << 4 | (lo & 15);
    }
    (bad < 16).then_some(out)
}

pub(crate) fn hex(bytes: &[u8; 32]) -> String {
    let mut out = Vec::with_capacity(64);
    push_hex(bytes, &mut out);
    String::from_utf8(out).expect("hexadecimal digits are ASCII")
}

/// Appends the lowercase hex of `bytes` to `out`.
pub(crate) fn push_hex(bytes: &[u8; 32], out: &mut Vec<u8>) {
    const DIGITS: &[u8; 16] = b"0123456789abcdef";
    out.extend(
        bytes
            .iter()
            .flat_map(|&b| [DIGITS[usize::from(b >> 4)], DIGITS[usize::from(b & 15)]]),
    );
}

/// The index of a valid tree, as the file's bytes; `json_len` is the
/// length of the `clusters.json` written beside it.
pub fn encode(tree: &Tree, json_len: u64) -> Vec<u8> {
    let made = unsealed(tree);
    let sections = made.sections();
    let mut out = made.parts(&sections).to_vec();
    set_json_len(&mut out, json_len);
    out
}

/// The index of a valid tree but its `clusters.json` length and checksum,
/// for [`Unsealed::parts`] to write and seal once the length is known: a
/// writer makes it while it writes that file.
pub(crate) fn unsealed(tree: &Tree) -> Unsealed {
    // The nodes, the records and the tree's figures are independent: made
    // side by side, as the writer's other tables are.
    let (nodes, (flat, (summary, baseline))) = rayon::join(
        || Nodes::new(tree),
        || rayon::join(|| Flat::of(tree), || (tree.summary(), tree.baseline())),
    );
    let class_count = |class: ClusterClass| summary.classes[class.name()] as u64;
    let counts = Counts {
        leaves: summary.leaves as u64,
        leaf_triangles: summary.leaf_triangles,
        classes: ClusterClass::ALL.map(class_count),
    };
    let levels: Vec<Level> = summary
        .levels
        .iter()
        .map(|l| Level {
            level: l.level,
            _pad: 0,
            clusters: l.clusters as u64,
            triangles: l.triangles,
            max_eps: l.max_eps,
            max_gamma: l.max_gamma,
        })
        .collect();
    let baseline: Vec<Change> = baseline
        .steps()
        .map(|(t, p)| Change {
            t,
            triangles: p.triangles,
            objects: p.objects,
            draws: p.draws,
        })
        .collect();
    Unsealed {
        nodes,
        flat,
        counts,
        levels,
        baseline,
        count: tree.cluster_count() as u32,
        root: tree.root,
    }
}

/// An index's sections, made ([`unsealed`]) and not yet laid out in a file.
pub(crate) struct Unsealed {
    nodes: Nodes,
    flat: Flat,
    counts: Counts,
    levels: Vec<Level>,
    baseline: Vec<Change>,
    count: u32,
    root: u32,
}

impl Unsealed {
    /// The sections' bytes, in file order.
    pub(crate) fn sections(&self) -> [&[u8]; SECTIONS] {
        let (nodes, flat) = (&self.nodes, &self.flat);
        [
            bytemuck::cast_slice(&nodes.nodes),
            bytemuck::cast_slice(&nodes.node_of),
            bytemuck::cast_slice(&nodes.order),
            bytemuck::cast_slice(&nodes.steps),
            bytemuck::cast_slice(&flat.records),
            bytemuck::cast_slice(&flat.keys),
            bytemuck::cast_slice(&flat.hashes),
            bytemuck::cast_slice(&flat.objects),
            bytemuck::cast_slice(&flat.string_starts),
            &flat.strings,
            bytemuck::bytes_of(&self.counts),
            bytemuck::cast_slice(&self.levels),
            bytemuck::cast_slice(&self.baseline),
        ]
    }

    /// The file of `sections` (as [`Unsealed::sections`] gives them).
    pub(crate) fn parts<'a>(&self, sections: &'a [&'a [u8]]) -> sections::Parts<'a> {
        sections::Parts::new(MAGIC, VERSION, self.count, self.root, sections)
    }
}

/// The records of an index and the flat arrays they point into.
struct Flat {
    records: Vec<Record>,
    keys: Vec<Key>,
    hashes: Vec<[u8; 32]>,
    objects: Vec<u32>,
    string_starts: Vec<u32>,
    strings: Vec<u8>,
}

impl Flat {
    fn of(tree: &Tree) -> Flat {
        let n = tree.cluster_count();
        // Object names, counted once per cluster that names them.
        let named = match &tree.clusters {
            Clusters::Built(clusters) => clusters.iter().map(|c| c.objects.len()).sum(),
            Clusters::Mapped(index) => index.section::<u32>(OBJECTS).len(),
        };
        let mut flat = Flat {
            records: Vec::with_capacity(n),
            keys: Vec::new(),
            hashes: Vec::with_capacity(n),
            objects: Vec::with_capacity(named),
            string_starts: Vec::with_capacity(named + 1),
            strings: Vec::new(),
        };
        flat.string_starts.push(0);
        // Keyed by the hashes' bytes: no string is copied to look one up.
        // Sized up front: growing them was a fifth of the records' time.
        let mut hash_ids: FxHashMap<[u8; 32], u32> =
            FxHashMap::with_capacity_and_hasher(n, Default::default());
        let mut string_ids: FxHashMap<String, u32> =
            FxHashMap::with_capacity_and_hasher(named, Default::default());
        let mut ranges: FxHashMap<u32, (u32, u32)> = FxHashMap::default();
        for c in tree.clusters() {
            let geometry = match &c.geometry {
                None => NONE,
                Some(h) => {
                    let bytes = hash_bytes(h).expect("a valid tree's hashes are hex");
                    *hash_ids.entry(bytes).or_insert_with(|| {
                        flat.hashes.push(bytes);
                        flat.hashes.len() as u32 - 1
                    })
                }
            };
            // A LOD chain's keyframes are stored once: every cluster of it
            // names the range of its top's (`Tree::motion_source`).
            let (first_key, key_count) = match tree.motion_source(c.id) {
                None => (0, 0),
                Some(source) => *ranges.entry(source).or_insert_with(|| {
                    let top = tree.cluster(source);
                    let m = top.motion.as_ref().expect("a motion source has a motion");
                    let first = flat.keys.len() as u32;
                    flat.keys.extend(m.keyframes().iter().map(|k| Key {
                        t: k.t,
                        translation: k.translation.to_array(),
                        rotation: k.rotation.to_array(),
                        scale: k.scale.to_array(),
                    }));
                    (first, m.keyframes().len() as u32)
                }),
            };
            let first_object = flat.objects.len() as u32;
            for id in &c.objects {
                let s = match string_ids.get(id.as_str()) {
                    Some(&s) => s,
                    None => {
                        flat.strings.extend_from_slice(id.as_bytes());
                        flat.string_starts.push(flat.strings.len() as u32);
                        let s = flat.string_starts.len() as u32 - 2;
                        string_ids.insert(id.clone(), s);
                        s
                    }
                };
                flat.objects.push(s);
            }
            flat.records.push(Record {
                triangles: c.triangles,
                gamma: c.gamma,
                parent: c.parent.unwrap_or(NONE),
                level: c.level,
                class: class_code(c.class),
                geometry,
                first_key,
                key_count,
                first_object,
                object_count: c.objects.len() as u32,
            });
        }
        flat
    }
}

/// Sets, in the bytes of an index, the length of the `clusters.json` it
/// was made beside, and seals it with its checksum.
pub(crate) fn set_json_len(bytes: &mut [u8], json_len: u64) {
    sections::set_json_len(bytes, json_len);
    sections::seal(bytes);
}

/// A checked, memory-mapped `clusters.bin`.
#[derive(Clone)]
pub struct Index {
    map: Arc<Mmap>,
    path: PathBuf,
    sections: [(usize, usize); SECTIONS],
    root: u32,
    version: u32,
}

impl std::fmt::Debug for Index {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Index")
            .field("path", &self.path)
            .field("clusters", &self.len())
            .finish()
    }
}

/// The file mapped. Trees are replaced by renaming a new directory into
/// place, never rewritten in place, so the mapped bytes do not change under
/// the reader.
fn map(path: &Path) -> Result<Mmap> {
    let file = File::open(path).map_err(|e| Error::io(path, e))?;
    // SAFETY: the mapping is read-only and the file is not modified while
    // mapped (see above); a file truncated under us would fault, as any
    // mapped file would.
    unsafe { Mmap::map(&file) }.map_err(|e| Error::io(path, e))
}

impl Index {
    /// Maps and checks `path`: header, version, sections, checksum, every
    /// invariant of the tree.
    pub fn open(path: &Path) -> Result<Index> {
        let index = Index::parse(map(path)?, path)?;
        // Both read the whole file: on two threads where there are two.
        let (sum, valid) = rayon::join(
            || sections::check_checksum(&LAYOUT, &index.map, path),
            || index.validate(),
        );
        // A damaged file is named as such before anything it fails.
        sum?;
        valid?;
        Ok(index)
    }

    /// The same file mapped afresh: none of its pages resident, so that
    /// what the checks and the load read is not kept. Errors when the file
    /// is no longer the one checked.
    pub fn remap(&self) -> Result<Index> {
        let fresh = Index::parse(map(&self.path)?, &self.path)?;
        if fresh.checksum() != self.checksum() || fresh.sections != self.sections {
            return Err(Error::invalid(
                &self.path,
                "header",
                "the file changed while it was being loaded",
            ));
        }
        Ok(fresh)
    }

    /// The length of the `clusters.json` the index was made from.
    pub fn json_len(&self) -> u64 {
        sections::json_len(&self.map)
    }

    /// The header and the section table, checked against the file's size.
    fn parse(map: Mmap, path: &Path) -> Result<Index> {
        let header = sections::read(&LAYOUT, &map, path)?;
        Ok(Index {
            map: Arc::new(map),
            path: path.to_owned(),
            sections: header.sections,
            root: header.word,
            version: header.version,
        })
    }

    /// The layout version of the file.
    pub fn version(&self) -> u32 {
        self.version
    }

    /// The stored checksum of the file but that field: it names the
    /// index's contents.
    pub fn checksum(&self) -> [u8; 32] {
        sections::stored_checksum(&self.map)
    }

    /// The tree's counts as the file stores them (version 2 on).
    pub(crate) fn summary(&self) -> Option<TreeSummary> {
        if self.version < 2 {
            return None;
        }
        let counts = self.section::<Counts>(COUNTS).first()?;
        Some(TreeSummary {
            clusters: self.len(),
            leaves: counts.leaves as usize,
            leaf_triangles: counts.leaf_triangles,
            classes: ClusterClass::ALL
                .iter()
                .zip(counts.classes)
                .map(|(c, n)| (c.name(), n as usize))
                .collect(),
            levels: self
                .section::<Level>(LEVELS)
                .iter()
                .map(|l| LevelSummary {
                    level: l.level,
                    clusters: l.clusters as usize,
                    triangles: l.triangles,
                    max_eps: l.max_eps,
                    max_gamma: l.max_gamma,
                })
                .collect(),
        })
    }

    /// The baseline as the file stores it (version 2 on).
    pub(crate) fn baseline(&self) -> Option<Baseline> {
        (self.version >= 2).then(|| {
            Baseline::from_steps(self.section::<Change>(BASELINE).iter().map(|c| {
                let present = Present {
                    triangles: c.triangles,
                    objects: c.objects,
                    draws: c.draws,
                };
                (c.t, present)
            }))
        })
    }

    fn section<T: Pod>(&self, k: usize) -> &[T] {
        let (a, b) = self.sections[k];
        bytemuck::cast_slice(&self.map[a..b])
    }

    pub fn len(&self) -> usize {
        self.section::<Record>(CLUSTERS).len()
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    pub fn root(&self) -> u32 {
        self.root
    }

    pub(crate) fn nodes(&self) -> &[Node] {
        self.section(NODES)
    }

    pub(crate) fn node_of(&self) -> &[u32] {
        self.section(NODE_OF)
    }

    pub(crate) fn order(&self) -> &[u32] {
        self.section(ORDER)
    }

    pub(crate) fn steps(&self) -> &[Step] {
        self.section(STEPS)
    }

    pub(crate) fn record(&self, id: u32) -> &Record {
        &self.section::<Record>(CLUSTERS)[id as usize]
    }

    fn node(&self, id: u32) -> &Node {
        &self.nodes()[self.node_of()[id as usize] as usize]
    }

    pub fn class(&self, id: u32) -> ClusterClass {
        class_of(self.record(id).class).expect("checked at open")
    }

    pub fn level(&self, id: u32) -> u32 {
        self.record(id).level
    }

    pub fn triangles(&self, id: u32) -> u64 {
        self.record(id).triangles
    }

    pub fn eps(&self, id: u32) -> f64 {
        self.node(id).eps
    }

    pub fn gamma(&self, id: u32) -> f64 {
        self.record(id).gamma
    }

    pub fn has_geometry(&self, id: u32) -> bool {
        self.record(id).geometry != NONE
    }

    pub fn object_count(&self, id: u32) -> usize {
        self.record(id).object_count as usize
    }

    pub fn children(&self, id: u32) -> &[u32] {
        let node = self.node(id);
        let first = node.first_child as usize;
        &self.section::<u32>(ORDER)[first..first + node.child_count as usize]
    }

    /// The distinct geometry hashes the clusters name.
    pub(crate) fn hashes(&self) -> &[[u8; 32]] {
        self.section(HASHES)
    }

    /// The first cluster whose geometry is `hashes()[k]`.
    pub(crate) fn cluster_with_hash(&self, k: usize) -> Option<u32> {
        self.section::<Record>(CLUSTERS)
            .iter()
            .position(|r| r.geometry as usize == k)
            .map(|id| id as u32)
    }

    /// The blake3 hex of the cluster's GLB.
    pub fn geometry(&self, id: u32) -> Option<String> {
        self.geometry_hash(id).map(hex)
    }

    /// The blake3 hash of cluster `id`'s GLB as stored; `None` on the root.
    pub fn geometry_hash(&self, id: u32) -> Option<&[u8; 32]> {
        let g = self.record(id).geometry;
        (g != NONE).then(|| &self.section::<[u8; 32]>(HASHES)[g as usize])
    }

    /// The object ids of a leaf.
    pub fn objects(&self, id: u32) -> impl ExactSizeIterator<Item = &str> + '_ {
        let r = self.record(id);
        let first = r.first_object as usize;
        self.section::<u32>(OBJECTS)[first..first + r.object_count as usize]
            .iter()
            .map(|&s| self.string(s))
    }

    fn string(&self, s: u32) -> &str {
        let starts = self.section::<u32>(STRING_STARTS);
        let bytes = &self.section::<u8>(STRINGS)
            [starts[s as usize] as usize..starts[s as usize + 1] as usize];
        std::str::from_utf8(bytes).expect("checked at open")
    }

    fn keys(&self, id: u32) -> &[Key] {
        let r = self.record(id);
        let first = r.first_key as usize;
        &self.section::<Key>(KEYFRAMES)[first..first + r.key_count as usize]
    }

    /// The interpolated keyframe of dynamic cluster `id` at `t`, as
    /// `Motion::sample` gives it, from the mapped keyframes.
    pub(crate) fn sample(&self, id: u32, t: f64) -> Keyframe {
        let keys = self.keys(id);
        let i = keys_until(keys.len(), t, |k| keys[k].t);
        if i == 0 {
            return keys[0].keyframe();
        }
        if i == keys.len() {
            return keys[i - 1].keyframe();
        }
        Motion::between(keys[i - 1].keyframe(), keys[i].keyframe(), t)
    }

    /// The visibility steps of cluster `id`.
    pub(crate) fn visibility(&self, id: u32) -> &[Step] {
        let node = self.node(id);
        let first = node.first_step as usize;
        &self.steps()[first..first + node.step_count as usize]
    }

    /// [`Cluster::same_content`] of cluster `id` and `c`, read in place:
    /// decoding every record (a motion's keyframes most of all) took longer
    /// than formatting them.
    pub(crate) fn same_content(&self, id: u32, c: &Cluster) -> bool {
        let node = self.node(id);
        let r = self.record(id);
        let floats = |b: &Aabb, w: f64, eps: f64, gamma: f64| {
            let (lo, hi) = (b.min, b.max);
            [lo.x, lo.y, lo.z, hi.x, hi.y, hi.z, w, eps, gamma].map(f64::to_bits)
        };
        let geometry = match (&c.geometry, r.geometry) {
            (None, NONE) => true,
            (Some(h), g) if g != NONE => {
                hash_bytes(h).as_ref() == Some(&self.section::<[u8; 32]>(HASHES)[g as usize])
            }
            _ => false,
        };
        let motion = match &c.motion {
            None => r.key_count == 0,
            Some(m) => (self.keys(id).iter())
                .map(|k| keyframe_bits(&k.keyframe()))
                .eq(m.keyframes().iter().map(keyframe_bits)),
        };
        r.level == c.level
            && self.class(id) == c.class
            && r.triangles == c.triangles
            && geometry
            && self.objects(id).eq(c.objects.iter().map(String::as_str))
            && floats(&node.bounds, node.w, node.eps, r.gamma)
                == floats(&c.bounds, c.w, c.eps, c.gamma)
            && (self.visibility(id).iter())
                .map(|s| step_bits((s.t, s.v)))
                .eq(c.visibility.steps().iter().map(|&s| step_bits(s)))
            && motion
    }

    /// The parent of cluster `id`; `None` for the root.
    pub(crate) fn parent(&self, id: u32) -> Option<u32> {
        let parent = self.record(id).parent;
        (parent != NONE).then_some(parent)
    }

    /// The top of cluster `id`'s LOD chain, whose keyframes it shares
    /// (`Tree::motion_source`).
    pub(crate) fn motion_source(&self, id: u32) -> Option<u32> {
        let source = self.node(id).motion;
        (source != NONE).then_some(source)
    }

    /// Cluster `id` decoded.
    pub fn cluster(&self, id: u32) -> Cluster {
        let node = self.node(id);
        let r = self.record(id);
        let motion = (r.key_count > 0).then(|| {
            Motion::new(self.keys(id).iter().map(Key::keyframe).collect()).expect("checked at open")
        });
        Cluster {
            id,
            parent: (r.parent != NONE).then_some(r.parent),
            children: self.children(id).to_vec(),
            level: r.level,
            class: self.class(id),
            bounds: node.bounds,
            w: node.w,
            eps: node.eps,
            gamma: r.gamma,
            visibility: Steps::from_checked(
                self.visibility(id).iter().map(|s| (s.t, s.v)).collect(),
            ),
            motion,
            geometry: self.geometry(id),
            triangles: r.triangles,
            objects: self.objects(id).map(str::to_owned).collect(),
        }
    }

    /// Every invariant `Tree::validate` checks, and that the records agree
    /// with each other (the breadth-first order, the children's ranges, the
    /// offsets into the flat arrays), without decoding the clusters.
    fn validate(&self) -> Result<()> {
        let n = self.len();
        let path = &self.path;
        let bad = |at: String, message: String| Error::invalid(path, at, message);
        if n == 0 {
            return Err(bad("header".into(), "the tree has no clusters".into()));
        }
        if self.root as usize >= n {
            return Err(bad(
                "header.root".into(),
                format!("root {} is not a cluster id", self.root),
            ));
        }
        let (nodes, node_of, order) = (self.nodes(), self.node_of(), self.section::<u32>(ORDER));
        let records = self.section::<Record>(CLUSTERS);
        let (steps, keys) = (self.steps(), self.section::<Key>(KEYFRAMES));
        let (hashes, objects) = (
            self.section::<[u8; 32]>(HASHES).len(),
            self.section::<u32>(OBJECTS),
        );
        let starts = self.section::<u32>(STRING_STARTS);
        let strings = self.section::<u8>(STRINGS);
        sections::check_strings(starts, strings, path)?;
        let range = |first: u32, count: u32, len: usize| {
            (first as usize)
                .checked_add(count as usize)
                .is_some_and(|end| end <= len)
        };
        // Breadth-first order: node 0 is the root, and the children of the
        // nodes in order take the following nodes in turn, each range after
        // its parent's node. Every node but the root is then in exactly
        // one range, below a node before it: one tree, no cycle.
        let mut next = 1usize;
        for (k, node) in nodes.iter().enumerate() {
            let id = node.id;
            let at = |field: &str| format!("clusters[{id}].{field}");
            if id as usize >= n || node_of[id as usize] as usize != k || order[k] != id {
                return Err(bad(
                    format!("nodes[{k}]"),
                    format!("cluster id {id} does not map back to node {k}"),
                ));
            }
            if (k == 0) != (id == self.root) {
                return Err(bad(
                    "header.root".into(),
                    format!("the first node is cluster {id}, not the root {}", self.root),
                ));
            }
            let r = &records[id as usize];
            if node.child_count > 0 {
                if node.first_child as usize != next || next <= k {
                    return Err(bad(
                        at("children"),
                        format!(
                            "start at node {}, not {next}: not in breadth-first order",
                            node.first_child
                        ),
                    ));
                }
                next += node.child_count as usize;
                if next > n {
                    return Err(bad(at("children"), "run past the last node".into()));
                }
                let first = node.first_child as usize;
                if let Some(child) = order[first..first + node.child_count as usize]
                    .iter()
                    .find(|&&c| records.get(c as usize).is_none_or(|r| r.parent != id))
                {
                    return Err(bad(
                        at("children"),
                        format!("child {child} does not name {id} as its parent"),
                    ));
                }
            }
            let Some(class) = class_of(r.class) else {
                return Err(bad(at("class"), format!("{} is no class", r.class)));
            };
            let is_root = class == ClusterClass::Root;
            if is_root != (id == self.root) {
                return Err(bad(
                    at("class"),
                    format!("only the root ({}) has class \"root\"", self.root),
                ));
            }
            if (r.parent == NONE) != is_root {
                return Err(bad(at("parent"), "only the root has no parent".into()));
            }
            let Aabb { min, max } = node.bounds;
            if !min.is_finite() || !max.is_finite() || min.cmpgt(max).any() {
                return Err(bad(
                    at("bounds"),
                    "bounds must be finite with min <= max".into(),
                ));
            }
            for (field, x) in [("w", node.w), ("eps", node.eps), ("gamma", r.gamma)] {
                if !x.is_finite() || x < 0.0 {
                    return Err(bad(at(field), format!("{x} is not a finite number >= 0")));
                }
            }
            if !range(node.first_step, node.step_count, steps.len()) {
                return Err(bad(at("visibility"), "lies outside the steps".into()));
            }
            let own = &steps[node.first_step as usize..][..node.step_count as usize];
            if own
                .iter()
                .any(|s| !s.t.is_finite() || !(0.0..=1.0).contains(&s.v))
                || own.windows(2).any(|w| w[0].t >= w[1].t)
            {
                return Err(bad(
                    at("visibility"),
                    "steps must be finite, in [0, 1], at increasing times".into(),
                ));
            }
            if (class == ClusterClass::Dynamic) != (r.key_count > 0) {
                return Err(bad(
                    at("motion"),
                    "dynamic clusters, and only they, have a motion".into(),
                ));
            }
            if !range(r.first_key, r.key_count, keys.len()) {
                return Err(bad(at("motion"), "lies outside the keyframes".into()));
            }
            let own = &keys[r.first_key as usize..][..r.key_count as usize];
            let finite = |k: &Key| {
                k.t.is_finite()
                    && k.translation
                        .iter()
                        .chain(&k.rotation)
                        .chain(&k.scale)
                        .all(|x| x.is_finite())
                    && Quat::from_array(k.rotation).length_squared() >= 1e-12
            };
            if !own.iter().all(finite) || own.windows(2).any(|w| w[0].t >= w[1].t) {
                return Err(bad(
                    at("motion"),
                    "keyframes must be finite at increasing times".into(),
                ));
            }
            if node.motion != NONE
                && records
                    .get(node.motion as usize)
                    .is_none_or(|m| m.key_count == 0)
            {
                return Err(bad(
                    format!("nodes[{k}].motion"),
                    format!("cluster {} has no motion", node.motion),
                ));
            }
            if (node.motion == NONE) != (r.key_count == 0) {
                return Err(bad(
                    format!("nodes[{k}].motion"),
                    "a node names a motion exactly when its cluster has one".into(),
                ));
            }
            if self.version >= 3 && node.triangles != triangle_count(r.triangles) {
                return Err(bad(
                    format!("nodes[{k}].triangles"),
                    format!(
                        "{} are not the cluster's {} triangles",
                        node.triangles, r.triangles
                    ),
                ));
            }
            if is_root != (r.geometry == NONE)
                || (r.geometry != NONE && r.geometry as usize >= hashes)
                || (node.has_geometry != 0) != (r.geometry != NONE)
            {
                return Err(bad(
                    at("geometry"),
                    "every cluster but the root has a geometry among the hashes".into(),
                ));
            }
            if !range(r.first_object, r.object_count, objects.len()) {
                return Err(bad(at("objects"), "lie outside the object list".into()));
            }
            let own = &objects[r.first_object as usize..][..r.object_count as usize];
            if own.iter().any(|&s| s as usize + 1 >= starts.len()) {
                return Err(bad(at("objects"), "name a string that is not there".into()));
            }
        }
        if next != n {
            return Err(bad(
                "nodes".into(),
                format!("{next} of {n} clusters hang under the root"),
            ));
        }
        if self.version >= 2 {
            self.validate_derived()?;
        }
        Ok(())
    }

    /// What version 2 stores beside the clusters: that it is whole. Its
    /// values are the writer's, from the clusters, and the checksum says
    /// they are what it wrote; they are not derived again here, which is
    /// what storing them saves.
    fn validate_derived(&self) -> Result<()> {
        let n = self.len() as u64;
        let bad = |at: &str, message: &str| Error::invalid(&self.path, at, message);
        let counts = self.section::<Counts>(COUNTS);
        let sum = |xs: &mut dyn Iterator<Item = u64>| xs.fold(0u64, u64::saturating_add);
        if counts.len() != 1 || sum(&mut counts[0].classes.iter().copied()) != n {
            return Err(bad(
                "counts",
                "must be one record whose classes add up to the clusters",
            ));
        }
        let levels = self.section::<Level>(LEVELS);
        if levels.windows(2).any(|w| w[0].level >= w[1].level)
            || sum(&mut levels.iter().map(|l| l.clusters)) != n
        {
            return Err(bad(
                "levels",
                "must be in increasing order and add up to the clusters",
            ));
        }
        let changes = self.section::<Change>(BASELINE);
        if changes.iter().any(|c| !c.t.is_finite()) || changes.windows(2).any(|w| w[0].t >= w[1].t)
        {
            return Err(bad("baseline", "times must be finite and increasing"));
        }
        Ok(())
    }
}
