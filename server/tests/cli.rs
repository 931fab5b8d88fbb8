//! `hdlod cut` and `hdlod bench paper` on a sample tree; `hdlod bench
//! objects` on the tiny fixture's.

mod common;

use std::process::Command;

use serde_json::Value;

fn hdlod(args: &[&str]) -> (bool, String, String) {
    let out = common::hdlod(args);
    (
        out.status.success(),
        String::from_utf8(out.stdout).unwrap(),
        String::from_utf8(out.stderr).unwrap(),
    )
}

#[test]
fn cut_prints_the_http_answer() {
    let dir = tempfile::tempdir().unwrap();
    let tree = common::sample_tree(dir.path(), 4);
    let tree = tree.to_str().unwrap();
    let camera = dir.path().join("camera.json");
    std::fs::write(
        &camera,
        r#"{"position": [150, 120, 150], "target": [0, 20, 0], "fov_y_deg": 50}"#,
    )
    .unwrap();

    let flags = [
        "cut",
        tree,
        "--time",
        "2024-04-20",
        "--position",
        "150,120,150",
        "--target",
        "0,20,0",
        "--fov",
        "50",
        "--pixel-error",
        "2",
        "--viewport",
        "1280x720",
        "--json",
    ];
    let (ok, by_flags, err) = hdlod(&flags);
    assert!(ok, "{err}");
    let (ok, by_file, err) = hdlod(&[
        "cut",
        tree,
        "--time",
        "2024-04-20",
        "--camera-json",
        camera.to_str().unwrap(),
        "--pixel-error",
        "2",
        "--viewport",
        "1280x720",
        "--json",
    ]);
    assert!(ok, "{err}");
    let a: Value = serde_json::from_str(&by_flags).unwrap();
    let b: Value = serde_json::from_str(&by_file).unwrap();
    assert_eq!(a["clusters"], b["clusters"]);
    assert!(!a["clusters"].as_array().unwrap().is_empty());

    common::assert_matches_schema(&a, "api/cut-response.schema.json");

    for (position, field) in [("1,2", "position"), ("0,0,0", "camera.target")] {
        let (ok, _, err) = hdlod(&[
            "cut",
            tree,
            "--time",
            "0",
            "--position",
            position,
            "--target",
            "0,0,0",
        ]);
        assert!(!ok && err.contains(field), "{err}");
    }
}

/// `hdlod bench skin` compares multi-pose levels of the skinned limb with
/// bind-pose ones of as many triangles; bad sizes are refused.
#[test]
fn bench_skin_reports_both_reductions() {
    let (ok, out, err) = hdlod(&["bench", "skin", "--rings", "16", "--sides", "8", "--json"]);
    assert!(ok, "{err}");
    let rows: Value = serde_json::from_str(&out).unwrap();
    let rows = rows.as_array().unwrap();
    assert_eq!(rows.len(), 6);
    for r in rows {
        let bind = r["bind_pose"]["largest"].as_f64().unwrap();
        let posed = r["multi_pose"]["largest"].as_f64().unwrap();
        assert!(bind > 0.0 && posed > 0.0, "{r}");
        assert!(r["triangles"].as_u64().unwrap() > 0, "{r}");
    }
    let (ok, _, err) = hdlod(&["bench", "skin", "--sides", "2"]);
    assert!(!ok);
    assert!(err.contains("--sides"), "{err}");
}

#[test]
fn bench_paper_writes_the_table() {
    let dir = tempfile::tempdir().unwrap();
    let tree = common::sample_tree(dir.path(), 4);
    let doc = dir.path().join("benchmarks.md");
    std::fs::write(&doc, "# Benchmarks\n\nOther text.\n").unwrap();
    let args = [
        "bench",
        "paper",
        tree.to_str().unwrap(),
        "--frames",
        "20",
        "--repeats",
        "3",
        "--doc",
        doc.to_str().unwrap(),
        "--json",
    ];
    for _ in 0..2 {
        let (ok, out, err) = hdlod(&args);
        assert!(ok, "{err}");
        let report: Value = serde_json::from_str(&out).unwrap();
        common::assert_valid(
            &common::schema("bench-paper.schema.json"),
            &report,
            "bench paper --json",
        );
        let rows = report["rows"].as_array().unwrap();
        assert_eq!(rows.len(), 15);
        for key in [
            "time",
            "screen",
            "triangles",
            "clusters",
            "baseline_triangles",
            "baseline_draws",
            "micros",
            "visited",
        ] {
            assert!(rows[0].get(key).is_some(), "{key}");
        }
        assert!(report["median_nanos_per_visited"].as_f64().unwrap() > 0.0);
        // Each cell's bytes per cut, stored and plain, within the tree's;
        // the animation rows have none.
        let tree_bytes = report["tree_bytes"].as_u64().unwrap();
        for r in rows {
            if r["time"] == "animation" {
                assert!(r["bytes"].is_null(), "{r}");
                continue;
            }
            let (stored, plain) = (
                r["bytes"]["stored"].as_u64().unwrap(),
                r["bytes"]["plain"].as_u64().unwrap(),
            );
            assert_eq!(stored > 0, r["clusters"].as_f64().unwrap() > 0.0, "{r}");
            assert_eq!(plain > 0, stored > 0, "{r}");
            assert!(stored <= tree_bytes, "{r}");
        }
    }
    // A frame that names no object is refused, naming what it looked for.
    for (frame, want) in [("site", "KEY=VALUE"), ("site=Nowhere", "\"Nowhere\"")] {
        let (ok, _, err) = hdlod(&["bench", "paper", tree.to_str().unwrap(), "--frame", frame]);
        assert!(!ok);
        assert!(err.contains(want), "{err}");
    }
    // Written twice, the section is replaced, not repeated.
    let text = std::fs::read_to_string(&doc).unwrap();
    assert!(text.starts_with("# Benchmarks\n\nOther text.\n"));
    assert_eq!(text.matches("| animation | 1/16 |").count(), 1, "{text}");

    // Without --doc, run where a docs/benchmarks.md lies, nothing is written.
    let here = dir.path().join("clone");
    std::fs::create_dir_all(here.join("docs")).unwrap();
    std::fs::write(here.join("docs/benchmarks.md"), "# Benchmarks\n").unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_hdlod"))
        .args(&args[..args.len() - 3])
        .current_dir(&here)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(String::from_utf8_lossy(&out.stdout).contains("| animation | 1/16 |"));
    assert_eq!(
        std::fs::read_to_string(here.join("docs/benchmarks.md")).unwrap(),
        "# Benchmarks\n"
    );
}

#[test]
fn bench_objects_times_the_tables() {
    let dir = tempfile::tempdir().unwrap();
    let tree = common::build_tree(dir.path());
    let (ok, out, err) = hdlod(&[
        "bench",
        "objects",
        tree.to_str().unwrap(),
        "--repeats",
        "2",
        "--json",
    ]);
    assert!(ok, "{err}");
    let report: Value = serde_json::from_str(&out).unwrap();
    assert_eq!(report["scene"], common::SCENE);
    assert!(report["objects"].as_u64().unwrap() > 500);
    for key in [
        "read_ms",
        "parse_ms",
        "tables_ms",
        "tree_load_ms",
        "search_all_ms",
    ] {
        assert!(report[key].as_f64().unwrap() >= 0.0, "{key}");
    }
    // A tree without tables: the error names the file.
    let sample = common::sample_tree(&dir.path().join("sample"), 2);
    let (ok, _, err) = hdlod(&["bench", "objects", sample.to_str().unwrap()]);
    assert!(!ok && err.contains("objects.json"), "{err}");
}
