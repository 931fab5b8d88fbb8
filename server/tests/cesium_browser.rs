//! CesiumJS (the npm `cesium` package) in headless chromium against the real
//! server (`tools/browser/cesium.mjs`), offline: no Cesium ion, imagery,
//! terrain or globe. The page comes from another loopback origin than the
//! server, so every tileset and content request is cross-origin (CORS), and
//! it follows the viewer's clock through the tiny fixture's slices with the
//! recipe of docs/tiles.md (`docs/examples/cesium-clock.js`, the doc's
//! snippet word for word). For one camera:
//!
//! - the tileset stands where the scene's georeference puts it, by its own
//!   root transform (no model matrix);
//! - CesiumJS draws the clusters of `POST .../cut` for its own camera
//!   (its view-projection in the scene's frame, its viewport and its
//!   `maximumScreenSpaceError` as the pixel error);
//! - a feature picked on screen has the properties the objects API gives;
//! - moving the clock to another date swaps the slice, other clusters are
//!   drawn, and no content GLB reaches the server twice: what an earlier
//!   date fetched, the browser's cache serves.

mod common;

use std::collections::{BTreeMap, BTreeSet};
use std::process::Command;
use std::time::Instant;

use common::{SCENE, Server, browser_ready, build_tree, repo};
use glam::{DMat4, DVec3};
use hdlod::scene::Georeference;
use serde_json::{Value, json};

const VIEWPORT: (u32, u32) = (640, 480);
/// CesiumJS's `maximumScreenSpaceError`, the cut's pixel error.
const PIXEL_ERROR: f64 = 1.0;
/// A day: the recipe's step, so each date below is one slice.
const DAY: f64 = 86400.0;

/// The scene's y-up frame to the tileset's z-up one, `(x, y, z) -> (x, -z, y)`
/// (docs/tiles.md).
fn z_up(p: [f64; 3]) -> DVec3 {
    DVec3::new(p[0], -p[2], p[1])
}

fn numbers(v: &Value) -> Vec<f64> {
    v.as_array()
        .unwrap_or_else(|| panic!("{v} is not an array"))
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect()
}

fn ids(v: &Value) -> BTreeSet<u64> {
    v.as_array()
        .unwrap_or_else(|| panic!("{v} is not an array"))
        .iter()
        .map(|x| x.as_u64().unwrap())
        .collect()
}

/// Runs tools/browser/cesium.mjs and returns its JSON.
fn run(config: &Value) -> Value {
    let tools = repo().join("tools");
    assert!(
        tools
            .join("node_modules/cesium/Build/Cesium/index.js")
            .is_file(),
        "cesium is not installed: run scripts/test (npm ci --prefix tools)"
    );
    let out = Command::new("node")
        .arg(tools.join("browser/cesium.mjs"))
        .arg(config.to_string())
        .output()
        .expect("node runs");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "cesium.mjs failed: {stderr}");
    serde_json::from_slice(&out.stdout)
        .unwrap_or_else(|e| panic!("cesium.mjs output: {e}; {stderr}"))
}

/// The ```js block after `heading` in a Markdown file.
fn snippet_after<'a>(markdown: &'a str, heading: &str) -> &'a str {
    let from = markdown
        .find(heading)
        .unwrap_or_else(|| panic!("no {heading:?}"));
    let block = &markdown[from..];
    let start = block.find("```js\n").expect("a js block") + "```js\n".len();
    let len = block[start..].find("```").expect("the block's end");
    &block[start..start + len]
}

#[test]
fn the_clock_recipe_is_the_doc_snippet() {
    let doc = std::fs::read_to_string(repo().join("docs/tiles.md")).unwrap();
    let module = std::fs::read_to_string(repo().join("docs/examples/cesium-clock.js")).unwrap();
    assert_eq!(
        snippet_after(&doc, "## Time in CesiumJS"),
        module,
        "docs/tiles.md shows docs/examples/cesium-clock.js as it is"
    );
}

#[test]
fn cesium_follows_the_clock_and_draws_the_cut() {
    if !browser_ready() {
        return;
    }
    let began = Instant::now();
    let dir = tempfile::tempdir().unwrap();
    let server = Server::start(&build_tree(dir.path()));
    let scene = server.get_json(&format!("/api/v1/scenes/{SCENE}"));
    let georeference: Georeference =
        serde_json::from_value(scene["georeference"].clone()).expect("the fixture is placed");
    let to_ecef: DMat4 = georeference.to_ecef().unwrap().expect("on Earth");

    // The oblique view of tiles_browser.rs, in ECEF.
    let position = to_ecef.transform_point3(z_up([120.0, 60.0, 120.0]));
    let target = to_ecef.transform_point3(z_up([0.0, 15.0, 0.0]));
    let direction = (target - position).normalize();
    let up = to_ecef.transform_vector3(DVec3::Z);
    let up = (up - direction * up.dot(direction)).normalize();
    // Two dates a third and two thirds into the period, then the first
    // again, whole days so that each is one step of the recipe.
    let period = scene["time"]["seconds"].as_f64().unwrap();
    let first = (period / 3.0 / DAY).floor() * DAY;
    let second = (2.0 * period / 3.0 / DAY).floor() * DAY;
    let times = [first, second, first];
    let config = json!({
        "server": server.base,
        "scene": SCENE,
        "camera": {"position": position.to_array(), "direction": direction.to_array(),
                   "up": up.to_array()},
        "viewport": {"width": VIEWPORT.0, "height": VIEWPORT.1},
        "maximumScreenSpaceError": PIXEL_ERROR,
        "step": DAY,
        "times": times,
        "pickAt": 0,
        "timeoutMs": 100000,
    });
    let report = run(&config);
    let init = &report["init"];
    eprintln!(
        "CesiumJS on {} (WebGL {}), page at {}, server at {}",
        init["renderer"],
        if init["webgl2"] == true { 2 } else { 1 },
        report["origin"],
        server.base
    );
    assert_eq!(report["pageErrors"], json!([]), "{}", report["pageErrors"]);
    assert_eq!(
        report["consoleErrors"],
        json!([]),
        "{}",
        report["consoleErrors"]
    );
    assert_eq!(
        report["foreign"],
        json!([]),
        "offline: no request leaves the two origins"
    );
    assert_ne!(report["origin"], json!(server.base), "cross-origin");

    // The clock spans the scene's period.
    assert_eq!(init["clock"]["start"], scene["time"]["start"]);
    assert_eq!(init["clock"]["stop"], scene["time"]["end"]);
    assert_eq!(init["clock"]["clamped"], true);

    let states = report["states"].as_array().unwrap();
    assert_eq!(states.len(), times.len());
    for (state, t) in states.iter().zip(times) {
        assert_eq!(state["settled"], true, "at {t} s: {state}");
        assert_eq!(
            state["seconds"].as_f64(),
            Some(t),
            "the recipe shows the clock's slice"
        );
        assert_eq!(state["primitives"], 1, "the old slice was removed");
    }

    placed_by_its_root_transform(&server, &states[0], to_ecef, first);
    for (i, state) in states.iter().enumerate() {
        draws_the_cut(&server, &format!("time {i}"), state);
    }
    picked_feature_is_the_objects(&server, &report["pick"], &states[0], first);
    content_is_fetched_once(&report, states);

    assert_ne!(
        ids(&states[0]["clusters"]),
        ids(&states[1]["clusters"]),
        "another date draws other clusters"
    );
    eprintln!(
        "browser {} ms, the whole test {} ms",
        report["ms"],
        began.elapsed().as_millis()
    );
}

/// No model matrix; the root's transform is the georeference's frame, and
/// the bounding sphere's centre is the root box's centre in it.
fn placed_by_its_root_transform(server: &Server, state: &Value, to_ecef: DMat4, t: f64) {
    let identity = DMat4::IDENTITY.to_cols_array().to_vec();
    assert_eq!(numbers(&state["modelMatrix"]), identity, "no model matrix");
    let root = numbers(&state["rootTransform"]);
    for (i, (a, b)) in root.iter().zip(to_ecef.to_cols_array()).enumerate() {
        // Rotation to 1e-9, translation (millions of metres) to 1 mm.
        let tolerance = if i >= 12 { 1e-3 } else { 1e-9 };
        assert!(
            (a - b).abs() <= tolerance,
            "root transform [{i}]: {a} vs {b}"
        );
    }
    let tileset = server.get_json(&format!("/api/v1/scenes/{SCENE}/tiles/{t}.json"));
    let b = numbers(&tileset["root"]["boundingVolume"]["box"]);
    let expected = to_ecef.transform_point3(DVec3::new(b[0], b[1], b[2]));
    let centre = DVec3::from_slice(&numbers(&state["boundingSphere"]["center"]));
    let off = centre.distance(expected);
    eprintln!(
        "bounding sphere centre {centre:?}, {off:.6} m from the georeferenced root box's centre"
    );
    assert!(off < 1e-3, "{off} m off");
}

/// CesiumJS's drawn tiles against `POST .../cut` for its own camera.
///
/// Both refine a tile while `geometricError * height / (distance * 2 tan(fovy
/// / 2)) > pixel error` (CesiumJS's screen-space error; ours is `delta_c(t) /
/// distance >= r` with `r = pixel_error * 2 tan(fovy / 2) / height`), with
/// the distance from the eye to the tile's box and the same frustum planes,
/// so the sets are equal, not merely close.
fn draws_the_cut(server: &Server, what: &str, state: &Value) {
    let buffer = &state["drawingBuffer"];
    let ratio = state["pixelRatio"].as_f64().unwrap();
    let css = |pixels: &Value| (pixels.as_f64().unwrap() / ratio).round() as u32;
    let viewport = json!({"width": css(&buffer["width"]), "height": css(&buffer["height"])});
    let body = json!({
        "time": state["seconds"],
        "camera": {"view_projection": state["viewProjection"]},
        "viewport": viewport,
        "pixel_error": state["maximumScreenSpaceError"],
    });
    let cut = server.post_json(&format!("/api/v1/scenes/{SCENE}/cut"), &body);
    let ours: BTreeSet<u64> = cut["clusters"]
        .as_array()
        .unwrap_or_else(|| panic!("{what}: {cut}"))
        .iter()
        .map(|c| c["id"].as_u64().unwrap())
        .collect();
    let theirs = ids(&state["clusters"]);
    let both = ours.intersection(&theirs).count();
    eprintln!(
        "{what} ({} s): CesiumJS drew {} tiles, the cut {} clusters, {both} in both, in {} ms",
        state["seconds"],
        theirs.len(),
        ours.len(),
        state["ms"]
    );
    assert!(ours.len() > 50, "{what}: the view sees the site");
    assert_eq!(
        theirs,
        ours,
        "{what}: only CesiumJS {:?}, only the cut {:?}",
        theirs.difference(&ours).collect::<Vec<_>>(),
        ours.difference(&theirs).collect::<Vec<_>>()
    );
}

/// The picked feature's properties against `GET .../objects/{index}`.
fn picked_feature_is_the_objects(server: &Server, pick: &Value, state: &Value, t: f64) {
    assert!(pick.is_object(), "a feature was picked: {pick}");
    let p = &pick["properties"];
    let index = p["index"].as_u64().expect("the index property");
    let object = server.get_json(&format!(
        "/api/v1/scenes/{SCENE}/objects/{index}?by=index&time={t}"
    ));
    eprintln!(
        "picked at ({}, {}) in cluster {}: {p}",
        pick["x"], pick["y"], pick["cluster"]
    );
    assert_eq!(p["id"], object["id"], "{object}");
    assert_eq!(p["name"], object["name"]);
    assert_eq!(p["class"], object["class"]);
    let storey = object["storey"].as_str().unwrap_or("");
    assert_eq!(p["storey"], storey);
    let task = &object["tasks"][0];
    assert_eq!(
        p["task"],
        task["id"].as_str().unwrap_or(""),
        "the first task"
    );
    assert_eq!(p["task_name"], task["name"].as_str().unwrap_or(""));
    assert_eq!(object["present"], true, "a drawn element is present");
    assert!(
        ids(&state["clusters"]).contains(&pick["cluster"].as_u64().unwrap()),
        "the picked tile is drawn"
    );
}

/// Every content GLB reached the server at most once: the server's count
/// of content requests at each date is the count of requests the browser's
/// cache did not answer, and no URL missed the cache twice.
fn content_is_fetched_once(report: &Value, states: &[Value]) {
    let requests = report["requests"].as_array().unwrap();
    let content: Vec<&Value> = requests
        .iter()
        .filter(|r| r["url"].as_str().unwrap().contains("/tiles/content/"))
        .collect();
    let mut fetched: BTreeMap<&str, usize> = BTreeMap::new();
    for r in &content {
        let url = r["url"].as_str().unwrap();
        assert!(!url.contains('?'), "a content URL without a query: {url}");
        assert_eq!(r["status"], 200, "{r}");
        assert!(r["allowOrigin"].is_string(), "CORS allowed {url}");
        if r["cached"] != true {
            *fetched.entry(url).or_default() += 1;
        }
    }
    let twice: Vec<_> = fetched.iter().filter(|(_, n)| **n > 1).collect();
    assert!(twice.is_empty(), "fetched again: {twice:?}");
    let mut before: BTreeSet<&str> = BTreeSet::new();
    for (i, state) in states.iter().enumerate() {
        let phase = json!(format!("time {i}"));
        let here: Vec<&Value> = content
            .iter()
            .copied()
            .filter(|r| r["phase"] == phase)
            .collect();
        let misses = here.iter().filter(|r| r["cached"] != true).count();
        let urls: BTreeSet<&str> = here.iter().map(|r| r["url"].as_str().unwrap()).collect();
        let reused = urls.intersection(&before).count();
        let hits = state["serverContentHits"].as_u64().unwrap() as usize;
        eprintln!(
            "time {i}: {} content requests, {reused} of GLBs an earlier date fetched, {misses} reached the server ({hits} by its metrics)",
            here.len()
        );
        assert_eq!(
            hits, misses,
            "time {i}: the server saw what the cache did not answer"
        );
        if i > 0 {
            assert!(reused > 0, "time {i}: GLBs of an earlier date were reused");
            assert!(
                here.iter()
                    .filter(|r| before.contains(r["url"].as_str().unwrap()))
                    .all(|r| r["cached"] == true),
                "time {i}: an earlier date's GLB came from the cache"
            );
        }
        before.extend(urls);
    }
    assert_eq!(
        states[2]["serverContentHits"], 0,
        "back at the first date, nothing reaches the server"
    );
}
