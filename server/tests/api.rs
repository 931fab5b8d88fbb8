//! The real server on loopback: `hdlod serve --addr 127.0.0.1:0` over a
//! sample tree, answers checked against the OpenAPI document it serves.

mod common;

use std::process::Command;
use std::time::{Duration, Instant};

use common::{Server, assert_component, client, geometry_files};
use reqwest::StatusCode;
use reqwest::blocking::Client;
use serde_json::{Value, json};

fn cut_body(time: Value) -> Value {
    json!({"time": time, "camera": {"position": [150.0, 120.0, 150.0], "target": [0.0, 20.0, 0.0], "far": 2000.0},
           "viewport": {"width": 1280, "height": 720}, "pixel_error": 2.0})
}

#[test]
fn responses_match_the_openapi_document() {
    let server = Server::sample(6);
    let http = client();
    let doc = server.get_json("/api/v1/openapi.json");
    assert_eq!(doc["openapi"], "3.1.0");
    // The served components are the files in schemas/api/.
    for (name, file) in [
        ("CutRequest", "cut-request"),
        ("CutResponse", "cut-response"),
        ("StreamMessage", "stream-message"),
    ] {
        common::assert_served_file(&doc, name, file);
    }
    for path in [
        "/healthz",
        "/api/v1/scenes",
        "/api/v1/scenes/{scene}",
        "/api/v1/scenes/{scene}/cut",
        "/api/v1/scenes/{scene}/stream",
    ] {
        assert!(doc["paths"].get(path).is_some(), "{path} documented");
    }

    let get = |path: &str| server.get_json(path);
    assert_component(&doc, "Health", &get("/healthz"));
    let scenes = get("/api/v1/scenes");
    assert_component(&doc, "SceneList", &scenes);
    assert_eq!(scenes["scenes"][0]["name"], "sample-1");
    let scene = get("/api/v1/scenes/sample-1");
    assert_component(&doc, "Scene", &scene);
    assert!(scene["classes"]["dynamic"].as_u64().unwrap() > 0);

    let mut seen_dynamic = false;
    for time in [
        json!(0.0),
        json!("2024-04-15T12:00:00Z"),
        json!(6e6),
        json!(9e6),
    ] {
        let body = cut_body(time);
        assert_component(&doc, "CutRequest", &body);
        let response = http
            .post(server.url("/api/v1/scenes/sample-1/cut"))
            .json(&body)
            .send()
            .unwrap();
        assert_eq!(response.status(), StatusCode::OK);
        let cut: Value = response.json().unwrap();
        assert_component(&doc, "CutResponse", &cut);
        assert_eq!(
            cut["stats"]["clusters"].as_u64().unwrap() as usize,
            cut["clusters"].as_array().unwrap().len()
        );
        seen_dynamic |= cut["clusters"]
            .as_array()
            .unwrap()
            .iter()
            .any(|c| c["transform"].is_array());
    }
    assert!(seen_dynamic, "the cranes are in some cut");

    // GET with query parameters answers the same cut as POST.
    let post = server.post_json("/api/v1/scenes/sample-1/cut", &cut_body(json!(5e6)));
    let get_cut = get(
        "/api/v1/scenes/sample-1/cut?time=5000000&position=150,120,150&target=0,20,0&far=2000&viewport=1280x720&pixel_error=2",
    );
    assert_component(&doc, "CutResponse", &get_cut);
    assert_eq!(get_cut["clusters"], post["clusters"]);

    // Exact presence draws the paper's clusters, and what is present of
    // those under half present: their children, down to the leaves.
    let mut body = cut_body(json!(5e6));
    body["presence"] = json!("exact");
    assert_component(&doc, "CutRequest", &body);
    let exact = server.post_json("/api/v1/scenes/sample-1/cut", &body);
    assert_component(&doc, "CutResponse", &exact);
    let ids = |cut: &Value| -> Vec<u64> {
        cut["clusters"]
            .as_array()
            .unwrap()
            .iter()
            .map(|c| c["id"].as_u64().unwrap())
            .collect()
    };
    let (paper_ids, exact_ids) = (ids(&post), ids(&exact));
    assert!(paper_ids.iter().all(|id| exact_ids.contains(id)));
    for c in exact["clusters"].as_array().unwrap() {
        if !paper_ids.contains(&c["id"].as_u64().unwrap()) {
            let v = c["visibility"].as_f64().unwrap();
            assert!(v > 0.0, "{c}");
            assert!(v >= 0.5 || c["level"] == 0, "{c}");
        }
    }

    // Without levels of detail: every present leaf, in view or not, which
    // are the baseline's triangles; a camera looking away changes nothing.
    let mut body = cut_body(json!(5e6));
    body["lod"] = json!("none");
    assert_component(&doc, "CutRequest", &body);
    let none = server.post_json("/api/v1/scenes/sample-1/cut", &body);
    assert_component(&doc, "CutResponse", &none);
    let stats = &none["stats"];
    assert_eq!(stats["triangles"], stats["baseline_triangles"], "{stats}");
    assert!(stats["triangles"].as_u64().unwrap() > post["stats"]["triangles"].as_u64().unwrap());
    assert!(
        none["clusters"]
            .as_array()
            .unwrap()
            .iter()
            .all(|c| c["level"] == 0)
    );
    let away = get(
        "/api/v1/scenes/sample-1/cut?time=5000000&position=150,120,150&target=300,120,300&lod=none",
    );
    assert_eq!(ids(&away), ids(&none));

    let error = get("/api/v1/scenes/nope");
    assert_component(&doc, "Error", &error);

    let metrics = http
        .get(server.url("/metrics"))
        .send()
        .unwrap()
        .text()
        .unwrap();
    assert!(
        metrics.contains(
            "hdlod_http_requests_total{route=\"/api/v1/scenes/{scene}/cut\",status=\"200\"}"
        ),
        "{metrics}"
    );
    assert!(metrics.contains("hdlod_cut_clusters_count"));
}

#[test]
fn bad_requests_name_the_field() {
    let server = Server::sample(6);
    let http = client();
    let cut = server.url("/api/v1/scenes/sample-1/cut");
    let with = |edit: &dyn Fn(&mut Value)| {
        let mut body = cut_body(json!(1000.0));
        edit(&mut body);
        body
    };
    let cases: Vec<(Value, &str)> = vec![
        (
            with(&|b| b.as_object_mut().unwrap().remove("time").map(drop).unwrap()),
            "time",
        ),
        (with(&|b| b["time"] = json!("yesterday")), "time"),
        (with(&|b| b["time"] = json!(true)), "time"),
        (
            with(&|b| b["camera"]["position"] = json!([1, 2])),
            "camera.position",
        ),
        (
            with(&|b| b["camera"]["target"] = json!([150.0, 120.0, 150.0])),
            "camera.target",
        ),
        (
            with(&|b| b["camera"]["fov_y_deg"] = json!(0)),
            "camera.fov_y_deg",
        ),
        (
            with(&|b| b["camera"]["fov_y_deg"] = json!("wide")),
            "camera.fov_y_deg",
        ),
        (with(&|b| b["camera"]["near"] = json!(-1)), "camera.near"),
        (with(&|b| b["camera"]["far"] = json!(0.01)), "camera.far"),
        (with(&|b| b["camera"]["up"] = json!([0, 0, 0])), "camera.up"),
        (with(&|b| b["camera"]["aspect"] = json!(0)), "camera.aspect"),
        (with(&|b| b["camera"]["zoom"] = json!(2)), "camera.zoom"),
        (
            with(&|b| b["camera"] = json!({"view_projection": [1, 2, 3]})),
            "camera.view_projection",
        ),
        (
            with(&|b| b["viewport"]["width"] = json!(0)),
            "viewport.width",
        ),
        (
            with(&|b| b["viewport"]["height"] = json!(-5)),
            "viewport.height",
        ),
        (with(&|b| b["pixel_error"] = json!(0)), "pixel_error"),
        (with(&|b| b["presence"] = json!("half")), "presence"),
        (with(&|b| b["extra"] = json!(1)), "extra"),
    ];
    for (body, field) in cases {
        let response = http.post(&cut).json(&body).send().unwrap();
        assert_eq!(response.status(), StatusCode::BAD_REQUEST, "{body}");
        let error: Value = response.json().unwrap();
        assert_eq!(error["error"]["field"], field, "{body} -> {error}");
    }
    let response = http.post(&cut).body("{not json").send().unwrap();
    assert_eq!(response.status(), StatusCode::BAD_REQUEST);
    let response = http
        .get(format!("{cut}?time=1&position=1,2&target=0,0,0"))
        .send()
        .unwrap();
    assert_eq!(response.status(), StatusCode::BAD_REQUEST);
    assert_eq!(
        response.json::<Value>().unwrap()["error"]["field"],
        "position"
    );
    let response = http
        .get(format!("{cut}?time=1&position=1,2,3&target=0,0,0&bogus=1"))
        .send()
        .unwrap();
    assert_eq!(response.json::<Value>().unwrap()["error"]["field"], "bogus");
    let response = http
        .get(format!(
            "{cut}?time=1&position=1,2,3&target=0,0,0&presence=most"
        ))
        .send()
        .unwrap();
    assert_eq!(response.status(), StatusCode::BAD_REQUEST);
    assert_eq!(
        response.json::<Value>().unwrap()["error"]["field"],
        "presence"
    );
    let response = http
        .get(format!("{cut}?time=1&position=1,2,3&target=0,0,0&lod=some"))
        .send()
        .unwrap();
    assert_eq!(response.status(), StatusCode::BAD_REQUEST);
    assert_eq!(response.json::<Value>().unwrap()["error"]["field"], "lod");

    let response = http
        .post(server.url("/api/v1/scenes/nope/cut"))
        .json(&cut_body(json!(0)))
        .send()
        .unwrap();
    assert_eq!(response.status(), StatusCode::NOT_FOUND);
    assert_eq!(response.json::<Value>().unwrap()["error"]["field"], "scene");
    let response = http.get(server.url("/api/v1/nothing")).send().unwrap();
    assert_eq!(response.status(), StatusCode::NOT_FOUND);
    let response = http.delete(&cut).send().unwrap();
    assert_eq!(response.status(), StatusCode::METHOD_NOT_ALLOWED);

    let huge = format!("{{\"time\": 0, \"pad\": \"{}\"}}", "x".repeat(100_000));
    let response = http
        .post(&cut)
        .header("content-type", "application/json")
        .body(huge)
        .send()
        .unwrap();
    assert_eq!(response.status(), StatusCode::PAYLOAD_TOO_LARGE);
    assert_eq!(response.json::<Value>().unwrap()["error"]["status"], 413);

    // None of it hurt the server. (A fresh client: after a 413 the server
    // closes that connection without reading the rest of the body.)
    assert_eq!(
        client()
            .get(server.url("/healthz"))
            .send()
            .unwrap()
            .status(),
        StatusCode::OK
    );
}

#[test]
fn geometry_is_immutable_cacheable_and_compressed() {
    let server = Server::sample(6);
    let http = client();
    let cut = server.post_json("/api/v1/scenes/sample-1/cut", &cut_body(json!(9e6)));
    let url = cut["clusters"][0]["geometry"].as_str().unwrap().to_owned();
    let hash = url
        .rsplit('/')
        .next()
        .unwrap()
        .trim_end_matches(".glb")
        .to_owned();

    let response = http.get(server.url(&url)).send().unwrap();
    assert_eq!(response.status(), StatusCode::OK);
    let headers = response.headers().clone();
    assert_eq!(headers["content-type"], "model/gltf-binary");
    assert_eq!(headers["etag"], format!("\"{hash}\"").as_str());
    assert!(
        headers["cache-control"]
            .to_str()
            .unwrap()
            .contains("immutable")
    );
    let bytes = response.bytes().unwrap();
    assert_eq!(&bytes[..4], b"glTF");
    assert_eq!(blake3::hash(&bytes).to_hex().as_str(), hash);
    assert_eq!(
        bytes.as_ref(),
        std::fs::read(
            server
                .tree
                .join("geometry")
                .join(&hash[..2])
                .join(format!("{hash}.glb"))
        )
        .unwrap()
    );

    let response = http
        .get(server.url(&url))
        .header("if-none-match", format!("\"{hash}\""))
        .send()
        .unwrap();
    assert_eq!(response.status(), StatusCode::NOT_MODIFIED);
    for encoding in ["gzip", "br"] {
        let response = http
            .get(server.url(&url))
            .header("accept-encoding", encoding)
            .send()
            .unwrap();
        assert_eq!(response.headers()["content-encoding"], encoding);
        assert!(response.bytes().unwrap().len() < bytes.len());
    }
    let missing = format!("/api/v1/scenes/sample-1/geometry/{}.glb", "0".repeat(64));
    assert_eq!(
        http.get(server.url(&missing)).send().unwrap().status(),
        StatusCode::NOT_FOUND
    );
    let traversal = "/api/v1/scenes/sample-1/geometry/..%2Fmanifest.json";
    assert_eq!(
        http.get(server.url(traversal)).send().unwrap().status(),
        StatusCode::NOT_FOUND
    );
}

#[test]
fn stream_sends_the_changes_of_the_cut() {
    use futures_util::{SinkExt, StreamExt};
    use tokio_tungstenite::tungstenite::Message;

    let server = Server::sample(6);
    let doc = server.get_json("/api/v1/openapi.json");
    let ws_url = server
        .url("/api/v1/scenes/sample-1/stream")
        .replace("http://", "ws://");
    let views: Vec<Value> = (0..12)
        .map(|i| {
            let mut body = cut_body(json!(i as f64 * 8e5));
            body["camera"]["position"] = json!([150.0 - i as f64 * 25.0, 120.0, 150.0]);
            body
        })
        .collect();
    let expected: Vec<Value> = views
        .iter()
        .map(|v| server.post_json("/api/v1/scenes/sample-1/cut", v))
        .collect();

    let runtime = tokio::runtime::Runtime::new().unwrap();
    runtime.block_on(async {
        let (mut socket, _) = tokio_tungstenite::connect_async(&ws_url).await.unwrap();
        let mut held: std::collections::BTreeMap<u64, Value> = Default::default();
        for (i, (view, want)) in views.iter().zip(&expected).enumerate() {
            socket.send(Message::text(view.to_string())).await.unwrap();
            let Some(Ok(Message::Text(text))) = socket.next().await else {
                panic!("no answer")
            };
            let message: Value = serde_json::from_str(text.as_str()).unwrap();
            assert_component(&doc, "StreamMessage", &message);
            assert_eq!(message["seq"], i + 1);
            assert_eq!(message["reset"], i == 0);
            for id in message["remove"].as_array().unwrap() {
                assert!(
                    held.remove(&id.as_u64().unwrap()).is_some(),
                    "removes only what it sent"
                );
            }
            for c in message["add"].as_array().unwrap() {
                assert!(
                    held.insert(c["id"].as_u64().unwrap(), c["transform"].clone())
                        .is_none()
                );
            }
            for u in message["update"].as_array().unwrap() {
                *held.get_mut(&u["id"].as_u64().unwrap()).unwrap() = u["transform"].clone();
            }
            let want: std::collections::BTreeMap<u64, Value> = want["clusters"]
                .as_array()
                .unwrap()
                .iter()
                .map(|c| (c["id"].as_u64().unwrap(), c["transform"].clone()))
                .collect();
            assert_eq!(held, want, "view {i}");
        }
        // A bad message gets an error naming the field; the stream goes on.
        socket
            .send(Message::text(
                r#"{"time": 0, "camera": {"position": [1, 2, 3]}}"#,
            ))
            .await
            .unwrap();
        let Some(Ok(Message::Text(text))) = socket.next().await else {
            panic!("no answer")
        };
        let error: Value = serde_json::from_str(text.as_str()).unwrap();
        assert_component(&doc, "StreamMessage", &error);
        assert_eq!(error["error"]["field"], "camera.target");
        socket
            .send(Message::text(views[0].to_string()))
            .await
            .unwrap();
        let Some(Ok(Message::Text(text))) = socket.next().await else {
            panic!("no answer")
        };
        assert_eq!(
            serde_json::from_str::<Value>(text.as_str()).unwrap()["seq"],
            views.len() + 1
        );
    });
}

#[test]
fn sighup_reloads_the_tree_without_dropping_requests() {
    reloads_without_dropping_requests(true);
}

#[test]
fn a_tree_replaced_on_disk_is_reloaded_without_dropping_requests() {
    reloads_without_dropping_requests(false);
}

/// Replaces the served tree (atomically, as `hdlod build` does) under a
/// stream of cut requests; with `hangup` the server does not watch files
/// and is sent SIGHUP, without it the file watch must pick the change up.
fn reloads_without_dropping_requests(hangup: bool) {
    let server = Server::sample_with(6, if hangup { &["--no-watch"] } else { &[] });
    let url = server.url("/api/v1/scenes/sample-1/cut");
    let clusters = |http: &Client| -> u64 {
        let scene: Value = http
            .get(server.url("/api/v1/scenes/sample-1"))
            .send()
            .unwrap()
            .json()
            .unwrap();
        scene["clusters"].as_u64().unwrap()
    };
    let before = clusters(&client());
    let stop = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    let load = {
        let stop = stop.clone();
        std::thread::spawn(move || {
            let http = client();
            let mut statuses = Vec::new();
            while !stop.load(std::sync::atomic::Ordering::Relaxed) {
                statuses.push(
                    http.post(&url)
                        .json(&cut_body(json!(4e6)))
                        .send()
                        .map(|r| r.status()),
                );
            }
            statuses
        })
    };
    hdlod_fixtures::sample::write_sample_tree(&server.tree, 1, 9).unwrap();
    if hangup {
        let status = Command::new("kill")
            .args(["-HUP", &server.pid().to_string()])
            .status()
            .unwrap();
        assert!(status.success());
    }
    let deadline = Instant::now() + Duration::from_secs(10);
    let http = client();
    while clusters(&http) == before {
        assert!(Instant::now() < deadline, "the new tree was not picked up");
        std::thread::sleep(Duration::from_millis(20));
    }
    std::thread::sleep(Duration::from_millis(100));
    stop.store(true, std::sync::atomic::Ordering::Relaxed);
    let statuses = load.join().unwrap();
    assert!(statuses.len() > 5);
    assert!(
        statuses.iter().all(|s| matches!(s, Ok(StatusCode::OK))),
        "{statuses:?}"
    );
}

/// The load does not list the geometry directory: a GLB the served tree
/// names whose file is gone is answered 503, saying that the tree is
/// incomplete (a hash the tree does not name stays a 404). A reload checks
/// every file: a replacement with a GLB missing keeps the previous tree
/// served, a whole one is served.
#[test]
fn a_missing_glb_is_a_server_error_and_keeps_a_replacement_out() {
    let server = Server::sample_with(3, &["--no-watch"]);
    let http = client();
    let clusters = || {
        server.get_json("/api/v1/scenes/sample-1")["clusters"]
            .as_u64()
            .unwrap()
    };
    let before = clusters();
    let cut = server.post_json("/api/v1/scenes/sample-1/cut", &cut_body(json!(4e6)));
    let url = cut["clusters"][0]["geometry"].as_str().unwrap().to_owned();
    let file = url.rsplit('/').next().unwrap();
    std::fs::remove_file(server.tree.join("geometry").join(&file[..2]).join(file)).unwrap();
    let response = http.get(server.url(&url)).send().unwrap();
    assert_eq!(response.status(), StatusCode::SERVICE_UNAVAILABLE);
    let body: Value = response.json().unwrap();
    let message = body["error"]["message"].as_str().unwrap();
    assert!(message.contains("is incomplete"), "{message}");

    let hangup = |server: &Server| {
        let reloaded = server.reloads();
        let status = Command::new("kill")
            .args(["-HUP", &server.pid().to_string()])
            .status()
            .unwrap();
        assert!(status.success());
        server.await_reloads(reloaded + 1);
    };
    // A bigger tree, one of its GLBs missing, renamed into place.
    let next = server.tree.with_file_name("next");
    hdlod_fixtures::sample::write_sample_tree(&next, 1, 6).unwrap();
    let glb = geometry_files(&next).swap_remove(0);
    std::fs::remove_file(glb).unwrap();
    std::fs::rename(&server.tree, server.tree.with_file_name("old")).unwrap();
    std::fs::rename(&next, &server.tree).unwrap();
    hangup(&server);
    assert_eq!(clusters(), before);
    hdlod_fixtures::sample::write_sample_tree(&server.tree, 1, 6).unwrap();
    hangup(&server);
    assert!(clusters() > before);
}

/// The index of a served tree replaced by a damaged one (renamed into
/// place): the reload fails and the previous tree stays served; once the
/// index is written again (`hdlod index`), the reload serves it.
#[test]
fn a_corrupt_index_keeps_the_previous_tree_served() {
    let server = Server::sample(3);
    let cut = server.url("/api/v1/scenes/sample-1/cut");
    let answer = |http: &Client| -> Value {
        let mut v: Value = http
            .post(&cut)
            .json(&cut_body(json!(4e6)))
            .send()
            .unwrap()
            .json()
            .unwrap();
        v["stats"]["micros"] = Value::Null;
        v
    };
    let http = client();
    let before = answer(&http);
    assert!(!before["clusters"].as_array().unwrap().is_empty());
    let index = server.tree.join("clusters.bin");
    let mut bytes = std::fs::read(&index).unwrap();
    let middle = bytes.len() / 2;
    bytes[middle] ^= 0xff;
    let reloaded = server.reloads();
    let damaged = server.tree.join(".clusters.bin.damaged");
    std::fs::write(&damaged, &bytes).unwrap();
    std::fs::rename(&damaged, &index).unwrap();
    server.await_reloads(reloaded + 1);
    assert_eq!(answer(&http), before);

    let out = common::hdlod(&["index".as_ref(), server.tree.as_os_str()]);
    common::assert_success(&out);
    server.await_reloads(reloaded + 2);
    assert_eq!(answer(&http), before);
}

#[test]
fn every_reference_of_the_openapi_document_resolves_within_it() {
    fn walk(doc: &Value, at: &Value, path: &str, refs: &mut usize) {
        match at {
            Value::Object(o) => {
                if let Some(r) = o.get("$ref").and_then(Value::as_str) {
                    let pointer = r
                        .strip_prefix('#')
                        .unwrap_or_else(|| panic!("{path}: {r} points outside the document"));
                    assert!(
                        doc.pointer(pointer).is_some(),
                        "{path}: {r} does not resolve"
                    );
                    *refs += 1;
                }
                for (k, v) in o {
                    walk(doc, v, &format!("{path}/{k}"), refs);
                }
            }
            Value::Array(a) => {
                for (i, v) in a.iter().enumerate() {
                    walk(doc, v, &format!("{path}/{i}"), refs);
                }
            }
            _ => {}
        }
    }
    let server = Server::sample(2);
    let doc = server.get_json("/api/v1/openapi.json");
    let mut refs = 0;
    walk(&doc, &doc, "", &mut refs);
    assert!(refs > 40, "{refs} references");
    // No schema resource of its own inside: one base for every reference.
    assert!(!doc.to_string().contains("\"$id\""));
}

/// The GLBs of a batch answer: the index's length, the index, the files.
fn unpack_batch(body: &[u8]) -> Vec<(String, Vec<u8>)> {
    let n = u32::from_le_bytes(body[..4].try_into().unwrap()) as usize;
    let index: Value = serde_json::from_slice(&body[4..4 + n]).unwrap();
    index["files"]
        .as_array()
        .unwrap()
        .iter()
        .map(|f| {
            let offset = f["offset"].as_u64().unwrap() as usize;
            let length = f["length"].as_u64().unwrap() as usize;
            assert_eq!(offset % 8, 0, "{f}");
            (
                f["hash"].as_str().unwrap().to_owned(),
                body[offset..offset + length].to_vec(),
            )
        })
        .collect()
}

#[test]
fn geometry_comes_compact_plain_on_request_and_in_batches() {
    let server = Server::sample(6);
    let http = client();
    let cut = server.post_json("/api/v1/scenes/sample-1/cut", &cut_body(json!(9e6)));
    let mut hashes: Vec<String> = cut["clusters"]
        .as_array()
        .unwrap()
        .iter()
        .map(|c| {
            let url = c["geometry"].as_str().unwrap();
            url.rsplit('/')
                .next()
                .unwrap()
                .trim_end_matches(".glb")
                .to_owned()
        })
        .collect();
    hashes.sort();
    hashes.dedup();
    assert!(hashes.len() >= 3, "{hashes:?}");
    let single = |hash: &str, query: &str| -> (reqwest::header::HeaderMap, Vec<u8>) {
        let r = http
            .get(server.url(&format!(
                "/api/v1/scenes/sample-1/geometry/{hash}.glb{query}"
            )))
            .send()
            .unwrap();
        assert_eq!(r.status(), StatusCode::OK, "{hash}{query}");
        (r.headers().clone(), r.bytes().unwrap().to_vec())
    };

    // The stored, compact form by default; the plain form derived from it.
    let (_, stored) = single(&hashes[0], "");
    assert!(hdlod::io::compact::is_compact(&stored));
    assert_eq!(single(&hashes[0], "?encoding=compact").1, stored);
    let (headers, plain) = single(&hashes[0], "?encoding=plain");
    assert!(!hdlod::io::compact::is_compact(&plain));
    assert_eq!(headers["etag"], format!("\"{}-plain\"", hashes[0]).as_str());
    assert_eq!(plain, hdlod::io::compact::plain(&stored).unwrap().as_ref());
    let response = http
        .get(server.url(&format!(
            "/api/v1/scenes/sample-1/geometry/{}.glb?encoding=plain",
            hashes[0]
        )))
        .header("if-none-match", format!("\"{}-plain\"", hashes[0]))
        .send()
        .unwrap();
    assert_eq!(response.status(), StatusCode::NOT_MODIFIED);

    // A batch holds the same bytes as the single requests, in order.
    let list = hashes.join(",");
    for query in ["", "&encoding=plain"] {
        let r = http
            .get(server.url(&format!("/api/v1/scenes/sample-1/geometry?h={list}{query}")))
            .send()
            .unwrap();
        assert_eq!(r.status(), StatusCode::OK);
        let headers = r.headers().clone();
        assert_eq!(
            headers["content-type"],
            "application/vnd.hdlod.geometry-batch"
        );
        assert!(
            headers["cache-control"]
                .to_str()
                .unwrap()
                .contains("immutable")
        );
        let files = unpack_batch(&r.bytes().unwrap());
        assert_eq!(files.len(), hashes.len());
        for ((hash, bytes), want) in files.iter().zip(&hashes) {
            assert_eq!(hash, want);
            let single_query = if query.is_empty() {
                ""
            } else {
                "?encoding=plain"
            };
            assert_eq!(bytes, &single(hash, single_query).1, "{hash}{query}");
        }
        let again = http
            .get(server.url(&format!("/api/v1/scenes/sample-1/geometry?h={list}{query}")))
            .header("if-none-match", headers["etag"].clone())
            .send()
            .unwrap();
        assert_eq!(again.status(), StatusCode::NOT_MODIFIED);
    }

    // Bad requests: JSON naming the parameter at fault.
    let unknown = "0".repeat(64);
    let many = vec![hashes[0].as_str(); 101].join(",");
    for (query, status, field) in [
        (String::new(), StatusCode::BAD_REQUEST, "h"),
        ("?h=".to_owned(), StatusCode::BAD_REQUEST, "h"),
        ("?h=xyz".to_owned(), StatusCode::BAD_REQUEST, "h"),
        (
            format!("?h={0},{0}", hashes[0]),
            StatusCode::BAD_REQUEST,
            "h",
        ),
        (format!("?h={many}"), StatusCode::BAD_REQUEST, "h"),
        (
            format!("?h={},{unknown}", hashes[0]),
            StatusCode::NOT_FOUND,
            "hash",
        ),
        (
            format!("?h={}&encoding=zip", hashes[0]),
            StatusCode::BAD_REQUEST,
            "encoding",
        ),
        (
            format!("?h={}&x=1", hashes[0]),
            StatusCode::BAD_REQUEST,
            "x",
        ),
    ] {
        let r = http
            .get(server.url(&format!("/api/v1/scenes/sample-1/geometry{query}")))
            .send()
            .unwrap();
        assert_eq!(r.status(), status, "{query}");
        assert!(
            r.headers()["content-type"]
                .to_str()
                .unwrap()
                .starts_with("application/json")
        );
        let body: Value = r.json().unwrap();
        assert_eq!(body["error"]["field"], field, "{query}: {body}");
    }
    let r = http
        .get(server.url(&format!(
            "/api/v1/scenes/sample-1/geometry/{}.glb?encoding=zip",
            hashes[0]
        )))
        .send()
        .unwrap();
    assert_eq!(r.status(), StatusCode::BAD_REQUEST);
    let body: Value = r.json().unwrap();
    assert_eq!(body["error"]["field"], "encoding");
}

/// A tree of the previous format (`hdlod-tree/1`, its geometry flat) is
/// served; `hdlod migrate` makes it `hdlod-tree/2` under the running
/// server, which serves the same geometry before and after it reloads the
/// tree. A second run has nothing to do.
#[test]
fn a_flat_tree_is_served_and_migrated_under_the_server() {
    let tmp = tempfile::tempdir().unwrap();
    let tree = common::sample_tree(tmp.path(), 3);
    common::flatten_tree(&tree);
    let server = Server::start(&tree);
    let http = client();
    let cut = server.post_json("/api/v1/scenes/sample-1/cut", &cut_body(json!(4e6)));
    let urls: Vec<String> = cut["clusters"]
        .as_array()
        .unwrap()
        .iter()
        .filter_map(|c| c["geometry"].as_str().map(str::to_owned))
        .collect();
    assert!(!urls.is_empty());
    let get = |url: &str| {
        let response = http.get(server.url(url)).send().unwrap();
        assert_eq!(response.status(), StatusCode::OK, "{url}");
        response.bytes().unwrap()
    };
    let before: Vec<_> = urls.iter().map(|u| get(u)).collect();
    let reloaded = server.reloads();
    let migrate = || common::hdlod(&[std::ffi::OsStr::new("migrate"), tree.as_os_str()]);
    let out = migrate();
    common::assert_success(&out);
    let said = String::from_utf8_lossy(&out.stdout);
    assert!(said.contains("hdlod-tree/1 -> hdlod-tree/2"), "{said}");
    for (url, bytes) in urls.iter().zip(&before) {
        assert_eq!(&get(url), bytes, "served from the shards before the reload");
    }
    server.await_reloads(reloaded + 1);
    for (url, bytes) in urls.iter().zip(&before) {
        assert_eq!(&get(url), bytes);
    }
    assert_eq!(common::checked_manifest(&tree)["format"], "hdlod-tree/2");
    assert!(
        geometry_files(&tree)
            .iter()
            .all(|f| f.parent() != Some(&tree.join("geometry")))
    );

    let out = migrate();
    common::assert_success(&out);
    let said = String::from_utf8_lossy(&out.stdout);
    assert!(said.contains("nothing to do"), "{said}");
}
