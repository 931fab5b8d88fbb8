//! Precision at map coordinates: an IFC model whose elements stand at an
//! easting and northing of about 10^6 m (where `f32` has a grid of 6 to 12
//! cm) is imported, built and served, and every vertex of the scene and
//! of the served tile content of the tree's leaves lies within 1 mm of
//! the model's own `f64` positions once the georeference's origin is added
//! back (docs/tiles.md, "Precision").
#![cfg(feature = "ifc")]

mod common;

use std::fmt::Write;
use std::path::Path;

use glam::DVec3;
use hdlod::scene::{Georeference, Projected};

/// Where the boxes stand, metres: far out on a map grid, off any round
/// number.
const EAST: f64 = 1_000_000.0;
const NORTH: f64 = 1_200_000.0;

/// Box `i`'s placement: metres apart, with millimetre fractions that a
/// grid of centimetres cannot hold.
fn placement(i: usize) -> DVec3 {
    DVec3::new(
        EAST + 3.217 * i as f64 + 0.0013,
        NORTH + 2.911 * (i % 3) as f64 + 0.0427,
        0.25 * i as f64,
    )
}

const BOXES: usize = 6;
/// The boxes' extrusion: a rectangle of 0.4 by 0.3 m about the placement,
/// 2.7 m high.
const HALF: [f64; 2] = [0.2, 0.15];
const HEIGHT: f64 = 2.7;

/// Every corner of every box, in the model's coordinates.
fn corners() -> Vec<DVec3> {
    let mut out = Vec::new();
    for i in 0..BOXES {
        let p = placement(i);
        for sx in [-1.0, 1.0] {
            for sy in [-1.0, 1.0] {
                for z in [0.0, HEIGHT] {
                    out.push(p + DVec3::new(sx * HALF[0], sy * HALF[1], z));
                }
            }
        }
    }
    out
}

/// An IFC4 file in metres with the boxes as building element proxies.
fn model() -> String {
    let mut s = String::from(
        "ISO-10303-21;\nHEADER;\nFILE_DESCRIPTION(('ViewDefinition [ReferenceView]'),'2;1');\n\
         FILE_NAME('far.ifc','2024-01-01T00:00:00',('hdlod'),('hdlod'),'generated','generated','');\n\
         FILE_SCHEMA(('IFC4'));\nENDSEC;\nDATA;\n\
         #1=IFCPROJECT('0FarProjectHdlod000001',$,'Far',$,$,$,$,(#20),#10);\n\
         #10=IFCUNITASSIGNMENT((#11,#12));\n\
         #11=IFCSIUNIT(*,.LENGTHUNIT.,$,.METRE.);\n\
         #12=IFCSIUNIT(*,.PLANEANGLEUNIT.,$,.RADIAN.);\n\
         #20=IFCGEOMETRICREPRESENTATIONCONTEXT($,'Model',3,1.E-05,#21,$);\n\
         #21=IFCAXIS2PLACEMENT3D(#22,$,$);\n#22=IFCCARTESIANPOINT((0.,0.,0.));\n\
         #23=IFCDIRECTION((0.,0.,1.));\n\
         #30=IFCSITE('1FarSiteHdlod000000001',$,'Site',$,$,#31,$,$,.ELEMENT.,$,$,$,$,$);\n\
         #31=IFCLOCALPLACEMENT($,#21);\n\
         #32=IFCRELAGGREGATES('1FarAggHdlod0000000001',$,$,$,#1,(#30));\n",
    );
    let mut contained = Vec::new();
    for i in 0..BOXES {
        let id = 100 + 10 * i;
        let p = placement(i);
        writeln!(
            s,
            "#{id}=IFCBUILDINGELEMENTPROXY('2FarBoxHdlod{i:010}',$,'box {i}',$,$,#{},#{},$,$);\n\
             #{}=IFCLOCALPLACEMENT(#31,#{});\n#{}=IFCAXIS2PLACEMENT3D(#{},$,$);\n\
             #{}=IFCCARTESIANPOINT(({:.4},{:.4},{:.4}));\n\
             #{}=IFCPRODUCTDEFINITIONSHAPE($,$,(#{}));\n\
             #{}=IFCSHAPEREPRESENTATION(#20,'Body','SweptSolid',(#{}));\n\
             #{}=IFCEXTRUDEDAREASOLID(#{},#21,#23,{HEIGHT:.1});\n\
             #{}=IFCRECTANGLEPROFILEDEF(.AREA.,$,#{},{:.1},{:.2});\n\
             #{}=IFCAXIS2PLACEMENT2D(#{},$);\n#{}=IFCCARTESIANPOINT((0.,0.));",
            id + 1,
            id + 4,
            id + 1,
            id + 2,
            id + 2,
            id + 3,
            id + 3,
            p.x,
            p.y,
            p.z,
            id + 4,
            id + 5,
            id + 5,
            id + 6,
            id + 6,
            id + 7,
            id + 7,
            id + 8,
            2.0 * HALF[0],
            2.0 * HALF[1],
            id + 8,
            id + 9,
            id + 9,
        )
        .unwrap();
        contained.push(format!("#{id}"));
    }
    writeln!(
        s,
        "#40=IFCRELCONTAINEDINSPATIALSTRUCTURE('1FarRelHdlod0000000001',$,$,$,({}),#30);\nENDSEC;\nEND-ISO-10303-21;",
        contained.join(",")
    )
    .unwrap();
    s
}

/// The largest distance from a vertex to the nearest corner, and from a
/// corner to the nearest vertex (the geometry is all there).
fn worst(vertices: &[DVec3], corners: &[DVec3]) -> f64 {
    let nearest = |p: &DVec3, set: &[DVec3]| {
        set.iter()
            .map(|q| p.distance(*q))
            .fold(f64::INFINITY, f64::min)
    };
    let there = vertices
        .iter()
        .map(|v| nearest(v, corners))
        .fold(0.0, f64::max);
    let back = corners
        .iter()
        .map(|c| nearest(c, vertices))
        .fold(0.0, f64::max);
    there.max(back)
}

fn glb_vertices(bytes: &[u8], origin: DVec3, dir: &Path) -> Vec<DVec3> {
    let path = dir.join("content.glb");
    std::fs::write(&path, bytes).unwrap();
    let mesh = hdlod::io::read_mesh(&path).unwrap();
    mesh.positions
        .iter()
        .map(|p| p.as_dvec3() + origin)
        .collect()
}

#[test]
fn a_model_at_map_coordinates_keeps_its_millimetres() {
    let tmp = tempfile::tempdir().unwrap();
    let ifc = tmp.path().join("far.ifc");
    std::fs::write(&ifc, model()).unwrap();
    let scene_dir = tmp.path().join("far");
    let tree_dir = tmp.path().join("tree");
    let run = |args: &[&std::ffi::OsStr]| {
        let out = std::process::Command::new(env!("CARGO_BIN_EXE_hdlod"))
            .args(args)
            .env("RUST_LOG", "warn")
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        out.stdout
    };
    let report = run(&[
        "import".as_ref(),
        "ifc".as_ref(),
        ifc.as_os_str(),
        "--out".as_ref(),
        scene_dir.as_os_str(),
        "--json".as_ref(),
    ]);
    let report: serde_json::Value = serde_json::from_slice(&report).unwrap();
    assert_eq!(report["elements"], BOXES, "{report}");
    run(&[
        "build".as_ref(),
        scene_dir.as_os_str(),
        "--out".as_ref(),
        tree_dir.as_os_str(),
    ]);
    let corners = corners();

    // The scene: near its own origin, placed by its georeference.
    let scene = hdlod::scene::format::load(&scene_dir).unwrap();
    let Some(Georeference::Projected(Projected {
        crs: None,
        easting,
        northing,
        height,
        ..
    })) = scene.georeference
    else {
        panic!("no map origin: {:?}", scene.georeference);
    };
    let origin = DVec3::new(easting, northing, height);
    assert!(origin.distance(placement(0)) < 100.0, "{origin}");
    let mut vertices = Vec::new();
    for o in &scene.objects {
        let m = o.transform;
        assert!(
            m.w_axis.truncate().abs().max_element() < 100.0,
            "{}",
            m.w_axis
        );
        vertices.extend(
            scene.meshes[o.mesh]
                .positions
                .iter()
                .map(|p| m.transform_point3(*p).as_dvec3() + origin),
        );
    }
    let scene_error = worst(&vertices, &corners);
    assert!(scene_error < 1e-3, "scene: {scene_error} m");
    // Without an origin of its own, f32 would put the corners on a
    // grid of 6 cm and more: what the scene is checked against is real.
    let naive: Vec<DVec3> = corners.iter().map(|c| c.as_vec3().as_dvec3()).collect();
    assert!(worst(&naive, &corners) > 1e-2);

    // Served: the scene answer's georeference, the leaf tiles' content
    // and their geometry files.
    let server = common::Server::start(&tree_dir);
    let answer = server.get_json("/api/v1/scenes/far");
    assert_eq!(answer["georeference"]["easting"], easting);
    let tileset = server.get_json("/api/v1/scenes/far/tiles/tileset.json?time=0&frame=local");
    let http = common::client();
    let mut leaves = Vec::new();
    let mut stack = vec![&tileset["root"]];
    while let Some(tile) = stack.pop() {
        let children = tile["children"]
            .as_array()
            .map(Vec::as_slice)
            .unwrap_or(&[]);
        stack.extend(children);
        if children.is_empty()
            && let Some(uri) = tile["content"]["uri"].as_str()
        {
            leaves.push(uri.to_owned());
        }
    }
    assert!(!leaves.is_empty());
    let mut served = Vec::new();
    for uri in &leaves {
        let bytes = http
            .get(server.url(&format!("/api/v1/scenes/far/tiles/{uri}")))
            .send()
            .unwrap()
            .error_for_status()
            .unwrap()
            .bytes()
            .unwrap();
        served.extend(glb_vertices(&bytes, origin, tmp.path()));
    }
    let served_error = worst(&served, &corners);
    assert!(served_error < 1e-3, "served tiles: {served_error} m");
    println!("worst: scene {scene_error:e} m, served {served_error:e} m");
}
