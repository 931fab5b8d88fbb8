//! `GET /api/v1/scenes/{scene}/schedule` and `.../appearance` from the real
//! server on loopback: the tiny site's tasks with their dates and feature
//! indices, revalidated by ETag; the default profile, or the scene's own,
//! and a tree built on the actual dates.

mod common;

use common::{SCENE, Server, assert_component, assert_success, build_tree, client, hdlod, repo};
use reqwest::StatusCode;
use reqwest::header::{ETAG, IF_NONE_MATCH};
use serde_json::{Value, json};

fn scene_json() -> Value {
    let text = std::fs::read_to_string(repo().join("fixtures/skyscraper-tiny/scene.json")).unwrap();
    serde_json::from_str(&text).unwrap()
}

/// The tiny fixture's model with `scene` as its scene.json, built into
/// `dir/tree`.
fn build_scene(dir: &std::path::Path, scene: &Value) -> std::path::PathBuf {
    let scene_dir = dir.join("scene");
    std::fs::create_dir(&scene_dir).unwrap();
    std::fs::copy(
        repo().join("fixtures/skyscraper-tiny/skyscraper-tiny.glb"),
        scene_dir.join("skyscraper-tiny.glb"),
    )
    .unwrap();
    std::fs::write(
        scene_dir.join("scene.json"),
        serde_json::to_vec_pretty(scene).unwrap(),
    )
    .unwrap();
    let tree = dir.join("tree");
    assert_success(&hdlod(&[
        "build".as_ref(),
        scene_dir.as_os_str(),
        "--out".as_ref(),
        tree.as_os_str(),
    ]));
    tree
}

#[test]
fn the_schedule_answer_gives_every_task_with_its_dates_and_features() {
    let dir = tempfile::tempdir().unwrap();
    let server = Server::start(&build_tree(dir.path()));
    let doc = server.get_json("/api/v1/openapi.json");
    let url = server.url(&format!("/api/v1/scenes/{SCENE}/schedule"));
    let first = client().get(&url).send().unwrap();
    assert_eq!(first.status(), StatusCode::OK);
    let etag = first.headers()[ETAG].clone();
    let answer: Value = first.json().unwrap();
    assert_component(&doc, "Schedule", &answer);
    assert_eq!(answer["dates"], "planned");

    // Every task of the scene, in order, with the dates it was given.
    let scene = scene_json();
    let tasks = answer["tasks"].as_array().unwrap();
    let given = scene["tasks"].as_array().unwrap();
    assert_eq!(tasks.len(), given.len());
    let recorded = given
        .iter()
        .filter(|t| t.get("actual_start").is_some())
        .count();
    assert!(
        recorded > 0 && recorded < given.len(),
        "the fixture records some progress"
    );
    for (row, task) in tasks.iter().zip(given) {
        assert_eq!(row["id"], task["id"]);
        for field in ["actual_start", "actual_finish"] {
            assert_eq!(
                row.get(field).is_some(),
                task.get(field).is_some(),
                "{}",
                task["id"]
            );
        }
        // The objects by feature index, as the task answer names them.
        let one = server.get_json(&format!(
            "/api/v1/scenes/{SCENE}/tasks/{}",
            task["id"].as_str().unwrap()
        ));
        let indices: Vec<&Value> = one["objects"]
            .as_array()
            .unwrap()
            .iter()
            .map(|o| &o["index"])
            .collect();
        let listed: Vec<&Value> = row["objects"].as_array().unwrap().iter().collect();
        assert_eq!(listed, indices, "task {}", task["id"]);
        assert_eq!(one["actual_start"], row["actual_start"]);
    }

    // Revalidation: the same ETag is 304 with no body.
    let again = client()
        .get(&url)
        .header(IF_NONE_MATCH, etag.clone())
        .send()
        .unwrap();
    assert_eq!(again.status(), StatusCode::NOT_MODIFIED);
    assert_eq!(again.headers()[ETAG], etag);
    assert!(again.bytes().unwrap().is_empty());

    let bad = client().get(format!("{url}?time=3")).send().unwrap();
    assert_eq!(bad.status(), StatusCode::BAD_REQUEST);
    let body: Value = bad.json().unwrap();
    assert_eq!(body["error"]["field"], "time");
    let none = Server::sample(6);
    let missing = client()
        .get(none.url("/api/v1/scenes/sample-1/schedule"))
        .send()
        .unwrap();
    assert_eq!(missing.status(), StatusCode::NOT_FOUND);

    // The default profile when the scene has none: construct green and
    // half transparent while active, demolish hidden after.
    let profile = server.get_json(&format!("/api/v1/scenes/{SCENE}/appearance"));
    assert_component(&doc, "Appearance", &profile);
    assert_eq!(profile["name"], "default");
    assert_eq!(profile["types"]["construct"]["active"]["transparency"], 0.5);
    assert_eq!(profile["types"]["demolish"]["after"], "hidden");
}

/// A scene with its own profile, built on its actual dates: the tree keeps
/// both, and objects of tasks the record has not started are absent.
#[test]
fn a_scene_profile_and_actual_dates_reach_the_answers() {
    let mut scene = scene_json();
    scene["schedule_options"] = json!("actual");
    scene["appearance"] = json!({
        "format": "hdlod-appearance/1",
        "name": "site review",
        "types": {"construct": {"active": {"color": "#0000ff"}, "late": {"color": "#ff0000"}}}
    });
    let dir = tempfile::tempdir().unwrap();
    let server = Server::start(&build_scene(dir.path(), &scene));
    let doc = server.get_json("/api/v1/openapi.json");
    let profile = server.get_json(&format!("/api/v1/scenes/{SCENE}/appearance"));
    assert_component(&doc, "Appearance", &profile);
    assert_eq!(profile["name"], "site review");
    assert_eq!(profile["types"]["construct"]["late"]["color"], "#ff0000");
    // Types the profile leaves out keep the defaults.
    assert_eq!(profile["types"]["demolish"]["after"], "hidden");

    let schedule = server.get_json(&format!("/api/v1/scenes/{SCENE}/schedule"));
    assert_eq!(schedule["dates"], "actual");
    // A construct task the record never started leaves its objects absent
    // at the end; one it started has them present from the actual start.
    let presence = server.get_json(&format!("/api/v1/scenes/{SCENE}/presence"))["presence"].clone();
    let tasks = schedule["tasks"].as_array().unwrap();
    let construct = |recorded: bool| {
        tasks
            .iter()
            .find(|t| {
                t["type"] == "construct"
                    && t.get("actual_start").is_some() == recorded
                    && !t["objects"].as_array().unwrap().is_empty()
            })
            .unwrap_or_else(|| panic!("a construct task with recorded = {recorded}"))
    };
    let unstarted = construct(false);
    for i in unstarted["objects"].as_array().unwrap() {
        let tasks_of =
            server.get_json(&format!("/api/v1/scenes/{SCENE}/objects/{i}?by=index"))["tasks"]
                .clone();
        if tasks_of.as_array().unwrap().len() == 1 {
            assert_eq!(
                presence[i.as_u64().unwrap() as usize],
                json!([]),
                "object {i} is never built"
            );
        }
    }
    let started = construct(true);
    let i = started["objects"][0].as_u64().unwrap() as usize;
    let intervals = presence[i].as_array().unwrap();
    assert!(!intervals.is_empty());
    let first_start = intervals[0][0].as_f64();
    assert!(
        first_start.is_none()
            || first_start.unwrap() <= started["actual_start"].as_f64().unwrap() + 1e-6,
        "object {i} is present from its task's actual start: {intervals:?}"
    );
}

/// Tasks the schedule typed INSTALLATION and CONSTRUCTION both construct,
/// and keep their names through the tree: the answers give each task's IFC
/// type beside its type, and a profile's INSTALLATION looks reach the
/// profile answer apart from construct's.
#[test]
fn ifc_task_types_keep_their_names_through_the_tree() {
    let mut scene = scene_json();
    let tasks = scene["tasks"].as_array_mut().unwrap();
    let mut construct = tasks
        .iter_mut()
        .filter(|t| t["type"] == "construct" && !t["objects"].as_array().unwrap().is_empty());
    let installed = construct.next().unwrap();
    installed["type"] = json!("installation");
    let installed = installed["id"].as_str().unwrap().to_string();
    let built = construct.next().unwrap();
    built["type"] = json!("CONSTRUCTION");
    let built = built["id"].as_str().unwrap().to_string();
    scene["appearance"] = json!({
        "format": "hdlod-appearance/1",
        "types": {"INSTALLATION": {"active": {"color": "#0000ff"}}}
    });
    let dir = tempfile::tempdir().unwrap();
    let server = Server::start(&build_scene(dir.path(), &scene));
    let doc = server.get_json("/api/v1/openapi.json");

    let schedule = server.get_json(&format!("/api/v1/scenes/{SCENE}/schedule"));
    assert_component(&doc, "Schedule", &schedule);
    let find = |id: &str| {
        schedule["tasks"]
            .as_array()
            .unwrap()
            .iter()
            .find(|t| t["id"] == id)
            .unwrap()
            .clone()
    };
    for (id, ifc) in [(&installed, "INSTALLATION"), (&built, "CONSTRUCTION")] {
        let row = find(id);
        assert_eq!(
            (&row["type"], &row["ifc_type"]),
            (&json!("construct"), &json!(ifc))
        );
        let task = server.get_json(&format!("/api/v1/scenes/{SCENE}/tasks/{id}"));
        assert_component(&doc, "Task", &task);
        assert_eq!(task["ifc_type"], ifc, "{task}");
    }
    // Tasks the scene typed with our names have none.
    assert!(
        schedule["tasks"]
            .as_array()
            .unwrap()
            .iter()
            .filter(|t| t.get("ifc_type").is_some())
            .count()
            == 2
    );

    let profile = server.get_json(&format!("/api/v1/scenes/{SCENE}/appearance"));
    assert_component(&doc, "Appearance", &profile);
    assert_eq!(
        profile["types"]["INSTALLATION"]["active"]["color"],
        "#0000ff"
    );
    // The phases it leaves out are construct's; CONSTRUCTION has no entry.
    assert_eq!(profile["types"]["INSTALLATION"]["after"], "model");
    assert!(profile["types"].get("CONSTRUCTION").is_none(), "{profile}");
}
