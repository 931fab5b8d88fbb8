//! What `hdlod inspect` and `build` read: a scene's models stay inside its
//! directory unless `--allow-outside-paths`, only regular files are read,
//! each within `--max-input-bytes`; every refusal is quick and names the
//! file.

mod common;

use std::ffi::OsStr;
use std::path::Path;
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

use common::saved_sample;
use serde_json::Value;

/// `hdlod ARGS`, killed after 30 s: a run that hangs fails the test rather
/// than the suite.
fn run<S: AsRef<OsStr>>(args: &[S]) -> (Output, Duration) {
    let start = Instant::now();
    let mut child = Command::new(env!("CARGO_BIN_EXE_hdlod"))
        .env("RUST_LOG", "warn")
        .args(args)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    while child.try_wait().unwrap().is_none() {
        if start.elapsed() > Duration::from_secs(30) {
            let _ = child.kill();
            let _ = child.wait();
            panic!("hdlod {:?} still ran after 30 s", args[0].as_ref());
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    (child.wait_with_output().unwrap(), start.elapsed())
}

fn with_models(scene: &Path, models: Value) {
    let file = scene.join("scene.json");
    let mut json: Value = serde_json::from_str(&std::fs::read_to_string(&file).unwrap()).unwrap();
    json["models"] = models;
    std::fs::write(&file, json.to_string()).unwrap();
}

fn refused<S: AsRef<OsStr> + std::fmt::Debug>(args: &[S], parts: &[&str]) {
    let (out, took) = run(args);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "{args:?} succeeded");
    assert!(took < Duration::from_secs(10), "{args:?} took {took:?}");
    for p in parts {
        assert!(stderr.contains(p), "{stderr:?} does not name {p:?}");
    }
}

#[test]
fn a_device_is_not_read() {
    let tmp = tempfile::tempdir().unwrap();
    let scene = saved_sample(tmp.path());
    with_models(&scene, serde_json::json!(["/dev/zero"]));
    let tree = tmp.path().join("tree");
    // Allowed outside, a device is still refused (before: inspect hung and
    // build grew to 7.7 GB).
    for command in [
        vec!["inspect".as_ref(), scene.as_os_str()],
        vec![
            "build".as_ref(),
            scene.as_os_str(),
            "--out".as_ref(),
            tree.as_os_str(),
        ],
    ] {
        let mut args = command.clone();
        args.push("--allow-outside-paths".as_ref());
        refused(&args, &["/dev/zero", "not a regular file"]);
        refused(&command, &["models[0]", "/dev/zero", "leads outside"]);
    }
}

#[test]
fn models_stay_inside_the_scene_directory() {
    let tmp = tempfile::tempdir().unwrap();
    let scene = saved_sample(tmp.path());
    let inspect = |extra: &[&str]| {
        let mut args: Vec<std::ffi::OsString> = vec!["inspect".into(), scene.clone().into()];
        args.extend(extra.iter().map(|e| e.into()));
        args
    };
    with_models(&scene, serde_json::json!(["../../../etc/passwd"]));
    refused(
        &inspect(&[]),
        &["models[0]", "../../../etc/passwd", "leads outside"],
    );

    // An absolute path to a good model elsewhere: refused, then allowed by
    // the flag.
    let elsewhere = tmp.path().join("elsewhere.glb");
    std::fs::copy(scene.join("sample.glb"), &elsewhere).unwrap();
    with_models(&scene, serde_json::json!([elsewhere.to_str().unwrap()]));
    refused(&inspect(&[]), &["models[0]", "leads outside"]);
    let (out, _) = run(&inspect(&["--allow-outside-paths"]));
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );

    // A symbolic link inside that points out.
    std::os::unix::fs::symlink(&elsewhere, scene.join("link.glb")).unwrap();
    with_models(&scene, serde_json::json!(["link.glb"]));
    refused(&inspect(&[]), &["models[0]", "symbolic link"]);

    // `..` that comes back inside is inside.
    std::fs::create_dir(scene.join("sub")).unwrap();
    with_models(&scene, serde_json::json!(["sub/../sample.glb"]));
    let (out, _) = run(&inspect(&[]));
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

#[test]
fn each_input_is_capped() {
    let tmp = tempfile::tempdir().unwrap();
    let scene = saved_sample(tmp.path());
    let glb = std::fs::metadata(scene.join("sample.glb")).unwrap().len();
    let json = std::fs::metadata(scene.join("scene.json")).unwrap().len();
    assert!(glb > json, "the test wants the model to be the larger file");
    let cap = json.to_string();
    refused(
        &[
            "inspect".as_ref(),
            scene.as_os_str(),
            "--max-input-bytes".as_ref(),
            cap.as_ref(),
        ],
        &[
            "sample.glb",
            &format!("{glb} bytes"),
            &format!("cap of {cap} bytes"),
        ],
    );
    let (out, _) = run(&["inspect".as_ref(), scene.as_os_str()]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

#[test]
fn a_build_config_must_be_a_regular_file() {
    let tmp = tempfile::tempdir().unwrap();
    let scene = saved_sample(tmp.path());
    let tree = tmp.path().join("tree");
    refused(
        &[
            "build".as_ref(),
            scene.as_os_str(),
            "--out".as_ref(),
            tree.as_os_str(),
            "--config".as_ref(),
            "/dev/zero".as_ref(),
        ],
        &["/dev/zero", "not a regular file"],
    );
}
