//! Time slices as 3D Tiles 1.1 from the real server and `hdlod export-tiles`
//! on the tree of the tiny fixture: every tileset file follows the official
//! schemas, every content GLB passes the Khronos glTF validator, the served
//! and the exported slices are the same (these need the schemas of the test
//! data), bad requests get a 4xx naming the field.

mod common;

use std::path::Path;

use common::{
    SCENE, Server, assert_content_type, assert_no_gltf_errors, assert_success, assert_valid,
    build_tree, client, hdlod, tileset_validator,
};
use reqwest::StatusCode;
use serde_json::Value;

fn tiles_path(query: &str) -> String {
    format!("/api/v1/scenes/{SCENE}/tiles/tileset.json{query}")
}

/// Every `content.uri` of a tileset, depth first.
fn uris(tile: &Value, out: &mut Vec<String>) {
    if let Some(uri) = tile["content"]["uri"].as_str() {
        out.push(uri.to_owned());
    }
    for child in tile["children"].as_array().into_iter().flatten() {
        uris(child, out);
    }
}

#[test]
fn served_slices_follow_the_schemas() {
    let Some(validator) = tileset_validator() else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let server = Server::start(&build_tree(dir.path()));
    let http = client();
    let doc = server.get_json("/api/v1/openapi.json");
    for path in [
        "/api/v1/scenes/{scene}/tiles/tileset.json",
        "/api/v1/scenes/{scene}/tiles/{time}.json",
        "/api/v1/scenes/{scene}/tiles/{time}/{id}.json",
        "/api/v1/scenes/{scene}/tiles/content/{version}/{id}.glb",
        "/api/v1/scenes/{scene}/tiles/{time}/content/{id}.glb",
    ] {
        assert!(doc["paths"].get(path).is_some(), "{path} documented");
    }
    // Content URIs of every date, to find those dates share.
    let mut seen: Vec<Vec<String>> = Vec::new();
    for time in ["0", "2024-05-03T05:40:00Z", "2024-06-15", "15613200"] {
        let answer = http
            .get(server.url(&tiles_path(&format!("?time={time}"))))
            .send()
            .unwrap();
        assert_eq!(answer.status(), StatusCode::OK, "time {time}");
        assert_content_type(&answer, "application/json");
        let etag = answer.headers()["etag"].clone();
        let again = http
            .get(server.url(&tiles_path(&format!("?time={time}"))))
            .header("If-None-Match", etag)
            .send()
            .unwrap();
        assert_eq!(again.status(), StatusCode::NOT_MODIFIED, "time {time}");
        let tileset: Value = answer.json().unwrap();
        assert_valid(&validator, &tileset, time);
        // The same file with the time in its path, beside it.
        let at: Value = http
            .get(server.url(&format!("/api/v1/scenes/{SCENE}/tiles/{time}.json")))
            .send()
            .unwrap()
            .json()
            .unwrap();
        assert_eq!(at, tileset, "tiles/{time}.json");
        assert_eq!(tileset["root"]["refine"], "REPLACE");
        assert!(
            tileset["asset"].get("tilesetVersion").is_none(),
            "no per-date content URLs in Cesium"
        );
        // Content resolves to content the same at every date, which is
        // served as immutable.
        let mut content = Vec::new();
        uris(&tileset["root"], &mut content);
        if time != "0" {
            assert!(!content.is_empty(), "time {time}: the site has content");
        }
        for uri in content.iter().take(3) {
            assert!(uri.starts_with("content/"), "{uri}");
            let url = server.url(&format!("/api/v1/scenes/{SCENE}/tiles/{uri}"));
            let glb = http.get(&url).send().unwrap();
            assert_eq!(glb.status(), StatusCode::OK, "{uri}");
            assert_content_type(&glb, "model/gltf-binary");
            let cache = glb.headers()["cache-control"].to_str().unwrap();
            assert!(cache.contains("immutable"), "{cache}");
            let etag = glb.headers()["etag"].clone();
            let again = http.get(&url).header("If-None-Match", etag).send().unwrap();
            assert_eq!(again.status(), StatusCode::NOT_MODIFIED, "{uri}");
        }
        seen.push(content);
    }
    // Later dates name many of the GLBs earlier ones named, by the same
    // URLs.
    let shared = seen[3].iter().filter(|u| seen[2].contains(u)).count();
    assert!(
        shared * 2 > seen[2].len(),
        "{shared} of {} shared",
        seen[2].len()
    );
}

#[test]
fn bad_tile_requests_name_the_field() {
    let dir = tempfile::tempdir().unwrap();
    let server = Server::start(&build_tree(dir.path()));
    let http = client();
    let error = |path: &str, status: StatusCode, field: &str| {
        let answer = http.get(server.url(path)).send().unwrap();
        assert_eq!(answer.status(), status, "{path}");
        let body: Value = answer.json().unwrap();
        assert_eq!(body["error"]["field"], field, "{path}: {body}");
    };
    error(&tiles_path(""), StatusCode::BAD_REQUEST, "time");
    error(
        &tiles_path("?time=yesterday"),
        StatusCode::BAD_REQUEST,
        "time",
    );
    error(&tiles_path("?time=1e300"), StatusCode::BAD_REQUEST, "time");
    error(
        &tiles_path("?time=0&camera=1"),
        StatusCode::BAD_REQUEST,
        "camera",
    );
    error(
        "/api/v1/scenes/nowhere/tiles/tileset.json?time=0",
        StatusCode::NOT_FOUND,
        "scene",
    );
    let sub = |rest: &str| format!("/api/v1/scenes/{SCENE}/tiles/{rest}");
    error(&sub("yesterday.json"), StatusCode::BAD_REQUEST, "time");
    error(&sub("0.json?time=0"), StatusCode::BAD_REQUEST, "time");
    error(&sub("0.json?camera=1"), StatusCode::BAD_REQUEST, "camera");
    error(&sub("0.glb"), StatusCode::NOT_FOUND, "time");
    error(&sub("5204400/0.json"), StatusCode::NOT_FOUND, "subtree");
    error(&sub("5204400/x.json"), StatusCode::NOT_FOUND, "subtree");
    error(&sub("soon/1.json"), StatusCode::NOT_FOUND, "time");
    error(&sub("status-soon/1.json"), StatusCode::NOT_FOUND, "time");
    error(
        &tiles_path("?time=0&status=maybe"),
        StatusCode::BAD_REQUEST,
        "status",
    );
    error(
        &sub("content/0123456789abcdef/1.glb"),
        StatusCode::NOT_FOUND,
        "version",
    );
}

fn export(tree: &Path, time: &str, out: &Path, max_bytes: Option<&str>) -> std::process::Output {
    let mut args: Vec<&std::ffi::OsStr> = vec![
        "export-tiles".as_ref(),
        tree.as_os_str(),
        "--time".as_ref(),
        time.as_ref(),
        "--out".as_ref(),
        out.as_os_str(),
    ];
    if let Some(m) = max_bytes {
        args.push("--max-bytes".as_ref());
        args.push(m.as_ref());
    }
    hdlod(&args)
}

fn read_json(path: &Path) -> Value {
    serde_json::from_slice(&std::fs::read(path).unwrap()).unwrap()
}

#[test]
fn exported_slices_match_the_served_ones_and_pass_the_validators() {
    let Some(validator) = tileset_validator() else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let tree = build_tree(dir.path());
    let time = "2024-05-03T05:40:00Z";

    // A small budget forces external tilesets on the tiny tree.
    let split = dir.path().join("out/split");
    assert_success(&export(&tree, time, &split, Some("16000")));
    let mut files = vec![split.join("tileset.json")];
    for entry in std::fs::read_dir(split.join("tilesets")).unwrap() {
        files.push(entry.unwrap().path());
    }
    assert!(files.len() > 2, "external tilesets written: {files:?}");
    let mut glbs = Vec::new();
    for file in &files {
        let bytes = std::fs::metadata(file).unwrap().len();
        assert!(bytes <= 16000, "{}: {bytes} bytes", file.display());
        let tileset = read_json(file);
        assert_valid(&validator, &tileset, &file.display().to_string());
        let mut content = Vec::new();
        uris(&tileset["root"], &mut content);
        for uri in content {
            // Every URI resolves to a file of the export.
            let target = file.parent().unwrap().join(&uri);
            assert!(target.is_file(), "{}: {uri}", file.display());
            if uri.ends_with(".glb") {
                glbs.push(target.canonicalize().unwrap());
            }
        }
    }
    glbs.sort();
    glbs.dedup();
    let written = std::fs::read_dir(split.join("content")).unwrap().count();
    assert_eq!(glbs.len(), written, "exactly the content GLBs are written");
    assert!(written > 100);
    for report in assert_no_gltf_errors(&glbs) {
        assert!(report["info"]["drawCallCount"].as_u64().unwrap() >= 1);
    }

    // Unsplit, the export is the served tileset with its GLBs beside it.
    let whole = dir.path().join("out/whole");
    assert!(export(&tree, time, &whole, None).status.success());
    let server = Server::start(&tree);
    let served = server.get_json(&tiles_path(&format!("?time={time}")));
    let on_disk = read_json(&whole.join("tileset.json"));
    let mut content = Vec::new();
    uris(&served["root"], &mut content);
    let version = content[0].split('/').nth(1).unwrap().to_owned();
    let served = serde_json::to_string(&served)
        .unwrap()
        .replace(&format!("\"content/{version}/"), "\"content/");
    assert_eq!(served, serde_json::to_string(&on_disk).unwrap());

    // A second export replaces the first whole, leaving nothing beside it.
    assert!(export(&tree, "0", &whole, None).status.success());
    assert!(read_json(&whole.join("tileset.json"))["root"]["children"].is_array());
    let names: Vec<String> = std::fs::read_dir(dir.path().join("out"))
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    assert_eq!(names.len(), 2, "{names:?}");

    // Bad input: the message names the argument, the old export stays.
    let bad = export(&tree, "someday", &whole, None);
    assert!(!bad.status.success());
    let stderr = String::from_utf8_lossy(&bad.stderr);
    assert!(stderr.contains("--time"), "{stderr}");
    let far = export(&tree, "1e13", &whole, None);
    let stderr = String::from_utf8_lossy(&far.stderr);
    assert!(
        stderr.contains("--time: is too far from the scene's period"),
        "{stderr}"
    );
    assert!(whole.join("tileset.json").is_file());
    let missing = export(&dir.path().join("no-tree"), "0", &whole, None);
    assert!(!missing.status.success());
    assert!(String::from_utf8_lossy(&missing.stderr).contains("no-tree"));
}

/// The JSON and binary chunks of a GLB.
fn glb_chunks(bytes: &[u8]) -> (Value, Vec<u8>) {
    let u32_at = |i: usize| u32::from_le_bytes(bytes[i..i + 4].try_into().unwrap()) as usize;
    let json_len = u32_at(12);
    let json: Value = serde_json::from_slice(&bytes[20..20 + json_len]).unwrap();
    let bin_at = 20 + json_len;
    let bin = if bin_at < bytes.len() {
        let len = u32_at(bin_at);
        bytes[bin_at + 8..bin_at + 8 + len].to_vec()
    } else {
        Vec::new()
    };
    (json, bin)
}

/// Column `name` of the GLB's property table, as strings (numbers and
/// booleans printed).
fn column(json: &Value, bin: &[u8], name: &str) -> Vec<String> {
    let ext = &json["extensions"]["EXT_structural_metadata"];
    let table = &ext["propertyTables"][0];
    let count = table["count"].as_u64().unwrap() as usize;
    let class = table["class"].as_str().unwrap();
    let kind = &ext["schema"]["classes"][class]["properties"][name];
    let view = |i: &Value| {
        let v = &json["bufferViews"][i.as_u64().unwrap() as usize];
        let at = v["byteOffset"].as_u64().unwrap_or(0) as usize;
        assert_eq!(at % 8, 0, "property values start 8-byte aligned");
        &bin[at..at + v["byteLength"].as_u64().unwrap() as usize]
    };
    let p = &table["properties"][name];
    let values = view(&p["values"]);
    let word = |b: &[u8], i: usize| u32::from_le_bytes(b[4 * i..4 * i + 4].try_into().unwrap());
    (0..count)
        .map(|i| {
            match (
                kind["type"].as_str().unwrap(),
                kind["componentType"].as_str(),
            ) {
                ("STRING", _) => {
                    let offsets = view(&p["stringOffsets"]);
                    let (a, b) = (word(offsets, i) as usize, word(offsets, i + 1) as usize);
                    String::from_utf8(values[a..b].to_vec()).unwrap()
                }
                ("SCALAR", Some("UINT32")) => word(values, i).to_string(),
                ("SCALAR", Some("FLOAT32")) => f32::from_bits(word(values, i)).to_string(),
                ("BOOLEAN", _) => ((values[i / 8] >> (i % 8)) & 1 == 1).to_string(),
                other => panic!("unexpected property type {other:?}"),
            }
        })
        .collect()
}

/// Content carries each element's properties, and with `status=true` the
/// slice's its task status and look at its time, renumbered per tile with
/// the scene-wide index kept, as the object and task answers give them.
#[test]
fn slice_content_carries_the_elements_task_status() {
    let dir = tempfile::tempdir().unwrap();
    let server = Server::start(&build_tree(dir.path()));
    let http = client();
    // A time inside a construct task on its planned dates.
    let schedule = server.get_json(&format!("/api/v1/scenes/{SCENE}/schedule"));
    let task = schedule["tasks"]
        .as_array()
        .unwrap()
        .iter()
        .find(|t| t["type"] == "construct" && t["objects"].as_array().unwrap().len() > 3)
        .unwrap();
    let t = (task["start"].as_f64().unwrap() + task["finish"].as_f64().unwrap()) / 2.0;
    // The default: the same at every date, no state.
    let tileset = server.get_json(&tiles_path(&format!("?time={t}")));
    let mut content = Vec::new();
    uris(&tileset["root"], &mut content);
    let bytes = http
        .get(server.url(&format!("/api/v1/scenes/{SCENE}/tiles/{}", content[0])))
        .send()
        .unwrap()
        .bytes()
        .unwrap();
    let (json, bin) = glb_chunks(&bytes);
    let properties = &json["extensions"]["EXT_structural_metadata"]["schema"]["classes"]["element"]
        ["properties"];
    for name in [
        "id",
        "index",
        "name",
        "class",
        "storey",
        "task",
        "task_name",
    ] {
        assert!(properties.get(name).is_some(), "{name}: {properties}");
    }
    assert!(properties.get("status").is_none(), "{properties}");
    let first = column(&json, &bin, "index")[0].clone();
    let object = server.get_json(&format!("/api/v1/scenes/{SCENE}/objects/{first}?by=index"));
    assert_eq!(column(&json, &bin, "id")[0], object["id"].as_str().unwrap());
    assert_eq!(
        column(&json, &bin, "name")[0],
        object["name"].as_str().unwrap_or_default()
    );

    let tileset = server.get_json(&tiles_path(&format!("?time={t}&status=true")));
    let mut content = Vec::new();
    uris(&tileset["root"], &mut content);
    let (mut rows, mut active) = (0, 0);
    for uri in &content {
        let bytes = http
            .get(server.url(&format!("/api/v1/scenes/{SCENE}/tiles/{uri}")))
            .send()
            .unwrap()
            .bytes()
            .unwrap();
        let (json, bin) = glb_chunks(&bytes);
        assert!(
            json["extensionsUsed"]
                .as_array()
                .unwrap()
                .contains(&"EXT_structural_metadata".into())
        );
        let ids =
            &json["meshes"][0]["primitives"][0]["extensions"]["EXT_mesh_features"]["featureIds"][0];
        assert_eq!(ids["propertyTable"], 0);
        let index = column(&json, &bin, "index");
        assert_eq!(ids["featureCount"].as_u64().unwrap() as usize, index.len());
        let (status, task_ids, color) = (
            column(&json, &bin, "status"),
            column(&json, &bin, "task"),
            column(&json, &bin, "color"),
        );
        let (transparency, show) = (
            column(&json, &bin, "transparency"),
            column(&json, &bin, "show"),
        );
        for r in 0..index.len() {
            rows += 1;
            if task_ids[r] != task["id"].as_str().unwrap() {
                continue;
            }
            active += 1;
            // The default profile: construct in progress is green, half
            // transparent.
            assert_eq!(status[r], "in_progress", "{uri} row {r}");
            assert_eq!(
                (
                    color[r].as_str(),
                    transparency[r].as_str(),
                    show[r].as_str()
                ),
                ("#2fb344", "0.5", "true")
            );
            let object = server.get_json(&format!(
                "/api/v1/scenes/{SCENE}/objects/{}?by=index&time={t}",
                index[r]
            ));
            let listed: Vec<&Value> = object["tasks"]
                .as_array()
                .unwrap()
                .iter()
                .map(|k| &k["id"])
                .collect();
            assert!(
                listed.contains(&&task["id"]),
                "object {} is the task's",
                index[r]
            );
        }
    }
    assert!(rows > 50, "{rows} elements in the slice");
    assert!(active > 0, "the task's elements are in the slice");
}
