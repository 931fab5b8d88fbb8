//! The object and task tables (`objects.json`) of the tree built from the
//! committed tiny fixture: every scene object in scene order with what the
//! scene says of it, read back equal, following the schema; a broken table
//! is reported by file and field.

mod common;

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use hdlod::build::{BuildConfig, Silent, build_to};
use hdlod::scene::status::{Dates, Progress};
use hdlod::scene::{Class, LinkType, Scene, format};
use hdlod::tree::objects::{LinkEntry, ObjectTables, ObjectsRecord};
use hdlod::tree::{Tree, load};

struct Built {
    scene: Scene,
    tree: Tree,
    dir: PathBuf,
    _tmp: tempfile::TempDir,
}

fn built() -> &'static Built {
    static BUILT: OnceLock<Built> = OnceLock::new();
    BUILT.get_or_init(|| {
        let fixture = Path::new(env!("CARGO_MANIFEST_DIR")).join("../fixtures/skyscraper-tiny");
        let scene = format::load(&fixture).expect("the tiny fixture loads");
        let tmp = tempfile::tempdir().unwrap();
        let dir = tmp.path().join("tree");
        let (tree, _) =
            build_to(&scene, &BuildConfig::default(), &dir, &Silent).expect("the build succeeds");
        assert_eq!(load(&dir).expect("the written tree loads"), tree);
        Built {
            scene,
            tree,
            dir,
            _tmp: tmp,
        }
    })
}

fn tables() -> &'static ObjectTables {
    built()
        .tree
        .objects
        .as_ref()
        .expect("the builder makes the tables")
}

#[test]
fn the_written_table_follows_the_schema() {
    let text = std::fs::read_to_string(built().dir.join("objects.json")).unwrap();
    common::assert_matches_schema(
        &serde_json::from_str(&text).unwrap(),
        "tree-objects.schema.json",
    );
}

/// The scene's links become links by task index, as the schema says.
#[test]
fn links_by_task_index() {
    let scene = common::sample_scene();
    let tables = ObjectTables::of(&scene, &[]);
    // The scaffolding (T3) is struck a day after the beams (T2) finish.
    assert_eq!(
        tables.tasks()[2].predecessors,
        [LinkEntry {
            task: 1,
            kind: LinkType::FinishFinish,
            lag: 86_400.0
        }]
    );
    let record = serde_json::to_value(tables.to_record(&scene.time)).unwrap();
    common::assert_matches_schema(&record, "tree-objects.schema.json");
    assert_eq!(
        record["tasks"][2]["predecessors"],
        serde_json::json!([{"task": 1, "type": "FF", "lag": 86400.0}])
    );
}

/// The table's index of an object is its index in the scene, absent
/// objects included; each row says what the scene and the tree say of it.
#[test]
fn every_scene_object_in_scene_order() {
    let (b, t) = (built(), tables());
    assert_eq!(t.objects().len(), b.scene.objects.len());
    let mut absent = 0;
    for (i, (row, o)) in t.objects().iter().zip(&b.scene.objects).enumerate() {
        assert_eq!(row.id, o.id);
        assert_eq!(t.object_index(&o.id), Some(i as u32));
        assert_eq!(row.properties, o.properties);
        assert_eq!(row.name.as_ref(), o.properties.get("name"));
        assert_eq!(row.class.as_ref(), o.properties.get("ifc_class"));
        assert_eq!(row.visibility_class, b.scene.class_of(o));
        assert_eq!(row.presence, o.visibility);
        let leaves: Vec<u32> = b
            .tree
            .clusters()
            .filter(|c| c.objects.contains(&o.id))
            .map(|c| c.id)
            .collect();
        assert_eq!(row.clusters, leaves, "object {}", o.id);
        if row.visibility_class == Class::Absent {
            absent += 1;
            assert!(row.clusters.is_empty());
        } else {
            assert!(!row.clusters.is_empty(), "object {} has no leaf", o.id);
        }
        let tasks: Vec<u32> = (0..b.scene.tasks.len() as u32)
            .filter(|&k| b.scene.tasks[k as usize].objects.contains(&o.id))
            .collect();
        assert_eq!(row.tasks, tasks, "object {}", o.id);
    }
    assert!(absent > 0, "the fixture has absent objects");
    assert!(
        t.objects().iter().any(|o| o.clusters.len() > 1),
        "a moving object split where it stands still has several leaves"
    );
}

#[test]
fn every_task_with_its_objects() {
    let (b, t) = (built(), tables());
    assert_eq!(t.tasks().len(), b.scene.tasks.len());
    for (k, (row, task)) in t.tasks().iter().zip(&b.scene.tasks).enumerate() {
        assert_eq!(row.id, task.id);
        assert_eq!(t.task_index(&task.id), Some(k as u32));
        assert_eq!(row.name.as_deref(), Some(task.name.as_str()));
        assert_eq!((row.kind, row.dates), (task.kind, task.dates()));
        let ids: Vec<&str> = row
            .objects
            .iter()
            .map(|&i| t.objects()[i as usize].id.as_str())
            .collect();
        let mut expected: Vec<&str> = task.objects.iter().map(String::as_str).collect();
        expected.sort_by_key(|id| t.object_index(id));
        assert_eq!(ids, expected, "task {}", task.id);
        let (d, plan) = (&row.dates, Dates::Planned);
        assert_eq!(d.progress(d.start - 1.0, plan), Progress::NotStarted);
        assert_eq!(d.progress(d.finish, plan), Progress::Finished);
        if d.finish > d.start {
            assert_eq!(d.progress(d.start, plan), Progress::Active);
        }
    }
    let record = t.to_record(&b.tree.time);
    assert_eq!(record.tasks[0].start_date, "2024-03-04T07:00:00Z");
}

#[test]
fn search_finds_by_id_name_and_property_ignoring_case() {
    let t = tables();
    let columns = t.search_objects("column l01", 0, 1000);
    assert!(columns.total > 0 && columns.next.is_none());
    for &i in &columns.items {
        let name = t.objects()[i as usize].name.as_deref().unwrap();
        assert!(name.to_lowercase().contains("column l01"), "{name}");
    }
    // By a property value only (the storey), and by the id.
    let storey = t.search_objects("level 01", 0, 1000);
    assert!(storey.total > columns.total);
    let by_id = t.search_objects("l01-c-00-00", 0, 10);
    assert_eq!(by_id.items, vec![t.object_index("L01-C-00-00").unwrap()]);
    // Pages cover the matches once, in order.
    let mut seen = Vec::new();
    let mut from = 0;
    loop {
        let page = t.search_objects("LEVEL 01", from, 7);
        assert_eq!(page.total, storey.total);
        seen.extend(page.items);
        match page.next {
            Some(next) => from = next as usize,
            None => break,
        }
    }
    assert_eq!(seen, storey.items);
    let all = t.search_objects("", 0, 5);
    assert_eq!(
        (all.items, all.next, all.total),
        (vec![0, 1, 2, 3, 4], Some(5), t.objects().len())
    );
    assert_eq!(t.search_objects("no such thing", 0, 5).total, 0);
    let tasks = t.search_tasks("DEMOLISH", 0, 100);
    assert!(tasks.total > 0);
    assert_eq!(t.search_tasks("", 0, 1000).items.len(), t.tasks().len());
}

/// A change to a written table.
type Edit = fn(&mut ObjectsRecord);

/// A table that does not fit the tree or itself is an error naming the
/// file and the field.
#[test]
fn a_broken_table_names_the_field() {
    let b = built();
    let file = b.dir.join("objects.json");
    let record = || tables().to_record(&b.tree.time);
    let cases: [(Edit, &str); 10] = [
        (|r| r.format = "hdlod-objects/9".into(), "format"),
        (
            |r| r.objects[3].id = r.objects[2].id.clone(),
            "objects[3].id",
        ),
        (|r| r.objects[5].clusters = vec![0], "objects[5].clusters"),
        (
            |r| r.objects[5].clusters = vec![u32::MAX],
            "objects[5].clusters",
        ),
        (|r| r.objects[5].clusters.clear(), "objects"),
        (|r| r.objects[0].tasks = vec![0], "objects[0].tasks"),
        (
            |r| r.objects[0].presence = vec![[Some(5.0), Some(1.0)]],
            "objects[0].presence",
        ),
        (|r| r.tasks[1].id = r.tasks[0].id.clone(), "tasks[1].id"),
        (|r| r.tasks[0].finish = -1.0, "tasks[0].finish"),
        (|r| r.tasks[0].objects = vec![0], "tasks[0].objects"),
    ];
    for (edit, field) in cases {
        let mut r = record();
        edit(&mut r);
        let e = ObjectTables::from_record(r, &b.tree, &file)
            .expect_err(field)
            .to_string();
        assert!(
            e.starts_with(&format!("{}: {field}: ", file.display())),
            "{field}: {e}"
        );
    }
}
