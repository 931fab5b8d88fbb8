//! The tree on disk: content-addressed GLB blobs under `geometry/`, in 256
//! shards by hash prefix ([`Layout`]), an atomic write of the whole
//! directory (docs/method.md section 8), and the migration of a tree of the
//! previous format ([`super::migrate`]).
//!
//! Atomicity: everything is written into a temporary directory beside the
//! target, then renamed into place. A failed or interrupted build leaves the
//! previous tree as it was; a reader sees either the old or the new tree,
//! except for the instant between the two renames of a replacement (the old
//! tree moved aside, the new one not yet in place), when the target is
//! missing and a reader must retry or keep what it has loaded.
//!
//! A schedule update keeps every geometry file, and linking each one into
//! the new directory costs seconds at paper scale. Instead the geometry
//! directory is shared between the two generations: it moves once into a
//! store beside the tree, `.NAME.geometry`, and each generation's
//! `geometry` is a relative symbolic link to it (docs/formats.md, "The
//! geometry store"). The move is one atomic exchange of the directory with
//! the link (`renameat2(RENAME_EXCHANGE)`, Linux), so a reader of the old
//! tree finds its files throughout, and content addressing makes the
//! store safe to share: a new generation only adds files.

use std::collections::HashSet;
use std::fs;
use std::hash::{BuildHasherDefault, Hasher};
use std::io::{BufWriter, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::sync::atomic::{AtomicU64, Ordering};

use rustc_hash::FxHashSet;

use super::Tree;
use super::format::{
    self, CLUSTERS_FILE, GEOMETRY_DIR, INDEX_FILE, Layout, MANIFEST_FILE, OBJECTS_FILE,
    OBJECTS_INDEX_FILE, SKINS_FILE, SOURCES_FILE,
};
use super::index::{self, Index};
use super::object_index::ObjectRows;
use super::objects::{ObjectTables, ObjectsRecord};
use super::objects_json::ObjectsJson;
use super::table::{ClustersJson, Previous};
use crate::error::{Error, Result};

static SEQUENCE: AtomicU64 = AtomicU64::new(0);

/// A path beside `target`: `.NAME.KIND-PID-N`, hidden and on the same file
/// system so that the final rename is atomic.
fn sibling(target: &Path, kind: &str) -> PathBuf {
    let name = target
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| "tree".into());
    let n = SEQUENCE.fetch_add(1, Ordering::Relaxed);
    target.with_file_name(format!(".{name}.{kind}-{}-{n}", std::process::id()))
}

/// Writes a tree: geometry first (from any thread), then [`TreeWriter::finish`]
/// with the cluster table. Dropped without `finish`, it removes its
/// temporary directory and leaves the target untouched.
pub struct TreeWriter {
    target: PathBuf,
    tmp: PathBuf,
    /// The hashes stored, as bytes: an update shares 120,000 files.
    stored: Mutex<FxHashSet<[u8; 32]>>,
    finished: bool,
}

impl TreeWriter {
    pub fn create(target: impl Into<PathBuf>) -> Result<Self> {
        let target: PathBuf = target.into();
        if let Some(parent) = target.parent().filter(|p| !p.as_os_str().is_empty()) {
            fs::create_dir_all(parent).map_err(|e| Error::io(parent, e))?;
        }
        crate::debris::remove_stale(&target);
        let tmp = sibling(&target, "tmp");
        let writer = TreeWriter {
            target,
            tmp,
            stored: Mutex::new(FxHashSet::default()),
            finished: false,
        };
        // Made up front, so that storing a file is one create.
        make_shards(&writer.tmp.join(GEOMETRY_DIR))?;
        Ok(writer)
    }

    /// Stores the geometry file `hash` of the tree in `from`, whose
    /// geometry lies as `layout` says, without reading it: a hard link
    /// where the file system allows (trees are immutable, so sharing the
    /// file is safe), else a copy.
    pub fn reuse_geometry(&self, from: &Path, layout: Layout, hash: &str) -> Result<()> {
        let source = layout.geometry_file(from, hash);
        let path = Layout::Sharded.geometry_file(&self.tmp, hash);
        // Stored already, maybe as a link to `source`: a copy onto it would
        // truncate the file it is copying.
        if fs::symlink_metadata(&path).is_ok() {
            return Ok(());
        }
        if fs::hard_link(&source, &path).is_err() {
            fs::copy(&source, &path).map_err(|e| Error::io(&source, e))?;
        }
        if let Some(bytes) = index::hash_bytes(hash) {
            self.stored
                .lock()
                .expect("no panic while holding")
                .insert(bytes);
        }
        Ok(())
    }

    /// Makes the new tree's `geometry` the geometry directory of the tree
    /// now at the target, shared rather than copied: the store that tree
    /// links to, or its own directory moved into the store `.NAME.geometry`
    /// beside it by one atomic exchange with a link to it. `hashes`: the
    /// files the new tree uses, all the old tree's; `layout`: the old
    /// tree's. Answers false, having changed nothing, where the exchange is
    /// not available (not Linux, or a file system without it) or the old
    /// tree's geometry is not sharded as the new tree's is; the caller then
    /// reuses the files one by one.
    pub fn share_geometry(
        &self,
        layout: Layout,
        hashes: impl IntoIterator<Item = [u8; 32]>,
    ) -> Result<bool> {
        if layout != Layout::Sharded {
            return Ok(false);
        }
        let old = self.target.join(GEOMETRY_DIR);
        let meta = fs::symlink_metadata(&old).map_err(|e| Error::io(&old, e))?;
        let link = if meta.file_type().is_symlink() {
            fs::read_link(&old).map_err(|e| Error::io(&old, e))?
        } else {
            let store = store_of(&self.target);
            let link = Path::new("..").join(store.file_name().expect("a store has a name"));
            // Left by an interrupted move (a dangling link) or by a full
            // build that replaced a tree with a store: nothing uses it.
            if let Ok(m) = fs::symlink_metadata(&store) {
                let removed = if m.is_dir() {
                    fs::remove_dir_all(&store)
                } else {
                    fs::remove_file(&store)
                };
                removed.map_err(|e| Error::io(&store, e))?;
            }
            // Made where the store goes, then exchanged with the directory:
            // the link lands in the tree (where `../` is the tree's parent),
            // the directory in the store's place, in one step.
            if !symlink(&link, &store)? {
                return Ok(false);
            }
            if !exchange(&old, &store) {
                let _ = fs::remove_file(&store);
                return Ok(false);
            }
            link
        };
        let path = self.tmp.join(GEOMETRY_DIR);
        // Its shards, empty.
        fs::remove_dir_all(&path).map_err(|e| Error::io(&path, e))?;
        if !symlink(&link, &path)? {
            return Err(Error::io(
                &path,
                std::io::Error::other("cannot link to the geometry store"),
            ));
        }
        self.stored
            .lock()
            .expect("no panic while holding")
            .extend(hashes);
        Ok(true)
    }

    /// Stores GLB bytes under the blake3 hex of their content and returns
    /// that hash; identical bytes are stored once.
    pub fn put_geometry(&self, glb: &[u8]) -> Result<String> {
        let digest = blake3::hash(glb);
        let hash = digest.to_hex().to_string();
        let bytes = *digest.as_bytes();
        if self
            .stored
            .lock()
            .expect("no panic while holding")
            .contains(&bytes)
        {
            return Ok(hash);
        }
        let path = Layout::Sharded.geometry_file(&self.tmp, &hash);
        fs::write(&path, glb).map_err(|e| Error::io(&path, e))?;
        self.stored
            .lock()
            .expect("no panic while holding")
            .insert(bytes);
        Ok(hash)
    }

    /// An error unless every geometry hash of `tree` was stored.
    fn check_stored(&self, tree: &Tree, clusters_path: &Path) -> Result<()> {
        let stored = self.stored.lock().expect("no panic while holding");
        for c in tree.clusters() {
            if let Some(h) = &c.geometry
                && !index::hash_bytes(h).is_some_and(|b| stored.contains(&b))
            {
                return Err(Error::invalid(
                    clusters_path,
                    format!("clusters[{}].geometry", c.id),
                    format!("geometry {h} was not stored with put_geometry"),
                ));
            }
        }
        Ok(())
    }

    /// Validates the tree (including that every geometry hash was stored),
    /// writes the manifest, the cluster table and the object and task
    /// tables when the tree has them, and moves the directory into place.
    pub fn finish(self, tree: &Tree) -> Result<()> {
        self.finish_with(tree, None).map(|_| ())
    }

    /// [`TreeWriter::finish`] for a tree that replaces `previous`, an
    /// update of it: the unchanged records of `clusters.json` are copied
    /// from the old file. The files are those `finish` writes, byte for
    /// byte. Answers how many records were copied.
    pub fn finish_replacing(self, tree: &Tree, previous: &Previous) -> Result<usize> {
        self.finish_with(tree, Some(previous))
    }

    fn finish_with(mut self, tree: &Tree, previous: Option<&Previous>) -> Result<usize> {
        let clock = std::time::Instant::now();
        let mut lap = {
            let mut last = clock.elapsed();
            move || {
                let now = clock.elapsed();
                let lap = (now - last).as_secs_f64();
                last = now;
                lap
            }
        };
        let clusters_path = self.target.join(CLUSTERS_FILE);
        let objects_path = self.target.join(OBJECTS_FILE);
        let (clusters_valid, (objects_valid, stored_valid)) = rayon::join(
            || tree.validate(&clusters_path),
            || {
                rayon::join(
                    || match &tree.objects {
                        Some(tables) => tables.validate(tree, &objects_path),
                        None => Ok(()),
                    },
                    || self.check_stored(tree, &clusters_path),
                )
            },
        );
        clusters_valid?;
        objects_valid?;
        stored_valid?;
        if let Some(skins) = &tree.skins {
            skins.validate(tree, &self.target.join(SKINS_FILE))?;
        }
        let validated = lap();
        write_json(&self.tmp.join(MANIFEST_FILE), &tree.manifest_record(), true)?;
        // The cluster table is most of the time at paper scale (hundreds of
        // megabytes): serialised in chunks on every core and written while
        // the index and the object tables are made beside it. The index
        // names the table's length, known last: it is written beside the
        // table but for its header, which is set and sealed afterwards.
        // The sources and the skins too: the skins' JSON is megabytes where
        // a scene has many skinned objects.
        let index_path = self.tmp.join(INDEX_FILE);
        let (table, (index, (objects, others))) = rayon::join(
            || -> Result<(u64, usize)> {
                let table = ClustersJson::of(tree, &self.tmp.join(CLUSTERS_FILE), previous)?;
                table.write(&self.tmp.join(CLUSTERS_FILE))?;
                Ok((table.len(), table.copied))
            },
            || {
                rayon::join(
                    || -> Result<(index::Unsealed, fs::File)> {
                        let made = index::unsealed(tree);
                        let mut file =
                            fs::File::create(&index_path).map_err(|e| Error::io(&index_path, e))?;
                        (made.parts(&made.sections()).write(&mut file))
                            .map_err(|e| Error::io(&index_path, e))?;
                        Ok((made, file))
                    },
                    || {
                        rayon::join(
                            || match &tree.objects {
                                Some(tables) => self.write_objects(tables, tree, previous),
                                None => Ok(()),
                            },
                            || self.write_sources_and_skins(tree, previous),
                        )
                    },
                )
            },
        );
        let (json_len, copied) = table?;
        objects?;
        others?;
        let (made, mut index_file) = index?;
        let header = made.parts(&made.sections()).sealed_header(json_len);
        index_file
            .seek(SeekFrom::Start(0))
            .and_then(|_| index_file.write_all(&header))
            .and_then(|()| index_file.sync_all())
            .map_err(|e| Error::io(&index_path, e))?;
        drop(made);
        let serialised = lap();

        let old = sibling(&self.target, "old");
        let had_old = self.target.exists();
        if had_old {
            fs::rename(&self.target, &old).map_err(|e| Error::io(&self.target, e))?;
        }
        if let Err(e) = fs::rename(&self.tmp, &self.target) {
            if had_old {
                let _ = fs::rename(&old, &self.target);
            }
            return Err(Error::io(&self.target, e));
        }
        self.finished = true;
        if had_old {
            // Removes the link to a shared store, not the store.
            fs::remove_dir_all(&old).map_err(|e| Error::io(&old, e))?;
        }
        // A full build over a tree with a store leaves the store unused.
        let shared = fs::symlink_metadata(self.target.join(GEOMETRY_DIR))
            .is_ok_and(|m| m.file_type().is_symlink());
        let store = store_of(&self.target);
        if !shared && fs::symlink_metadata(&store).is_ok() {
            fs::remove_dir_all(&store).map_err(|e| Error::io(&store, e))?;
        }
        tracing::debug!(
            "{}: validated in {validated:.2} s, the tables, the indexes, the sources and the \
             skins made and written in {serialised:.2} s ({copied} of {} cluster records \
             copied from the tree replaced), moved into place and the old tree removed in \
             {:.2} s",
            self.target.display(),
            tree.cluster_count(),
            lap()
        );
        Ok(copied)
    }
}

impl TreeWriter {
    /// Writes `sources.bin` and `skins.json`, where the tree has them;
    /// where the skins are those of the tree replaced (an update that
    /// added or removed no skinned object), links that tree's
    /// `skins.json`, which it was loaded from: megabytes of JSON that
    /// would be made again the same.
    fn write_sources_and_skins(&self, tree: &Tree, previous: Option<&Previous>) -> Result<()> {
        if let Some(digests) = &tree.sources {
            write_bytes(
                &self.tmp.join(SOURCES_FILE),
                &super::sources::encode(digests),
            )?;
        }
        if let Some(skins) = tree.skins.as_ref().filter(|s| !s.is_empty()) {
            let path = self.tmp.join(SKINS_FILE);
            let linked = previous.is_some_and(|p| {
                p.tree.skins.as_ref() == Some(skins)
                    && fs::hard_link(p.dir.join(SKINS_FILE), &path).is_ok()
            });
            if !linked {
                write_json(&path, &skins.to_record(), false)?;
            }
        }
        Ok(())
    }

    /// Writes `objects.json` and `objects.bin`; where the JSON is that of
    /// the tree replaced, byte for byte (an update that moved geometry
    /// only), links that tree's two files instead: the binary rows are made
    /// from the same tables, so they are the same too.
    fn write_objects(
        &self,
        tables: &ObjectTables,
        tree: &Tree,
        previous: Option<&Previous>,
    ) -> Result<()> {
        let (json_path, index_path) = (
            self.tmp.join(OBJECTS_FILE),
            self.tmp.join(OBJECTS_INDEX_FILE),
        );
        let json = ObjectsJson::of(tables, &tree.time, &json_path)?;
        if let Some(p) = previous {
            let (old_json, old_index) = (p.dir.join(OBJECTS_FILE), p.dir.join(OBJECTS_INDEX_FILE));
            let current = |path: &Path| {
                let mut header = [0u8; 12];
                fs::File::open(path)
                    .and_then(|mut f| std::io::Read::read_exact(&mut f, &mut header))
                    .is_ok_and(|()| header[8..12] == super::object_index::VERSION.to_le_bytes())
            };
            // Read only when it may be the same: a removal changes its length.
            let same_len = |path: &Path| fs::metadata(path).is_ok_and(|m| m.len() == json.len());
            if current(&old_index)
                && same_len(&old_json)
                && fs::read(&old_json).is_ok_and(|old| json.is(&old))
                && fs::hard_link(&old_json, &json_path).is_ok()
                && fs::hard_link(&old_index, &index_path).is_ok()
            {
                return Ok(());
            }
            // A link made before the other failed.
            let _ = fs::remove_file(&json_path);
        }
        let (written, index) = rayon::join(
            || json.write(&json_path),
            || {
                let index = tables.to_index(json.rest(), json.len());
                super::sections::write_pieces(&index_path, index.pieces())
            },
        );
        written.and(index)
    }
}

/// Makes `geometry` and its [`format::SHARDS`] shard directories (those
/// there already are kept).
pub(super) fn make_shards(geometry: &Path) -> Result<()> {
    fs::create_dir_all(geometry).map_err(|e| Error::io(geometry, e))?;
    for name in format::shard_names() {
        let shard = geometry.join(name);
        match fs::create_dir(&shard) {
            Err(e) if e.kind() != std::io::ErrorKind::AlreadyExists => {
                return Err(Error::io(&shard, e));
            }
            _ => {}
        }
    }
    Ok(())
}

/// The geometry store of `target` when its generations share their
/// geometry: `.NAME.geometry` beside it.
fn store_of(target: &Path) -> PathBuf {
    let name = target
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| "tree".into());
    target.with_file_name(format!(".{name}.geometry"))
}

/// A symbolic link at `path` to `to`; false where there are none.
#[cfg(unix)]
fn symlink(to: &Path, path: &Path) -> Result<bool> {
    std::os::unix::fs::symlink(to, path)
        .map(|()| true)
        .map_err(|e| Error::io(path, e))
}

#[cfg(not(unix))]
fn symlink(_to: &Path, _path: &Path) -> Result<bool> {
    Ok(false)
}

/// Swaps the entries `a` and `b` in one step (`renameat2` with
/// `RENAME_EXCHANGE`); false where the system or file system cannot.
#[cfg(target_os = "linux")]
fn exchange(a: &Path, b: &Path) -> bool {
    use std::ffi::CString;
    use std::os::unix::ffi::OsStrExt;
    let (Ok(a), Ok(b)) = (
        CString::new(a.as_os_str().as_bytes()),
        CString::new(b.as_os_str().as_bytes()),
    ) else {
        return false;
    };
    // SAFETY: both paths are NUL-terminated strings that outlive the call.
    let done = unsafe {
        libc::syscall(
            libc::SYS_renameat2,
            libc::AT_FDCWD,
            a.as_ptr(),
            libc::AT_FDCWD,
            b.as_ptr(),
            libc::RENAME_EXCHANGE,
        )
    };
    done == 0
}

#[cfg(not(target_os = "linux"))]
fn exchange(_a: &Path, _b: &Path) -> bool {
    false
}

impl Drop for TreeWriter {
    fn drop(&mut self) {
        if !self.finished {
            let _ = fs::remove_dir_all(&self.tmp);
        }
    }
}

/// Writes `value` as JSON and returns the file's length.
fn write_json<T: serde::Serialize>(path: &Path, value: &T, pretty: bool) -> Result<u64> {
    let file = fs::File::create(path).map_err(|e| Error::io(path, e))?;
    let mut w = BufWriter::new(file);
    let written = if pretty {
        serde_json::to_writer_pretty(&mut w, value)
    } else {
        serde_json::to_writer(&mut w, value)
    };
    written.map_err(|e| Error::invalid(path, "", e.to_string()))?;
    w.write_all(b"\n")
        .and_then(|()| w.flush())
        .map_err(|e| Error::io(path, e))?;
    let file = w
        .into_inner()
        .map_err(|e| Error::io(path, e.into_error()))?;
    file.sync_all().map_err(|e| Error::io(path, e))?;
    Ok(file.metadata().map_err(|e| Error::io(path, e))?.len())
}

fn write_bytes(path: &Path, bytes: &[u8]) -> Result<()> {
    let mut file = fs::File::create(path).map_err(|e| Error::io(path, e))?;
    file.write_all(bytes)
        .and_then(|()| file.sync_all())
        .map_err(|e| Error::io(path, e))
}

fn read_json<T: serde::de::DeserializeOwned>(path: &Path) -> Result<T> {
    let bytes = fs::read(path).map_err(|e| Error::io(path, e))?;
    serde_json::from_slice(&bytes).map_err(|e| {
        Error::invalid(
            path,
            format!("line {} column {}", e.line(), e.column()),
            e.to_string(),
        )
    })
}

/// Loads and validates a tree directory: the manifest, the clusters (mapped
/// from `clusters.bin` when the tree has one, else read from
/// `clusters.json`) and the object and task tables when there are any;
/// makes what the cut and the server derive from the clusters. It does not
/// list the geometry directory (121,000 files at paper scale, 0.1 to 0.2 s
/// of CPU, half the start of a server): [`check_geometry`] does, for whoever needs
/// every file present before going on.
pub fn load(dir: impl AsRef<Path>) -> Result<Tree> {
    load_from(dir.as_ref(), true)
}

/// [`load`] from `clusters.json`, whether or not the tree has an index.
pub fn load_json(dir: impl AsRef<Path>) -> Result<Tree> {
    load_from(dir.as_ref(), false)
}

/// What a schedule update reads of the tree it replaces: the manifest and
/// the clusters, checked as [`load`] checks them, every geometry file
/// present, but neither the object tables (the update makes them again)
/// nor what the cut and the server derive.
pub fn load_to_update(dir: impl AsRef<Path>) -> Result<Tree> {
    let dir = dir.as_ref();
    // The listing needs the manifest's layout alone: made beside the
    // clusters' load and checks.
    let layout = layout_of(dir)?;
    let (tree, present) = rayon::join(|| load_clusters(dir, true), || list_geometry(dir, layout));
    let tree = tree?;
    check_present(dir, &tree, &present?)?;
    Ok(tree)
}

/// The ids of the objects of the tree at `dir`, by feature id, read from
/// its object index; `None` when it has none. What an update needs of the
/// tables to keep the old tree's feature ids (`build::align`).
pub fn object_ids(dir: impl AsRef<Path>) -> Result<Option<Vec<String>>> {
    let path = dir.as_ref().join(OBJECTS_INDEX_FILE);
    if !path.exists() {
        return Ok(None);
    }
    let rows = ObjectRows::open(&path)?;
    Ok(Some(
        (0..rows.len() as u32)
            .map(|i| rows.id(i).to_string())
            .collect(),
    ))
}

fn load_from(dir: &Path, use_index: bool) -> Result<Tree> {
    // The directory, not its files: see [`load`].
    let geometry = dir.join(GEOMETRY_DIR);
    fs::read_dir(&geometry).map_err(|e| Error::io(&geometry, e))?;
    let mut tree = load_clusters(dir, use_index)?;
    tree.objects = load_objects_from(dir, &tree, use_index)?;
    // Made now so that no cut, the first one included, pays for them.
    tree.presence();
    tree.nodes();
    tree.summary();
    tree.baseline();
    // What the load read of a mapped index need not stay resident: the
    // cuts fault in the pages they visit.
    tree.remap()?;
    Ok(tree)
}

/// An error unless `json`, described as `what`, is as long as the JSON
/// file the binary index at `index_path` was made from: an index left
/// behind by an edit of its JSON is stale.
fn check_made_from(index_path: &Path, json: &Path, what: &str, made_from: u64) -> Result<()> {
    let json_len = fs::metadata(json).map_err(|e| Error::io(json, e))?.len();
    if json_len != made_from {
        return Err(Error::invalid(
            index_path,
            "header",
            format!(
                "was made from {what} of {made_from} bytes, this one has {json_len}: write it \
                 again with `hdlod index TREE`"
            ),
        ));
    }
    Ok(())
}

/// The manifest and the clusters, from the index or from `clusters.json`.
pub(super) fn load_clusters(dir: &Path, use_index: bool) -> Result<Tree> {
    let manifest: format::ManifestRecord = read_json(&dir.join(MANIFEST_FILE))?;
    let index_path = dir.join(INDEX_FILE);
    // The skins' JSON (megabytes where many objects are skinned) is read
    // while the clusters are, and checked against them after.
    let (tree, skins) = rayon::join(
        || load_records(dir, manifest, &index_path, use_index),
        || read_skins(dir),
    );
    let tree = tree?;
    let skins = match skins? {
        Some((skins, path)) => {
            skins.validate(&tree, &path)?;
            Some(skins)
        }
        None => None,
    };
    Ok(Tree {
        sources: load_sources(dir)?,
        skins,
        ..tree
    })
}

/// The tree of `manifest` with its clusters, from the index at
/// `index_path` when there is one and `use_index`, else from the JSON.
fn load_records(
    dir: &Path,
    manifest: format::ManifestRecord,
    index_path: &Path,
    use_index: bool,
) -> Result<Tree> {
    Ok(if use_index && index_path.exists() {
        let index = Index::open(index_path)?;
        check_made_from(
            index_path,
            &dir.join(CLUSTERS_FILE),
            "a clusters.json",
            index.json_len(),
        )?;
        if index.root() != manifest.root {
            return Err(Error::invalid(
                index_path,
                "header.root",
                format!(
                    "root {} is not the manifest's root {}",
                    index.root(),
                    manifest.root
                ),
            ));
        }
        let tree = Tree::from_manifest(manifest, dir)?;
        let tree = Tree::mapped(tree, index);
        tree.validate(index_path)?;
        tree
    } else {
        let clusters: format::ClustersRecord = read_json(&dir.join(CLUSTERS_FILE))?;
        Tree::from_records(manifest, clusters, dir)?
    })
}

/// The skinned objects' skeletons and their file, when the tree has them;
/// not yet checked against its clusters.
fn read_skins(dir: &Path) -> Result<Option<(super::Skins, PathBuf)>> {
    let path = dir.join(SKINS_FILE);
    if !path.exists() {
        return Ok(None);
    }
    let record: super::skins::SkinsRecord = read_json(&path)?;
    let skins = super::Skins::from_record(record, &path)?;
    Ok(Some((skins, path)))
}

/// The objects' source digests, when the tree has them.
fn load_sources(dir: &Path) -> Result<Option<Vec<super::sources::Digest>>> {
    let path = dir.join(SOURCES_FILE);
    match fs::read(&path) {
        Ok(bytes) => super::sources::decode(&bytes, &path).map(Some),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(None),
        Err(e) => Err(Error::io(&path, e)),
    }
}

/// Hashes blake3 hashes by their first eight bytes: they are uniform
/// already, and a listing of 120,000 files is hashed at every load.
#[derive(Default)]
struct Prefix(u64);

impl Hasher for Prefix {
    fn finish(&self) -> u64 {
        self.0
    }

    fn write(&mut self, bytes: &[u8]) {
        let mut word = [0u8; 8];
        let n = bytes.len().min(8);
        word[..n].copy_from_slice(&bytes[..n]);
        self.0 ^= u64::from_le_bytes(word);
    }

    /// The array's length, the same for every key.
    fn write_usize(&mut self, _: usize) {}
}

/// Hashes of geometry files.
type Hashes = HashSet<[u8; 32], BuildHasherDefault<Prefix>>;

/// The hashes of the geometry files of the tree in `dir`, laid out as
/// `layout`: one listing of the directory, or of each shard (on every
/// core), no reads. A file in a shard not its own is not counted: no
/// reader looks for it there.
fn list_geometry(dir: &Path, layout: Layout) -> Result<Hashes> {
    use rayon::prelude::*;
    let geometry = dir.join(GEOMETRY_DIR);
    match layout {
        Layout::Flat => {
            let mut present = Hashes::default();
            list_into(&geometry, None, &mut present)?;
            Ok(present)
        }
        Layout::Sharded => {
            fs::read_dir(&geometry).map_err(|e| Error::io(&geometry, e))?;
            let shards = format::shard_names()
                .collect::<Vec<_>>()
                .into_par_iter()
                .map(|name| {
                    let mut present = Vec::new();
                    let shard = geometry.join(&name);
                    // A shard with no files may be missing.
                    if shard.exists() {
                        list_into(&shard, Some(&name), &mut present)?;
                    }
                    Ok(present)
                })
                .collect::<Result<Vec<_>>>()?;
            let mut present = Hashes::default();
            present.reserve(shards.iter().map(Vec::len).sum());
            present.extend(shards.into_iter().flatten());
            Ok(present)
        }
    }
}

/// Adds the hashes of the `{hash}.glb` files in `dir` to `present`, only
/// those starting with `prefix` when there is one.
fn list_into(dir: &Path, prefix: Option<&str>, present: &mut impl Extend<[u8; 32]>) -> Result<()> {
    for entry in fs::read_dir(dir).map_err(|e| Error::io(dir, e))? {
        let name = entry.map_err(|e| Error::io(dir, e))?.file_name();
        if let Some(hash) = name
            .to_str()
            .and_then(|n| n.strip_suffix(".glb"))
            .filter(|h| prefix.is_none_or(|p| h.starts_with(p)))
            .and_then(index::hash_bytes)
        {
            present.extend([hash]);
        }
    }
    Ok(())
}

/// The layout of the tree in `dir`, as its manifest's format says.
pub fn layout_of(dir: &Path) -> Result<Layout> {
    let path = dir.join(MANIFEST_FILE);
    let manifest: format::ManifestRecord = read_json(&path)?;
    super::layout_of(&manifest, &path)
}

/// Every geometry file of the tree in `dir` (named by hash or not by the
/// clusters), with its hash, where its manifest's layout puts it.
pub fn geometry_files(dir: &Path) -> Result<Vec<(String, PathBuf)>> {
    let layout = layout_of(dir)?;
    let geometry = dir.join(GEOMETRY_DIR);
    let dirs: Vec<(PathBuf, Option<String>)> = match layout {
        Layout::Flat => vec![(geometry, None)],
        Layout::Sharded => format::shard_names()
            .map(|name| (geometry.join(&name), Some(name)))
            .filter(|(shard, _)| shard.exists())
            .collect(),
    };
    let mut files = Vec::new();
    for (listed, prefix) in dirs {
        for entry in fs::read_dir(&listed).map_err(|e| Error::io(&listed, e))? {
            let name = entry.map_err(|e| Error::io(&listed, e))?.file_name();
            if let Some(hash) = name
                .to_str()
                .and_then(|n| n.strip_suffix(".glb"))
                .filter(|h| prefix.as_deref().is_none_or(|p| h.starts_with(p)))
                .filter(|h| index::hash_bytes(h).is_some())
            {
                files.push((hash.to_owned(), listed.join(&name)));
            }
        }
    }
    Ok(files)
}

/// Checks that every geometry file the clusters of `tree` (loaded from
/// `dir`) name is in its geometry directory: one listing of the directory,
/// no reads. Names are compared as hash bytes, and a mapped tree's are its
/// index's distinct hashes, so no hex string is made per cluster.
pub fn check_geometry(dir: &Path, tree: &Tree) -> Result<()> {
    check_present(dir, tree, &list_geometry(dir, tree.layout)?)
}

/// An error unless every geometry file of `tree` is among those `present`.
fn check_present(dir: &Path, tree: &Tree, present: &Hashes) -> Result<()> {
    let missing = match tree.index() {
        Some(index) => index
            .hashes()
            .iter()
            .position(|h| !present.contains(h))
            .and_then(|k| index.cluster_with_hash(k)),
        None => (0..tree.cluster_count() as u32).find(|&id| {
            tree.geometry_of(id)
                .is_some_and(|h| index::hash_bytes(&h).is_none_or(|b| !present.contains(&b)))
        }),
    };
    match missing {
        None => Ok(()),
        Some(id) => Err(Error::invalid(
            dir.join(CLUSTERS_FILE),
            format!("clusters[{id}].geometry"),
            format!(
                "{} is missing",
                tree.geometry_file(dir, &tree.geometry_of(id).unwrap_or_default())
                    .display()
            ),
        )),
    }
}

/// Writes `clusters.bin` and, when the tree has object tables,
/// `objects.bin` for the tree in `dir` from its JSON files (a tree written
/// before the indexes, or whose indexes are damaged), checked as
/// [`load_json`] checks it, each by a rename: a reader sees the old index
/// or the new one. The object index goes first: the server reloads on the
/// cluster index's change.
pub fn write_index(dir: impl AsRef<Path>) -> Result<()> {
    let dir = dir.as_ref();
    let tree = load_json(dir)?;
    if let Some(tables) = &tree.objects {
        let json = dir.join(OBJECTS_FILE);
        let json_len = fs::metadata(&json).map_err(|e| Error::io(&json, e))?.len();
        let rest = serde_json::to_vec(&tables.to_record_without_objects(&tree.time))
            .map_err(|e| Error::invalid(&json, "", e.to_string()))?;
        replace(
            &dir.join(OBJECTS_INDEX_FILE),
            &tables.to_index(&rest, json_len).to_vec(),
        )?;
    }
    let json = dir.join(CLUSTERS_FILE);
    let json_len = fs::metadata(&json).map_err(|e| Error::io(&json, e))?.len();
    replace(&dir.join(INDEX_FILE), &index::encode(&tree, json_len))
}

/// Writes `bytes` to `target` by a rename of a temporary beside it.
pub(super) fn replace(target: &Path, bytes: &[u8]) -> Result<()> {
    let tmp = sibling(target, "tmp");
    let written = write_bytes(&tmp, bytes)
        .and_then(|()| fs::rename(&tmp, target).map_err(|e| Error::io(target, e)));
    if written.is_err() {
        let _ = fs::remove_file(&tmp);
    }
    written
}

/// The object and task tables of the tree in `dir` (loaded, with its
/// clusters, as `tree`), checked against its clusters; `None` when the tree
/// has none. Their rows are mapped from `objects.bin` when the tree has it
/// (made from this `objects.json`), else read from `objects.json`.
pub fn load_objects(dir: &Path, tree: &Tree) -> Result<Option<ObjectTables>> {
    load_objects_from(dir, tree, true)
}

fn load_objects_from(dir: &Path, tree: &Tree, use_index: bool) -> Result<Option<ObjectTables>> {
    let path = dir.join(OBJECTS_FILE);
    if !path.exists() {
        return Ok(None);
    }
    let index_path = dir.join(OBJECTS_INDEX_FILE);
    if use_index && index_path.exists() {
        let rows = ObjectRows::open(&index_path)?;
        check_made_from(&index_path, &path, "an objects.json", rows.json_len())?;
        return ObjectTables::from_index(rows, tree, &index_path).map(Some);
    }
    let record: ObjectsRecord = read_json(&path)?;
    ObjectTables::from_record(record, tree, &path).map(Some)
}
