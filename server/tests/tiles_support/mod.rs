//! Shared by the 3D Tiles tests: the tiny fixture's tree built with the real
//! binary, the real server on loopback, the official 3D Tiles 1.1 schemas.
#![allow(dead_code)]

use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Output, Stdio};

pub const SCENE: &str = "skyscraper-tiny";

pub fn hdlod(args: &[&std::ffi::OsStr]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_hdlod"))
        .args(args)
        .output()
        .expect("the binary runs")
}

pub fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("..")
        .canonicalize()
        .unwrap()
}

/// Builds the tree of `fixtures/skyscraper-tiny` into `dir/tree`.
pub fn build_tree(dir: &Path) -> PathBuf {
    let tree = dir.join("tree");
    let out = hdlod(&[
        "build".as_ref(),
        repo().join("fixtures/skyscraper-tiny").as_os_str(),
        "--out".as_ref(),
        tree.as_os_str(),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    tree
}

pub struct Server {
    child: Child,
    pub base: String,
}

impl Server {
    pub fn start(tree: &Path) -> Server {
        let mut child = Command::new(env!("CARGO_BIN_EXE_hdlod"))
            .args(["serve", "--addr", "127.0.0.1:0"])
            .arg(tree)
            .stdout(Stdio::piped())
            .stderr(Stdio::null())
            .spawn()
            .unwrap();
        let mut line = String::new();
        BufReader::new(child.stdout.take().unwrap())
            .read_line(&mut line)
            .unwrap();
        let base = line
            .trim()
            .strip_prefix("listening on ")
            .expect("the address line")
            .to_owned();
        Server { child, base }
    }

    pub fn url(&self, path: &str) -> String {
        format!("{}{path}", self.base)
    }
}

impl Drop for Server {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// `shared/data/3d-tiles-schema` beside the repository: in the directory
/// that holds it, or in the nearest ancestor that has one.
pub fn schema_dir() -> PathBuf {
    let repo = repo();
    repo.ancestors()
        .skip(1)
        .map(|a| a.join("shared/data/3d-tiles-schema"))
        .find(|d| d.join("tileset.schema.json").is_file())
        .unwrap_or_else(|| {
            panic!(
                "no shared/data/3d-tiles-schema beside {} (the official 3D Tiles 1.1 schemas)",
                repo.display()
            )
        })
}

/// The official `tileset.schema.json`; its relative `$ref`s resolve as
/// files next to it.
pub fn tileset_validator() -> jsonschema::Validator {
    let path = schema_dir().join("tileset.schema.json");
    let schema: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
    jsonschema::options()
        .with_base_uri(format!("file://{}", path.display()))
        .build(&schema)
        .expect("the 3D Tiles schemas compile")
}

pub fn assert_tileset(v: &jsonschema::Validator, value: &serde_json::Value, what: &str) {
    let errors: Vec<String> = v
        .iter_errors(value)
        .take(5)
        .map(|e| format!("{}: {e}", e.instance_path()))
        .collect();
    assert!(errors.is_empty(), "{what}: {errors:?}");
}
