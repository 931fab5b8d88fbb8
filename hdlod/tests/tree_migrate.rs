//! The migration of a tree of the previous format (`hdlod-tree/1`, its
//! geometry flat) to the current one (`hdlod-tree/2`, in shards): the
//! migrated tree loads with the same clusters, a second run changes
//! nothing, and a run interrupted at any step leaves a tree that loads and
//! that a rerun completes.

use std::path::Path;

use hdlod::build::{BuildConfig, Silent, build_or_update_to, build_to};
use hdlod::scene::format;
use hdlod::tree::migrate::migrate;
use hdlod::tree::store::check_geometry;
use hdlod::tree::{Layout, Tree, load};

mod common;

/// The tiny fixture's tree, built into `dir`.
fn built(dir: &Path) -> Tree {
    let fixture = Path::new(env!("CARGO_MANIFEST_DIR")).join("../fixtures/skyscraper-tiny");
    let scene = format::load(&fixture).expect("the tiny fixture loads");
    build_to(&scene, &BuildConfig::default(), dir, &Silent)
        .unwrap()
        .0
}

fn clusters(tree: &Tree) -> Vec<hdlod::tree::Cluster> {
    tree.clusters().map(|c| c.into_owned()).collect()
}

/// Loads the tree in `dir`, checks its geometry and that it is `want`
/// laid out as `layout`.
fn assert_loads(dir: &Path, want: &Tree, layout: Layout) {
    let tree = load(dir).expect("the tree loads");
    assert_eq!(tree.layout, layout);
    check_geometry(dir, &tree).expect("every geometry file is where the layout says");
    assert_eq!(clusters(&tree), clusters(want));
    assert_eq!(common::checked_manifest(dir)["format"], layout.format());
}

/// Whether `dir/geometry` holds any file right in it (the flat layout's).
fn has_flat_files(dir: &Path) -> bool {
    common::geometry_files(dir)
        .iter()
        .any(|f| f.parent() == Some(&dir.join("geometry")))
}

#[test]
fn a_built_tree_is_sharded() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("tree");
    let tree = built(&dir);
    assert_eq!(common::checked_manifest(&dir)["format"], "hdlod-tree/2");
    let shards = std::fs::read_dir(dir.join("geometry")).unwrap().count();
    assert_eq!(shards, 256, "every shard is made up front");
    let mut files = 0;
    for c in tree.clusters() {
        if let Some(hash) = &c.geometry {
            let path = dir
                .join("geometry")
                .join(&hash[..2])
                .join(format!("{hash}.glb"));
            assert_eq!(tree.geometry_file(&dir, hash), path);
            assert!(path.is_file(), "{}", path.display());
            files += 1;
        }
    }
    assert!(files > 10);
    assert!(!has_flat_files(&dir));
}

#[test]
fn a_flat_tree_loads_and_migrates_once() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("tree");
    let want = built(&dir);
    let sharded = common::geometry_files(&dir);
    common::flatten_tree(&dir);
    assert_loads(&dir, &want, Layout::Flat);

    let done = migrate(&dir).unwrap();
    assert_eq!(done.from, "hdlod-tree/1");
    assert!(done.manifest);
    assert_eq!(done.linked, sharded.len());
    assert_eq!(done.removed, sharded.len());
    assert!(!done.indexes, "the indexes do not depend on the layout");
    assert_loads(&dir, &want, Layout::Sharded);
    assert_eq!(common::geometry_files(&dir), sharded);

    let again = migrate(&dir).unwrap();
    assert!(!again.changed(), "{again:?}");
    assert_eq!(again.from, "hdlod-tree/2");
    assert_eq!(common::geometry_files(&dir), sharded);
}

/// Killed after the links, before the manifest's rename: a flat tree with
/// its files in the shards too. Killed after the rename: a sharded tree
/// with its flat files still there. Each loads, and a rerun completes.
#[test]
fn an_interrupted_migration_loads_and_a_rerun_completes_it() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("tree");
    let want = built(&dir);
    let sharded = common::geometry_files(&dir);
    common::flatten_tree(&dir);
    let geometry = dir.join("geometry");
    // Half the files linked into their shards.
    for (i, path) in sharded.iter().enumerate().filter(|(i, _)| i % 2 == 0) {
        let flat = geometry.join(path.file_name().unwrap());
        std::fs::create_dir_all(path.parent().unwrap()).unwrap();
        std::fs::hard_link(&flat, path).unwrap_or_else(|e| panic!("{i}: {e}"));
    }
    assert_loads(&dir, &want, Layout::Flat);
    let done = migrate(&dir).unwrap();
    assert_eq!(done.linked, sharded.len() - sharded.len().div_ceil(2));
    assert_loads(&dir, &want, Layout::Sharded);
    assert_eq!(common::geometry_files(&dir), sharded);

    // After the rename: stray flat files beside the shards.
    for path in &sharded {
        std::fs::hard_link(path, geometry.join(path.file_name().unwrap())).unwrap();
    }
    assert_loads(&dir, &want, Layout::Sharded);
    let done = migrate(&dir).unwrap();
    assert!(!done.manifest);
    assert_eq!((done.linked, done.removed), (0, sharded.len()));
    assert_eq!(common::geometry_files(&dir), sharded);
}

/// A tree whose geometry is a link to a store shared by its generations
/// (a schedule update made it) is migrated inside the store, and the next
/// update shares the migrated store again.
#[cfg(target_os = "linux")]
#[test]
fn a_shared_store_is_migrated_in_place() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("tree");
    built(&dir);
    let fixture = Path::new(env!("CARGO_MANIFEST_DIR")).join("../fixtures/skyscraper-tiny");
    let mut scene = format::load(&fixture).unwrap();
    scene.name.push_str("-next");
    let config = BuildConfig::default();
    let update = |scene: &hdlod::scene::Scene| {
        build_or_update_to(scene, &config, &dir, false, &Silent).unwrap()
    };
    let (want, _, how) = update(&scene);
    assert!(
        matches!(how, hdlod::build::How::ScheduleUpdate { .. }),
        "{how:?}"
    );
    let link = std::fs::read_link(dir.join("geometry")).expect("a shared store");
    let sharded = common::geometry_files(&dir);
    common::flatten_tree(&dir);
    assert_loads(&dir, &want, Layout::Flat);

    let done = migrate(&dir).unwrap();
    assert!(done.manifest);
    assert_eq!(std::fs::read_link(dir.join("geometry")).unwrap(), link);
    assert_loads(&dir, &want, Layout::Sharded);
    assert_eq!(common::geometry_files(&dir), sharded);

    scene.name.push_str("-again");
    update(&scene);
    assert_eq!(std::fs::read_link(dir.join("geometry")).unwrap(), link);
    assert_eq!(common::geometry_files(&dir), sharded);
}
