//! The cut answer of a tree with a skinned object: a bar bending at its
//! middle joint beside a static box. Its clusters carry their joint
//! matrices at the requested time; the box's carry none. The stream sends
//! their change, and the web viewer draws the bar bent, and a walker of the
//! tiny site with its legs in their stride. A 3D Tiles slice's tile of it
//! holds its mesh posed at the slice's time.

mod common;

use std::collections::HashSet;

use glam::{Mat4, Vec3};
use hdlod::build::{BuildConfig, Silent, build_to};
use hdlod::scene::Scene;
use reqwest::StatusCode;
use serde_json::{Value, json};

use common::{
    SCENE, Server, assert_component, assert_content_type, assert_no_gltf_errors, assert_success,
    assert_valid, browser_driver, browser_ready, build_tree, client, hdlod, repo,
    skinned_bar_scene, tileset_validator,
};

/// The skinned bar's scene, its tree built in a temporary directory (also
/// kept there for other files) and served.
fn served_bar() -> (tempfile::TempDir, Scene, Server) {
    let dir = tempfile::tempdir().unwrap();
    let tree = dir.path().join("tree");
    let scene = skinned_bar_scene();
    build_to(&scene, &BuildConfig::default(), &tree, &Silent).unwrap();
    let server = Server::start(&tree);
    (dir, scene, server)
}

/// The cut request of the bar's tests at `t`.
fn view(t: f64) -> Value {
    json!({"time": t,
        "camera": {"position": [0.0, 2.0, 12.0], "target": [-1.0, 2.0, 0.0]},
        "viewport": {"width": 1280, "height": 720}, "pixel_error": 1.0})
}

/// The bar's joint matrices at `t`, as the answers write them.
fn matrices(scene: &Scene, t: f64) -> Vec<[f32; 16]> {
    let skin = scene.objects[0].skin.as_ref().unwrap();
    skin.matrices(t).iter().map(Mat4::to_cols_array).collect()
}

#[test]
fn a_skinned_cluster_s_answer_carries_its_joint_matrices() {
    let (_dir, scene, server) = served_bar();
    let doc = server.get_json("/api/v1/openapi.json");
    let mut answers = Vec::new();
    for t in [12.0, 19.0] {
        let cut = server.post_json("/api/v1/scenes/bar/cut", &view(t));
        assert_component(&doc, "CutResponse", &cut);
        let clusters = cut["clusters"].as_array().unwrap();
        let skinned: Vec<&Value> = clusters
            .iter()
            .filter(|c| c.get("joints").is_some())
            .collect();
        assert_eq!(skinned.len(), 1, "the bar, once: {cut}");
        let got: Vec<[f32; 16]> = serde_json::from_value(skinned[0]["joints"].clone()).unwrap();
        assert_eq!(got, matrices(&scene, t), "at {t}");
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

    let (_dir, scene, server) = served_bar();
    let doc = server.get_json("/api/v1/openapi.json");
    let ws_url = server
        .url("/api/v1/scenes/bar/stream")
        .replace("http://", "ws://");
    let matrices = |t: f64| matrices(&scene, t);
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
    let (dir, _scene, server) = served_bar();
    let shots = dir.path().join("shots");
    // Straight at 10 s, its top half turned 0.9 of a quarter towards the
    // camera at 19 s.
    let out = browser_driver(
        "skinned.mjs",
        &[
            server.base.as_ref(),
            "bar".as_ref(),
            shots.as_os_str(),
            "10".as_ref(),
            "19".as_ref(),
        ],
    );
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

/// The tiny site's walker seen side on in chromium at a heel strike, its
/// feet far apart, and three minutes later as its legs pass each other:
/// its pixels change by more than any shift of them explains, and its feet
/// close up. Drawn in its bind pose it would not change at all, and moved
/// whole (the pelvis's path alone) it would only shift.
#[test]
fn the_viewer_draws_a_walking_worker_s_legs_in_their_stride_in_chromium() {
    if !browser_ready() {
        return;
    }
    let scene = hdlod::scene::format::load(&repo().join("fixtures/skyscraper-tiny")).unwrap();
    let walker = scene
        .objects
        .iter()
        .find(|o| o.id == "WALKER-0")
        .expect("a walker on the tiny site");
    let skin = walker.skin.as_deref().expect("a skinned walker");
    let start = scene
        .tasks
        .iter()
        .find(|t| t.objects.contains(&walker.id))
        .expect("the walker's task")
        .start;
    // The soles, under the knee joints (2 and 4).
    let sole = |knee: usize, t: f64| {
        let below = Vec3::new(0.0, -hdlod_fixtures::models::WALKER_KNEE, 0.0);
        skin.joints[knee].pose(t).transform_point3(below)
    };
    let spread = |t: f64| sole(2, t).distance(sole(4, t));
    // Keys come every 3 minutes: of ten from 09:00 on its first day, the
    // one with its feet furthest apart, then the next.
    let t1 = (0..10)
        .map(|k| start + 2.0 * 3600.0 + 180.0 * f64::from(k))
        .max_by(|a, b| spread(*a).total_cmp(&spread(*b)))
        .unwrap();
    let t2 = t1 + 180.0;
    assert!(
        spread(t1) > spread(t2) + 0.3,
        "feet {} m apart, then {} m",
        spread(t1),
        spread(t2)
    );
    // From its side away from the tower, 4.5 m off, a little above.
    let pelvis = skin.joints[0].pose(t1);
    let at = pelvis.w_axis.truncate();
    let mut side = pelvis.transform_vector3(Vec3::Z).cross(Vec3::Y).normalize();
    if side.dot(at.with_y(0.0)) < 0.0 {
        side = -side;
    }
    let dir = tempfile::tempdir().unwrap();
    let tree = build_tree(dir.path());
    let server = Server::start(&tree);
    let feature = server.get_json(&format!("/api/v1/scenes/{SCENE}/objects/WALKER-0"))["index"]
        .as_u64()
        .unwrap();
    let shots = dir.path().join("shots");
    let out = browser_driver(
        "walker.mjs",
        &[
            server.base.clone(),
            SCENE.into(),
            shots.display().to_string(),
            feature.to_string(),
            t1.to_string(),
            t2.to_string(),
            format!("{},{},{}", at.x, at.y, at.z),
            "4.5".into(),
            side.z.atan2(side.x).to_string(),
            "0.15".into(),
        ],
    );
    // The walker's pixels, every third one, in cells of 3 x 3.
    let cells = |k: usize| -> HashSet<(i64, i64)> {
        out["shots"][k]["pixels"]
            .as_array()
            .unwrap_or_else(|| panic!("no pixels: {out:#}"))
            .iter()
            .map(|p| {
                let at = |i: usize| (p[i].as_f64().unwrap() / 3.0).floor() as i64;
                (at(0), at(1))
            })
            .collect()
    };
    let (a, b) = (cells(0), cells(1));
    // 1.8 m at 4.5 m is about 200 pixels tall, some 400 cells.
    assert!(
        a.len() > 200 && b.len() > 200,
        "the walker in view: {} and {} cells",
        a.len(),
        b.len()
    );
    // The most cells a shift of the first picture lays on the second.
    let overlap = (-30..=30)
        .flat_map(|dx| (-30..=30).map(move |dy| (dx, dy)))
        .map(|(dx, dy)| {
            a.iter()
                .filter(|(x, y)| b.contains(&(x + dx, y + dy)))
                .count()
        })
        .max()
        .unwrap();
    let unexplained = a.len() + b.len() - 2 * overlap;
    assert!(
        unexplained * 5 > a.len().min(b.len()),
        "{unexplained} cells of {} and {} differ after the best shift",
        a.len(),
        b.len()
    );
    // Across the lowest quarter of the walker: its feet.
    let feet = |s: &HashSet<(i64, i64)>| {
        let (top, bottom) = s.iter().fold((i64::MAX, i64::MIN), |(lo, hi), c| {
            (lo.min(c.1), hi.max(c.1))
        });
        let xs: Vec<i64> = s
            .iter()
            .filter(|c| c.1 * 4 >= top + 3 * bottom)
            .map(|c| c.0)
            .collect();
        xs.iter().max().unwrap() - xs.iter().min().unwrap()
    };
    assert!(
        feet(&a) * 2 > feet(&b) * 3,
        "the feet span {} cells, then {}",
        feet(&a),
        feet(&b)
    );
    assert!(out["diff"]["differ"].as_u64().unwrap() > 500, "{out:#}");
}

/// Every tile of a tileset with content: `(cluster, uri)`, depth first.
fn content_tiles(tile: &Value, out: &mut Vec<(u64, String)>) {
    if let Some(uri) = tile["content"]["uri"].as_str() {
        out.push((tile["extras"]["cluster"].as_u64().unwrap(), uri.to_owned()));
    }
    for child in tile["children"].as_array().into_iter().flatten() {
        content_tiles(child, out);
    }
}

/// The largest distance from a vertex of `mesh` to the nearest of `to`.
fn farthest(mesh: &hdlod::geometry::Mesh, to: &hdlod::geometry::Mesh) -> f32 {
    mesh.positions
        .iter()
        .map(|p| {
            to.positions
                .iter()
                .map(|q| p.distance(*q))
                .fold(f32::INFINITY, f32::min)
        })
        .fold(0.0, f32::max)
}

/// A slice's skinned tile is served posed at the slice's time, under a URL
/// of that time, and `hdlod export-tiles` writes the same; its rigid tiles
/// name their content as before.
#[test]
fn a_slice_s_skinned_tile_is_its_mesh_posed_at_the_slice_s_time() {
    let validator = tileset_validator();
    let (dir, scene, server) = served_bar();
    let tree = dir.path().join("tree");
    let doc = server.get_json("/api/v1/openapi.json");
    assert!(
        doc["paths"]
            .get("/api/v1/scenes/{scene}/tiles/posed/{version}/{time}/{id}.glb")
            .is_some()
    );
    let http = client();
    let tiles = |rest: &str| server.url(&format!("/api/v1/scenes/bar/tiles/{rest}"));
    let skin = scene.objects[0].skin.as_ref().unwrap();
    let read = |bytes: &[u8], name: &str| {
        let file = dir.path().join(name);
        std::fs::write(&file, bytes).unwrap();
        (hdlod::io::read_mesh(&file).unwrap(), file)
    };
    let mut posed = Vec::new();
    let mut files = Vec::new();
    let mut rigid_uris = Vec::new();
    let mut skinned_id = 0;
    let mut version = String::new();
    for t in [12.0, 19.0] {
        let tileset: Value = http
            .get(tiles(&format!("{t}.json")))
            .send()
            .unwrap()
            .json()
            .unwrap();
        if let Some(v) = &validator {
            assert_valid(v, &tileset, &format!("the slice at {t} s"));
        }
        let mut named = Vec::new();
        content_tiles(&tileset["root"], &mut named);
        let (skinned, rigid): (Vec<_>, Vec<_>) = named
            .into_iter()
            .partition(|(_, uri)| uri.starts_with("posed/"));
        // The finest level of the bar: the one with the most vertices.
        let mut best: Option<(hdlod::geometry::Mesh, u64)> = None;
        for (id, uri) in &skinned {
            let parts: Vec<&str> = uri.split('/').collect();
            assert_eq!(parts[2..], [t.to_string(), format!("{id}.glb")], "{uri}");
            version = parts[1].to_owned();
            let answer = http.get(tiles(uri)).send().unwrap();
            assert_eq!(answer.status(), StatusCode::OK, "{uri}");
            assert_content_type(&answer, "model/gltf-binary");
            let cache = answer.headers()["cache-control"]
                .to_str()
                .unwrap()
                .to_owned();
            assert!(cache.contains("immutable"), "{cache}");
            let etag = answer.headers()["etag"].clone();
            let glb = answer.bytes().unwrap();
            let again = http
                .get(tiles(uri))
                .header("If-None-Match", etag)
                .send()
                .unwrap();
            assert_eq!(again.status(), StatusCode::NOT_MODIFIED, "{uri}");
            let (mesh, file) = read(&glb, &format!("{t}-{id}.glb"));
            // Every vertex is one of the scene's bar posed at t.
            let far = farthest(&mesh, &skin.pose(&scene.meshes[1], t));
            assert!(far < 1e-4, "{uri}: {far} from the posed bar");
            files.push(file);
            if best
                .as_ref()
                .is_none_or(|b| b.0.positions.len() < mesh.positions.len())
            {
                best = Some((mesh, *id));
            }
        }
        let (mesh, id) = best.unwrap_or_else(|| panic!("no skinned tile at {t}: {tileset}"));
        skinned_id = id;
        posed.push(mesh);
        // Rigid tiles name the same content at every date, as before.
        assert!(!rigid.is_empty(), "the box at {t}");
        for (id, uri) in &rigid {
            assert_eq!(*uri, format!("content/{version}/{id}.glb"));
        }
        rigid_uris.push(rigid);
    }
    assert_eq!(rigid_uris[0], rigid_uris[1]);
    assert!(
        farthest(&posed[0], &posed[1]) > 0.5,
        "the bar's top turned between the two times"
    );
    let reports = assert_no_gltf_errors(&files);
    for report in &reports {
        // Plain glTF: no skin for a client to apply a second time.
        assert_eq!(report["info"]["hasSkins"], false, "{report}");
        assert_eq!(report["info"]["maxInfluences"], 0, "{report}");
    }

    // With state, the skinned tile's content is the slice's own, posed too.
    let status: Value = http
        .get(tiles("19.json?status=true"))
        .send()
        .unwrap()
        .json()
        .unwrap();
    let mut named = Vec::new();
    content_tiles(&status["root"], &mut named);
    let uri = format!("19/content/{skinned_id}.glb");
    assert!(named.iter().any(|(_, u)| *u == uri), "{named:?}");
    let answer = http.get(tiles(&uri)).send().unwrap();
    assert_eq!(answer.status(), StatusCode::OK, "{uri}");
    let (mesh, _) = read(&answer.bytes().unwrap(), "status.glb");
    assert_eq!(mesh.positions, posed[1].positions);

    // The export writes it where its tileset names it.
    let out = dir.path().join("export");
    assert_success(&hdlod(&[
        "export-tiles".as_ref(),
        tree.as_os_str(),
        "--time".as_ref(),
        "19".as_ref(),
        "--out".as_ref(),
        out.as_os_str(),
    ]));
    let exported: Value =
        serde_json::from_slice(&std::fs::read(out.join("tileset.json")).unwrap()).unwrap();
    let mut named = Vec::new();
    content_tiles(&exported["root"], &mut named);
    let uri = format!("content/19/{skinned_id}.glb");
    assert!(named.iter().any(|(_, u)| *u == uri), "{named:?}");
    let mesh = hdlod::io::read_mesh(&out.join(&uri)).unwrap();
    assert_eq!(mesh.positions, posed[1].positions);

    // Bad times and clusters get a 4xx naming the field.
    let error = |rest: &str, status: StatusCode, field: &str| {
        let answer = http.get(tiles(rest)).send().unwrap();
        assert_eq!(answer.status(), status, "{rest}");
        let body: Value = answer.json().unwrap();
        assert_eq!(body["error"]["field"], field, "{rest}: {body}");
    };
    let id = skinned_id;
    error(
        &format!("posed/{version}/soon/{id}.glb"),
        StatusCode::NOT_FOUND,
        "time",
    );
    error(
        &format!("posed/{version}/1e300/{id}.glb"),
        StatusCode::BAD_REQUEST,
        "time",
    );
    error(
        &format!("posed/{version}/inf/{id}.glb"),
        StatusCode::NOT_FOUND,
        "time",
    );
    error(
        &format!("posed/0123456789abcdef/12/{id}.glb"),
        StatusCode::NOT_FOUND,
        "version",
    );
    error(
        &format!("posed/{version}/12/x.glb"),
        StatusCode::NOT_FOUND,
        "cluster",
    );
    let (rigid, _) = &rigid_uris[0][0];
    error(
        &format!("posed/{version}/12/{rigid}.glb"),
        StatusCode::NOT_FOUND,
        "cluster",
    );
}
