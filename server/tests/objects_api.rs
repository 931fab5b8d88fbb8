//! The objects and tasks of a scene from the real server on loopback, over
//! the tree of the tiny fixture (which has `objects.json`): answers follow
//! the served OpenAPI document, search pages cover every match once, states
//! follow the time, bad requests get a 4xx naming the field; a tree without
//! the tables (the sample tree) answers 404.

mod common;

use common::{SCENE, Server, assert_component, build_tree, client};
use reqwest::StatusCode;
use serde_json::Value;

fn scene_path(rest: &str) -> String {
    format!("/api/v1/scenes/{SCENE}{rest}")
}

/// Every item of a listing, page by page, and the total each page gave.
fn all_pages(server: &Server, doc: &Value, listing: &str, query: &str, limit: usize) -> Vec<Value> {
    let schema = if listing == "objects" {
        "ObjectList"
    } else {
        "TaskList"
    };
    let mut items = Vec::new();
    let mut cursor = String::new();
    let mut total = None;
    loop {
        let page = server.get_json(&scene_path(&format!(
            "/{listing}?q={query}&limit={limit}{cursor}"
        )));
        assert_component(doc, schema, &page);
        assert!(page["items"].as_array().unwrap().len() <= limit);
        assert_eq!(*total.get_or_insert(page["total"].clone()), page["total"]);
        items.extend(page["items"].as_array().unwrap().iter().cloned());
        match page["next"].as_str() {
            Some(next) => cursor = format!("&cursor={next}"),
            None => break,
        }
    }
    assert_eq!(total.unwrap().as_u64().unwrap() as usize, items.len());
    items
}

#[test]
fn objects_and_tasks_follow_the_openapi_document() {
    let dir = tempfile::tempdir().unwrap();
    let server = Server::start(&build_tree(dir.path()));
    let doc = server.get_json("/api/v1/openapi.json");
    for path in [
        "/api/v1/scenes/{scene}/objects",
        "/api/v1/scenes/{scene}/objects/{id}",
        "/api/v1/scenes/{scene}/tasks",
        "/api/v1/scenes/{scene}/tasks/{id}",
    ] {
        assert!(doc["paths"].get(path).is_some(), "{path} documented");
    }
    // The served components are the files in schemas/api/.
    for (name, file) in [
        ("ObjectList", "object-list"),
        ("Object", "object"),
        ("TaskList", "task-list"),
        ("Task", "task"),
    ] {
        common::assert_served_file(&doc, name, file);
    }

    // An empty query lists every object, in scene order, page by page.
    let objects = all_pages(&server, &doc, "objects", "", 100);
    let fixture: Value = serde_json::from_str(
        &std::fs::read_to_string(common::repo().join("fixtures/skyscraper-tiny/scene.json"))
            .unwrap(),
    )
    .unwrap();
    assert_eq!(objects.len(), fixture["objects"].as_object().unwrap().len());
    for (i, o) in objects.iter().enumerate() {
        assert_eq!(o["index"], i);
    }

    // A search ignores case and looks at ids, names and property values.
    let columns = all_pages(&server, &doc, "objects", "COLUMN%20l01", 4);
    assert!(!columns.is_empty());
    for o in &columns {
        assert!(o["name"].as_str().unwrap().starts_with("Column L01"), "{o}");
        assert_eq!(o["class"], "IfcColumn");
        assert_eq!(o["storey"], "Level 01");
    }
    let storey = all_pages(&server, &doc, "objects", "level%2001", 1000);
    assert!(storey.len() > columns.len());

    // One object by id and by index; its state follows the time.
    let column = &columns[0];
    let id = column["id"].as_str().unwrap();
    let by_id = server.get_json(&scene_path(&format!("/objects/{id}")));
    assert_component(&doc, "Object", &by_id);
    assert_eq!(by_id["at"], Value::Null);
    assert!(by_id.get("present").is_none());
    let by_index = server.get_json(&scene_path(&format!(
        "/objects/{}?by=index",
        column["index"]
    )));
    assert_eq!(by_id, by_index);
    assert_eq!(server.get_json(column["url"].as_str().unwrap()), by_id);
    assert_eq!(by_id["properties"]["storey"], "Level 01");
    assert!(!by_id["clusters"].as_array().unwrap().is_empty());
    let task = &by_id["tasks"][0];
    let start = task["start"].as_f64().unwrap();
    let finish = task["finish"].as_f64().unwrap();
    let appears = by_id["presence"][0][0].as_f64().unwrap();
    for (time, state, present) in [
        (
            format!("{}", start - 1.0),
            "not_started",
            appears <= start - 1.0,
        ),
        (format!("{start}"), "in_progress", true),
        (
            task["finish_date"].as_str().unwrap().to_owned(),
            "finished",
            true,
        ),
    ] {
        let at = server.get_json(&scene_path(&format!("/objects/{id}?time={time}")));
        assert_component(&doc, "Object", &at);
        assert_eq!(at["tasks"][0]["state"], state, "at {time}");
        assert_eq!(at["present"], present, "at {time}");
    }
    let at = server.get_json(&scene_path(&format!("/objects/{id}?time={finish}")));
    assert_eq!(at["at"]["time"], finish);

    // Tasks: all of them, and one with its objects.
    let tasks = all_pages(&server, &doc, "tasks", "", 10);
    assert_eq!(tasks.len(), fixture["tasks"].as_array().unwrap().len());
    let one = server.get_json(task["url"].as_str().unwrap());
    assert_component(&doc, "Task", &one);
    assert_eq!(one["id"], task["id"]);
    assert!(
        one["objects"]
            .as_array()
            .unwrap()
            .iter()
            .any(|o| o["id"] == id && o["index"] == column["index"])
    );
    let during = server.get_json(&scene_path(&format!(
        "/tasks/{}?by=index&time={}",
        task["index"],
        (start + finish) / 2.0
    )));
    assert_component(&doc, "Task", &during);
    assert_eq!(during["state"], "in_progress");
    let demolitions = all_pages(&server, &doc, "tasks", "Demolish", 1000);
    assert!(demolitions.iter().all(|t| {
        t["type"] == "demolish"
            || t["name"]
                .as_str()
                .unwrap_or_default()
                .to_lowercase()
                .contains("demolish")
    }));
}

#[test]
fn bad_requests_name_the_field() {
    let dir = tempfile::tempdir().unwrap();
    let server = Server::start(&build_tree(dir.path()));
    let doc = server.get_json("/api/v1/openapi.json");
    let http = client();
    let cases = [
        ("/objects?limit=0", StatusCode::BAD_REQUEST, "limit"),
        ("/objects?limit=1001", StatusCode::BAD_REQUEST, "limit"),
        ("/objects?limit=ten", StatusCode::BAD_REQUEST, "limit"),
        ("/objects?cursor=12", StatusCode::BAD_REQUEST, "cursor"),
        ("/tasks?cursor=next", StatusCode::BAD_REQUEST, "cursor"),
        ("/objects?colour=red", StatusCode::BAD_REQUEST, "colour"),
        (
            "/objects/L01-C-00-00?time=yesterday",
            StatusCode::BAD_REQUEST,
            "time",
        ),
        (
            "/objects/L01-C-00-00?time=1e300",
            StatusCode::BAD_REQUEST,
            "time",
        ),
        (
            "/objects/L01-C-00-00?by=name",
            StatusCode::BAD_REQUEST,
            "by",
        ),
        ("/objects/column?by=index", StatusCode::BAD_REQUEST, "id"),
        ("/objects/no-such-object", StatusCode::NOT_FOUND, "id"),
        ("/objects/100000?by=index", StatusCode::NOT_FOUND, "id"),
        ("/tasks/T99999", StatusCode::NOT_FOUND, "id"),
        ("/tasks/T00001?time=soon", StatusCode::BAD_REQUEST, "time"),
    ];
    for (path, status, field) in cases {
        let response = http.get(server.url(&scene_path(path))).send().unwrap();
        assert_eq!(response.status(), status, "{path}");
        let error: Value = response.json().unwrap();
        assert_component(&doc, "Error", &error);
        assert_eq!(error["error"]["field"], field, "{path}: {error}");
    }
    let response = http
        .get(server.url("/api/v1/scenes/nope/objects"))
        .send()
        .unwrap();
    assert_eq!(response.status(), StatusCode::NOT_FOUND);
    assert_eq!(response.json::<Value>().unwrap()["error"]["field"], "scene");
}

#[test]
fn a_tree_without_tables_answers_404() {
    let server = Server::sample(2);
    let doc = server.get_json("/api/v1/openapi.json");
    let http = client();
    for path in ["/objects", "/objects/C-1", "/tasks", "/tasks/T1"] {
        let response = http
            .get(server.url(&format!("/api/v1/scenes/sample-1{path}")))
            .send()
            .unwrap();
        assert_eq!(response.status(), StatusCode::NOT_FOUND, "{path}");
        let error: Value = response.json().unwrap();
        assert_component(&doc, "Error", &error);
        assert_eq!(error["error"]["field"], "scene");
        assert!(
            error["error"]["message"]
                .as_str()
                .unwrap()
                .contains("objects.json"),
            "{error}"
        );
    }
    // The cut is served as before.
    let scene = server.get_json("/api/v1/scenes/sample-1");
    assert!(scene["clusters"].as_u64().unwrap() > 0);
}

/// A dynamic cluster's GLB is shared by every instance of its model and
/// carries no feature ids: the cut answer names its object, a moving one.
#[test]
fn dynamic_clusters_name_their_object() {
    let dir = tempfile::tempdir().unwrap();
    let server = Server::start(&build_tree(dir.path()));
    let doc = server.get_json("/api/v1/openapi.json");
    let scene = server.get_json(&scene_path(""));
    let mut named = 0;
    for k in 1..20 {
        let body = common::cut_over(&scene, f64::from(k) / 20.0);
        let cut = server.post_json(&scene_path("/cut"), &body);
        assert_component(&doc, "CutResponse", &cut);
        for c in cut["clusters"].as_array().unwrap() {
            let object = &c["object"];
            if c["class"] != "dynamic" {
                assert!(object.is_null(), "{c}");
                continue;
            }
            let index = object.as_u64().expect("a dynamic cluster names its object");
            let entry = server.get_json(&scene_path(&format!("/objects/{index}?by=index")));
            assert_eq!(entry["visibility_class"], "dynamic", "{c} -> {entry}");
            named += 1;
        }
    }
    assert!(named > 0, "no dynamic cluster in any cut");
}

/// The object index of a served tree replaced by a damaged one (renamed
/// into place): the reload fails and the previous tree and its tables stay served; once
/// the indexes are written again (`hdlod index`), the reload serves them.
#[test]
fn a_corrupt_object_index_keeps_the_previous_tables_served() {
    let dir = tempfile::tempdir().unwrap();
    let tree = build_tree(dir.path());
    let server = Server::start(&tree);
    let object = scene_path("/objects/0?by=index");
    let before = server.get_json(&object);
    assert!(before["id"].is_string());
    let path = tree.join("objects.bin");
    let mut bytes = std::fs::read(&path).unwrap();
    let middle = bytes.len() / 2;
    bytes[middle] ^= 0xff;
    let reloaded = server.reloads();
    let damaged = tree.join(".objects.bin.damaged");
    std::fs::write(&damaged, &bytes).unwrap();
    std::fs::rename(&damaged, &path).unwrap();
    server.await_reloads(reloaded + 1);
    assert_eq!(server.get_json(&object), before);

    let out = common::hdlod(&["index".as_ref(), tree.as_os_str()]);
    common::assert_success(&out);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(stdout.contains("objects.bin"), "{stdout}");
    server.await_reloads(reloaded + 2);
    assert_eq!(server.get_json(&object), before);
}
