//! The cut answer of a tree with a skinned object: a bar bending at its
//! middle joint beside a static box. Its clusters carry their joint
//! matrices at the requested time; the box's carry none. The stream sends
//! their change, and the web viewer draws the bar bent.

mod common;

use glam::Mat4;
use hdlod::build::{BuildConfig, Silent, build_to};
use serde_json::{Value, json};

use common::{Server, assert_component, browser_ready, repo, skinned_bar_scene};

#[test]
fn a_skinned_cluster_s_answer_carries_its_joint_matrices() {
    let dir = tempfile::tempdir().unwrap();
    let tree = dir.path().join("tree");
    let scene = skinned_bar_scene();
    build_to(&scene, &BuildConfig::default(), &tree, &Silent).unwrap();
    let server = Server::start(&tree);
    let doc = server.get_json("/api/v1/openapi.json");
    let skin = scene.objects[0].skin.as_ref().unwrap();
    let mut answers = Vec::new();
    for t in [12.0, 19.0] {
        let body = json!({"time": t,
            "camera": {"position": [0.0, 2.0, 12.0], "target": [-1.0, 2.0, 0.0]},
            "viewport": {"width": 1280, "height": 720}, "pixel_error": 1.0});
        let cut = server.post_json("/api/v1/scenes/bar/cut", &body);
        assert_component(&doc, "CutResponse", &cut);
        let clusters = cut["clusters"].as_array().unwrap();
        let skinned: Vec<&Value> = clusters
            .iter()
            .filter(|c| c.get("joints").is_some())
            .collect();
        assert_eq!(skinned.len(), 1, "the bar, once: {cut}");
        let expected: Vec<[f32; 16]> = skin.matrices(t).iter().map(Mat4::to_cols_array).collect();
        let got: Vec<[f32; 16]> = serde_json::from_value(skinned[0]["joints"].clone()).unwrap();
        assert_eq!(got, expected, "at {t}");
        assert_eq!(skinned[0]["class"], "dynamic");
        // The box is drawn, and rigid.
        assert!(clusters.iter().any(|c| c["class"] == "static"), "{cut}");
        // GET answers the same.
        let get = server.get_json(&format!(
            "/api/v1/scenes/bar/cut?time={t}&position=0,2,12&target=-1,2,0&viewport=1280x720&pixel_error=1"
        ));
        assert_eq!(get["clusters"], cut["clusters"]);
        answers.push(got);
    }
    assert_ne!(answers[0], answers[1]);
}

#[test]
fn the_stream_sends_a_kept_skinned_cluster_s_new_joints() {
    use futures_util::{SinkExt, StreamExt};
    use tokio_tungstenite::tungstenite::Message;

    let dir = tempfile::tempdir().unwrap();
    let tree = dir.path().join("tree");
    let scene = skinned_bar_scene();
    build_to(&scene, &BuildConfig::default(), &tree, &Silent).unwrap();
    let server = Server::start(&tree);
    let doc = server.get_json("/api/v1/openapi.json");
    let skin = scene.objects[0].skin.as_ref().unwrap();
    let ws_url = server
        .url("/api/v1/scenes/bar/stream")
        .replace("http://", "ws://");
    let view = |t: f64| {
        json!({"time": t,
            "camera": {"position": [0.0, 2.0, 12.0], "target": [-1.0, 2.0, 0.0]},
            "viewport": {"width": 1280, "height": 720}, "pixel_error": 1.0})
    };
    let matrices =
        |t: f64| -> Vec<[f32; 16]> { skin.matrices(t).iter().map(Mat4::to_cols_array).collect() };
    tokio::runtime::Runtime::new().unwrap().block_on(async {
        let (mut socket, _) = tokio_tungstenite::connect_async(&ws_url).await.unwrap();
        let mut ask = async |t: f64| -> Value {
            socket
                .send(Message::text(view(t).to_string()))
                .await
                .unwrap();
            let Some(Ok(Message::Text(text))) = socket.next().await else {
                panic!("no answer at {t}")
            };
            let message: Value = serde_json::from_str(text.as_str()).unwrap();
            assert_component(&doc, "StreamMessage", &message);
            message
        };
        let first = ask(12.0).await;
        let added: Vec<&Value> = first["add"]
            .as_array()
            .unwrap()
            .iter()
            .filter(|c| c.get("joints").is_some())
            .collect();
        assert_eq!(added.len(), 1, "the bar, once: {first}");
        let id = added[0]["id"].clone();
        let got: Vec<[f32; 16]> = serde_json::from_value(added[0]["joints"].clone()).unwrap();
        assert_eq!(got, matrices(12.0));

        // The same view later: the bar is kept, its joints bent further.
        let second = ask(19.0).await;
        assert_eq!(second["add"], json!([]), "{second}");
        let updates = second["update"].as_array().unwrap();
        let bar: Vec<&Value> = updates.iter().filter(|u| u["id"] == id).collect();
        assert_eq!(bar.len(), 1, "the bar's new pose: {second}");
        let got: Vec<[f32; 16]> = serde_json::from_value(bar[0]["joints"].clone()).unwrap();
        assert_eq!(got, matrices(19.0));
        assert_ne!(matrices(12.0), matrices(19.0));

        // Asked again at the same time, nothing changed: nothing is sent.
        let third = ask(19.0).await;
        assert_eq!(third["update"], json!([]), "{third}");
    });
}

#[test]
fn the_viewer_draws_a_skinned_cluster_in_its_pose_in_chromium() {
    if !browser_ready() {
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let tree = dir.path().join("tree");
    build_to(&skinned_bar_scene(), &BuildConfig::default(), &tree, &Silent).unwrap();
    let server = Server::start(&tree);
    let shots = dir.path().join("shots");
    // Straight at 10 s, its top half turned 0.9 of a quarter towards the
    // camera at 19 s.
    let run = std::process::Command::new("node")
        .arg(repo().join("tools/browser/skinned.mjs"))
        .args([server.base.as_str(), "bar"])
        .arg(&shots)
        .args(["10", "19"])
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
    assert_eq!(out["errors"], json!([]), "{out:#}");
    let (straight, bent) = (&out["shots"][0], &out["shots"][1]);
    // The same clusters at both times: only the pose moved the pixels.
    assert_eq!(straight["ids"], bent["ids"], "{out:#}");
    let top = |s: &Value| {
        s["top"]
            .as_f64()
            .unwrap_or_else(|| panic!("no bar: {out:#}"))
    };
    // At 10 m and 60 degrees of view over 600 pixels, the bar's top 2 m
    // stand about 100 pixels over its joint; turned towards the camera they
    // stand 0.3 m (and come 2 m nearer, which makes them look a little
    // taller). Drawn in its bind pose the top would not move at all.
    assert!(
        top(bent) > top(straight) + 50.0,
        "the bent bar's top row {} against the straight one's {}: {out:#}",
        top(bent),
        top(straight)
    );
    assert!(
        f64::from(out["diff"]["differ"].as_u64().unwrap() as u32) > 500.0,
        "{out:#}"
    );
}
