//! `hdlod build` and `hdlod inspect TREE` on the committed tiny fixture: the
//! JSON follows the schemas, bad configurations are clear errors, a failed
//! build leaves the previous tree as it was.

mod common;

use common::{assert_success, hdlod, repo};

#[test]
fn builds_the_tiny_fixture_and_inspects_the_tree() {
    let tmp = tempfile::tempdir().unwrap();
    let tree = tmp.path().join("tree");
    let fixture = repo().join("fixtures/skyscraper-tiny");
    let summary = built(&fixture, &tree, &[]);
    assert_eq!(summary["objects"], 633);
    assert_eq!(summary["mode"], "full");

    // The same scene again: its schedule is updated, no geometry made.
    let again = |extra: &[&str]| built(&fixture, &tree, extra);
    let updated = again(&[]);
    assert_eq!(updated["mode"], "schedule-update");
    assert_eq!(updated["reused"]["clusters"], summary["clusters"]);
    assert_eq!(updated["reused"]["dissolved_groups"], 0);
    assert!(updated["reused"]["geometry_files"].as_u64().unwrap() > 100);
    let full = again(&["--full"]);
    assert_eq!(full["mode"], "full");
    assert!(full.get("not_updated").is_none());

    // One object moved: only the clusters above it are made again.
    let edited = one_object_moved(&fixture, &tmp.path().join("edited"));
    let local = built(&edited, &tree, &[]);
    assert_eq!(local["mode"], "geometry-update", "{local}");
    let reused = &local["reused"];
    assert_eq!(reused["edited_objects"], 1);
    assert_eq!(reused["added_objects"], 0);
    let rebuilt = reused["rebuilt_clusters"].as_u64().unwrap();
    assert!((2..=12).contains(&rebuilt), "{local}");
    assert_eq!(
        reused["clusters"].as_u64().unwrap() + rebuilt,
        local["clusters"].as_u64().unwrap()
    );
    assert!(tree.join("sources.bin").is_file());

    let out = hdlod(&["inspect".as_ref(), tree.as_os_str(), "--json".as_ref()]);
    assert_success(&out);
    let inspect: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    common::assert_matches_schema(&inspect, "inspect-tree.schema.json");
    assert_eq!(inspect["clusters"], summary["clusters"]);
    // Level 0 holds the leaves: every visible object (a moving object that
    // stands still before or after its motion has more than one).
    let levels = inspect["levels"].as_array().unwrap();
    assert_eq!(levels[0]["level"], 0);
    assert_eq!(levels[0]["clusters"], inspect["leaves"]);
    assert!(
        levels[0]["clusters"].as_u64().unwrap()
            >= 628 - summary["absent_objects"].as_u64().unwrap()
    );

    let table = hdlod(&["inspect".as_ref(), tree.as_os_str()]);
    let text = String::from_utf8_lossy(&table.stdout);
    assert!(
        text.contains("tree skyscraper-tiny") && text.contains("max eps"),
        "{text}"
    );
}

#[test]
fn a_bad_configuration_names_the_field_and_keeps_the_old_tree() {
    let tmp = tempfile::tempdir().unwrap();
    let tree = tmp.path().join("tree");
    std::fs::create_dir_all(&tree).unwrap();
    std::fs::write(tree.join("marker"), "the previous tree").unwrap();
    let fixture = repo().join("fixtures/skyscraper-tiny");
    for (config, field) in [
        (r#"{"max_children": 1}"#, "max_children"),
        (r#"{"k_eps": -1}"#, "k_eps"),
        (r#"{"gamma_maxx": 0.1}"#, "gamma_maxx"),
    ] {
        let path = tmp.path().join("config.json");
        std::fs::write(&path, config).unwrap();
        let out = hdlod(&[
            "build".as_ref(),
            fixture.as_os_str(),
            "--out".as_ref(),
            tree.as_os_str(),
            "--config".as_ref(),
            path.as_os_str(),
        ]);
        assert!(!out.status.success());
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains("config.json") && err.contains(field), "{err}");
    }
    let out = hdlod(&[
        "build".as_ref(),
        tmp.path().join("no-such-scene").as_os_str(),
        "--out".as_ref(),
        tree.as_os_str(),
    ]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("no-such-scene"));
    assert_eq!(
        std::fs::read_to_string(tree.join("marker")).unwrap(),
        "the previous tree"
    );
}

/// The README's main command: `hdlod demo` generates, builds and serves.
#[test]
fn demo_generates_builds_and_serves() {
    let tmp = tempfile::tempdir().unwrap();
    let demo = common::Server::spawn(&[
        "demo".as_ref(),
        "--scale".as_ref(),
        "tiny".as_ref(),
        "--addr".as_ref(),
        "127.0.0.1:0".as_ref(),
        "--dir".as_ref(),
        tmp.path().as_os_str(),
    ]);
    let scenes = demo.get_json("/api/v1/scenes");
    drop(demo);
    assert_eq!(scenes["scenes"][0]["name"], "skyscraper-tiny");
    assert!(
        tmp.path()
            .join("skyscraper-tiny-tree/manifest.json")
            .is_file()
    );
}

/// A build killed with SIGKILL leaves its temporary beside the target; the
/// next build to that target removes it, and the temporaries of processes
/// still alive (this test's own PID stands for a build running elsewhere)
/// stay. `hdlod fixture --out` cleans up after itself the same way.
#[test]
fn a_build_removes_what_killed_builds_left() {
    let tmp = tempfile::tempdir().unwrap();
    let tree = tmp.path().join("tree");
    let fixture = repo().join("fixtures/skyscraper-tiny");
    let temporaries = || -> Vec<String> {
        let mut names: Vec<String> = std::fs::read_dir(tmp.path())
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .filter(|n| n.starts_with(".tree.") || n.starts_with(".scene."))
            .collect();
        names.sort();
        names
    };

    let mut build = std::process::Command::new(env!("CARGO_BIN_EXE_hdlod"))
        .args([
            "build".as_ref(),
            fixture.as_os_str(),
            "--out".as_ref(),
            tree.as_os_str(),
        ])
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn()
        .unwrap();
    let started = std::time::Instant::now();
    while temporaries().is_empty() && started.elapsed().as_secs() < 60 {
        std::thread::sleep(std::time::Duration::from_millis(5));
    }
    build.kill().unwrap();
    build.wait().unwrap();
    let killed = temporaries();
    assert_eq!(killed.len(), 1, "{killed:?}");
    assert!(killed[0].starts_with(&format!(".tree.tmp-{}-", build.id())));

    let alive = format!(".tree.tmp-{}-0", std::process::id());
    let scene_alive = format!(".scene.tmp-{}", std::process::id());
    for name in [alive.as_str(), ".scene.tmp-4194999", scene_alive.as_str()] {
        std::fs::create_dir(tmp.path().join(name)).unwrap();
    }
    assert_success(&hdlod(&[
        "build".as_ref(),
        fixture.as_os_str(),
        "--out".as_ref(),
        tree.as_os_str(),
    ]));
    assert_success(&hdlod(&[
        "fixture".as_ref(),
        "skyscraper".as_ref(),
        "--out".as_ref(),
        tmp.path().join("scene").as_os_str(),
    ]));
    let mut left = vec![scene_alive, alive];
    left.sort();
    assert_eq!(temporaries(), left);
}

/// An update killed with SIGKILL at any point leaves a tree that loads:
/// the old one until the rename, the new one after (the first update
/// moves the geometry into the store beside the tree by an atomic
/// exchange, so the old tree has its files throughout). The next build
/// updates it and leaves no temporary.
#[test]
fn a_killed_update_leaves_a_tree_that_loads() {
    let fixture = repo().join("fixtures/skyscraper-tiny");
    killed_updates(&[&fixture], "schedule-update");
}

/// The same for geometry updates: each build is the tiny site with one
/// object moved, or the site as it was, in turn.
#[test]
fn a_killed_geometry_update_leaves_a_tree_that_loads() {
    let fixture = repo().join("fixtures/skyscraper-tiny");
    let tmp = tempfile::tempdir().unwrap();
    let edited = one_object_moved(&fixture, &tmp.path().join("edited"));
    killed_updates(&[&edited, &fixture], "geometry-update");
}

/// The summary of `hdlod build SCENE --out TREE --json` and `extra`,
/// which must succeed and follow its schema.
fn built(scene: &std::path::Path, tree: &std::path::Path, extra: &[&str]) -> serde_json::Value {
    let mut args = vec![
        "build".as_ref(),
        scene.as_os_str(),
        "--out".as_ref(),
        tree.as_os_str(),
        "--json".as_ref(),
    ];
    args.extend(extra.iter().map(|a| std::ffi::OsStr::new(*a)));
    let out = hdlod(&args);
    assert_success(&out);
    let summary: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    common::assert_matches_schema(&summary, "build-summary.schema.json");
    summary
}

/// The scene at `fixture` with one object of a storey moved 50 cm, saved
/// at `to`.
fn one_object_moved(fixture: &std::path::Path, to: &std::path::Path) -> std::path::PathBuf {
    let mut scene = hdlod::scene::format::load(fixture).unwrap();
    let still = scene
        .objects
        .iter()
        .position(|o| o.motion.is_none() && o.properties.contains_key("storey"))
        .unwrap();
    scene.objects[still].transform.w_axis.x += 0.5;
    hdlod::scene::format::save(&scene, to).unwrap();
    to.to_path_buf()
}

/// Updates of a tree of `scenes[0]` to each of `scenes` in turn, killed
/// ever later; then one to the end, whose mode is `mode`.
fn killed_updates(scenes: &[&std::path::Path], mode: &str) {
    let tmp = tempfile::tempdir().unwrap();
    let tree = common::build_tree(tmp.path());
    let args = |k: usize| {
        [
            "build".as_ref(),
            scenes[k % scenes.len()].as_os_str(),
            "--out".as_ref(),
            tree.as_os_str(),
            "--json".as_ref(),
        ]
    };
    let mut interrupted = 0;
    for (k, extra) in [0, 0, 2, 5, 10, 20, 40, 80].into_iter().enumerate() {
        let mut update = std::process::Command::new(env!("CARGO_BIN_EXE_hdlod"))
            .args(args(k))
            .stdout(std::process::Stdio::null())
            .stderr(std::process::Stdio::null())
            .spawn()
            .unwrap();
        let temporary = format!(".tree.tmp-{}-", update.id());
        let started = std::time::Instant::now();
        while started.elapsed().as_secs() < 60
            && update.try_wait().unwrap().is_none()
            && !std::fs::read_dir(tmp.path()).unwrap().any(|e| {
                e.unwrap()
                    .file_name()
                    .to_string_lossy()
                    .starts_with(&temporary)
            })
        {
            std::thread::sleep(std::time::Duration::from_millis(1));
        }
        std::thread::sleep(std::time::Duration::from_millis(extra));
        let _ = update.kill();
        let status = update.wait().unwrap();
        interrupted += usize::from(!status.success());
        hdlod::tree::load(&tree).unwrap_or_else(|e| panic!("killed after {extra} ms more: {e}"));
    }
    assert!(interrupted > 0, "no update was killed before its end");

    // The tree holds one of the scenes: updated to the other (or, with
    // one scene, to it again), to the end.
    let loaded = hdlod::tree::load(&tree).unwrap();
    let sources =
        |p: &std::path::Path| hdlod::build::object_sources(&hdlod::scene::format::load(p).unwrap());
    let next = (0..scenes.len())
        .find(|&k| sources(scenes[k]) != *loaded.sources.as_ref().unwrap())
        .unwrap_or(0);
    let out = hdlod(&args(next));
    assert_success(&out);
    let summary: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(summary["mode"], mode, "{summary}");
    let mut left: Vec<String> = std::fs::read_dir(tmp.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    left.sort();
    assert_eq!(left, [".tree.geometry", "tree"]);
}

/// `hdlod bench build SCENE` times the scene's build and then schedule and
/// geometry updates of its tree (a storey moved, then removed), and leaves
/// nothing behind in its work directory.
#[test]
fn bench_build_times_builds_and_updates() {
    let tmp = tempfile::tempdir().unwrap();
    let work = tmp.path().join("work");
    let fixture = repo().join("fixtures/skyscraper-tiny");
    let out = hdlod(&[
        "bench".as_ref(),
        "build".as_ref(),
        fixture.as_os_str(),
        "--repeats".as_ref(),
        "1".as_ref(),
        "--work".as_ref(),
        work.as_os_str(),
        "--json".as_ref(),
    ]);
    assert_success(&out);
    let report: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(report["runs"].as_array().unwrap().len(), 1);
    assert_eq!(report["update_runs"].as_array().unwrap().len(), 1);
    assert!(report["schedule_edit_tasks"].as_u64().unwrap() > 0);
    assert!(report["median_update_wall_seconds"].as_f64().unwrap() > 0.0);
    // One storey moved and back: geometry updates, against a full build.
    assert_eq!(report["geometry_edit_storey"], "Level 02");
    assert!(report["geometry_edit_objects"].as_u64().unwrap() > 0);
    assert_eq!(report["geometry_update_runs"].as_array().unwrap().len(), 1);
    let rebuilt = report["rebuilt_clusters"].as_u64().unwrap();
    assert!(rebuilt > 0 && rebuilt < report["clusters"].as_u64().unwrap() / 2);
    assert!(report["table_largest_change_percent"].as_f64().unwrap() < 50.0);
    // Then that storey removed: a geometry update that drops clusters.
    assert_eq!(report["removed_storeys"], serde_json::json!(["Level 02"]));
    assert_eq!(
        report["removed_objects"],
        report["geometry_edit_objects"]
            .as_u64()
            .map(|n| serde_json::json!([n]))
            .unwrap()
    );
    assert_eq!(report["removal_runs"].as_array().unwrap().len(), 1);
    assert!(report["removal_dropped_clusters"].as_u64().unwrap() > 0);
    assert!(
        report["removal_table_largest_change_percent"]
            .as_f64()
            .unwrap()
            < 50.0
    );
    // Then that storey back as new objects: a geometry update that makes
    // the clusters above them again.
    assert_eq!(report["added_objects"], report["removed_objects"]);
    assert_eq!(report["addition_runs"].as_array().unwrap().len(), 1);
    assert!(report["addition_rebuilt_clusters"].as_u64().unwrap() > 0);
    assert!(
        report["addition_table_largest_change_percent"]
            .as_f64()
            .unwrap()
            < 50.0
    );
    assert!(!work.exists(), "the work directory is removed");
}

/// A served tree updated in place by `hdlod build` (a schedule update, then
/// a geometry update, each sharing the geometry store and removing the
/// old tree's directory) is reloaded by the file watch, and every geometry
/// file a cut of the new tree names is served.
#[test]
fn a_served_tree_updated_in_place_is_reloaded() {
    let tmp = tempfile::tempdir().unwrap();
    let tree = common::build_tree(tmp.path());
    let fixture = repo().join("fixtures/skyscraper-tiny");
    let edited = one_object_moved(&fixture, &tmp.path().join("edited"));
    let server = common::Server::start(&tree);
    let scene = server.get_json("/api/v1/scenes/skyscraper-tiny");
    let http = common::client();
    for (source, mode) in [(&fixture, "schedule-update"), (&edited, "geometry-update")] {
        let before = server.reloads();
        assert_eq!(built(source, &tree, &[])["mode"], mode);
        server.await_reloads(before + 1);
        let cut = server.post_json(
            "/api/v1/scenes/skyscraper-tiny/cut",
            &common::cut_over(&scene, 0.6),
        );
        let clusters = cut["clusters"].as_array().unwrap();
        assert!(!clusters.is_empty(), "{cut}");
        for c in clusters {
            let url = server.url(c["geometry"].as_str().unwrap());
            let response = http.get(&url).send().unwrap();
            assert_eq!(response.status(), 200, "{url} after the {mode}");
        }
    }
}
