//! `GET /api/v1/scenes/{scene}/presence` from the real server on loopback,
//! over the tree of the tiny fixture: every object's presence by index, as
//! the object answers give it one at a time.

mod common;

use common::{SCENE, Server, assert_component, build_tree, client};
use reqwest::StatusCode;

/// The presence of every object by index, in one answer that follows its
/// schema; 404 for a tree without object tables.
#[test]
fn the_presence_answer_follows_the_objects() {
    let dir = tempfile::tempdir().unwrap();
    let server = Server::start(&build_tree(dir.path()));
    let doc = server.get_json("/api/v1/openapi.json");
    assert!(
        doc["paths"]
            .get("/api/v1/scenes/{scene}/presence")
            .is_some()
    );
    let answer = server.get_json(&format!("/api/v1/scenes/{SCENE}/presence"));
    assert_component(&doc, "Presence", &answer);
    let presence = answer["presence"].as_array().unwrap();
    let all = server.get_json(&format!("/api/v1/scenes/{SCENE}/objects?limit=1"));
    assert_eq!(presence.len() as u64, all["total"].as_u64().unwrap());
    for i in [0, presence.len() / 2, presence.len() - 1] {
        let o = server.get_json(&format!("/api/v1/scenes/{SCENE}/objects/{i}?by=index"));
        assert_eq!(presence[i], o["presence"], "object {i}");
    }
    let bad = client()
        .get(server.url(&format!("/api/v1/scenes/{SCENE}/presence?time=3")))
        .send()
        .unwrap();
    assert_eq!(bad.status(), StatusCode::BAD_REQUEST);
    let sample = Server::sample(6);
    let none = client()
        .get(sample.url("/api/v1/scenes/sample-1/presence"))
        .send()
        .unwrap();
    assert_eq!(none.status(), StatusCode::NOT_FOUND);
}
