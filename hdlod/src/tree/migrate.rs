//! Brings a tree on disk to the current format in place (`hdlod migrate`):
//! a `hdlod-tree/1` tree's geometry moves into its shards and its manifest
//! says `hdlod-tree/2`; then its serving indexes are written if missing or
//! of an earlier version (docs/formats.md, "Migration").
//!
//! Crash safety comes from the order: every flat file is first hard-linked
//! into its shard (a file already there is kept), then the manifest is
//! replaced by a rename, then the flat files are removed. Killed before the
//! rename, the tree is a whole `hdlod-tree/1` tree with shard directories
//! beside its files, which no reader lists; after it, a whole
//! `hdlod-tree/2` tree with stray flat files, which no reader lists either.
//! Run again, the migration finishes from either state. A geometry
//! directory that is a link to a shared store (`.NAME.geometry`) is
//! migrated through the link, inside the store.

use std::fs;
use std::io::ErrorKind;
use std::path::{Path, PathBuf};

use rayon::prelude::*;

use super::format::{
    self, CLUSTERS_FILE, FORMAT, FORMAT_FLAT, GEOMETRY_DIR, INDEX_FILE, Layout, MANIFEST_FILE,
    OBJECTS_FILE, OBJECTS_INDEX_FILE, shard_of,
};
use super::index::{self, Index};
use super::object_index::ObjectRows;
use super::store;
use crate::error::{Error, Result};

/// What a migration did.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Migration {
    /// The manifest's format before.
    pub from: String,
    /// Geometry files linked into their shards by this run.
    pub linked: usize,
    /// Flat geometry files removed, each already in its shard.
    pub removed: usize,
    /// Whether the manifest was rewritten.
    pub manifest: bool,
    /// Whether the serving indexes were written.
    pub indexes: bool,
}

impl Migration {
    /// Whether the run changed anything: false on a current tree.
    pub fn changed(&self) -> bool {
        self.linked > 0 || self.removed > 0 || self.manifest || self.indexes
    }
}

/// Migrates the tree in `dir` to [`FORMAT`]; a tree already there is left
/// as it is, but for the stray flat files of an interrupted migration and
/// indexes missing or of an earlier version.
pub fn migrate(dir: impl AsRef<Path>) -> Result<Migration> {
    let dir = dir.as_ref();
    let manifest_path = dir.join(MANIFEST_FILE);
    let bytes = fs::read(&manifest_path).map_err(|e| Error::io(&manifest_path, e))?;
    // As JSON values, so that the rewrite keeps every field as it is.
    let mut manifest: serde_json::Value = serde_json::from_slice(&bytes)
        .map_err(|e| Error::invalid(&manifest_path, "", e.to_string()))?;
    let from = manifest
        .get("format")
        .and_then(|f| f.as_str())
        .unwrap_or_default()
        .to_owned();
    let layout = Layout::of_format(&from).ok_or_else(|| {
        Error::invalid(
            &manifest_path,
            "format",
            format!("{from:?} is not {FORMAT:?} nor {FORMAT_FLAT:?}"),
        )
    })?;
    let mut done = Migration {
        from,
        ..Migration::default()
    };
    let geometry = dir.join(GEOMETRY_DIR);
    let flat = flat_files(&geometry)?;
    if layout == Layout::Flat {
        // A tree with a file missing is not made into one that claims it.
        let mut tree =
            store::load_clusters(dir, true).or_else(|_| store::load_clusters(dir, false))?;
        store::check_geometry(dir, &tree)?;
        store::make_shards(&geometry)?;
        done.linked = link_into_shards(&geometry, &flat)?;
        tree.layout = Layout::Sharded;
        store::check_geometry(dir, &tree)?;
        manifest["format"] = FORMAT.into();
        let mut json = serde_json::to_vec_pretty(&manifest)
            .map_err(|e| Error::invalid(&manifest_path, "", e.to_string()))?;
        json.push(b'\n');
        store::replace(&manifest_path, &json)?;
        sync_dir(dir)?;
        done.manifest = true;
    }
    done.removed = remove_flat(&geometry, &flat)?;
    if !indexes_current(dir) {
        store::write_index(dir)?;
        done.indexes = true;
    }
    Ok(done)
}

/// The names of the `{hash}.glb` files right in `geometry` (the flat
/// layout's).
fn flat_files(geometry: &Path) -> Result<Vec<String>> {
    let mut names = Vec::new();
    for entry in fs::read_dir(geometry).map_err(|e| Error::io(geometry, e))? {
        let entry = entry.map_err(|e| Error::io(geometry, e))?;
        let Ok(name) = entry.file_name().into_string() else {
            continue;
        };
        let is_file = entry.file_type().is_ok_and(|t| t.is_file());
        if is_file
            && name
                .strip_suffix(".glb")
                .and_then(index::hash_bytes)
                .is_some()
        {
            names.push(name);
        }
    }
    Ok(names)
}

/// The shard path of the flat file `name` in `geometry`.
fn sharded(geometry: &Path, name: &str) -> PathBuf {
    geometry.join(shard_of(name)).join(name)
}

/// Hard-links each flat file into its shard, shards in parallel, and
/// flushes the shards: the links must be on disk before the manifest
/// that points at them. Returns the links made (a file already in its
/// shard, linked by an interrupted run, is kept).
fn link_into_shards(geometry: &Path, flat: &[String]) -> Result<usize> {
    let mut by_shard: Vec<Vec<&String>> = vec![Vec::new(); format::SHARDS];
    for name in flat {
        let shard = usize::from_str_radix(shard_of(name), 16).expect("a hex hash");
        by_shard[shard].push(name);
    }
    let linked = by_shard
        .par_iter()
        .enumerate()
        .map(|(shard, names)| {
            let mut linked = 0;
            for name in names {
                let from = geometry.join(name);
                let to = sharded(geometry, name);
                match fs::hard_link(&from, &to) {
                    Ok(()) => linked += 1,
                    Err(e) if e.kind() == ErrorKind::AlreadyExists => {}
                    // No hard links here: a copy, renamed into place so
                    // that an interrupted one is never taken for the file.
                    Err(_) => {
                        let tmp = to.with_extension("glb.tmp");
                        fs::copy(&from, &tmp).map_err(|e| Error::io(&from, e))?;
                        fs::File::open(&tmp)
                            .and_then(|f| f.sync_all())
                            .and_then(|()| fs::rename(&tmp, &to))
                            .map_err(|e| Error::io(&to, e))?;
                        linked += 1;
                    }
                }
            }
            sync_dir(&geometry.join(format!("{shard:02x}")))?;
            Ok(linked)
        })
        .collect::<Result<Vec<usize>>>()?;
    Ok(linked.into_iter().sum())
}

/// Removes the flat files of a sharded tree: each is in its shard already
/// (linked before the manifest changed); one that is not, which only a hand
/// edit leaves, is moved there instead. Returns the files removed.
fn remove_flat(geometry: &Path, flat: &[String]) -> Result<usize> {
    if flat.is_empty() {
        return Ok(0);
    }
    store::make_shards(geometry)?;
    let removed = flat
        .par_iter()
        .map(|name| {
            let from = geometry.join(name);
            let to = sharded(geometry, name);
            if to.exists() {
                fs::remove_file(&from).map_err(|e| Error::io(&from, e))?;
            } else {
                fs::rename(&from, &to).map_err(|e| Error::io(&to, e))?;
            }
            Ok(1)
        })
        .collect::<Result<Vec<usize>>>()?;
    Ok(removed.into_iter().sum())
}

/// Whether the tree in `dir` has its serving indexes, of the current
/// version and made from its JSON files as they are.
fn indexes_current(dir: &Path) -> bool {
    let len = |file: &str| fs::metadata(dir.join(file)).ok().map(|m| m.len());
    let clusters = Index::open(&dir.join(INDEX_FILE))
        .is_ok_and(|i| i.version() == index::VERSION && Some(i.json_len()) == len(CLUSTERS_FILE));
    let objects = !dir.join(OBJECTS_FILE).exists()
        || ObjectRows::open(&dir.join(OBJECTS_INDEX_FILE))
            .is_ok_and(|r| Some(r.json_len()) == len(OBJECTS_FILE));
    clusters && objects
}

/// Flushes a directory's entries (the names made or renamed in it).
fn sync_dir(dir: &Path) -> Result<()> {
    #[cfg(unix)]
    fs::File::open(dir)
        .and_then(|d| d.sync_all())
        .map_err(|e| Error::io(dir, e))?;
    #[cfg(not(unix))]
    let _ = dir;
    Ok(())
}
