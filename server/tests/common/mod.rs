//! Shared by the server's tests: the binary run as a command, trees to serve
//! (the tiny fixture's, built by the binary; the sample tree of
//! `hdlod-fixtures`), the real server on loopback, the browser's presence,
//! and (from the library's test helpers) scenes and JSON Schema checks.
#![allow(dead_code, unused_imports)]

#[path = "../../../hdlod/tests/common/mod.rs"]
mod library;

use std::ffi::OsStr;
use std::io::{BufRead, BufReader, Write};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Output, Stdio};
use std::time::Duration;

pub use library::{
    assert_matches_schema, assert_no_gltf_errors, assert_valid, checked_manifest, data,
    flatten_tree, geometry_files, gltf_reports, repo, sample_scene, saved_sample, schema,
    schema_errors, skinned_bar, skinned_bar_scene, tileset_validator,
};
use reqwest::blocking::Client;
use serde_json::Value;

/// The scene name of `fixtures/skyscraper-tiny` and of its tree.
pub const SCENE: &str = "skyscraper-tiny";

/// A cut request at `fraction` of the period of `scene` (its API summary),
/// at 1 px, from a camera a scene's size up and aside of its centre.
pub fn cut_over(scene: &Value, fraction: f64) -> Value {
    let (lo, hi) = (&scene["bounds"]["min"], &scene["bounds"]["max"]);
    let at = |k: usize| (lo[k].as_f64().unwrap() + hi[k].as_f64().unwrap()) / 2.0;
    let size = (0..3)
        .map(|k| hi[k].as_f64().unwrap() - lo[k].as_f64().unwrap())
        .fold(0.0, f64::max);
    let seconds = scene["time"]["seconds"].as_f64().unwrap();
    serde_json::json!({
        "time": seconds * fraction,
        "camera": {"position": [at(0) + size, at(1) + size, at(2) + size], "target": [at(0), at(1), at(2)]},
        "pixel_error": 1.0
    })
}

fn command() -> Command {
    let mut command = Command::new(env!("CARGO_BIN_EXE_hdlod"));
    command.env("RUST_LOG", "warn");
    command
}

/// Runs `hdlod ARGS` to its end.
pub fn hdlod<S: AsRef<OsStr>>(args: &[S]) -> Output {
    command().args(args).output().expect("the binary runs")
}

/// Asserts that a run succeeded, with its stderr as the failure message.
pub fn assert_success(out: &Output) {
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// Builds the tree of `fixtures/skyscraper-tiny` into `dir/tree` with
/// `hdlod build`.
pub fn build_tree(dir: &Path) -> PathBuf {
    let tree = dir.join("tree");
    assert_success(&hdlod(&[
        "build".as_ref(),
        repo().join("fixtures/skyscraper-tiny").as_os_str(),
        "--out".as_ref(),
        tree.as_os_str(),
    ]));
    tree
}

/// The sample tree (scene `sample-1`) of `floors` floors in
/// `dir/tree`.
pub fn sample_tree(dir: &Path, floors: usize) -> PathBuf {
    let tree = dir.join("tree");
    hdlod_fixtures::sample::write_sample_tree(&tree, 1, floors).unwrap();
    tree
}

/// A client that gives up rather than hang a test.
pub fn client() -> Client {
    Client::builder()
        .timeout(Duration::from_secs(20))
        .build()
        .unwrap()
}

/// Asserts the media type of an answer (parameters such as the charset may
/// follow).
pub fn assert_content_type(response: &reqwest::blocking::Response, media_type: &str) {
    let header = response.headers()["content-type"].to_str().unwrap();
    assert!(header.starts_with(media_type), "{header}, not {media_type}");
}

/// Asserts that `value` follows the schema `name` of a served OpenAPI
/// document's components; the other components ride along so that
/// references between them resolve.
pub fn assert_component(doc: &Value, name: &str, value: &Value) {
    let schema = serde_json::json!({
        "components": {"schemas": doc["components"]["schemas"]},
        "$ref": format!("#/components/schemas/{name}"),
    });
    let validator = jsonschema::validator_for(&schema).unwrap();
    assert_valid(&validator, value, &format!("{name} in {value}"));
}

/// Asserts that the served component `name` is the schema file
/// `schemas/api/FILE.schema.json`, but for its `$id` and `$schema` and
/// its references, which the server points into the document.
pub fn assert_served_file(doc: &Value, name: &str, file: &str) {
    fn plain(v: &Value) -> Value {
        match v {
            Value::Object(o) => Value::Object(
                o.iter()
                    .filter(|(k, _)| !matches!(k.as_str(), "$id" | "$schema"))
                    .map(|(k, v)| {
                        let v = if k == "$ref" { Value::Null } else { plain(v) };
                        (k.clone(), v)
                    })
                    .collect(),
            ),
            Value::Array(a) => Value::Array(a.iter().map(plain).collect()),
            other => other.clone(),
        }
    }
    let path = repo().join(format!("schemas/api/{file}.schema.json"));
    let text = std::fs::read_to_string(path).unwrap();
    assert_eq!(
        plain(&doc["components"]["schemas"][name]),
        plain(&serde_json::from_str::<Value>(&text).unwrap()),
        "{name}"
    );
}

/// A running `hdlod` that listens on a free loopback port; killed on drop.
pub struct Server {
    child: Child,
    /// `http://127.0.0.1:PORT`.
    pub base: String,
    /// The tree it serves.
    pub tree: PathBuf,
    http: Client,
    _dir: Option<tempfile::TempDir>,
}

impl Server {
    /// `hdlod_reloads_total` of the server's metrics.
    pub fn reloads(&self) -> u64 {
        let text = client()
            .get(self.url("/metrics"))
            .send()
            .unwrap()
            .text()
            .unwrap();
        text.lines()
            .find_map(|l| l.strip_prefix("hdlod_reloads_total "))
            .and_then(|n| n.trim().parse().ok())
            .expect("a reload count")
    }

    /// Waits (up to 10 s) until the file watch has reloaded the trees
    /// `count` times.
    pub fn await_reloads(&self, count: u64) {
        let deadline = std::time::Instant::now() + Duration::from_secs(10);
        while self.reloads() < count {
            assert!(
                std::time::Instant::now() < deadline,
                "no reload after the change"
            );
            std::thread::sleep(Duration::from_millis(20));
        }
    }

    /// `hdlod serve --addr 127.0.0.1:0 TREE`.
    pub fn start(tree: &Path) -> Server {
        Server::start_with(tree, &[])
    }

    /// `hdlod serve --addr 127.0.0.1:0 OPTIONS... TREE`.
    pub fn start_with(tree: &Path, options: &[&str]) -> Server {
        let mut args: Vec<&OsStr> =
            vec!["serve".as_ref(), "--addr".as_ref(), "127.0.0.1:0".as_ref()];
        args.extend(options.iter().map(OsStr::new));
        args.push(tree.as_os_str());
        let mut server = Server::spawn(&args);
        server.tree = tree.to_owned();
        server
    }

    /// The server over a fresh sample tree of `floors` floors that it owns.
    pub fn sample(floors: usize) -> Server {
        Server::sample_with(floors, &[])
    }

    /// `sample` with extra `serve` options.
    pub fn sample_with(floors: usize, options: &[&str]) -> Server {
        let dir = tempfile::tempdir().unwrap();
        let mut server = Server::start_with(&sample_tree(dir.path(), floors), options);
        server._dir = Some(dir);
        server
    }

    /// Any command that serves (`serve`, `demo`): its address is the line
    /// `listening on BASE` on stdout.
    pub fn spawn<S: AsRef<OsStr>>(args: &[S]) -> Server {
        let mut child = command()
            .args(args)
            .stdout(Stdio::piped())
            .stderr(Stdio::null())
            .spawn()
            .unwrap();
        let line = BufReader::new(child.stdout.take().unwrap())
            .lines()
            .map_while(Result::ok)
            .find(|l| l.starts_with("listening on "));
        let Some(line) = line else {
            let _ = child.kill();
            let _ = child.wait();
            panic!("the server printed no address line");
        };
        Server {
            child,
            base: line["listening on ".len()..].trim().to_owned(),
            tree: PathBuf::new(),
            http: client(),
            _dir: None,
        }
    }

    pub fn url(&self, path: &str) -> String {
        format!("{}{path}", self.base)
    }

    pub fn pid(&self) -> u32 {
        self.child.id()
    }

    /// Whether the server ended successfully within `limit` (`None`: it
    /// still runs).
    pub fn wait_for_exit(&mut self, limit: Duration) -> Option<bool> {
        let start = std::time::Instant::now();
        while start.elapsed() < limit {
            if let Some(status) = self.child.try_wait().unwrap() {
                return Some(status.success());
            }
            std::thread::sleep(Duration::from_millis(50));
        }
        None
    }

    /// The JSON body of `GET PATH`, whatever its status.
    pub fn get_json(&self, path: &str) -> Value {
        self.http
            .get(self.url(path))
            .send()
            .unwrap()
            .json()
            .unwrap()
    }

    /// The JSON answer of `POST PATH` with a JSON body, whatever its status.
    pub fn post_json(&self, path: &str, body: &Value) -> Value {
        self.http
            .post(self.url(path))
            .json(body)
            .send()
            .unwrap()
            .json()
            .unwrap()
    }
}

impl Drop for Server {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// Runs the browser driver `tools/browser/{script}` with `args` and answers
/// the JSON object it prints, once it exited cleanly and its page reported
/// no errors (its `errors` list empty).
pub fn browser_driver<S: AsRef<OsStr>>(script: &str, args: &[S]) -> Value {
    let run = Command::new("node")
        .arg(repo().join("tools/browser").join(script))
        .args(args)
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&run.stdout);
    assert!(
        run.status.success(),
        "driver failed: {}\n{stdout}",
        String::from_utf8_lossy(&run.stderr)
    );
    let out: Value = serde_json::from_str(stdout.trim())
        .unwrap_or_else(|e| panic!("driver output is not JSON ({e}): {stdout}"));
    assert_eq!(out["errors"], serde_json::json!([]), "{out:#}");
    out
}

/// Whether the browser tests can run: chromium (`HDLOD_CHROMIUM`, else
/// `/usr/bin/chromium`), node and `tools/node_modules/playwright-core`. When
/// one is missing the test says so loudly and passes, unless
/// `HDLOD_REQUIRE_BROWSER=1` (CI), where that is a failure.
pub fn browser_ready() -> bool {
    let Some(why) = missing_browser() else {
        return true;
    };
    assert!(
        std::env::var("HDLOD_REQUIRE_BROWSER").as_deref() != Ok("1"),
        "HDLOD_REQUIRE_BROWSER=1 but {why}"
    );
    // Past the harness's capture of `eprintln!`, which would hide it.
    let line = format!("\n*** BROWSER TESTS SKIPPED: {why} ***\n\n");
    let _ = std::io::stderr().write_all(line.as_bytes());
    false
}

fn missing_browser() -> Option<String> {
    let chromium = std::env::var("HDLOD_CHROMIUM").unwrap_or_else(|_| "/usr/bin/chromium".into());
    if !Path::new(&chromium).exists() {
        return Some(format!(
            "chromium not found at {chromium} (apt-get install chromium)"
        ));
    }
    if !repo().join("tools/node_modules/playwright-core").is_dir() {
        return Some("tools/node_modules has no playwright-core (npm ci --prefix tools)".into());
    }
    if Command::new("node").arg("--version").output().is_err() {
        return Some("node not found (apt-get install nodejs)".into());
    }
    None
}
