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
        // A static is never dropped: in cargo's temporary directory for
        // tests, which `cargo clean` empties, not the system's.
        let tmp = tempfile::tempdir_in(env!("CARGO_TARGET_TMPDIR")).unwrap();
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
    assert_eq!(t.object_count(), b.scene.objects.len());
    let mut absent = 0;
    for (i, o) in b.scene.objects.iter().enumerate() {
        let row = t.object(i as u32);
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
        (0..t.object_count() as u32).any(|i| t.rows().clusters(i).len() > 1),
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
        let ids: Vec<&str> = row.objects.iter().map(|&i| t.rows().id(i)).collect();
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
        let name = t.rows().name(i).unwrap();
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
        (vec![0, 1, 2, 3, 4], Some(5), t.object_count())
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

/// A copy of the built tree, to damage.
fn copy_of_built() -> (tempfile::TempDir, PathBuf) {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("tree");
    let from = &built().dir;
    std::fs::create_dir_all(&dir).unwrap();
    for entry in std::fs::read_dir(from).unwrap() {
        let path = entry.unwrap().path();
        if path.is_file() {
            std::fs::copy(&path, dir.join(path.file_name().unwrap())).unwrap();
        }
    }
    for path in common::geometry_files(from) {
        let to = dir.join(path.strip_prefix(from).unwrap());
        std::fs::create_dir_all(to.parent().unwrap()).unwrap();
        std::fs::copy(&path, to).unwrap();
    }
    (tmp, dir)
}

/// The object index and `objects.json` describe the same tables: the
/// rows mapped from `objects.bin` decode, search and look up as those read
/// from the JSON, and a tree written without the index gets it from
/// `write_index`.
#[test]
fn the_object_index_and_the_json_describe_the_same_tables() {
    use hdlod::tree::format::OBJECTS_INDEX_FILE;
    use hdlod::tree::store::{load_json, write_index};
    let b = built();
    let mapped = load(&b.dir).unwrap().objects.unwrap();
    let json = load_json(&b.dir).unwrap().objects.unwrap();
    assert!(mapped.rows().is_mapped() && !json.rows().is_mapped());
    assert_eq!(mapped, json);
    assert_eq!(&mapped, tables());
    assert!(mapped.object_count() > 100);
    for i in 0..json.object_count() as u32 {
        let o = json.object(i);
        assert_eq!(mapped.object(i), o);
        assert_eq!(mapped.object_index(&o.id), Some(i));
    }
    for q in ["", "column", "LEVEL 01", "no such thing"] {
        assert_eq!(
            mapped.search_objects(q, 3, 20),
            json.search_objects(q, 3, 20),
            "{q}"
        );
    }
    assert_eq!(mapped.tasks(), json.tasks());
    assert_eq!(mapped.to_record(&b.tree.time), json.to_record(&b.tree.time));
    // The migration: a tree without the index loads from the JSON, and
    // `write_index` gives it back the same bytes.
    let (_tmp, dir) = copy_of_built();
    let path = dir.join(OBJECTS_INDEX_FILE);
    let written = std::fs::read(&path).unwrap();
    std::fs::remove_file(&path).unwrap();
    assert!(!load(&dir).unwrap().objects.unwrap().rows().is_mapped());
    write_index(&dir).unwrap();
    assert_eq!(std::fs::read(&path).unwrap(), written);
}

/// A damaged object index fails the load, naming the file and what is
/// wrong, as a damaged cluster index does.
#[test]
fn a_damaged_object_index_is_named_with_what_is_wrong() {
    use hdlod::tree::format::{OBJECTS_FILE, OBJECTS_INDEX_FILE};
    use hdlod::tree::object_index::VERSION;
    type Damage = Box<dyn FnOnce(&mut Vec<u8>)>;
    let cases: Vec<(&str, Damage)> = vec![
        ("not an hdlod object index", Box::new(|b| b[0] = b'X')),
        (
            "version 2, this reader reads version 1",
            Box::new(|b| b[8..12].copy_from_slice(&(VERSION + 1).to_le_bytes())),
        ),
        (
            "shorter than its 240-byte header",
            Box::new(|b| b.truncate(100)),
        ),
        ("(truncated)", Box::new(|b| b.truncate(b.len() - 8))),
        (
            "header.checksum: does not match",
            Box::new(|b| {
                let at = b.len() / 2;
                b[at] ^= 0x40;
            }),
        ),
        (
            "header.checksum: does not match",
            Box::new(|b| {
                let at = b.len() - 1;
                b[at] ^= 1;
            }),
        ),
    ];
    for (expected, damage) in cases {
        let (_tmp, dir) = copy_of_built();
        let path = dir.join(OBJECTS_INDEX_FILE);
        let mut bytes = std::fs::read(&path).unwrap();
        damage(&mut bytes);
        std::fs::write(&path, &bytes).unwrap();
        let e = load(&dir).unwrap_err().to_string();
        assert!(
            e.contains(OBJECTS_INDEX_FILE) && e.contains(expected),
            "{expected:?} not in {e}"
        );
    }
    // An index left behind by a hand edit of objects.json.
    let (_tmp, dir) = copy_of_built();
    let mut json = std::fs::read(dir.join(OBJECTS_FILE)).unwrap();
    json.push(b' ');
    std::fs::write(dir.join(OBJECTS_FILE), json).unwrap();
    let e = load(&dir).unwrap_err().to_string();
    assert!(
        e.contains(OBJECTS_INDEX_FILE) && e.contains("was made from an objects.json of"),
        "{e}"
    );
}
