//! IFC geometry and IFC4 tasks: the hand-written fixtures/ifc-tiny/tiny.ifc
//! (every number below follows from its text), broken files, .ifczip, and
//! the real Schependomlaan models when the test data holds them.
#![cfg(feature = "ifc")]

mod common;

use std::io::Write;
use std::path::{Path, PathBuf};

use glam::Vec3;
use hdlod::import::{Options, Recorded, ifc, import};
use hdlod::scene::{Georeference, NamedType, Projected, TaskType, VisibilityType};

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

fn tiny() -> PathBuf {
    root().join("fixtures/ifc-tiny/tiny.ifc")
}

fn world_bounds(e: &ifc::Element) -> (Vec3, Vec3) {
    let (lo, hi) = e.mesh.bounds().unwrap();
    let o = e.origin.as_vec3();
    (lo + o, hi + o)
}

fn close(a: Vec3, b: Vec3) -> bool {
    (a - b).abs().max_element() < 1e-4
}

#[test]
fn tiny_model_elements_in_metres_with_storey_and_style() {
    let model = ifc::read(&tiny()).unwrap();
    assert_eq!(model.schema, "IFC4");
    let ids: Vec<&str> = model.elements.iter().map(|e| e.id.as_str()).collect();
    assert_eq!(ids, ["2WallTinyHdlod00000001", "2SlabTinyHdlod00000001"]);
    let (wall, slab) = (&model.elements[0], &model.elements[1]);

    assert_eq!(wall.class, "IfcWall");
    assert_eq!(wall.name, "wall A");
    assert_eq!(wall.storey.as_deref(), Some("00 ground floor"));
    // 4000 x 200 x 3000 mm placed at x = 1000 mm.
    let (lo, hi) = world_bounds(wall);
    assert!(close(lo, Vec3::new(1.0, 0.0, 0.0)), "{lo}");
    assert!(close(hi, Vec3::new(5.0, 0.2, 3.0)), "{hi}");
    // The opening is cut: a plain box has 12 triangles, a box with a hole
    // through it more, and none inside the hole.
    assert!(
        wall.mesh.triangle_count() > 12,
        "{}",
        wall.mesh.triangle_count()
    );
    let o = wall.origin.as_vec3();
    for t in wall.mesh.triangles() {
        let c = (t[0] + t[1] + t[2]) / 3.0 + o;
        let in_hole = c.x > 2.01 && c.x < 2.99 && c.z > 0.51 && c.z < 1.49;
        assert!(
            !(in_hole && c.y > 0.01 && c.y < 0.19),
            "triangle inside the hole at {c}"
        );
    }
    // Red from IfcStyledItem (linear 1, 0, 0), one colour so no vertex colours.
    assert_eq!(wall.color, [1.0, 0.0, 0.0, 1.0]);
    assert!(wall.mesh.colors.is_empty());

    assert_eq!(slab.class, "IfcSlab");
    let (lo, hi) = world_bounds(slab);
    assert!(close(lo, Vec3::new(0.0, 0.0, 3.0)), "{lo}");
    assert!(close(hi, Vec3::new(2.0, 2.0, 3.2)), "{hi}");
    assert_eq!(slab.color, ifc::default_color("IfcSlab"));

    let skipped = |class: &str| model.skipped.get(class).map(|r| r.values().sum::<usize>());
    assert_eq!(skipped("IfcOpeningElement"), Some(1));
    assert_eq!(skipped("IfcSpace"), Some(1));
    assert_eq!(skipped("IfcBuildingElementProxy"), Some(1));
    assert_eq!(model.skipped.len(), 3, "{:?}", model.skipped);
}

#[test]
fn ifc4_tasks_drive_visibility() {
    let model = ifc::read(&tiny()).unwrap();
    // Each task keeps its IFC type's name beside our type.
    let tasks: Vec<(&str, Option<NamedType>, &[String])> = model
        .tasks
        .iter()
        .map(|t| (t.id.as_str(), t.kind, t.objects.as_slice()))
        .collect();
    assert_eq!(
        tasks,
        [
            (
                "T1",
                Some(NamedType {
                    kind: TaskType::Construct,
                    ifc: Some("CONSTRUCTION")
                }),
                &["2WallTinyHdlod00000001".to_string()][..]
            ),
            (
                "T2",
                Some(NamedType {
                    kind: TaskType::Demolish,
                    ifc: Some("DEMOLITION")
                }),
                &["2SlabTinyHdlod00000001".to_string()][..]
            ),
        ]
    );

    let options = Options {
        name: "tiny".into(),
        ..Options::default()
    };
    let (scene, report) = import(&[tiny()], &options, &|_| {}).unwrap();
    assert_eq!(report.elements, 2);
    assert_eq!(report.scheduled, 2);
    assert!(report.unmatched.is_empty());
    // From the slab's removal (2024-02-01 08:00) to the wall's (2024-03-05 17:00).
    assert_eq!(report.time.start, "2024-02-01T08:00:00Z");
    assert_eq!(report.time.end, "2024-03-05T17:00:00Z");
    let span = scene.time.seconds;
    let wall = &scene.objects[0];
    let slab = &scene.objects[1];
    assert_eq!(wall.visibility.kind(span), VisibilityType::Appearing);
    assert_eq!(slab.visibility.kind(span), VisibilityType::Disappearing);
    // The scene keeps the IFC names, through its file too.
    let named = |s: &hdlod::scene::Scene| -> Vec<Option<&str>> {
        s.tasks.iter().map(|t| t.ifc_type).collect()
    };
    assert_eq!(named(&scene), [Some("CONSTRUCTION"), Some("DEMOLITION")]);
    let dir = tempfile::tempdir().unwrap();
    hdlod::scene::format::save(&scene, dir.path()).unwrap();
    let again = hdlod::scene::format::load(&dir.path().join("scene.json")).unwrap();
    assert_eq!(named(&again), named(&scene));
    let removed = scene
        .time
        .seconds_of(hdlod::time::parse_date("2024-02-02T17:00:00").unwrap());
    assert!(slab.visibility.at(removed - 1.0) && !slab.visibility.at(removed + 1.0));
    assert_eq!(wall.properties["storey"], "00 ground floor");
    assert_eq!(wall.properties["ifc_class"], "IfcWall");
    assert_eq!(wall.properties["source_file"], "tiny.ifc");
    assert_eq!(scene.up, hdlod::scene::Up::Z);
}

fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, text).unwrap();
    path
}

/// tiny.ifc as a progress record: T1 done late, T2 still running, both
/// nested in a summary task `W` without times of its own.
fn tiny_in_progress() -> String {
    let text = std::fs::read_to_string(tiny()).unwrap();
    let nested = "#220=IFCTASK('3TaskTinyHdlod00000003',$,'Works',$,$,'W',$,$,$,.F.,$,$,\
                  .CONSTRUCTION.);\n\
                  #221=IFCRELNESTS('3RelTinyHdlod000000003',$,$,$,#220,(#200,#210));\n\
                  ENDSEC;\nEND-ISO";
    text.replace(
        "'2024-03-05T17:00:00',$,$,$,$,$,$,$,$,$,$,$,$,$);",
        "'2024-03-05T17:00:00',$,$,$,$,$,$,$,$,$,'2024-03-04T08:00:00','2024-03-08T17:00:00',$,$);",
    )
    .replace(
        "'2024-02-02T17:00:00',$,$,$,$,$,$,$,$,$,$,$,$,$);",
        "'2024-02-02T17:00:00',$,$,$,$,$,$,$,$,$,'2024-02-01T10:00:00',$,$,$);",
    )
    .replacen("ENDSEC;\nEND-ISO", nested, 1)
}

#[test]
fn ifc4_actual_dates_and_nested_tasks() {
    let dir = tempfile::tempdir().unwrap();
    let text = tiny_in_progress();
    assert!(text.contains("#221=IFCRELNESTS"), "the fixture's end moved");
    let path = write(dir.path(), "progress.ifc", &text);
    let model = ifc::read(&path).unwrap();
    let d = |s: &str| Some(hdlod::time::parse_date(s).unwrap());
    let got: Vec<_> = model
        .tasks
        .iter()
        .map(|t| (t.id.as_str(), t.parent.as_deref(), t.actual))
        .collect();
    assert_eq!(
        got,
        [
            (
                "T1",
                Some("W"),
                Recorded {
                    start: d("2024-03-04T08:00:00"),
                    finish: d("2024-03-08T17:00:00")
                }
            ),
            (
                "T2",
                Some("W"),
                Recorded {
                    start: d("2024-02-01T10:00:00"),
                    finish: None
                }
            ),
            // The summary spans its tasks; running while T2 is.
            (
                "W",
                None,
                Recorded {
                    start: d("2024-02-01T10:00:00"),
                    finish: None
                }
            ),
        ]
    );
    let w = &model.tasks[2];
    assert_eq!(
        (w.start, w.finish),
        (
            d("2024-02-01T08:00:00").unwrap(),
            d("2024-03-05T17:00:00").unwrap()
        )
    );

    // In the scene: the two tasks under their summary, a task without
    // objects.
    let options = Options {
        name: "tiny".into(),
        ..Options::default()
    };
    let (scene, report) = import(&[path], &options, &|_| {}).unwrap();
    let tasks: Vec<(&str, Option<&str>, usize)> = scene
        .tasks
        .iter()
        .map(|t| (t.id.as_str(), t.parent.as_deref(), t.objects.len()))
        .collect();
    assert_eq!(
        tasks,
        [("T1", Some("W"), 1), ("T2", Some("W"), 1), ("W", None, 0)]
    );
    assert_eq!((report.summary_tasks, report.actual_tasks), (1, 3));
    // The span reaches T1's actual finish.
    assert_eq!(report.time.end, "2024-03-08T17:00:00Z");

    // Bad actual dates name the file, the entity and the attribute.
    let bad = |name: &str, text: String| {
        ifc::read(&write(dir.path(), name, &text))
            .unwrap_err()
            .to_string()
    };
    let e = bad("late.ifc", text.replace("'2024-03-04T08:00:00'", "'soon'"));
    assert!(
        e.contains("late.ifc")
            && e.contains("#201 (IfcTaskTime) ActualStart")
            && e.contains("soon"),
        "{e}"
    );
    let e = bad("orphan.ifc", text.replace("'2024-03-04T08:00:00'", "$"));
    assert!(
        e.contains("#201 (IfcTaskTime) ActualFinish") && e.contains("needs an actual start"),
        "{e}"
    );
    let e = bad(
        "backwards.ifc",
        text.replace("'2024-03-08T17:00:00'", "'2024-03-01T17:00:00'"),
    );
    assert!(
        e.contains("#201 (IfcTaskTime) ActualFinish") && e.contains("before"),
        "{e}"
    );
}

/// IFC4's IfcMapConversion and IfcProjectedCRS on the tiny model: the
/// scene's origin in RD New (EPSG:28992), millimetres read as the
/// project's unit, the x axis turned 30 degrees anticlockwise from grid
/// east; placed on Earth near Rotterdam.
#[test]
fn ifc4_map_conversion_gives_a_projected_origin() {
    let text = std::fs::read_to_string(tiny()).unwrap().replace(
        "#20=IFCGEOMETRICREPRESENTATIONCONTEXT($,'Model',3,1.E-05,#21,$);",
        "#20=IFCGEOMETRICREPRESENTATIONCONTEXT($,'Model',3,1.E-05,#21,$);\n\
         #900=IFCPROJECTEDCRS('EPSG:28992','Amersfoort / RD New','EPSG:4289',$,$,$,$);\n\
         #901=IFCMAPCONVERSION(#20,#900,92000000.,437000000.,2000.,0.8660254037844387,0.5,$);",
    );
    let dir = tempfile::tempdir().unwrap();
    let path = write(dir.path(), "mapped.ifc", &text);
    let (scene, report) = import(&[path], &Options::default(), &|_| {}).unwrap();
    assert!(report.warnings.is_empty(), "{:?}", report.warnings);
    let Some(Georeference::Projected(p)) = scene.georeference else {
        panic!("{:?}", scene.georeference);
    };
    assert!((p.heading + 30.0).abs() < 1e-9, "{p:?}");
    assert_eq!(
        p,
        Projected {
            crs: Some(28992),
            easting: 92_000.0,
            northing: 437_000.0,
            height: 2.0,
            scale: 1.0,
            ..p
        }
    );
    let on_earth = scene.georeference.unwrap().geographic().unwrap().unwrap();
    assert!((on_earth.latitude - 51.92).abs() < 0.01, "{on_earth:?}");
    assert!((on_earth.longitude - 4.48).abs() < 0.01, "{on_earth:?}");
}

#[test]
fn broken_step_names_the_file_and_the_entity() {
    let dir = tempfile::tempdir().unwrap();
    let text = std::fs::read_to_string(tiny()).unwrap();
    // A record that never closes.
    let broken = text.replace(
        "#48=IFCEXTRUDEDAREASOLID(#44,#21,#23,3000.);",
        "#48=IFCEXTRUDEDAREASOLID(#44,#21,#23,3000.;",
    );
    let path = write(dir.path(), "broken.ifc", &broken);
    let e = ifc::read(&path).unwrap_err().to_string();
    assert!(e.contains("broken.ifc") && e.contains("#48"), "{e}");

    let path = write(dir.path(), "nothing.ifc", "hello");
    let e = ifc::read(&path).unwrap_err().to_string();
    assert!(
        e.contains("nothing.ifc") && e.contains("FILE_SCHEMA"),
        "{e}"
    );
}

#[test]
fn unsupported_geometry_is_skipped_not_fatal() {
    let dir = tempfile::tempdir().unwrap();
    let text = std::fs::read_to_string(tiny()).unwrap();
    // The slab's body becomes an entity no mesher knows.
    let odd = text.replace(
        "#121=IFCFACETEDBREP(#120);",
        "#121=IFCCARTESIANPOINT((1.,2.,3.));",
    );
    let path = write(dir.path(), "odd.ifc", &odd);
    let model = ifc::read(&path).unwrap();
    assert_eq!(model.elements.len(), 1);
    assert!(model.skipped.contains_key("IfcSlab"), "{:?}", model.skipped);
}

#[test]
fn ifczip_reads_the_ifc_inside() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("tiny.ifczip");
    let mut zip = zip::ZipWriter::new(std::fs::File::create(&path).unwrap());
    let options = zip::write::SimpleFileOptions::default()
        .compression_method(zip::CompressionMethod::Deflated);
    zip.start_file("model/tiny.ifc", options).unwrap();
    zip.write_all(&std::fs::read(tiny()).unwrap()).unwrap();
    zip.finish().unwrap();
    let model = ifc::read(&path).unwrap();
    assert_eq!(model.elements.len(), 2);

    let empty = dir.path().join("empty.ifczip");
    let mut zip = zip::ZipWriter::new(std::fs::File::create(&empty).unwrap());
    zip.start_file("readme.txt", options).unwrap();
    zip.finish().unwrap();
    let e = ifc::read(&empty).unwrap_err().to_string();
    assert!(e.contains("empty.ifczip") && e.contains("no .ifc"), "{e}");
}

/// The real building: every model imports, the rules link every element
/// but the surveyor's marker, and the storeys rise in order through 2015.
#[test]
fn schependomlaan_rises_storey_by_storey() {
    let Some(data) = common::data("schependomlaan") else {
        return;
    };
    let mut models: Vec<PathBuf> = std::fs::read_dir(data.join("ifc"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    models.sort();
    assert_eq!(models.len(), 12);
    let options = Options {
        name: "schependomlaan".into(),
        schedule: Some(data.join("planning.xml")),
        links: Some(root().join("fixtures/schependomlaan/links.json")),
        ..Options::default()
    };
    let (scene, report) = import(&models, &options, &|_| {}).unwrap();
    assert!(report.elements > 650, "{}", report.elements);
    assert!(report.triangles > 50_000, "{}", report.triangles);
    assert!(
        report.rules.iter().all(|r| r.matched > 0),
        "{:?}",
        report.rules
    );
    assert_eq!(report.unmatched.len(), 1, "{:?}", report.unmatched);
    assert!(report.time.start.starts_with("2015-") && report.time.end.starts_with("2015-"));

    // The first instant each storey shows an element, in storey order.
    let span = scene.time.seconds;
    let mut first: std::collections::BTreeMap<&str, f64> = Default::default();
    for o in &scene.objects {
        let Some(storey) = o.properties.get("storey") else {
            continue;
        };
        if let Some(&(t, _)) = o.visibility.clipped(span).first() {
            let e = first.entry(storey.as_str()).or_insert(t);
            *e = e.min(t);
        }
    }
    let order: Vec<f64> = ["00", "01", "02", "03"]
        .iter()
        .map(|s| {
            first
                .iter()
                .find(|(k, _)| k.starts_with(s))
                .map(|(_, &t)| t)
                .unwrap()
        })
        .collect();
    assert!(order.windows(2).all(|w| w[0] < w[1]), "{first:?}");
    // Bounds in metres: a building of about 22 x 22 x 13 m.
    let (mut lo, mut hi) = (Vec3::splat(f32::MAX), Vec3::splat(f32::MIN));
    for o in &scene.objects {
        let (a, b) = scene.meshes[o.mesh].bounds().unwrap();
        lo = lo.min(o.transform.transform_point3(a));
        hi = hi.max(o.transform.transform_point3(b));
    }
    let size = hi - lo;
    assert!(size.max_element() < 30.0 && size.z > 10.0, "{size}");
    // Every model's IfcSite: 52 deg 9' N, 5 deg 23' E, 20,000 mm up; the
    // building stands near its IFC origin, which stays the scene's.
    let Some(Georeference::Geographic(g)) = scene.georeference else {
        panic!("{:?}", scene.georeference);
    };
    assert!((g.latitude - (52.0 + 9.0 / 60.0)).abs() < 1e-9, "{g:?}");
    assert!((g.longitude - (5.0 + 23.0 / 60.0)).abs() < 1e-9, "{g:?}");
    assert!((g.height - 20.0).abs() < 1e-9 && g.heading == 0.0, "{g:?}");
}

/// The real building as planned against as built: the as-built event log
/// names no element of these models and none of the plan's task ids, so its
/// tasks are matched to the plan by name (nearest planned start among the
/// tasks of a name) and the rules link the elements to the plan. Computes
/// the figures and the table of docs/import.md ("As planned against as
/// built") and checks that the page holds them.
#[test]
fn schependomlaan_as_planned_against_as_built() {
    let Some(data) = common::data("schependomlaan") else {
        return;
    };
    let mut models: Vec<PathBuf> = std::fs::read_dir(data.join("ifc"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    models.sort();
    let (plan, log) = (
        data.join("planning.xml"),
        data.join("eventlog-as-built.csv"),
    );
    let options = Options {
        name: "schependomlaan".into(),
        schedule: Some(plan.clone()),
        links: Some(root().join("fixtures/schependomlaan/links.json")),
        actual: vec![log.clone()],
        ..Options::default()
    };
    let (scene, report) = import(&models, &options, &|_| {}).unwrap();
    let a = report.actual.as_ref().unwrap();
    // 3,661 element rows of 72 tasks (the 3,505 empty rows left out), every
    // task found in the plan by its name.
    assert_eq!(
        (
            a.rows,
            a.tasks,
            a.by_id,
            a.by_name,
            a.dated,
            a.unmatched_rows
        ),
        (3661, 72, 0, 72, 72, 0)
    );
    assert_eq!((report.scene_tasks, report.actual_tasks), (29, 25));

    // Finish against plan in days: the days of the finishes, a finish at
    // midnight being the end of the day before (the log gives days).
    let day = |d: chrono::DateTime<chrono::Utc>| (d - chrono::Duration::seconds(1)).date_naive();
    let late_by = |planned: chrono::DateTime<chrono::Utc>,
                   actual: chrono::DateTime<chrono::Utc>| {
        (day(actual) - day(planned)).num_days()
    };
    let date = |t: f64| scene.time.date_at(t);
    let mut rows: Vec<(i64, &hdlod::scene::Task)> = scene
        .tasks
        .iter()
        .filter_map(|t| Some((late_by(date(t.finish), date(t.actual.finish?)), t)))
        .collect();
    assert_eq!(rows.len(), 25, "every dated task of the scene has finished");
    // Latest against the plan first; of equals, the one planned to finish
    // last.
    rows.sort_by(|(a, x), (b, y)| {
        b.cmp(a)
            .then(y.finish.total_cmp(&x.finish))
            .then(x.id.cmp(&y.id))
    });
    let mut table = String::from(
        "| task | planned finish | actual finish (last day) | days late |\n|---|---|---|---|\n",
    );
    for (late, t) in rows.iter().take(5) {
        table += &format!(
            "| {} {} | {} | {} | {late} |\n",
            t.id,
            t.name.trim(),
            date(t.finish).format("%Y-%m-%d %H:%M"),
            day(date(t.actual.finish.unwrap())),
        );
    }
    let count = |rows: &[i64]| {
        (
            rows.iter().filter(|&&d| d == 0).count(),
            rows.iter().filter(|&&d| d < 0).count(),
            rows.iter().filter(|&&d| d > 0).count(),
        )
    };
    let scene_late: Vec<i64> = rows.iter().map(|(d, _)| *d).collect();
    let early: Vec<String> = rows
        .iter()
        .rev()
        .filter(|(d, _)| *d < 0)
        .map(|(d, t)| format!("{} {} by {}", t.id, t.name.trim(), -d))
        .collect();

    // Every plan task the log dates, not only those acting on the models.
    let mut tasks = hdlod::import::msproject::read(&plan).unwrap();
    let logs = [hdlod::import::actual::read(&log).unwrap()];
    hdlod::import::actual::apply(&mut tasks, &logs, &mut Vec::new());
    let plan_late: Vec<i64> = tasks
        .iter()
        .filter_map(|t| Some(late_by(t.finish, t.actual.finish?)))
        .collect();
    // How the log's names meet the plan's: one plan task of the name, or
    // several told apart by the planned start.
    let normal = |n: &str| {
        n.split_whitespace()
            .collect::<Vec<_>>()
            .join(" ")
            .to_lowercase()
    };
    let plan_names: Vec<String> = tasks.iter().map(|t| normal(&t.name)).collect();
    let shared = |n: &str| plan_names.iter().filter(|p| **p == normal(n)).count();
    let log_tasks = &logs[0].tasks;
    let distinct: std::collections::BTreeSet<String> =
        log_tasks.iter().map(|t| normal(&t.name)).collect();
    let same_day = tasks
        .iter()
        .filter(|t| {
            t.actual
                .start
                .is_some_and(|s| s.date_naive() == t.start.date_naive())
        })
        .count();
    let names = format!(
        "Its {} tasks carry {} distinct names, {} of them names of the plan; {} tasks have a \
         name the plan gives one task, the other {} share theirs with 2 to {} plan tasks. \
         For {same_day} of the {} plan tasks so dated the log's start is the planned start's \
         day.",
        log_tasks.len(),
        distinct.len(),
        distinct.iter().filter(|n| shared(n) > 0).count(),
        log_tasks.iter().filter(|t| shared(&t.name) == 1).count(),
        log_tasks.iter().filter(|t| shared(&t.name) > 1).count(),
        log_tasks.iter().map(|t| shared(&t.name)).max().unwrap(),
        plan_late.len(),
    );
    // The as-built log's task dates are the as-planned log's, task by task.
    let planned_log = hdlod::import::actual::read(&data.join("eventlog-as-planned.csv")).unwrap();
    for t in log_tasks {
        let p = planned_log.tasks.iter().find(|p| p.id == t.id).unwrap();
        assert_eq!(p.actual, t.actual, "{}", t.id);
    }
    // Elements whose every task has no actual start: never there on the
    // actual dates.
    let undated: std::collections::HashSet<&str> = scene
        .tasks
        .iter()
        .filter(|t| t.actual.start.is_none())
        .flat_map(|t| t.objects.iter().map(String::as_str))
        .collect();
    let dated: std::collections::HashSet<&str> = scene
        .tasks
        .iter()
        .filter(|t| t.actual.start.is_some())
        .flat_map(|t| t.objects.iter().map(String::as_str))
        .collect();
    let never = undated.difference(&dated).count();
    let undated_tasks: Vec<String> = scene
        .tasks
        .iter()
        .filter(|t| t.actual.start.is_none())
        .map(|t| t.id.clone())
        .collect();
    let unrecorded = format!(
        "the {} without ({}) are not in the log, and their {never} elements never appear on \
         the actual dates",
        undated_tasks.len(),
        undated_tasks.join(", ")
    );

    let (on, before, after) = count(&scene_late);
    let (plan_on, plan_before, plan_after) = count(&plan_late);
    let summary = format!(
        "Of the {} tasks of the scene with actual dates, {on} finished on their planned \
         day, {before} earlier ({}) and {after} later; of all {} plan tasks the log dates, \
         {plan_on} finished on their planned day, {plan_before} earlier and {plan_after} later.",
        scene_late.len(),
        early.join(", "),
        plan_late.len(),
    );

    // The log's own judgement, per element and without dates.
    let mut reader = csv::Reader::from_path(&log).unwrap();
    let flag = reader
        .headers()
        .unwrap()
        .iter()
        .position(|h| h == "Element on time or not")
        .unwrap();
    let mut too_late: std::collections::BTreeMap<String, usize> = Default::default();
    for row in reader.records() {
        let row = row.unwrap();
        if &row[flag] == "Too late" {
            *too_late
                .entry(format!("{} {}", &row[5], &row[7]))
                .or_default() += 1;
        }
    }
    let flagged = format!(
        "{} element rows of {} tasks are marked \"Too late\"",
        too_late.values().sum::<usize>(),
        too_late.len()
    );

    // Compared with white space collapsed: the page wraps its lines.
    let flat = |s: &str| s.split_whitespace().collect::<Vec<_>>().join(" ");
    let doc = flat(&std::fs::read_to_string(root().join("docs/import.md")).unwrap());
    let missing: Vec<&String> = [&table, &summary, &flagged, &names, &unrecorded]
        .into_iter()
        .filter(|text| !doc.contains(&flat(text)))
        .collect();
    assert!(
        missing.is_empty(),
        "docs/import.md lacks what this data gives:\n{}\n(flags by log task: {too_late:?})",
        missing
            .iter()
            .map(|s| s.as_str())
            .collect::<Vec<_>>()
            .join("\n\n")
    );
}
