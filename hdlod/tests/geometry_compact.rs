//! The compact GLB form (`hdlod::io::compact`): what is written reads back
//! within the quantization's error (normals, colours, texture coordinates;
//! positions within the allowance given, the move answered) and exactly
//! (positions without an allowance, feature ids, the texture's PNG, the
//! triangles in order, each with its winding), corner by corner: vertices
//! that no stored value tells apart are stored once; the
//! plain form derived from it is today's `f32` GLB; both pass the Khronos
//! glTF validator; a tree stores the compact form under the hash of its
//! bytes.

mod common;

use std::path::PathBuf;

use common::assert_no_gltf_errors;
use glam::{Vec2, Vec3};
use hdlod::geometry::Mesh;
use hdlod::geometry::bake::Atlas;
use hdlod::io::compact;
use hdlod::io::glb::{Encoding, compact_mesh_to_glb, encoded_mesh_to_glb, mesh_to_glb};
use hdlod::io::texture::{Texture, encode_png};

/// Two boxes of two objects far from the origin (as a georeferenced site's
/// clusters are), with colours.
fn two_objects() -> Mesh {
    let mut a = Mesh::cuboid(
        Vec3::new(1000.0, 2000.0, 5.0),
        Vec3::new(1012.5, 2003.0, 9.25),
        3,
    );
    a.features = vec![7; a.positions.len()];
    a.colors = vec![[0.8, 0.2, 0.1, 1.0]; a.positions.len()];
    let mut b = Mesh::cuboid(
        Vec3::new(1001.0, 2001.0, 9.25),
        Vec3::new(1002.0, 2002.0, 30.0),
        2,
    );
    b.features = vec![300_000; b.positions.len()];
    b.colors = vec![[0.1, 0.5, 0.9, 0.5]; b.positions.len()];
    let offset = a.positions.len() as u32;
    a.positions.extend(b.positions);
    a.normals.extend(b.normals);
    a.colors.extend(b.colors);
    a.features.extend(b.features);
    a.indices.extend(b.indices.iter().map(|i| i + offset));
    a
}

/// The mesh with a texture: one coordinate per vertex over a small atlas.
fn textured() -> (Mesh, Texture) {
    let mesh = two_objects();
    let uvs = mesh
        .positions
        .iter()
        .map(|p| Vec2::new((p.x - 1000.0) / 12.5, (p.z - 5.0) / 25.0).clamp(Vec2::ZERO, Vec2::ONE))
        .collect();
    let atlas = Atlas {
        width: 4,
        height: 2,
        texels: (0..8).map(|i| [i * 30, 255 - i * 30, 7, 255]).collect(),
    };
    let png = encode_png(&atlas);
    (mesh, Texture { uvs, png })
}

/// Positions are stored exact: the only difference allowed is the f32
/// rounding of moving them to the node's translation and back, as in the
/// plain form.
fn position_tolerance(mesh: &Mesh) -> f32 {
    let far = mesh
        .positions
        .iter()
        .fold(0.0f32, |m, p| m.max(p.abs().max_element()));
    4.0 * f32::EPSILON * far
}

/// One triangle corner as a reader sees it: the position (moved by the
/// node's translation), normal, colour, feature id and texture coordinate.
#[derive(Debug, Clone, Copy)]
struct Corner {
    p: Vec3,
    n: Option<Vec3>,
    c: Option<[f32; 4]>,
    f: Option<u32>,
    uv: Option<Vec2>,
}

fn corners(mesh: &Mesh, translation: Vec3, uvs: Option<&[Vec2]>) -> Vec<[Corner; 3]> {
    mesh.indices
        .chunks_exact(3)
        .map(|t| {
            [0, 1, 2].map(|k| {
                let i = t[k] as usize;
                Corner {
                    p: mesh.positions[i] + translation,
                    n: mesh.normals.get(i).copied(),
                    c: mesh.colors.get(i).copied(),
                    f: mesh.features.get(i).copied(),
                    uv: uvs.map(|u| u[i]),
                }
            })
        })
        .collect()
}

/// The triangles `read` are those `written`, in order, each with its
/// winding: the index codec may rotate a triangle's corners, and the
/// vertices are numbered anew. `check` compares each corner with the one
/// it was written as.
fn same_triangles(written: &[[Corner; 3]], read: &[[Corner; 3]], check: impl Fn(&Corner, &Corner)) {
    assert_eq!(written.len(), read.len(), "triangles");
    for (w, r) in written.iter().zip(read) {
        let turn = (0..3)
            .min_by(|&a, &b| {
                let d = |k: usize| r[k].p.distance(w[0].p);
                d(a).total_cmp(&d(b))
            })
            .unwrap();
        for k in 0..3 {
            check(&w[k], &r[(k + turn) % 3]);
        }
    }
}

/// How many vertices the GLB's one primitive stores.
fn stored_vertices(glb: &[u8]) -> u64 {
    let json = json_of(glb);
    let position = &json["meshes"][0]["primitives"][0]["attributes"]["POSITION"];
    json["accessors"][position.as_u64().unwrap() as usize]["count"]
        .as_u64()
        .unwrap()
}

/// How many of `mesh`'s vertices differ in position or object.
fn distinct_vertices(mesh: &Mesh) -> usize {
    (mesh.positions.iter().zip(&mesh.features))
        .map(|(p, f)| (p.to_array().map(f32::to_bits), *f))
        .collect::<std::collections::HashSet<_>>()
        .len()
}

fn json_of(glb: &[u8]) -> serde_json::Value {
    let container = gltf::binary::Glb::from_slice(glb).unwrap();
    serde_json::from_slice(&container.json).unwrap()
}

#[test]
fn a_compact_glb_reads_back_its_positions_exact_and_the_rest_within_the_quantization_error() {
    let (mesh, texture) = textured();
    let glb = encoded_mesh_to_glb(&mesh, Some(&texture), Encoding::Compact);
    let plain = encoded_mesh_to_glb(&mesh, Some(&texture), Encoding::Plain);
    assert!(compact::is_compact(&glb));
    assert!(!compact::is_compact(&plain));
    assert!(
        glb.len() * 2 < plain.len(),
        "compact {} bytes, plain {}",
        glb.len(),
        plain.len()
    );

    // A box's faces share their corners once their normals are left out
    // (flat): each position of an object is stored once, as the colours
    // and texture coordinates are functions of it here.
    assert_eq!(stored_vertices(&glb), distinct_vertices(&mesh) as u64);
    assert!(distinct_vertices(&mesh) < mesh.positions.len());

    let decoded = compact::decode(&glb).unwrap().drawn();
    let read = decoded.texture.clone().expect("the texture reads back");
    assert_eq!(read.png, texture.png);
    let tolerance = position_tolerance(&mesh);
    same_triangles(
        &corners(&mesh, Vec3::ZERO, Some(&texture.uvs)),
        &corners(&decoded.mesh, decoded.translation, Some(&read.uvs)),
        |w, r| {
            assert!(
                w.p.distance(r.p) <= tolerance,
                "{} read as {}, tolerance {tolerance}",
                w.p,
                r.p
            );
            assert_eq!(w.f, r.f);
            let (n, m) = (w.n.unwrap(), r.n.unwrap());
            assert!(n.distance(m) <= 0.01, "{n} read as {m}");
            let (c, d) = (w.c.unwrap(), r.c.unwrap());
            for k in 0..4 {
                assert!(
                    (c[k] - d[k]).abs() <= 0.5 / 255.0 + 1e-6,
                    "{c:?} read as {d:?}"
                );
            }
            let (u, v) = (w.uv.unwrap(), r.uv.unwrap());
            assert!(u.distance(v) <= 1.0 / 65535.0, "{u} read as {v}");
        },
    );
}

#[test]
fn flat_normals_are_left_out_and_read_back_as_the_triangles_own() {
    let has_normals = |glb: &[u8]| {
        json_of(glb)["meshes"][0]["primitives"][0]["attributes"]
            .get("NORMAL")
            .is_some()
    };
    // Boxes, turned off the axes: each vertex's normal is its face's.
    let mut flat = two_objects();
    let turn = glam::Quat::from_euler(glam::EulerRot::ZXY, 0.5, 0.3, 0.0);
    for (p, n) in flat.positions.iter_mut().zip(&mut flat.normals) {
        (*p, *n) = (turn * *p, turn * *n);
    }
    for allowance in [0.0, 0.01] {
        let (glb, _) = compact_mesh_to_glb(&flat, None, allowance);
        assert!(!has_normals(&glb), "allowance {allowance}");
        assert_eq!(stored_vertices(&glb), distinct_vertices(&flat) as u64);
        let decoded = compact::decode(&glb).unwrap().drawn();
        // A corner shared by faces reads back once for each face, with
        // that face's normal.
        same_triangles(
            &corners(&flat, Vec3::ZERO, None),
            &corners(&decoded.mesh, decoded.translation, None),
            |w, r| {
                let (n, m) = (w.n.unwrap(), r.n.unwrap());
                assert!(n.distance(m) <= 0.01, "{n} read as {m}");
                // On the grid of a stored 8-bit normal, as they read back
                // when stored.
                assert_eq!(m * 127.0, (m * 127.0).round(), "{m}");
                assert_eq!(w.f, r.f);
            },
        );
        // The plain form writes them out, for readers that do not compute
        // them.
        assert!(has_normals(&compact::plain(&glb).unwrap()));
    }
    // Smooth normals, and one flat normal turned by a degree: kept.
    let mut smooth = two_objects();
    let centre = smooth.positions.iter().copied().sum::<Vec3>() / smooth.positions.len() as f32;
    smooth.normals = smooth
        .positions
        .iter()
        .map(|&p| (p - centre).normalize())
        .collect();
    let mut turned = two_objects();
    let axis = turned.normals[0].any_orthonormal_vector();
    turned.normals[0] = glam::Quat::from_axis_angle(axis, 1f32.to_radians()) * turned.normals[0];
    for (what, mesh) in [("smooth", smooth), ("turned", turned)] {
        let (glb, _) = compact_mesh_to_glb(&mesh, None, 0.0);
        assert!(has_normals(&glb), "{what}");
        let decoded = compact::decode(&glb).unwrap().drawn();
        same_triangles(
            &corners(&mesh, Vec3::ZERO, None),
            &corners(&decoded.mesh, decoded.translation, None),
            |w, r| {
                let (n, m) = (w.n.unwrap(), r.n.unwrap());
                assert!(n.distance(m) <= 0.01, "{what}: {n} read as {m}");
            },
        );
    }
}

#[test]
fn the_plain_form_of_a_compact_glb_is_an_f32_glb_of_the_same_mesh() {
    let (mesh, texture) = textured();
    let glb = encoded_mesh_to_glb(&mesh, Some(&texture), Encoding::Compact);
    let plain = compact::plain(&glb).unwrap().into_owned();
    // Deterministic: a content-addressed server derives the same bytes.
    assert_eq!(compact::plain(&glb).unwrap().as_ref(), &plain[..]);
    let json = json_of(&plain);
    assert!(json.get("extensionsRequired").is_none(), "{json}");
    assert_eq!(
        json["extensionsUsed"],
        serde_json::json!(["EXT_mesh_features"])
    );
    for accessor in json["accessors"].as_array().unwrap() {
        assert!(
            [5125, 5126].contains(&accessor["componentType"].as_u64().unwrap()),
            "{accessor}"
        );
    }
    // A plain GLB's plain form is itself.
    let again = compact::plain(&plain).unwrap();
    assert!(matches!(again, std::borrow::Cow::Borrowed(_)));

    // Both forms read back as the same mesh through the glTF reader.
    let dir = tempfile::tempdir().unwrap();
    let (a, b) = (dir.path().join("compact.glb"), dir.path().join("plain.glb"));
    std::fs::write(&a, &glb).unwrap();
    std::fs::write(&b, &plain).unwrap();
    let (ma, ta) = hdlod::io::read_textured_mesh(&a).unwrap();
    let (mb, tb) = hdlod::io::read_textured_mesh(&b).unwrap();
    let (ta, tb) = (ta.unwrap(), tb.unwrap());
    assert_eq!(ta.png, tb.png);
    let tolerance = position_tolerance(&mesh);
    let same = |w: &Corner, r: &Corner| {
        assert!(w.p.distance(r.p) <= tolerance, "{} {}", w.p, r.p);
        assert_eq!(w.f, r.f);
        let (u, v) = (w.uv.unwrap(), r.uv.unwrap());
        assert!(u.distance(v) <= 1.0 / 65535.0, "{u} {v}");
    };
    let compact = corners(&ma, Vec3::ZERO, Some(&ta.uvs));
    same_triangles(&compact, &corners(&mb, Vec3::ZERO, Some(&tb.uvs)), same);
    same_triangles(
        &corners(&mesh, Vec3::ZERO, Some(&texture.uvs)),
        &compact,
        same,
    );
}

#[test]
fn a_compact_glb_declares_both_extensions_and_a_fallback_buffer() {
    let glb = encoded_mesh_to_glb(&two_objects(), None, Encoding::Compact);
    let json = json_of(&glb);
    for key in ["extensionsUsed", "extensionsRequired"] {
        let list = json[key].as_array().unwrap();
        for name in ["EXT_meshopt_compression", "KHR_mesh_quantization"] {
            assert!(list.iter().any(|v| v == name), "{key}: {list:?}");
        }
    }
    let buffers = json["buffers"].as_array().unwrap();
    assert_eq!(buffers.len(), 2, "{buffers:?}");
    assert_eq!(
        buffers[1]["extensions"]["EXT_meshopt_compression"]["fallback"],
        true
    );
    assert!(buffers[1].get("uri").is_none());
    let bin = gltf::binary::Glb::from_slice(&glb).unwrap().bin.unwrap();
    let views = json["bufferViews"].as_array().unwrap();
    for view in views {
        let ext = &view["extensions"]["EXT_meshopt_compression"];
        assert_eq!(view["buffer"], 1, "{view}");
        assert_eq!(ext["buffer"], 0, "{view}");
        // 0, the default, is left out.
        let first = bin[ext.get("byteOffset").map_or(0, |o| o.as_u64().unwrap()) as usize];
        match ext["mode"].as_str().unwrap() {
            // The vertex codec's version 0, the one the extension defines.
            "ATTRIBUTES" => assert_eq!(first, 0xa0, "{view}"),
            "TRIANGLES" => assert_eq!(first & 0xf0, 0xe0, "{view}"),
            other => panic!("mode {other}"),
        }
    }
}

#[test]
fn both_forms_have_zero_validator_errors() {
    let dir = tempfile::tempdir().unwrap();
    let (mesh, texture) = textured();
    let mut files: Vec<PathBuf> = Vec::new();
    for (name, glb) in [
        (
            "compact.glb",
            encoded_mesh_to_glb(&mesh, None, Encoding::Compact),
        ),
        (
            "compact-textured.glb",
            encoded_mesh_to_glb(&mesh, Some(&texture), Encoding::Compact),
        ),
        (
            "compact-box.glb",
            encoded_mesh_to_glb(&common::unit_box(), None, Encoding::Compact),
        ),
    ] {
        let plain = compact::plain(&glb).unwrap().into_owned();
        let path = dir.path().join(name);
        std::fs::write(&path, &glb).unwrap();
        files.push(path);
        let path = dir.path().join(format!("plain-{name}"));
        std::fs::write(&path, &plain).unwrap();
        files.push(path);
    }
    let path = dir.path().join("today.glb");
    std::fs::write(&path, mesh_to_glb(&mesh)).unwrap();
    files.push(path);
    let reports = assert_no_gltf_errors(&files);
    for (file, report) in files.iter().zip(&reports) {
        assert_eq!(
            report["issues"]["numWarnings"],
            0,
            "{}: {}",
            file.display(),
            report["issues"]
        );
        assert!(
            report["info"]["drawCallCount"].as_u64().unwrap() >= 1,
            "{report}"
        );
    }
}

/// With an allowance, positions become 16-bit shorts when that moves none
/// by more than it (docs/benchmarks.md measures the bytes saved on real
/// trees; a box or two gains nothing): the farthest move is answered,
/// and every position reads back within that move. An allowance below
/// the move a 16-bit grid needs keeps them exact.
#[test]
fn positions_are_quantized_within_the_allowance_and_the_move_is_answered() {
    let (mesh, texture) = textured();
    let (exact, none) = compact_mesh_to_glb(&mesh, Some(&texture), 0.0);
    assert_eq!(none, 0.0);
    assert_eq!(
        exact,
        encoded_mesh_to_glb(&mesh, Some(&texture), Encoding::Compact)
    );
    // The mesh is 30 m across: a 16-bit step is under a millimetre.
    let (glb, moved) = compact_mesh_to_glb(&mesh, Some(&texture), 0.001);
    assert!(moved > 0.0 && moved <= 0.001, "moved {moved}");
    let json = json_of(&glb);
    let position = json["meshes"][0]["primitives"][0]["attributes"]["POSITION"]
        .as_u64()
        .unwrap();
    assert_eq!(json["accessors"][position as usize]["componentType"], 5122);
    // The node's f32 translation and scale as their shortest decimals.
    for key in ["translation", "scale"] {
        for v in json["nodes"][0][key].as_array().unwrap() {
            let text = v.to_string();
            let x: f32 = text.parse().unwrap();
            assert!(text.len() <= 12 && x.to_string() == text, "{key}: {text}");
        }
    }
    let decoded = compact::decode(&glb).unwrap().drawn();
    let slack = position_tolerance(&mesh);
    let farthest = std::cell::Cell::new(0.0f32);
    same_triangles(
        &corners(&mesh, Vec3::ZERO, None),
        &corners(&decoded.mesh, decoded.translation, None),
        |w, r| {
            let d = w.p.distance(r.p);
            assert!(
                d <= moved + slack,
                "{} read as {}: {d} beyond {moved}",
                w.p,
                r.p
            );
            farthest.set(farthest.get().max(d));
        },
    );
    let farthest = farthest.get();
    // The answer is the move, not a loose bound of it.
    assert!(farthest > moved / 4.0, "moved {farthest}, answered {moved}");
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("quantized.glb");
    std::fs::write(&path, &glb).unwrap();
    assert_no_gltf_errors(&[path]);
    let (kept, zero) = compact_mesh_to_glb(&mesh, Some(&texture), 1e-6);
    assert_eq!((kept, zero), (exact, 0.0));
}
