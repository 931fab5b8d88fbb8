//! `hdlod::scene::format::load` on any `scene.json` beside a valid model.
#![no_main]

#[path = "input.rs"]
mod input;

use std::sync::OnceLock;

use libfuzzer_sys::fuzz_target;

/// A one-triangle model (`tri.gltf`, node "tri") beside the `scene.json`
/// each input replaces.
fn scene_dir() -> &'static std::path::Path {
    static DIR: OnceLock<std::path::PathBuf> = OnceLock::new();
    DIR.get_or_init(|| {
        let dir = input::dir().join("scene");
        std::fs::create_dir_all(&dir).unwrap();
        let model = serde_json::json!({
            "asset": {"version": "2.0"},
            "buffers": [{"byteLength": 36,
                "uri": "data:application/octet-stream;base64,AAAAAAAAAAAAAAAAAACAPwAAAAAAAAAAAAAAAAAAgD8AAAAA"}],
            "bufferViews": [{"buffer": 0, "byteLength": 36}],
            "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
                           "min": [0, 0, 0], "max": [1, 1, 0]}],
            "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}],
            "nodes": [{"name": "tri", "mesh": 0}],
            "scenes": [{"nodes": [0]}],
            "scene": 0
        });
        std::fs::write(dir.join("tri.gltf"), model.to_string()).unwrap();
        dir
    })
}

fuzz_target!(|data: &[u8]| {
    let dir = scene_dir();
    std::fs::write(dir.join("scene.json"), data).unwrap();
    let _ = hdlod::scene::format::load(dir);
});
