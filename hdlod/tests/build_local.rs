//! Local geometry updates of a built tree (`build_or_update_to`, module
//! `build::local`): a storey of the tiny site edited and an object added.
//! Only the clusters above them are made again, every stored error is
//! still a bound on the distance to the objects, the cuts are those of a
//! full build within a few percent, and what it cannot do builds in full.

use std::collections::{HashMap, HashSet};
use std::path::Path;

use glam::{DVec3, Vec3};
use hdlod::build::{BuildConfig, How, Silent, build_or_update_to, build_to};
use hdlod::io::gltf::read_mesh;
use hdlod::scene::{Scene, format};
use hdlod::tree::cut::cut;
use hdlod::tree::{CameraSpec, ClusterClass, Previous, Tree, TreeWriter, View, Viewport, load};

mod common;

fn tiny() -> Scene {
    let fixture = Path::new(env!("CARGO_MANIFEST_DIR")).join("../fixtures/skyscraper-tiny");
    format::load(&fixture).expect("the tiny fixture loads")
}

const STOREY: &str = "Level 02";

/// Whether object `o` stands still on [`STOREY`].
fn on_storey(o: &hdlod::scene::Object) -> bool {
    o.properties.get("storey").map(String::as_str) == Some(STOREY) && o.motion.is_none()
}

/// The tiny site with every object of one storey moved 30 cm along x, and
/// a copy of one of them added after the last object, a metre away.
fn edited(scene: &Scene) -> (Scene, usize) {
    let mut scene = scene.clone();
    let mut edited = 0;
    let mut copy = None;
    for o in &mut scene.objects {
        if on_storey(o) {
            o.transform.w_axis.x += 0.3;
            edited += 1;
            copy.get_or_insert_with(|| o.clone());
        }
    }
    let mut added = copy.expect("an object on the storey");
    added.id = "ADDED-1".into();
    added.transform.w_axis.z += 1.0;
    scene.objects.push(added);
    scene.apply_schedule();
    (scene, edited)
}

/// The tiny site built into a temporary directory (removed when `tmp` is
/// dropped): its tree and the tree's geometry files.
struct Built {
    scene: Scene,
    config: BuildConfig,
    tmp: tempfile::TempDir,
    dir: std::path::PathBuf,
    before: Tree,
    before_files: HashSet<String>,
}

fn built() -> Built {
    let scene = tiny();
    let config = BuildConfig::default();
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("tree");
    build_to(&scene, &config, &dir, &Silent).unwrap();
    let before = load(&dir).unwrap();
    let before_files = files(&before);
    Built {
        scene,
        config,
        tmp,
        dir,
        before,
        before_files,
    }
}

fn files(tree: &Tree) -> HashSet<String> {
    tree.clusters().filter_map(|c| c.geometry.clone()).collect()
}

/// Triangles of the cut at 1 px, 1920x1080, from azimuth 45 and elevation
/// 30 degrees at `factor` times the distance where the scene fills the
/// view, at `t`.
fn cut_triangles(tree: &Tree, factor: f64, t: f64) -> u64 {
    let centre = (tree.bounds.min + tree.bounds.max) / 2.0;
    let radius = tree.bounds.diagonal() / 2.0;
    let (az, el) = (45f64.to_radians(), 30f64.to_radians());
    let dir = DVec3::new(el.cos() * az.cos(), el.sin(), el.cos() * az.sin());
    let distance = factor * radius / 30f64.to_radians().sin();
    let camera = CameraSpec {
        position: Some((centre + dir * distance).to_array()),
        target: Some(centre.to_array()),
        up: Some([0.0, 1.0, 0.0]),
        fov_y_deg: Some(60.0),
        aspect: None,
        near: Some((distance - radius) * 0.5),
        far: Some(distance + 2.0 * radius),
        view_projection: None,
    };
    let viewport = Viewport {
        width: 1920,
        height: 1080,
    };
    let view = View::new(&camera, viewport, 1.0, DVec3::Y).unwrap();
    cut(tree, &view, t).stats.triangles
}

/// Checks that every static or pseudo-dynamic cluster of `after` among
/// `ids` but the leaves bounds the distance to the objects of `scene`
/// below it; answers how many it checked.
fn bounds_hold(after: &Tree, dir: &Path, scene: &Scene, ids: &[u32]) -> usize {
    let mut checked = 0;
    for c in (ids.iter().map(|&id| after.cluster(id))).filter(|c| {
        !c.is_leaf() && matches!(c.class, ClusterClass::Static | ClusterClass::PseudoDynamic)
    }) {
        common::assert_eps_bound(after, dir, scene, &c);
        checked += 1;
    }
    checked
}

/// Checks that `clusters.json` at `dir`, whose unchanged records an update
/// copies from the tree it replaced (its ids written afresh where they
/// changed), is the file a fresh write of the tree makes, byte for byte;
/// and `skins.json`, which it links where the skins stayed, too.
fn table_as_fresh(dir: &Path, tree: &Tree) {
    let fresh = dir.with_file_name("fresh");
    let writer = TreeWriter::create(&fresh).unwrap();
    for c in tree.clusters() {
        if let Some(hash) = &c.geometry {
            writer.reuse_geometry(dir, tree.layout, hash).unwrap();
        }
    }
    writer.finish(tree).unwrap();
    let read = |d: &Path, name: &str| std::fs::read(d.join(name)).ok();
    for name in ["clusters.json", "skins.json"] {
        assert!(
            read(dir, name) == read(&fresh, name),
            "the updated {name} is not the one a fresh write makes"
        );
    }
    assert!(
        read(dir, "skins.json").is_some() == tree.skins.as_ref().is_some_and(|s| !s.is_empty()),
        "skins.json is there exactly when the tree has skins"
    );
    std::fs::remove_dir_all(&fresh).unwrap();
}

/// Checks that the cuts of `after` are those of a full build of `scene`
/// (made in `tmp`) within a few percent over the table's views, a cell of
/// a few hundred triangles within a quarter.
fn cuts_as_full(after: &Tree, scene: &Scene, config: &BuildConfig, tmp: &Path) {
    let full_dir = tmp.join("full");
    build_to(scene, config, &full_dir, &Silent).unwrap();
    let full = load(&full_dir).unwrap();
    let (mut ours_sum, mut theirs_sum) = (0, 0);
    for factor in [1.0, 2.0, 4.0] {
        for fraction in [0.0, 1.0 / 3.0, 2.0 / 3.0, 1.0] {
            let t = scene.time.seconds * fraction;
            let (ours, theirs) = (
                cut_triangles(after, factor, t),
                cut_triangles(&full, factor, t),
            );
            let ratio = ours as f64 / theirs.max(1) as f64;
            assert!(
                (0.75..=1.25).contains(&ratio),
                "at {factor}x, {fraction:.2} of the period: {ours} triangles against {theirs}"
            );
            ours_sum += ours;
            theirs_sum += theirs;
        }
    }
    let ratio = ours_sum as f64 / theirs_sum as f64;
    assert!(
        (0.95..=1.05).contains(&ratio),
        "{ours_sum} against {theirs_sum}"
    );
}

#[test]
fn a_storey_edited_and_an_object_added_rebuild_only_what_is_above_them() {
    let Built {
        scene,
        config,
        tmp,
        dir,
        before,
        before_files,
    } = built();

    let (changed, storey) = edited(&scene);
    let (_, _, how) = build_or_update_to(&changed, &config, &dir, false, &Silent).unwrap();
    let How::GeometryUpdate {
        edited_objects,
        added_objects,
        rebuilt,
        widened,
        geometry_files,
        ..
    } = how
    else {
        panic!("{how:?}")
    };
    assert_eq!((edited_objects, added_objects), (storey, 1));
    let after = load(&dir).expect("the updated tree passes every check of the loader");
    table_as_fresh(&dir, &after);
    common::assert_visibility_follows_children(&after, &config);
    assert_eq!(after.cluster_count(), before.cluster_count() + 1);
    assert!(
        rebuilt < after.cluster_count() / 2,
        "{rebuilt} of {} clusters made again",
        after.cluster_count()
    );
    let after_files = files(&after);
    assert_eq!(
        geometry_files,
        after_files.intersection(&before_files).count()
    );
    assert!(
        geometry_files * 2 > after_files.len(),
        "{geometry_files} of {} files kept",
        after_files.len()
    );

    // What was made again or widened is exactly the leaves of the edited
    // and added objects and the clusters above them, up to the root's
    // children; each one made again has new geometry unless it came out
    // the same (a coarse proxy the moved elements are dropped from).
    let touched: HashSet<String> = changed
        .objects
        .iter()
        .zip(
            scene
                .objects
                .iter()
                .map(Some)
                .chain(std::iter::repeat(None)),
        )
        .filter(|(new, old)| old.is_none_or(|old| old.transform != new.transform))
        .map(|(new, _)| new.id.clone())
        .collect();
    let mut expected: Vec<u32> = Vec::new();
    for c in after.clusters().filter(|c| c.is_leaf()) {
        if c.objects.iter().any(|o| touched.contains(o)) {
            let mut at = Some(c.id);
            while let Some(id) = at.filter(|&id| id != after.root) {
                expected.push(id);
                at = after.cluster(id).parent;
            }
        }
    }
    expected.sort_unstable();
    expected.dedup();
    let remade: Vec<u32> = after
        .clusters()
        .filter(|c| {
            c.geometry
                .as_ref()
                .is_some_and(|g| !before_files.contains(g))
        })
        .map(|c| c.id)
        .collect();
    assert_eq!(
        rebuilt + widened,
        expected.len(),
        "made again: {expected:?}"
    );
    let unexpected: Vec<&u32> = remade.iter().filter(|c| !expected.contains(c)).collect();
    assert!(
        unexpected.is_empty(),
        "new geometry outside {expected:?}: {unexpected:?}"
    );
    assert!(remade.len() * 10 >= rebuilt * 9, "{remade:?} of {rebuilt}");

    // The added object is a leaf of the tree and a row of its tables.
    let tables = after.objects.as_ref().expect("object tables");
    let added = tables.object_index("ADDED-1").expect("the added object");
    assert_eq!(added as usize, changed.objects.len() - 1);
    assert_eq!(tables.object(added).clusters.len(), 1);

    // Every cluster made again or widened bounds the distance to its
    // objects as placed now.
    let checked = bounds_hold(&after, &dir, &changed, &expected);
    assert!(checked >= 3, "only {checked} clusters made again");
    // The edited storey's leaves stand where the scene now puts them.
    let moved = after
        .clusters()
        .filter(|c| c.is_leaf() && c.objects.iter().any(|o| o.starts_with("L02")))
        .count();
    assert!(moved > 0);
    let objects: HashMap<&str, &hdlod::scene::Object> =
        changed.objects.iter().map(|o| (o.id.as_str(), o)).collect();
    for c in after.clusters().filter(|c| c.is_leaf()) {
        let o = objects[c.objects[0].as_str()];
        // A moving object's leaf is placed by its motion, a skinned one's
        // (the walker) by its joints: its geometry is the bind pose.
        if o.motion.is_some() || o.skin.is_some() {
            continue;
        }
        let mesh = read_mesh(&after.geometry_file(&dir, c.geometry.as_ref().unwrap())).unwrap();
        let want = changed.meshes[o.mesh]
            .positions
            .iter()
            .map(|&p| o.transform.transform_point3(p))
            .fold(Vec3::splat(f32::INFINITY), Vec3::min);
        let got = mesh
            .positions
            .iter()
            .fold(Vec3::splat(f32::INFINITY), |a, &p| a.min(p));
        assert!(want.distance(got) < 1e-3, "{}: {want} against {got}", o.id);
    }

    // The cuts are those of a full build of the edited scene within a few
    // percent over the table's views.
    cuts_as_full(&after, &changed, &config, tmp.path());

    // Updated again with the same scene: a schedule update, nothing made.
    let (_, _, how) = build_or_update_to(&changed, &config, &dir, false, &Silent).unwrap();
    assert!(matches!(how, How::ScheduleUpdate { .. }), "{how:?}");
}

#[test]
fn a_small_move_widens_the_errors_above_it_and_keeps_their_geometry() {
    let Built {
        scene,
        config,
        tmp,
        dir,
        before,
        ..
    } = built();
    // The storey 2 cm along x: far less than most levels' budgets.
    const MOVE: f64 = 0.02;
    let mut moved = scene.clone();
    let mut storey = HashSet::new();
    for o in &mut moved.objects {
        if on_storey(o) {
            o.transform.w_axis.x += MOVE as f32;
            storey.insert(o.id.clone());
        }
    }
    // And one object elsewhere re-tessellated: the same surface, one
    // triangle split at its centre, so its move is measured.
    let other = (moved.objects.iter_mut())
        .find(|o| o.motion.is_none() && !storey.contains(&o.id))
        .expect("an object on another storey");
    let mut mesh = moved.meshes[other.mesh].clone();
    let corners: Vec<u32> = mesh.indices[..3].to_vec();
    let centre = corners
        .iter()
        .map(|&i| mesh.positions[i as usize])
        .sum::<Vec3>()
        / 3.0;
    let c = mesh.positions.len() as u32;
    mesh.positions.push(centre);
    if !mesh.normals.is_empty() {
        let normal = mesh.normals[corners[0] as usize];
        mesh.normals.push(normal);
    }
    if !mesh.colors.is_empty() {
        let colour = mesh.colors[corners[0] as usize];
        mesh.colors.push(colour);
    }
    if !mesh.features.is_empty() {
        let feature = mesh.features[corners[0] as usize];
        mesh.features.push(feature);
    }
    mesh.indices[2] = c;
    mesh.indices
        .extend_from_slice(&[corners[1], corners[2], c, corners[2], corners[0], c]);
    moved.meshes.push(mesh);
    other.mesh = moved.meshes.len() - 1;
    let retessellated = other.id.clone();
    let mut edited = storey.clone();
    edited.insert(retessellated.clone());
    moved.apply_schedule();
    let (_, _, how) = build_or_update_to(&moved, &config, &dir, false, &Silent).unwrap();
    let How::GeometryUpdate {
        edited_objects,
        rebuilt,
        widened,
        ..
    } = how
    else {
        panic!("{how:?}")
    };
    assert_eq!(edited_objects, edited.len());
    assert!(widened > 0, "nothing widened, {rebuilt} made again");
    let after = load(&dir).expect("the updated tree passes every check of the loader");
    table_as_fresh(&dir, &after);
    common::assert_visibility_follows_children(&after, &config);
    assert_eq!(after.cluster_count(), before.cluster_count());

    // Above the edited leaves, a cluster either has new geometry or keeps
    // its file with its error widened by at most the move (the
    // re-tessellated object did not move, up to the measure's tolerance),
    // or raised to a child's.
    let mut above: Vec<u32> = Vec::new();
    for c in after.clusters().filter(|c| c.is_leaf()) {
        if edited.contains(&c.objects[0]) {
            let mut at = c.parent;
            while let Some(id) = at.filter(|&id| id != after.root) {
                above.push(id);
                at = after.cluster(id).parent;
            }
        }
    }
    above.sort_unstable();
    above.dedup();
    let mut kept = 0;
    for &id in &above {
        let (now, was) = (after.cluster(id), before.cluster(id));
        if now.geometry != was.geometry {
            continue;
        }
        kept += 1;
        let children = (now.children.iter())
            .map(|&k| after.cluster(k).eps)
            .fold(0.0, f64::max);
        assert!(
            // The move as measured on single-precision positions.
            now.eps >= was.eps && now.eps <= (was.eps + MOVE).max(children) + 1e-5,
            "cluster {id}: eps {} from {}",
            now.eps,
            was.eps
        );
        assert!(
            now.bounds.contains(&was.bounds, 0.0),
            "cluster {id}'s box shrank"
        );
    }
    assert!(
        kept >= widened,
        "{kept} kept their geometry, {widened} widened"
    );
    let leaf = (after.clusters())
        .find(|c| c.is_leaf() && c.objects[0] == retessellated)
        .expect("the re-tessellated object's leaf");
    let parent = leaf.parent.expect("a parent");
    assert_eq!(
        after.cluster(parent).geometry,
        before.cluster(parent).geometry,
        "the cluster above the re-tessellated object was made again"
    );
    assert_eq!(rebuilt + widened, above.len() + edited.len());
    // Every one of them bounds the distance to its objects as placed now.
    let checked = bounds_hold(&after, &dir, &moved, &above);
    assert!(checked >= widened, "{checked} checked");
    cuts_as_full(&after, &moved, &config, tmp.path());
}

#[test]
fn a_storey_added_anew_is_grouped_among_itself() {
    let Built {
        scene,
        config,
        tmp,
        dir,
        before_files,
        ..
    } = built();
    // A copy of the storey 20 m up, new ids, in the same tasks: more added
    // leaves than join their neighbours' groups one by one.
    let mut added = scene.clone();
    let copies: Vec<hdlod::scene::Object> = (scene.objects.iter())
        .filter(|o| on_storey(o))
        .map(|o| {
            let mut copy = o.clone();
            copy.id = format!("{}+", o.id);
            copy.transform.w_axis.y += 20.0;
            copy
        })
        .collect();
    assert!(copies.len() > 64, "{} objects on the storey", copies.len());
    let ids: HashSet<String> = copies.iter().map(|o| o.id.clone()).collect();
    for task in &mut added.tasks {
        let more: Vec<String> = (task.objects.iter())
            .map(|o| format!("{o}+"))
            .filter(|o| ids.contains(o))
            .collect();
        task.objects.extend(more);
    }
    added.objects.extend(copies);
    added.apply_schedule();
    let (_, _, how) = build_or_update_to(&added, &config, &dir, false, &Silent).unwrap();
    let How::GeometryUpdate {
        added_objects,
        rebuilt,
        ..
    } = how
    else {
        panic!("{how:?}")
    };
    assert_eq!(added_objects, ids.len());
    let after = load(&dir).expect("the updated tree passes every check of the loader");
    table_as_fresh(&dir, &after);
    common::assert_visibility_follows_children(&after, &config);
    // The added leaves' parents are made of added leaves alone, and no
    // cluster of the old tree was made again for them.
    let leaf_of_added = |c: &hdlod::tree::Cluster| c.is_leaf() && ids.contains(&c.objects[0]);
    let mut parents = HashSet::new();
    for c in after.clusters().filter(|c| leaf_of_added(c)) {
        let parent = c.parent.expect("a parent");
        if parent != after.root {
            parents.insert(parent);
        }
    }
    assert!(!parents.is_empty());
    for &p in &parents {
        for &k in &after.cluster(p).children {
            assert!(
                leaf_of_added(&after.cluster(k)),
                "cluster {p} mixes old and added"
            );
        }
    }
    let remade: Vec<u32> = (after.clusters())
        .filter(|c| (c.geometry.as_ref()).is_some_and(|g| !before_files.contains(g)))
        .map(|c| c.id)
        .collect();
    assert!(
        rebuilt >= remade.len(),
        "{rebuilt} made, {} new files",
        remade.len()
    );
    let checked = bounds_hold(&after, &dir, &added, &remade);
    assert!(checked >= parents.len(), "{checked} checked");
    cuts_as_full(&after, &added, &config, tmp.path());
}

#[test]
fn what_a_geometry_update_cannot_do_builds_in_full() {
    let scene = tiny();
    let config = BuildConfig::default();
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("tree");
    build_to(&scene, &config, &dir, &Silent).unwrap();
    let full_why = |s: &Scene| {
        let (_, _, how) = build_or_update_to(s, &config, &dir, false, &Silent).unwrap();
        let How::Full { why: Some(why) } = how else {
            panic!("{how:?}")
        };
        // Back to the original, in full, for the next case.
        build_to(&scene, &config, &dir, &Silent).unwrap();
        why
    };

    let mut most = scene.clone();
    for o in most.objects.iter_mut().filter(|o| o.motion.is_none()) {
        o.transform.w_axis.y += 0.1;
    }
    let why = full_why(&most);
    assert!(why.contains("more than a quarter"), "{why}");
}

/// `scene` without the objects `gone` names, in the reverse order, its
/// tasks no longer naming them.
fn without(scene: &Scene, gone: &HashSet<String>) -> Scene {
    let mut out = scene.clone();
    out.objects.retain(|o| !gone.contains(&o.id));
    out.objects.reverse();
    for t in &mut out.tasks {
        t.objects.retain(|o| !gone.contains(o));
    }
    out.apply_schedule();
    out
}

#[test]
fn removed_objects_leave_tombstones_and_the_others_keep_their_feature_ids() {
    let Built {
        scene,
        config,
        tmp,
        dir,
        before,
        before_files,
    } = built();
    let index_before: HashMap<String, u32> = (0..scene.objects.len())
        .map(|i| (scene.objects[i].id.clone(), i as u32))
        .collect();

    // Every third object of one storey that stands still, and one moving
    // object; the scene's order reversed, so only the ids say which is
    // which.
    let mut gone: HashSet<String> = scene
        .objects
        .iter()
        .filter(|o| on_storey(o))
        .step_by(3)
        .map(|o| o.id.clone())
        .collect();
    let moving = scene
        .objects
        .iter()
        .find(|o| o.motion.as_ref().is_some_and(|m| m.moves()))
        .expect("a moving object");
    gone.insert(moving.id.clone());
    let changed = without(&scene, &gone);
    let gone_leaves = before
        .clusters()
        .filter(|c| c.is_leaf() && c.objects.iter().any(|o| gone.contains(o)))
        .count();

    let (_, _, how) = build_or_update_to(&changed, &config, &dir, false, &Silent).unwrap();
    let How::GeometryUpdate {
        edited_objects,
        added_objects,
        removed_objects,
        rebuilt,
        dropped,
        dissolved,
        ..
    } = how
    else {
        panic!("{how:?}")
    };
    assert_eq!(
        (edited_objects, added_objects, removed_objects),
        (0, 0, gone.len())
    );
    assert!(
        dropped >= gone_leaves,
        "{dropped} dropped, {gone_leaves} leaves removed"
    );
    let after = load(&dir).expect("the updated tree passes every check of the loader");
    table_as_fresh(&dir, &after);
    assert_eq!(
        after.cluster_count(),
        before.cluster_count() - dropped - dissolved
    );
    assert!(
        rebuilt < after.cluster_count() / 4,
        "{rebuilt} of {} clusters made again",
        after.cluster_count()
    );

    // Every object keeps its feature id; a removed one's row is empty.
    let tables = after.objects.as_ref().expect("object tables");
    assert_eq!(tables.object_count(), scene.objects.len());
    for (id, &i) in &index_before {
        assert_eq!(tables.object_index(id), Some(i), "{id}");
        let row = tables.object(i);
        if gone.contains(id) {
            assert!(row.clusters.is_empty() && row.tasks.is_empty(), "{row:?}");
            assert!(row.open_presence().is_empty(), "{row:?}");
        } else {
            let was = before.objects.as_ref().unwrap().object(i);
            assert_eq!(row.clusters.len(), was.clusters.len(), "{id}");
            assert_eq!(row.presence, was.presence, "{id}");
        }
    }
    let absent = after.stats["absent_objects"].as_array().unwrap();
    assert!(
        absent.iter().all(|id| !gone.contains(id.as_str().unwrap())),
        "{absent:?}"
    );
    // No cluster names a removed object, and each static or
    // pseudo-dynamic leaf's vertices carry its object's feature id (a
    // moving object's cluster names it).
    for c in after.clusters() {
        assert!(
            c.objects.iter().all(|o| !gone.contains(o)),
            "cluster {}",
            c.id
        );
        if c.is_leaf() && matches!(c.class, ClusterClass::Static | ClusterClass::PseudoDynamic) {
            let mesh = read_mesh(&after.geometry_file(&dir, c.geometry.as_ref().unwrap())).unwrap();
            let want = index_before[&c.objects[0]];
            assert!(!mesh.features.is_empty(), "cluster {}", c.id);
            assert!(
                mesh.features.iter().all(|&f| f == want),
                "cluster {} of {}",
                c.id,
                c.objects[0]
            );
        }
    }
    let remade: Vec<u32> = (after.clusters())
        .filter(|c| (c.geometry.as_ref()).is_some_and(|g| !before_files.contains(g)))
        .map(|c| c.id)
        .collect();
    let checked = bounds_hold(&after, &dir, &changed, &remade);
    assert!(checked >= 1, "only {checked} clusters made again");
    cuts_as_full(&after, &changed, &config, tmp.path());

    // The same scene again: a schedule update, the tombstones kept.
    let (tree, _, how) = build_or_update_to(&changed, &config, &dir, false, &Silent).unwrap();
    assert!(matches!(how, How::ScheduleUpdate { .. }), "{how:?}");
    assert_eq!(
        tree.objects.as_ref().unwrap().object_count(),
        scene.objects.len()
    );

    // A removed object back: its index is a tombstone, so in full.
    let mut back = without(&scene, &gone);
    let returned = scene
        .objects
        .iter()
        .find(|o| o.id == moving.id)
        .unwrap()
        .clone();
    back.objects.push(returned);
    back.apply_schedule();
    let (tree, _, how) = build_or_update_to(&back, &config, &dir, false, &Silent).unwrap();
    let How::Full { why: Some(why) } = how else {
        panic!("{how:?}")
    };
    assert!(why.contains(&moving.id) && why.contains("back"), "{why}");
    assert_eq!(
        tree.objects.as_ref().unwrap().object_count(),
        back.objects.len()
    );
}

#[test]
fn a_moving_object_edited_and_one_added_get_their_own_chains() {
    let Built {
        scene,
        config,
        tmp,
        dir,
        before,
        ..
    } = built();

    let mut changed = scene.clone();
    let moving = changed
        .objects
        .iter()
        .position(|o| o.motion.as_ref().is_some_and(|m| m.moves()))
        .expect("a moving object");
    let id = changed.objects[moving].id.clone();
    changed.objects[moving].color[0] *= 0.5;
    let mut copy = changed.objects[moving].clone();
    copy.id = "ADDED-MOVING".into();
    copy.color = [0.9, 0.1, 0.1, 1.0];
    // A third, without a task: there throughout, it stands still where
    // its motion starts and ends, pieces that join groups.
    let mut idle = copy.clone();
    idle.id = "ADDED-IDLE".into();
    changed.objects.push(copy);
    changed.objects.push(idle);
    // A second excavator on the first one's tasks.
    for task in &mut changed.tasks {
        if task.objects.contains(&id) {
            task.objects.push("ADDED-MOVING".into());
        }
    }
    changed.apply_schedule();
    let old_leaves = before
        .clusters()
        .filter(|c| c.is_leaf() && c.objects == [id.clone()])
        .count();
    assert!(old_leaves > 0);

    let (_, _, how) = build_or_update_to(&changed, &config, &dir, false, &Silent).unwrap();
    let How::GeometryUpdate {
        edited_objects,
        added_objects,
        removed_objects,
        dropped,
        ..
    } = how
    else {
        panic!("{how:?}")
    };
    assert_eq!((edited_objects, added_objects, removed_objects), (1, 2, 0));
    assert!(
        dropped >= old_leaves,
        "{dropped} dropped of {old_leaves} leaves"
    );
    let after = load(&dir).expect("the updated tree passes every check of the loader");
    table_as_fresh(&dir, &after);
    // Both objects have their leaves, each moving leaf under its own chain
    // to the root, moving as its object.
    for name in [id.as_str(), "ADDED-MOVING"] {
        let leaves: Vec<_> = after
            .clusters()
            .filter(|c| c.is_leaf() && c.objects == [name])
            .collect();
        assert_eq!(leaves.len(), old_leaves, "{name}");
        assert!(leaves.iter().any(|c| c.class == ClusterClass::Dynamic));
        for leaf in leaves.iter().filter(|c| c.class == ClusterClass::Dynamic) {
            assert_eq!(leaf.motion, changed.objects[moving].motion, "{name}");
            let mut at = leaf.parent;
            while let Some(c) = at.filter(|&c| c != after.root) {
                assert_eq!(after.cluster(c).class, ClusterClass::Dynamic);
                at = after.cluster(c).parent;
            }
        }
    }
    let idle: Vec<_> = after
        .clusters()
        .filter(|c| c.is_leaf() && c.objects == ["ADDED-IDLE"])
        .map(|c| c.class)
        .collect();
    assert_eq!(idle.len(), 3, "{idle:?}");
    // Where it stands still before its motion it fits no group in time:
    // that leaf has lone parents of its own, as a build gives it.
    let lone = after.clusters().any(|c| {
        c.is_leaf()
            && c.objects == ["ADDED-IDLE"]
            && c.class != ClusterClass::Dynamic
            && after.cluster(c.parent.unwrap()).children.len() == 1
    });
    assert!(lone);
    let tables = after.objects.as_ref().unwrap();
    assert_eq!(tables.object_index(&id), Some(moving as u32));
    cuts_as_full(&after, &changed, &config, tmp.path());

    // The same scene again: a schedule update finds every leaf's piece.
    let (_, _, how) = build_or_update_to(&changed, &config, &dir, false, &Silent).unwrap();
    assert!(matches!(how, How::ScheduleUpdate { .. }), "{how:?}");
}

/// A write that replaces a tree copies every record whose content did not
/// change, writing only its ids, and the file is the one a fresh write
/// makes, byte for byte: here with one cluster's error changed and the
/// others as they were (the moving objects' chains among them, whose
/// records name the top of their chain). Object tables that did not change
/// are linked.
#[test]
fn a_write_that_replaces_a_tree_copies_its_unchanged_records() {
    let Built {
        tmp, dir, before, ..
    } = built();
    let mut tree = hdlod::tree::store::load_json(&dir).unwrap();
    let n = tree.cluster_count();
    let changed = tree
        .clusters()
        .position(|c| c.eps > 0.0 && c.motion.is_none())
        .expect("a reduced cluster");
    tree.clusters_mut()[changed].eps *= 1.5;
    assert!(tree.clusters().any(|c| c.motion.is_some() && !c.is_leaf()));
    let write = |to: &Path| {
        let writer = TreeWriter::create(to).unwrap();
        for c in tree.clusters() {
            if let Some(hash) = &c.geometry {
                writer.reuse_geometry(&dir, before.layout, hash).unwrap();
            }
        }
        writer
    };
    let (fresh, replacing) = (tmp.path().join("fresh"), tmp.path().join("replacing"));
    write(&fresh).finish(&tree).unwrap();
    let origin: Vec<Option<u32>> = (0..n as u32).map(Some).collect();
    let previous = Previous {
        tree: &before,
        dir: &dir,
        origin: &origin,
        table: None,
    };
    let copied = write(&replacing)
        .finish_replacing(&tree, &previous)
        .unwrap();
    assert_eq!(copied, n - 1, "every record but the changed one copied");
    let read = |d: &Path| std::fs::read(d.join("clusters.json")).unwrap();
    assert!(
        read(&fresh) == read(&replacing),
        "the copied table differs from a fresh one"
    );
    // The old table opened ahead, as an update opens it beside its plan.
    let opened = hdlod::tree::OldTable::open(&before, &dir).expect("a table this writer wrote");
    let ahead = tmp.path().join("ahead");
    let given = Previous {
        table: Some(&opened),
        ..previous
    };
    let copied = write(&ahead).finish_replacing(&tree, &given).unwrap();
    assert_eq!(copied, n - 1);
    assert!(read(&fresh) == read(&ahead));
    // The object tables did not change: the tree replaced's files linked.
    #[cfg(unix)]
    for file in ["objects.json", "objects.bin"] {
        use std::os::unix::fs::MetadataExt;
        let inode = |d: &Path| std::fs::metadata(d.join(file)).unwrap().ino();
        assert_eq!(inode(&dir), inode(&replacing), "{file} not linked");
        assert!(
            std::fs::read(fresh.join(file)).unwrap()
                == std::fs::read(replacing.join(file)).unwrap()
        );
    }
    // Nothing is copied from a cluster said to come from another one.
    let shifted: Vec<Option<u32>> = (0..n as u32).map(|c| Some((c + 1) % n as u32)).collect();
    let previous = Previous {
        origin: &shifted,
        ..previous
    };
    let other = tmp.path().join("other");
    let copied = write(&other).finish_replacing(&tree, &previous).unwrap();
    assert!(
        copied * 100 < n,
        "{copied} of {n} records copied from the wrong clusters"
    );
    assert!(read(&fresh) == read(&other));
}
