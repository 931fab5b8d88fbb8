//! `hdlod simplify`: its JSON matches schemas/simplify.schema.json, and bad
//! input gets a clear error.

use std::path::{Path, PathBuf};
use std::process::Command;

fn hdlod(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_hdlod"))
        .args(args)
        .output()
        .expect("run hdlod")
}

fn fandisk() -> PathBuf {
    let here = Path::new(env!("CARGO_MANIFEST_DIR"));
    [
        here.join("../../shared/data/meshes"),
        here.join("../../../shared/data/meshes"),
    ]
    .into_iter()
    .find(|d| d.exists())
    .expect("shared/data/meshes next to the repository")
    .join("fandisk.obj")
}

fn schema() -> jsonschema::Validator {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../schemas/simplify.schema.json");
    let schema: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap();
    jsonschema::validator_for(&schema).unwrap()
}

fn report(args: &[&str]) -> serde_json::Value {
    let out = hdlod(args);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    if let Err(e) = schema().validate(&json) {
        panic!("{e}: {json}");
    }
    json
}

#[test]
fn both_methods_report_valid_json() {
    let dir = tempfile::tempdir().unwrap();
    let input = fandisk();
    for method in ["qem", "clustering"] {
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
fn glb_out_and_back_in() {
    let dir = tempfile::tempdir().unwrap();
    let (glb, again) = (dir.path().join("o.glb"), dir.path().join("again.obj"));
    let f = fandisk();
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

#[test]
fn an_error_budget_and_a_ratio_above_one() {
    let dir = tempfile::tempdir().unwrap();
    let (input, out) = (fandisk(), dir.path().join("o.obj"));
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
    let f = fandisk();
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
