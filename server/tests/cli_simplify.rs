//! `hdlod simplify`, `hdlod lod` and `hdlod bench simplify`: their JSON
//! matches the schemas (schemas/simplify.schema.json,
//! schemas/bench-simplify.schema.json), and bad input gets a clear error.

mod common;

use std::path::PathBuf;

use common::{assert_no_gltf_errors, assert_valid, data, hdlod, schema};

/// A classic mesh of the test data, or `None` when it is missing.
fn mesh(name: &str) -> Option<PathBuf> {
    Some(data("meshes")?.join(name))
}

fn report(args: &[&str]) -> serde_json::Value {
    let out = hdlod(args);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_valid(&schema("simplify.schema.json"), &json, "simplify --json");
    json
}

#[test]
fn every_method_reports_valid_json() {
    let Some(input) = mesh("fandisk.obj") else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    for method in ["qem", "clustering", "vertex-removal"] {
        let out = dir.path().join(format!("{method}.obj"));
        let json = report(&[
            "simplify",
            input.to_str().unwrap(),
            out.to_str().unwrap(),
            "--method",
            method,
            "--ratio",
            "0.1",
            "--json",
        ]);
        let (n, m) = (
            json["triangles_in"].as_u64().unwrap(),
            json["triangles_out"].as_u64().unwrap(),
        );
        assert_eq!(n, 12_946);
        assert!(m <= n / 10 + 1 && m > 0, "{json}");
        let h = json["hausdorff"].as_f64().unwrap();
        assert!(
            h > 0.0
                && h >= json["hausdorff_lower"].as_f64().unwrap()
                && h >= json["rms"].as_f64().unwrap()
        );
        let area = json["area_ratio"].as_f64().unwrap();
        assert!(area > 0.8 && area < 1.2, "{json}");
        let written = hdlod::io::obj::read_mesh(&out).unwrap();
        assert_eq!(written.triangle_count() as u64, m);
    }
}

#[test]
fn positions_only_drops_the_normals_and_says_so() {
    let Some(horse) = mesh("horse.ply") else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    assert!(
        !hdlod::io::ply::read_mesh(&horse)
            .unwrap()
            .normals
            .is_empty()
    );
    for (flag, weighed) in [(None, true), (Some("--positions-only"), false)] {
        let out = dir.path().join("out.glb");
        let mut args = vec![
            "simplify",
            horse.to_str().unwrap(),
            out.to_str().unwrap(),
            "--ratio",
            "0.1",
            "--json",
        ];
        args.extend(flag);
        let json = report(&args);
        assert_eq!(json["positions_only"], !weighed, "{json}");
        let written = hdlod::io::gltf::read_mesh(&out).unwrap();
        assert_eq!(!written.normals.is_empty(), weighed);
        assert!(json["triangles_out"].as_u64().unwrap() <= 9_697, "{json}");
    }
}

#[test]
fn glb_out_and_back_in() {
    let Some(f) = mesh("fandisk.obj") else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let (glb, again) = (dir.path().join("o.glb"), dir.path().join("again.obj"));
    let first = report(&[
        "simplify",
        f.to_str().unwrap(),
        glb.to_str().unwrap(),
        "--ratio",
        "0.5",
        "--json",
    ]);
    let second = report(&[
        "simplify",
        glb.to_str().unwrap(),
        again.to_str().unwrap(),
        "--ratio",
        "1",
        "--json",
    ]);
    assert_eq!(first["triangles_out"], second["triangles_in"]);
}

/// horse.ply's normals are not unit length; glTF requires them to be.
#[test]
fn glb_output_passes_the_gltf_validator() {
    let Some(horse) = mesh("horse.ply") else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let glb = dir.path().join("horse.glb");
    report(&[
        "simplify",
        horse.to_str().unwrap(),
        glb.to_str().unwrap(),
        "--method",
        "clustering",
        "--ratio",
        "0.1",
        "--json",
    ]);
    assert_no_gltf_errors(&[glb]);
}

#[test]
fn an_error_budget_and_a_ratio_above_one() {
    let Some(input) = mesh("fandisk.obj") else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("o.obj");
    let (i, o) = (input.to_str().unwrap(), out.to_str().unwrap());
    let json = report(&["simplify", i, o, "--error", "0.01", "--json"]);
    assert!(json["triangles_out"].as_u64() < json["triangles_in"].as_u64());
    let json = report(&["simplify", i, o, "--ratio", "1.5", "--json"]);
    assert_eq!(json["triangles_out"], json["triangles_in"]);
    assert!(json["hausdorff"].as_f64().unwrap() < 1e-4, "{json}");
}

#[test]
fn bad_input_is_a_clear_error() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("o.obj");
    let o = out.to_str().unwrap();
    let fail = |args: &[&str], needle: &str| {
        let r = hdlod(args);
        let stderr = String::from_utf8_lossy(&r.stderr).to_string();
        assert!(
            !r.status.success() && stderr.contains(needle),
            "{needle:?} not in {stderr}"
        );
    };
    fail(
        &["simplify", "/nonexistent/in.obj", o, "--ratio", "0.5"],
        "/nonexistent/in.obj",
    );
    let nan = dir.path().join("nan.obj");
    std::fs::write(&nan, "v 0 0 0\nv 1 NaN 0\nv 0 1 0\nf 1 2 3\n").unwrap();
    fail(
        &["simplify", nan.to_str().unwrap(), o, "--ratio", "0.5"],
        "line 2",
    );
    let empty = dir.path().join("empty.obj");
    std::fs::write(&empty, "# nothing\n").unwrap();
    fail(
        &["simplify", empty.to_str().unwrap(), o, "--ratio", "0.5"],
        "no triangles",
    );
    let f = dir.path().join("tetra.obj");
    std::fs::write(
        &f,
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n",
    )
    .unwrap();
    fail(
        &["simplify", f.to_str().unwrap(), o, "--ratio", "-1"],
        "--ratio",
    );
    fail(&["simplify", f.to_str().unwrap(), o], "--ratio");
    fail(
        &["simplify", f.to_str().unwrap(), "x.stl", "--ratio", "0.5"],
        "x.stl",
    );
}

#[test]
fn bench_simplify_rows_match_the_schema() {
    let Some(dir) = data("meshes") else {
        return;
    };
    let out = hdlod(&[
        "bench",
        "simplify",
        "--meshes",
        dir.to_str().unwrap(),
        "--models",
        "fandisk",
        "--ratios",
        "0.05",
        "--runs",
        "1",
        "--json",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_valid(
        &schema("bench-simplify.schema.json"),
        &json,
        "bench simplify --json",
    );
    let rows = json.as_array().unwrap();
    assert_eq!(rows.len(), 3, "one row per method");
    for r in rows {
        let (n, m) = (
            r["triangles_in"].as_u64().unwrap(),
            r["triangles_out"].as_u64().unwrap(),
        );
        let ratio = r["ratio"].as_f64().unwrap();
        assert!(
            m > 0 && (m as f64) <= (ratio * n as f64).ceil() + 1.0,
            "{r}"
        );
        assert!(
            r["hausdorff"].as_f64().unwrap() >= r["mean"].as_f64().unwrap(),
            "{r}"
        );
    }
}

#[test]
fn bench_simplify_names_the_meshes_it_lacks() {
    let fail = hdlod(&["bench", "simplify", "--meshes", "/nonexistent", "--json"]);
    assert!(!fail.status.success());
    assert!(String::from_utf8_lossy(&fail.stderr).contains("/nonexistent"));
    // Without --meshes or HDLOD_DATA it says what to pass.
    let fail = std::process::Command::new(env!("CARGO_BIN_EXE_hdlod"))
        .args(["bench", "simplify", "--json"])
        .env_remove("HDLOD_DATA")
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&fail.stderr);
    assert!(!fail.status.success());
    assert!(
        stderr.contains("--meshes") && stderr.contains("HDLOD_DATA"),
        "{stderr}"
    );
}

#[test]
fn lod_writes_one_glb_and_measures_each_level() {
    let Some(f) = mesh("fandisk.obj") else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("fandisk-lod.glb");
    let run = hdlod(&[
        "lod",
        f.to_str().unwrap(),
        out.to_str().unwrap(),
        "--levels",
        "1,0.3,0.1",
        "--method",
        "vertex-removal",
        "--json",
    ]);
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let levels: serde_json::Value = serde_json::from_slice(&run.stdout).unwrap();
    let levels = levels.as_array().unwrap();
    assert_eq!(levels.len(), 3);
    assert_eq!(levels[0]["triangles"], 12_946);
    assert!(levels[0]["hausdorff"].as_f64().unwrap() < 1e-4);
    for pair in levels.windows(2) {
        assert!(pair[1]["triangles"].as_u64() < pair[0]["triangles"].as_u64());
        assert!(pair[1]["screen_coverage"].as_f64() < pair[0]["screen_coverage"].as_f64());
    }
    assert!(levels[2]["hausdorff"].as_f64().unwrap() > 0.0);
    let bytes = std::fs::read(&out).unwrap();
    assert_eq!(&bytes[..4], b"glTF");

    let o = out.to_str().unwrap();
    for (levels, needle) in [("1,1", "level 1"), ("0.5,0", "level 1"), ("2", "level 0")] {
        let r = hdlod(&["lod", f.to_str().unwrap(), o, "--levels", levels]);
        let stderr = String::from_utf8_lossy(&r.stderr);
        assert!(
            !r.status.success() && stderr.contains(needle),
            "{levels}: {stderr}"
        );
    }
    let r = hdlod(&["lod", f.to_str().unwrap(), "x.obj"]);
    assert!(String::from_utf8_lossy(&r.stderr).contains("x.obj"));
}
