//! In headless chromium, 3DTilesRendererJS (three.js) loads a time slice
//! from the real server (and one split into external tilesets, written by
//! `hdlod export-tiles`) and, for a fixed camera, draws the triangles of our
//! own cut for that view (`POST .../cut` with the same camera, viewport and
//! pixel error as the renderer's `errorTarget`), within 5%.

mod common;

use std::path::Path;
use std::process::Command;

use common::{SCENE, Server, assert_success, browser_ready, build_tree, hdlod, repo};
use serde_json::{Value, json};

const VIEWPORT: (u32, u32) = (800, 600);

/// The scene's y-up frame to the tileset's z-up one, `(x, y, z) -> (x, -z, y)`
/// (docs/tiles.md): how a 3D Tiles client sees a y-up scene.
fn z_up(p: [f64; 3]) -> [f64; 3] {
    [p[0], -p[2], p[1]]
}

/// Runs tools/browser/tiles.mjs and returns its JSON.
fn render(
    origin: &str,
    tileset: &str,
    position: [f64; 3],
    target: [f64; 3],
    files: Option<&Path>,
) -> Value {
    let tools = repo().join("tools");
    assert!(
        tools.join("node_modules/3d-tiles-renderer").is_dir(),
        "3d-tiles-renderer is not installed: run scripts/test (npm ci --prefix tools)"
    );
    let mut config = json!({
        "origin": origin,
        "tileset": tileset,
        "camera": {"position": z_up(position), "target": z_up(target), "up": [0.0, 0.0, 1.0],
                   "fov": 60.0, "near": 0.1, "far": 1e6},
        "viewport": {"width": VIEWPORT.0, "height": VIEWPORT.1},
        "errorTarget": 1.0,
        "timeoutMs": 90000,
    });
    if let Some(dir) = files {
        config["files"] = json!(dir);
    }
    let out = Command::new("node")
        .arg(tools.join("browser/tiles.mjs"))
        .arg(config.to_string())
        .output()
        .expect("node runs");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "tiles.mjs failed: {stderr}");
    serde_json::from_slice(&out.stdout)
        .unwrap_or_else(|e| panic!("tiles.mjs output: {e}; {stderr}"))
}

fn cut(server: &Server, time: f64, position: [f64; 3], target: [f64; 3]) -> Value {
    let body = json!({"time": time, "camera": {"position": position, "target": target},
                      "viewport": {"width": VIEWPORT.0, "height": VIEWPORT.1}, "pixel_error": 1.0});
    server.post_json(&format!("/api/v1/scenes/{SCENE}/cut"), &body)
}

fn compare(what: &str, drawn: &Value, cut: &Value) {
    assert_eq!(
        drawn["settled"], true,
        "{what}: the renderer settled: {drawn}"
    );
    assert_eq!(drawn["errors"], json!([]), "{what}: {drawn}");
    assert_eq!(drawn["pageErrors"], json!([]), "{what}: {drawn}");
    let triangles = drawn["triangles"].as_f64().unwrap();
    let expected = cut["stats"]["triangles"].as_f64().unwrap();
    let mut ours: Vec<u64> = cut["clusters"]
        .as_array()
        .unwrap()
        .iter()
        .map(|c| c["id"].as_u64().unwrap())
        .collect();
    ours.sort_unstable();
    let theirs: Vec<u64> = drawn["clusters"]
        .as_array()
        .unwrap()
        .iter()
        .map(|c| c.as_u64().unwrap())
        .collect();
    let same = ours
        .iter()
        .filter(|id| theirs.binary_search(id).is_ok())
        .count();
    eprintln!(
        "{what}: renderer {triangles} triangles in {} tiles, cut {expected} in {} clusters, {same} clusters in both, {} ms",
        theirs.len(),
        ours.len(),
        drawn["ms"]
    );
    assert!(
        expected > 1000.0,
        "{what}: the view sees the site ({expected})"
    );
    assert!(
        (triangles - expected).abs() <= 0.05 * expected,
        "{what}: renderer {triangles} vs cut {expected}"
    );
}

#[test]
fn three_js_tiles_renderer_draws_the_cut() {
    if !browser_ready() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let tree = build_tree(dir.path());
    let server = Server::start(&tree);
    // A third into the period, where many clusters are partly built.
    let time = 15613200.0 / 3.0;
    let views = [
        ("oblique", [120.0, 60.0, 120.0], [0.0, 15.0, 0.0]),
        ("far", [-260.0, 140.0, 330.0], [0.0, 20.0, 0.0]),
    ];
    for (name, position, target) in views {
        let tileset = server.url(&format!(
            "/api/v1/scenes/{SCENE}/tiles/tileset.json?time={time}&frame=local"
        ));
        let drawn = render(&server.base, &tileset, position, target, None);
        compare(name, &drawn, &cut(&server, time, position, target));
    }

    // The same slice split into external tilesets, from disk.
    let split = dir.path().join("split");
    let out = hdlod(&[
        "export-tiles".as_ref(),
        tree.as_os_str(),
        "--time".as_ref(),
        time.to_string().as_ref(),
        "--out".as_ref(),
        split.as_os_str(),
        "--max-bytes".as_ref(),
        "16000".as_ref(),
        // three.js works in the site's frame: ECEF's millions of metres
        // would cost f32 precision.
        "--frame".as_ref(),
        "local".as_ref(),
    ]);
    assert_success(&out);
    assert!(split.join("tilesets").read_dir().unwrap().count() > 1);
    let (name, position, target) = views[0];
    let tileset = server.url("/__tiles-files/tileset.json");
    let drawn = render(&server.base, &tileset, position, target, Some(&split));
    compare(
        &format!("{name}, external tilesets"),
        &drawn,
        &cut(&server, time, position, target),
    );
}
