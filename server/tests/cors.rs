//! Cross-origin access from the real server on loopback: any origin may
//! read by default (preflights answered, ETag exposed), `--cors-origin`
//! names who may also POST cuts, and a bad origin is refused at start.

mod common;

use common::{SCENE, Server, build_tree, client, hdlod};
use reqwest::Method;
use reqwest::StatusCode;

const OTHER: &str = "https://viewer.example";

fn header(r: &reqwest::blocking::Response, name: &str) -> Option<String> {
    r.headers()
        .get(name)
        .map(|v| v.to_str().unwrap().to_owned())
}

fn preflight(server: &Server, path: &str, method: &str) -> reqwest::blocking::Response {
    client()
        .request(Method::OPTIONS, server.url(path))
        .header("Origin", OTHER)
        .header("Access-Control-Request-Method", method)
        .header("Access-Control-Request-Headers", "content-type")
        .send()
        .unwrap()
}

#[test]
fn any_origin_reads_by_default_and_named_ones_may_post() {
    let dir = tempfile::tempdir().unwrap();
    let tree = build_tree(dir.path());
    let tileset = format!("/api/v1/scenes/{SCENE}/tiles/tileset.json?time=0");
    let cut = format!("/api/v1/scenes/{SCENE}/cut");

    let server = Server::start(&tree);
    let answer = client()
        .get(server.url(&tileset))
        .header("Origin", OTHER)
        .send()
        .unwrap();
    assert_eq!(answer.status(), StatusCode::OK);
    assert_eq!(
        header(&answer, "access-control-allow-origin").as_deref(),
        Some("*")
    );
    let schedule = client()
        .get(server.url(&format!("/api/v1/scenes/{SCENE}/schedule")))
        .header("Origin", OTHER)
        .send()
        .unwrap();
    let exposed = header(&schedule, "access-control-expose-headers").unwrap_or_default();
    assert!(exposed.to_ascii_lowercase().contains("etag"), "{exposed}");
    let pre = preflight(&server, &tileset, "GET");
    assert!(pre.status().is_success(), "{}", pre.status());
    assert_eq!(
        header(&pre, "access-control-allow-origin").as_deref(),
        Some("*")
    );
    let pre = preflight(&server, &cut, "POST");
    let methods = header(&pre, "access-control-allow-methods").unwrap_or_default();
    assert!(!methods.contains("POST"), "read-only by default: {methods}");

    let named = Server::start_with(&tree, &["--cors-origin", OTHER]);
    let pre = preflight(&named, &cut, "POST");
    assert_eq!(
        header(&pre, "access-control-allow-origin").as_deref(),
        Some(OTHER)
    );
    assert!(
        header(&pre, "access-control-allow-methods")
            .unwrap()
            .contains("POST")
    );
    let stranger = client()
        .get(named.url(&tileset))
        .header("Origin", "https://elsewhere.example")
        .send()
        .unwrap();
    assert_eq!(stranger.status(), StatusCode::OK);
    assert_eq!(header(&stranger, "access-control-allow-origin"), None);

    let bad = hdlod(&[
        "serve",
        "--cors-origin",
        "example.com/x",
        tree.to_str().unwrap(),
    ]);
    assert!(!bad.status.success());
    let stderr = String::from_utf8_lossy(&bad.stderr);
    assert!(
        stderr.contains("--cors-origin \"example.com/x\""),
        "{stderr}"
    );
}
