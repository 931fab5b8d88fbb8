//! Schedule-only updates of a built tree (`build_or_update_to`): what they
//! recompute is what a full build computes, they keep every geometry file,
//! and a new configuration or a class change builds in full.

use std::collections::HashSet;
use std::path::{Path, PathBuf};

use hdlod::build::{BuildConfig, How, Silent, StepFunction, build_or_update_to, build_to};
use hdlod::scene::{Scene, format};
use hdlod::tree::{Cluster, Layout, Tree, load};

mod common;

fn tiny() -> Scene {
    let fixture = Path::new(env!("CARGO_MANIFEST_DIR")).join("../fixtures/skyscraper-tiny");
    format::load(&fixture).expect("the tiny fixture loads")
}

/// The tiny site with every fourth task of still objects `by` seconds
/// later: the same objects in the same classes, other dates.
fn rescheduled(scene: &Scene, by: f64) -> Scene {
    let mut scene = scene.clone();
    let day = by;
    let still: HashSet<String> = scene
        .objects
        .iter()
        .filter(|o| o.motion.is_none())
        .map(|o| o.id.clone())
        .collect();
    let mut moved = 0;
    for (i, task) in scene.tasks.iter_mut().enumerate() {
        if i % 4 == 0
            && task.finish + day < scene.time.seconds
            && task.objects.iter().all(|o| still.contains(o))
        {
            task.start += day;
            task.finish += day;
            moved += 1;
        }
    }
    assert!(moved > 5, "{moved} tasks moved");
    scene.apply_schedule();
    scene
}

fn records(tree: &Tree) -> Vec<Cluster> {
    tree.clusters().map(|c| c.into_owned()).collect()
}

fn geometry(tree: &Tree) -> Vec<Option<String>> {
    records(tree).into_iter().map(|c| c.geometry).collect()
}

/// An update tells edited objects by their source digests, so a scene
/// read, saved and read again must give the same ones: the tiny site's
/// walkers, whose joints' motions are sampled from a clip on load, too.
#[test]
fn the_tiny_site_saved_and_read_again_has_the_same_object_sources() {
    let scene = tiny();
    assert!(
        scene.objects.iter().any(|o| o.skin.is_some()),
        "the tiny site has a skinned walker"
    );
    let dir = tempfile::tempdir().unwrap();
    format::save(&scene, &dir.path().join("again")).unwrap();
    let again = format::load(&dir.path().join("again")).unwrap();
    let (a, b) = (
        hdlod::build::object_sources(&scene),
        hdlod::build::object_sources(&again),
    );
    let edited: Vec<&str> = (0..a.len())
        .filter(|&i| a[i] != b[i])
        .map(|i| scene.objects[i].id.as_str())
        .collect();
    assert!(edited.is_empty(), "read again, these differ: {edited:?}");
}

#[test]
fn an_update_recomputes_what_the_build_computes() {
    let scene = tiny();
    let config = BuildConfig::default();
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("tree");
    build_to(&scene, &config, &dir, &Silent).unwrap();
    let built = load(&dir).unwrap();
    let files: HashSet<String> = geometry(&built).into_iter().flatten().collect();

    // The same schedule again: every cluster exactly as built.
    let (same, _, how) = build_or_update_to(&scene, &config, &dir, false, &Silent).unwrap();
    assert_eq!(
        how,
        How::ScheduleUpdate {
            geometry_files: files.len(),
            dissolved: 0,
        }
    );
    assert_eq!(records(&same), records(&built));
    assert_eq!(records(&load(&dir).unwrap()), records(&built));

    // An hour later: the leaves follow the new dates, the geometry stays.
    let later = rescheduled(&scene, 3600.0);
    let (_, _, how) = build_or_update_to(&later, &config, &dir, false, &Silent).unwrap();
    let How::ScheduleUpdate { dissolved, .. } = how else {
        panic!("{how:?}")
    };
    let updated = load(&dir).expect("the updated tree loads and validates");
    assert_eq!(updated.cluster_count(), built.cluster_count() - dissolved);
    let span = later.time.seconds;
    let mut changed = 0;
    let leaves = |t: &Tree| {
        records(t)
            .into_iter()
            .filter(|c| c.is_leaf())
            .collect::<Vec<_>>()
    };
    let (now, before) = (leaves(&updated), leaves(&built));
    assert_eq!(now.len(), before.len());
    for (leaf, was) in now.iter().zip(&before) {
        assert_eq!(
            (&leaf.objects, &leaf.geometry),
            (&was.objects, &was.geometry)
        );
        changed += usize::from(leaf.visibility != was.visibility);
        let object = later.objects.iter().find(|o| o.id == leaf.objects[0]);
        if let Some(object) = object.filter(|o| o.motion.is_none()) {
            let want = StepFunction::of_visibility(&object.visibility, span).to_tree();
            assert_eq!(leaf.visibility, want, "leaf {}", leaf.id);
        }
    }
    assert!(changed > 5, "{changed} leaves changed visibility");
    // Kept where nothing below changed, recomputed above every change.
    common::assert_visibility_follows_children(&updated, &config);
    for hash in geometry(&updated).into_iter().flatten() {
        assert!(files.contains(&hash));
        let shard = dir.join("geometry").join(&hash[..2]);
        assert!(shard.join(format!("{hash}.glb")).is_file());
    }
}

#[test]
fn groups_that_no_longer_fit_the_schedule_are_dissolved() {
    let scene = tiny();
    let later = rescheduled(&scene, 86_400.0);
    let config = BuildConfig::default();
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("tree");
    let (built, stats) = build_to(&scene, &config, &dir, &Silent).unwrap();
    let (_, _, how) = build_or_update_to(&later, &config, &dir, false, &Silent).unwrap();
    let How::ScheduleUpdate { dissolved, .. } = how else {
        panic!("{how:?}")
    };
    assert!(
        dissolved > 0,
        "a day's shift breaks some group of the tiny site"
    );
    let tree = load(&dir).expect("the updated tree loads and validates");
    assert_eq!(tree.cluster_count(), built.cluster_count() - dissolved);
    common::assert_visibility_follows_children(&tree, &config);
    let leaves = |t: &Tree| records(t).iter().filter(|c| c.is_leaf()).count();
    assert_eq!(leaves(&tree), leaves(&built));
    let clusters = records(&tree);
    // Groups dissolved before the moving objects' leaves renumber those;
    // the object tables follow.
    let leaf_ids = |t: &Tree| -> Vec<u32> {
        records(t)
            .iter()
            .filter(|c| c.is_leaf())
            .map(|c| c.id)
            .collect()
    };
    assert_ne!(
        leaf_ids(&tree),
        leaf_ids(&built),
        "some leaf was renumbered"
    );
    assert_eq!(
        tree.objects.as_ref(),
        Some(&hdlod::tree::ObjectTables::of(&later, &clusters)),
        "the object tables name the leaves by their new ids"
    );
    for c in &clusters {
        if c.class == hdlod::tree::ClusterClass::Root {
            continue;
        }
        let budget = hdlod::build::thresholds(&config, stats.scene_w, stats.levels, c.level);
        assert!(
            c.gamma <= budget.gamma,
            "cluster {}: gamma {} over {}",
            c.id,
            c.gamma,
            budget.gamma
        );
        for &k in &c.children {
            assert!(clusters[k as usize].eps <= c.eps, "eps grows up the tree");
        }
    }
}

#[test]
fn a_new_configuration_a_class_change_or_full_build_in_full() {
    let scene = tiny();
    let config = BuildConfig::default();
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("tree");
    let (_, _, how) = build_or_update_to(&scene, &config, &dir, false, &Silent).unwrap();
    assert_eq!(how, How::Full { why: None }, "no tree there yet");

    let (_, _, how) = build_or_update_to(&scene, &config, &dir, true, &Silent).unwrap();
    assert_eq!(how, How::Full { why: None }, "a full build asked for");

    // An object moved: a geometry update (tests/build_local.rs).
    let mut moved = scene.clone();
    moved.objects[0].transform.w_axis.x += 1.0;
    let (_, _, how) = build_or_update_to(&moved, &config, &dir, false, &Silent).unwrap();
    assert!(matches!(how, How::GeometryUpdate { .. }), "{how:?}");

    let coarser = BuildConfig {
        max_children: config.max_children + 1,
        ..config.clone()
    };
    let (_, _, how) = build_or_update_to(&moved, &coarser, &dir, false, &Silent).unwrap();
    let How::Full { why: Some(why) } = how else {
        panic!("{how:?}")
    };
    assert!(why.contains("configuration"), "{why}");

    // An object present throughout gets a task: it leaves the static class.
    let (_, _, how) = build_or_update_to(&scene, &config, &dir, false, &Silent).unwrap();
    assert!(matches!(how, How::Full { .. }));
    let mut reclassed = scene.clone();
    let always = reclassed
        .objects
        .iter()
        .position(|o| reclassed.class_of(o) == hdlod::scene::Class::Static)
        .expect("a static object");
    let id = reclassed.objects[always].id.clone();
    let half = reclassed.time.seconds / 2.0;
    reclassed.tasks.push(hdlod::scene::Task::planned(
        "X1",
        "Demolish",
        hdlod::scene::TaskType::Demolish,
        half,
        half + 3600.0,
        vec![id],
    ));
    reclassed.apply_schedule();
    let (_, _, how) = build_or_update_to(&reclassed, &config, &dir, false, &Silent).unwrap();
    let How::Full { why: Some(why) } = how else {
        panic!("{how:?}")
    };
    assert!(why.contains("class"), "{why}");
}

/// The digests that decide between an update and a full build are computed
/// the same way by every release: a tree built by an earlier one updates.
#[test]
fn the_geometry_key_is_stable_across_releases() {
    assert_eq!(
        hdlod::build::geometry_key(&tiny(), &BuildConfig::default()),
        "a30283bc0dd798f56055300aeb27a7f9c1814f43765f37a1180b260fa7b816fe"
    );
    // And the objects' digests a geometry update compares (`sources.bin`).
    let sources = hdlod::build::object_sources(&tiny());
    let all: Vec<u8> = sources.iter().flatten().copied().collect();
    assert_eq!(
        blake3::hash(&all).to_hex().as_str(),
        "d4bf10f6f86ec7dd67b6c2744dc9b388c90de25392a45b267deb79f3f227f124"
    );
}

/// An update shares the old tree's geometry directory instead of linking
/// each file: it moves once into the store beside the tree and both
/// generations link to it; no geometry file is written or replaced, so a
/// tree hard-linked from another is not written through. A full build
/// makes a directory of its own again and removes the store.
#[cfg(target_os = "linux")]
#[test]
fn updates_share_the_geometry_store_and_a_full_build_removes_it() {
    use std::collections::BTreeMap;
    use std::os::unix::fs::MetadataExt;

    let scene = tiny();
    let config = BuildConfig::default();
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("tree");
    let store = tmp.path().join(".tree.geometry");
    build_to(&scene, &config, &dir, &Silent).unwrap();
    let files = |dir: &Path| -> BTreeMap<PathBuf, (u64, Vec<u8>)> {
        common::geometry_files(dir)
            .into_iter()
            .map(|path| {
                let name = path.strip_prefix(dir).unwrap().to_owned();
                let inode = std::fs::metadata(&path).unwrap().ino();
                (name, (inode, std::fs::read(&path).unwrap()))
            })
            .collect()
    };
    let built = files(&dir);

    for by in [3600.0, 7200.0] {
        let (_, _, how) =
            build_or_update_to(&rescheduled(&scene, by), &config, &dir, false, &Silent).unwrap();
        assert!(matches!(how, How::ScheduleUpdate { .. }), "{how:?}");
        let link = std::fs::read_link(dir.join("geometry")).expect("geometry is a link");
        assert_eq!(link, Path::new("../.tree.geometry"));
        assert!(store.is_dir());
        assert_eq!(files(&dir), built, "the same files, not one rewritten");
        load(&dir).expect("the updated tree loads");
    }
    let mut names: Vec<String> = std::fs::read_dir(tmp.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    assert_eq!(names, [".tree.geometry", "tree"]);

    build_or_update_to(&scene, &config, &dir, true, &Silent).unwrap();
    assert!(
        std::fs::symlink_metadata(dir.join("geometry"))
            .unwrap()
            .is_dir()
    );
    assert!(
        !store.exists(),
        "the store goes with the last tree using it"
    );
    load(&dir).expect("the rebuilt tree loads");
}

/// A tree of the previous format (`hdlod-tree/1`, its geometry flat) is
/// updated into one of the current format: its files linked one by one
/// into the new tree's shards, not shared.
#[test]
fn a_flat_tree_is_updated_into_a_sharded_one() {
    let scene = tiny();
    let config = BuildConfig::default();
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("tree");
    let (built, _) = build_to(&scene, &config, &dir, &Silent).unwrap();
    common::flatten_tree(&dir);
    let flat = load(&dir).expect("a flat tree loads");
    assert_eq!(flat.layout, Layout::Flat);
    assert_eq!(records(&flat), records(&built));
    hdlod::tree::store::check_geometry(&dir, &flat).unwrap();

    let (_, _, how) =
        build_or_update_to(&rescheduled(&scene, 3600.0), &config, &dir, false, &Silent).unwrap();
    assert!(matches!(how, How::ScheduleUpdate { .. }), "{how:?}");
    assert_eq!(common::checked_manifest(&dir)["format"], "hdlod-tree/2");
    assert!(
        std::fs::symlink_metadata(dir.join("geometry"))
            .unwrap()
            .is_dir(),
        "not shared: the layouts differ"
    );
    assert!(!tmp.path().join(".tree.geometry").exists());
    let updated = load(&dir).unwrap();
    assert_eq!(updated.layout, Layout::Sharded);
    hdlod::tree::store::check_geometry(&dir, &updated).unwrap();
    let want: Vec<PathBuf> = {
        let mut files: Vec<PathBuf> = geometry(&updated)
            .into_iter()
            .flatten()
            .collect::<std::collections::BTreeSet<_>>()
            .into_iter()
            .map(|h| updated.geometry_file(&dir, &h))
            .collect();
        files.sort();
        files
    };
    assert_eq!(common::geometry_files(&dir), want);
}

/// An update names every geometry file of the tree it replaces, so a tree
/// missing one is not updated, by either kind of update: it is built in
/// full, and the tree left is whole.
#[test]
fn a_tree_missing_a_geometry_file_is_built_in_full() {
    let scene = tiny();
    let config = BuildConfig::default();
    let mut moved = scene.clone();
    moved.objects[0].transform.w_axis.x += 1.0;
    for edited in [rescheduled(&scene, 3600.0), moved] {
        let tmp = tempfile::tempdir().unwrap();
        let dir = tmp.path().join("tree");
        build_to(&scene, &config, &dir, &Silent).unwrap();
        let gone = common::geometry_files(&dir).pop().expect("a geometry file");
        std::fs::remove_file(&gone).unwrap();
        let (tree, _, how) = build_or_update_to(&edited, &config, &dir, false, &Silent).unwrap();
        let How::Full { why: Some(why) } = how else {
            panic!("{how:?}")
        };
        let name = gone.file_name().unwrap().to_string_lossy().into_owned();
        let hash = name.trim_end_matches(".glb");
        assert!(why.contains("does not load") && why.contains(hash), "{why}");
        let loaded = load(&dir).expect("the rebuilt tree loads");
        hdlod::tree::store::check_geometry(&dir, &loaded).expect("every file there");
        assert_eq!(geometry(&loaded), geometry(&tree));
    }
}
