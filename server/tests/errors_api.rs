//! Every 4xx answer is the API's JSON error, whoever refuses the request
//! (a route, axum's extractors, the connection's head watch), naming the
//! field actually at fault and quoting at most about 100 characters of the
//! request.

mod common;

use std::io::{Read, Write};
use std::net::TcpStream;
use std::time::Duration;

use common::{Server, client};
use reqwest::StatusCode;
use serde_json::{Value, json};

/// The status and JSON body of a raw request.
fn raw(server: &Server, request: &[u8]) -> (u16, Value) {
    let address = server.base.trim_start_matches("http://");
    let mut socket = TcpStream::connect(address).unwrap();
    socket
        .set_read_timeout(Some(Duration::from_secs(20)))
        .unwrap();
    socket.write_all(request).unwrap();
    let mut answer = Vec::new();
    let _ = socket.read_to_end(&mut answer);
    let text = String::from_utf8_lossy(&answer);
    let (head, body) = text.split_once("\r\n\r\n").expect("an HTTP answer");
    let status = head.split(' ').nth(1).unwrap().parse().unwrap();
    assert!(
        head.to_ascii_lowercase()
            .contains("content-type: application/json"),
        "{head}"
    );
    (status, serde_json::from_str(body).expect("a JSON body"))
}

fn assert_error(status: u16, body: &Value, want: u16, field: &str) {
    assert_eq!(status, want, "{body}");
    assert_eq!(body["error"]["status"], want, "{body}");
    assert_eq!(body["error"]["field"], field, "{body}");
}

/// The status and JSON body of `GET PATH` (PATH as it goes on the wire).
fn get(server: &Server, path: &str) -> (u16, Value) {
    let response = client().get(server.url(path)).send().unwrap();
    let status = response.status().as_u16();
    let text = response.text().unwrap();
    let body =
        serde_json::from_str(&text).unwrap_or_else(|_| panic!("GET {path}: not JSON: {text:?}"));
    (status, body)
}

#[test]
fn invalid_utf8_in_a_path_segment_is_a_json_400() {
    let server = Server::sample(2);
    for (path, field) in [
        ("/api/v1/scenes/%ff%fe", "scene"),
        ("/api/v1/scenes/sample-1/geometry/%ff.glb", "file"),
        ("/viewer/%ff", "file"),
        ("/api/v1/scenes/sample-1/tiles/%ff/0.json", "time"),
        ("/api/v1/scenes/%ff/objects", "scene"),
    ] {
        let (status, body) = get(&server, path);
        assert_eq!(status, 400, "{path}: {body}");
        assert_eq!(body["error"]["status"], 400, "{path}: {body}");
        assert_eq!(body["error"]["field"], field, "{path}: {body}");
    }
}

#[test]
fn a_plain_get_on_the_stream_is_a_json_400() {
    let server = Server::sample(2);
    let (status, body) = get(&server, "/api/v1/scenes/sample-1/stream");
    assert_error(status, &body, 400, "upgrade");
    assert!(
        body["error"]["message"]
            .as_str()
            .unwrap()
            .contains("WebSocket"),
        "{body}"
    );
}

#[test]
fn an_overlong_path_or_head_is_a_json_414_or_431() {
    let server = Server::sample(2);
    let long = format!(
        "GET /api/v1/scenes/{} HTTP/1.1\r\nHost: x\r\n\r\n",
        "a".repeat(100_000)
    );
    let (status, body) = raw(&server, long.as_bytes());
    assert_error(status, &body, 414, "path");
    // Too many headers, and too large a head.
    for (count, size) in [(150, 10), (50, 2000)] {
        let headers: String = (0..count)
            .map(|i| format!("x-filler-{i}: {}\r\n", "b".repeat(size)))
            .collect();
        let big = format!("GET /healthz HTTP/1.1\r\nHost: x\r\n{headers}\r\n");
        let (status, body) = raw(&server, big.as_bytes());
        assert_error(status, &body, 431, "headers");
    }
    // A long request line after a request with a body on the same
    // connection is still seen as a request line.
    let body = r#"{"time": 1}"#;
    let two = format!(
        "POST /api/v1/scenes/sample-1/cut HTTP/1.1\r\nHost: x\r\nContent-Type: \
         application/json\r\nContent-Length: {}\r\n\r\n{body}{long}",
        body.len()
    );
    let address = server.base.trim_start_matches("http://");
    let mut socket = TcpStream::connect(address).unwrap();
    socket
        .set_read_timeout(Some(Duration::from_secs(20)))
        .unwrap();
    socket.write_all(two.as_bytes()).unwrap();
    let mut answer = Vec::new();
    let _ = socket.read_to_end(&mut answer);
    let text = String::from_utf8_lossy(&answer);
    assert!(text.starts_with("HTTP/1.1 400"), "{text}");
    assert!(text.contains("HTTP/1.1 414"), "{text}");
    // None of it hurt the server.
    assert_eq!(get(&server, "/healthz").0, 200);
}

#[test]
fn camera_errors_name_the_field_sent() {
    let server = Server::sample(2);
    let cut = "/api/v1/scenes/sample-1/cut";
    let body = |camera: Value| json!({"time": 1000.0, "camera": camera});
    let far = 1e308;
    for (camera, field) in [
        (
            json!({"position": [far, 0, 0], "target": [-far, 0, 0]}),
            "camera.position",
        ),
        (
            json!({"position": [0, 0, 10], "target": [0, 0, 0], "fov_y_deg": 1e-300}),
            "camera.fov_y_deg",
        ),
        (
            json!({"position": [0, 0, 10], "target": [0, 0, 0], "near": 1e-300, "far": 1e300}),
            "camera.near",
        ),
        (
            json!({"position": [0, 0, 10], "target": [0, 0, 0], "near": 1.0, "far": 1e300}),
            "camera.far",
        ),
        (
            json!({"position": [far, far, far], "target": [0, 0, 0]}),
            "camera.position",
        ),
        (
            json!({"position": [0, 0, 10], "target": [0, 0, 0], "up": [far, far, 0]}),
            "",
        ),
    ] {
        let answer = server.post_json(cut, &body(camera.clone()));
        if field.is_empty() {
            // A huge up vector is still a direction.
            assert!(answer["clusters"].is_array(), "{camera} -> {answer}");
        } else {
            assert_eq!(answer["error"]["field"], field, "{camera} -> {answer}");
        }
    }
}

#[test]
fn errors_quote_at_most_about_100_characters() {
    let server = Server::sample(2);
    let name = "p".repeat(60_000);
    let hash = "h".repeat(5_000);
    for path in [
        format!("/api/v1/scenes/sample-1/cut?time=1&{name}=1"),
        format!("/api/v1/scenes/sample-1/geometry/{hash}.glb"),
        format!("/api/v1/scenes/{hash}"),
        format!("/api/v1/scenes/sample-1/cut?time={hash}&position=1,2,3&target=0,0,0"),
        format!("/api/v1/scenes/sample-1/objects?limit={hash}"),
    ] {
        let response = client().get(server.url(&path)).send().unwrap();
        assert!(response.status().is_client_error(), "{}", &path[..60]);
        let text = response.text().unwrap();
        assert!(text.len() < 500, "{} bytes: {}", text.len(), &text[..300]);
        let body: Value = serde_json::from_str(&text).unwrap();
        assert!(body["error"]["message"].is_string());
    }
    // serde's own messages quote an unknown field or a bad string whole.
    let long = "p".repeat(50_000);
    for body in [
        format!(r#"{{"time": 1000, "{long}": 1}}"#),
        format!(
            r#"{{"time": "{long}", "camera": {{"position": [1, 2, 3], "target": [0, 0, 0]}}}}"#
        ),
        format!(r#"{{"time": 1000, "presence": "{long}"}}"#),
    ] {
        let response = client()
            .post(server.url("/api/v1/scenes/sample-1/cut"))
            .header("content-type", "application/json")
            .body(body)
            .send()
            .unwrap();
        assert_eq!(response.status(), StatusCode::BAD_REQUEST);
        let text = response.text().unwrap();
        assert!(text.len() < 600, "{} bytes: {}", text.len(), &text[..300]);
    }
}

#[test]
fn a_query_parameter_given_twice_is_a_400_naming_it() {
    let server = Server::sample(2);
    for (path, field) in [
        (
            "/api/v1/scenes/sample-1/cut?time=1&time=2&position=1,2,3&target=0,0,0",
            "time",
        ),
        (
            "/api/v1/scenes/sample-1/tiles/tileset.json?time=1&frame=local&frame=local",
            "frame",
        ),
        ("/api/v1/scenes/sample-1/objects?limit=1&limit=2", "limit"),
    ] {
        let (status, body) = get(&server, path);
        assert_error(status, &body, 400, field);
        assert!(
            body["error"]["message"]
                .as_str()
                .unwrap()
                .contains("more than once"),
            "{body}"
        );
    }
    // Once each is fine.
    let (status, _) = get(
        &server,
        "/api/v1/scenes/sample-1/cut?time=1&position=1,2,3&target=0,0,0",
    );
    assert_eq!(status, StatusCode::OK.as_u16());
}

#[test]
fn a_tree_whose_scene_name_is_no_url_segment_is_not_served() {
    let tmp = tempfile::tempdir().unwrap();
    let tree = common::sample_tree(tmp.path(), 1);
    let manifest = tree.join(hdlod::tree::format::MANIFEST_FILE);
    let mut json: Value =
        serde_json::from_str(&std::fs::read_to_string(&manifest).unwrap()).unwrap();
    json["scene"] = json!("");
    std::fs::write(&manifest, json.to_string()).unwrap();
    let out = common::hdlod(&[
        "serve".as_ref(),
        "--addr".as_ref(),
        "127.0.0.1:0".as_ref(),
        tree.as_os_str(),
    ]);
    assert!(!out.status.success());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains("cannot be served") && stderr.contains("empty"),
        "{stderr}"
    );
}
