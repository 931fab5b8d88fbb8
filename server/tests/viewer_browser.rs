//! The web viewer in a real browser: the tiny fixture's tree built with
//! `hdlod build`, served by `hdlod serve --addr 127.0.0.1:0`, and the page
//! driven in headless chromium by `tools/browser/viewer.mjs` (playwright-core)
//! through the viewer's test hook. Screenshots go to
//! `target/browser-screenshots/viewer/`.
//!
//! Without chromium (or the npm tools) the test says so loudly and passes,
//! unless `HDLOD_REQUIRE_BROWSER=1` (CI), where that is a failure.

use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};

use serde_json::Value;

const SCENE: &str = "skyscraper-tiny";

fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// `None` when the browser can run; otherwise why not.
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

struct Server(Child);

/// `hdlod serve` on a free loopback port: the server and its base URL.
fn serve(tree: &Path) -> (Server, String) {
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
    (Server(child), base)
}

impl Drop for Server {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

fn f(v: &Value) -> f64 {
    v.as_f64().unwrap_or_else(|| panic!("{v} is not a number"))
}

fn ids(v: &Value) -> Vec<u64> {
    v.as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_u64().unwrap())
        .collect()
}

fn geometry_requests(base: &str) -> f64 {
    let text = reqwest::blocking::get(format!("{base}/metrics"))
        .unwrap()
        .text()
        .unwrap();
    text.lines()
        .filter(|l| {
            l.starts_with(
                "hdlod_http_requests_total{route=\"/api/v1/scenes/{scene}/geometry/{file}\"",
            )
        })
        .filter_map(|l| l.rsplit(' ').next()?.parse::<f64>().ok())
        .sum()
}

/// The embedded files, with or without a browser.
#[test]
fn the_viewer_files_are_served() {
    let dir = tempfile::tempdir().unwrap();
    let tree = dir.path().join("tree");
    hdlod::tree::sample::write_sample_tree(&tree, 1, 6).unwrap();
    let (_server, base) = serve(&tree);
    let get = |path: &str| reqwest::blocking::get(format!("{base}{path}")).unwrap();
    let page = get("/");
    assert_eq!(page.status(), 200);
    assert!(
        page.headers()["content-type"]
            .to_str()
            .unwrap()
            .starts_with("text/html")
    );
    let html = page.text().unwrap();
    // Every file the page and its modules name is served; nothing comes
    // from elsewhere.
    let mut names = vec!["main.js".to_owned()];
    for file in [
        "main.js",
        "camera.js",
        "stream.js",
        "renderer.js",
        "glb.js",
        "mat4.js",
    ] {
        let response = get(&format!("/viewer/{file}"));
        assert_eq!(response.status(), 200, "{file}");
        assert!(
            response.headers()["content-type"]
                .to_str()
                .unwrap()
                .starts_with("text/javascript")
        );
        let text = response.text().unwrap();
        assert!(
            !text.contains("http://") && !text.contains("https://"),
            "{file} loads from outside"
        );
        names.extend(text.match_indices("from \"./").map(|(i, _)| {
            let rest = &text[i + 8..];
            rest[..rest.find('"').unwrap()].to_owned()
        }));
    }
    assert!(html.contains("/viewer/main.js") && html.contains("/viewer/viewer.css"));
    assert!(!html.contains("http://") && !html.contains("https://"));
    for name in names {
        assert_eq!(get(&format!("/viewer/{name}")).status(), 200, "{name}");
    }
    let css = get("/viewer/viewer.css");
    assert!(
        css.headers()["content-type"]
            .to_str()
            .unwrap()
            .starts_with("text/css")
    );
    let missing = get("/viewer/nope.js");
    assert_eq!(missing.status(), 404);
    let body: Value = missing.json().unwrap();
    assert_eq!(body["error"]["field"], "file");
}

#[test]
fn the_viewer_draws_the_schedule_in_chromium() {
    if let Some(why) = missing_browser() {
        if std::env::var("HDLOD_REQUIRE_BROWSER").as_deref() == Ok("1") {
            panic!("HDLOD_REQUIRE_BROWSER=1 but {why}");
        }
        eprintln!("\n*** BROWSER TESTS SKIPPED: {why} ***\n");
        return;
    }
    let hdlod = env!("CARGO_BIN_EXE_hdlod");
    let dir = tempfile::tempdir().unwrap();
    let tree = dir.path().join("tree");
    let build = Command::new(hdlod)
        .arg("build")
        .arg(repo().join("fixtures/skyscraper-tiny"))
        .arg("--out")
        .arg(&tree)
        .output()
        .unwrap();
    assert!(
        build.status.success(),
        "{}",
        String::from_utf8_lossy(&build.stderr)
    );

    let (_server, base) = serve(&tree);

    // target/debug/hdlod -> target/browser-screenshots/viewer
    let shots = Path::new(hdlod)
        .parent()
        .and_then(Path::parent)
        .unwrap()
        .join("browser-screenshots/viewer");
    let run = Command::new("node")
        .arg(repo().join("tools/browser/viewer.mjs"))
        .args([&base, SCENE])
        .arg(&shots)
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
    assert_eq!(out["hasStats"], true);

    // The canvas is not blank: the site covers a share of it in several colours.
    for shot in ["start", "end"] {
        let p = &out[shot]["pixels"];
        assert!(f(&p["nonBackgroundShare"]) > 0.05, "{shot}: {p}");
        assert!(f(&p["distinctColours"]) >= 6.0, "{shot}: {p}");
    }
    for mode in ["classPixels", "levelPixels"] {
        assert!(f(&out[mode]["nonBackgroundShare"]) > 0.05, "{mode}");
    }

    // The drawn clusters are the server's cut of the same view, and they
    // follow the schedule: the tower rises, so the end draws more than the
    // start, and more objects are present.
    let (start, end) = (&out["start"], &out["end"]);
    for s in [start, end] {
        assert_eq!(ids(&s["ids"]), ids(&s["serverIds"]), "{s}");
        assert!(f(&s["triangles"]) <= f(&s["baseline"]), "{s}");
        assert!(f(&s["clusters"]) > 0.0);
    }
    assert_eq!(f(&end["triangles"]), f(&end["serverTriangles"]));
    assert_eq!(f(&start["time"]), 0.0);
    assert_eq!(f(&end["time"]), f(&out["span"]));
    assert_ne!(ids(&start["ids"]), ids(&end["ids"]));
    assert!(
        f(&end["triangles"]) > f(&start["triangles"]),
        "{start} {end}"
    );
    assert!(f(&end["baseline"]) > f(&start["baseline"]));

    // Zooming out (mouse wheel, twice the distance a step) never adds
    // triangles and, at four times the distance, takes some away.
    let zoom = out["zoom"].as_array().unwrap();
    let distance: Vec<f64> = zoom.iter().map(|z| f(&z["distance"])).collect();
    let triangles: Vec<f64> = zoom.iter().map(|z| f(&z["triangles"])).collect();
    assert!(
        (distance[2] / distance[0] - 4.0).abs() < 0.05,
        "{distance:?}"
    );
    assert!(triangles.windows(2).all(|w| w[1] <= w[0]), "{triangles:?}");
    assert!(triangles[2] < triangles[0], "{triangles:?}");

    // Fly mode: holding W moves the eye.
    let fly = &out["fly"];
    assert_eq!(fly["mode"], "fly");
    let step: f64 = (0..3)
        .map(|i| (f(&fly["after"][i]) - f(&fly["before"][i])).powi(2))
        .sum::<f64>()
        .sqrt();
    assert!(step > 1.0, "{fly}");

    // A dynamic object moves on screen while time plays.
    assert!(
        out["moving"].is_object(),
        "no dynamic cluster moves: {out:#}"
    );
    let d = &out["dynamic"];
    assert!(f(&d["timeAfter"]) > f(&d["timeBefore"]), "{d}");
    let (a, b) = (&d["before"], &d["after"]);
    let moved = (f(&a["x"]) - f(&b["x"])).hypot(f(&a["y"]) - f(&b["y"]));
    assert!(moved > 1.0, "moved {moved} px: {d}");

    // Each GLB was fetched once: as many geometry requests reached the
    // server as the page loaded distinct files.
    assert!(f(&out["finalGlbBytes"]) > 0.0);
    assert_eq!(geometry_requests(&base), f(&out["finalGlbFiles"]));

    // The address follows the view, so a view can be shared.
    let address = out["address"].as_str().unwrap();
    assert!(
        address.contains(&format!("scene={SCENE}")) && address.contains("time=2024-"),
        "{address}"
    );

    let message = out["missingSceneMessage"].as_str().unwrap();
    assert!(
        message.contains("no-such-scene") && message.contains(SCENE),
        "{message}"
    );
}
