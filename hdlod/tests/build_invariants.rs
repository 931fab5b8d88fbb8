//! The invariants of docs/method.md sections 2 and 3 on the tree built from the
//! committed tiny fixture, read back from disk.

mod common;

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use glam::Vec3;
use hdlod::build::{BuildConfig, Silent, StepFunction, build_to};
use hdlod::geometry::ErrorMetric;
use hdlod::geometry::Mesh;
use hdlod::io::gltf::{read_mesh, read_textured_mesh};
use hdlod::io::texture::decode_png;
use hdlod::scene::{Class, Scene, format};
use hdlod::tree::{ClusterClass, Tree, load};

struct Built {
    scene: Scene,
    tree: Tree,
    dir: PathBuf,
    _tmp: tempfile::TempDir,
}

fn built() -> &'static Built {
    static BUILT: OnceLock<Built> = OnceLock::new();
    BUILT.get_or_init(|| build(&BuildConfig::default()))
}

fn build(config: &BuildConfig) -> Built {
    let fixture = Path::new(env!("CARGO_MANIFEST_DIR")).join("../fixtures/skyscraper-tiny");
    let scene = format::load(&fixture).expect("the tiny fixture loads");
    // The tree of `built()` lives in a static, which is never dropped: in
    // cargo's temporary directory for tests, not the system's, so what a
    // run leaves goes with `cargo clean`.
    let tmp = tempfile::tempdir_in(env!("CARGO_TARGET_TMPDIR")).unwrap();
    let dir = tmp.path().join("tree");
    build_to(&scene, config, &dir, &Silent).expect("the build succeeds");
    let tree = load(&dir).expect("the written tree loads");
    Built {
        scene,
        tree,
        dir,
        _tmp: tmp,
    }
}

/// Every visible object is in the leaves, and the leaves naming it share
/// out its visibility without overlap: one leaf, or a moving leaf and the
/// pseudo-dynamic leaves where it stands still before and after its motion.
#[test]
fn the_leaves_of_an_object_partition_its_visibility() {
    let b = built();
    let span = b.tree.time.seconds;
    let clusters: Vec<_> = b.tree.clusters().collect();
    let mut leaves: HashMap<&str, Vec<StepFunction>> = HashMap::new();
    for c in &clusters {
        assert!(
            c.objects.is_empty() || c.is_leaf(),
            "cluster {} lists objects but has children",
            c.id
        );
        for o in &c.objects {
            leaves
                .entry(o.as_str())
                .or_default()
                .push(StepFunction::from_tree(&c.visibility));
        }
    }
    let mut split = 0;
    for o in &b.scene.objects {
        let Some(parts) = leaves.get(o.id.as_str()) else {
            assert_eq!(
                b.scene.class_of(o),
                Class::Absent,
                "object {} has no leaf",
                o.id
            );
            continue;
        };
        let n = parts.len() as f64;
        split += usize::from(parts.len() > 1);
        let whole = StepFunction::of_visibility(&o.visibility, span);
        let zero = StepFunction::constant(0.0);
        // The mean of the parts is whole / n exactly when they partition it.
        let mean = StepFunction::weighted_mean(&parts.iter().map(|p| (1.0, p)).collect::<Vec<_>>());
        let expected = StepFunction::weighted_mean(&[(1.0, &whole), (n - 1.0, &zero)]);
        assert!(
            mean.l1_distance(&expected, span) <= 1e-9 * span,
            "object {}",
            o.id
        );
    }
    assert!(
        split > 0,
        "no moving object stands still at either end of its motion"
    );
}

#[test]
fn parents_contain_children_and_errors_grow_upwards() {
    let t = &built().tree;
    for c in t.clusters() {
        for &ch in &c.children {
            let child = &t.cluster(ch);
            if c.class != ClusterClass::Root {
                assert_eq!(child.class, c.class, "cluster {} mixes classes", c.id);
                // Dynamic chains share one frame; the others are in the world.
                assert!(
                    c.bounds.contains(&child.bounds, 1e-3),
                    "cluster {} does not contain {}",
                    c.id,
                    ch
                );
            }
            assert!(
                c.eps >= child.eps,
                "eps falls from {} ({}) to {} ({})",
                ch,
                child.eps,
                c.id,
                c.eps
            );
        }
    }
}

#[test]
fn fractional_visibility_is_the_size_weighted_mean() {
    let t = &built().tree;
    let span = t.time.seconds;
    let k = BuildConfig::default().max_steps;
    let mut exact = 0;
    for c in t.clusters().filter(|c| !c.is_leaf()) {
        let v = StepFunction::from_tree(&c.visibility);
        assert!(
            v.points().iter().all(|p| (0.0..=1.0).contains(&p.1)),
            "cluster {}",
            c.id
        );
        let children: Vec<(f64, StepFunction)> = c
            .children
            .iter()
            .map(|&i| {
                let ch = &t.cluster(i);
                (ch.w.max(1e-9), StepFunction::from_tree(&ch.visibility))
            })
            .collect();
        let parts: Vec<(f64, &StepFunction)> = children.iter().map(|(w, s)| (*w, s)).collect();
        let mean = StepFunction::weighted_mean(&parts);
        if mean.points().len() <= k {
            // Unsimplified: equal up to the f32 the file stores.
            exact += 1;
            assert!(
                v.l1_distance(&mean, span) <= 1e-6 * span,
                "cluster {}",
                c.id
            );
        } else {
            // Simplified to K steps: the integral is kept.
            let zero = StepFunction::constant(0.0);
            let (a, b) = (v.l1_distance(&zero, span), mean.l1_distance(&zero, span));
            assert!((a - b).abs() <= 1e-6 * span, "cluster {}: {a} vs {b}", c.id);
            assert!(v.points().len() <= k);
        }
    }
    assert!(exact > 0);
}

#[test]
fn temporal_error_is_measured_against_the_objects() {
    let b = built();
    let span = b.tree.time.seconds;
    let objects: HashMap<&str, &hdlod::scene::Object> =
        b.scene.objects.iter().map(|o| (o.id.as_str(), o)).collect();
    for c in b
        .tree
        .clusters()
        .filter(|c| c.class == ClusterClass::PseudoDynamic)
    {
        let v = StepFunction::from_tree(&c.visibility);
        // A leaf is an object, or the part of a moving object's life where
        // it stands still: its visibility is that part's.
        let worst = common::leaves_below(&b.tree, c.id)
            .iter()
            .map(|&l| {
                let leaf = &b.tree.cluster(l);
                let object = objects[leaf.objects[0].as_str()];
                let own = StepFunction::of_visibility(&object.visibility, span);
                let part = StepFunction::from_tree(&leaf.visibility);
                // The leaf's part never shows the object where it is absent.
                assert!(
                    part.l1_distance(&own, span)
                        <= own.l1_distance(&StepFunction::constant(0.0), span),
                    "leaf {l}"
                );
                v.l1_distance(&part, span) / span
            })
            .fold(0.0, f64::max);
        assert!(
            c.gamma >= worst - 1e-6,
            "cluster {}: gamma {} < {worst}",
            c.id,
            c.gamma
        );
        let delta_mid = c.delta(0.5);
        assert!(delta_mid >= c.eps && c.delta(0.0) == c.eps && c.delta(1.0) == c.eps);
    }
}

/// The stored eps is a bound: re-measured directly against the original
/// objects below, the Hausdorff distance is never above it. The check uses
/// the re-measurement's lower bound (a distance actually attained), which
/// must not exceed any valid upper bound.
#[test]
fn stored_eps_bounds_the_distance_to_the_original_objects() {
    eps_bounds_the_distance(built());
}

/// Held to colour, the errors are still geometric bounds, and colour
/// patterns the geometric bound lets go stay: the parents keep more of the
/// originals' colours, at more triangles.
#[test]
fn an_appearance_bound_is_a_geometric_bound_that_keeps_colours() {
    let config = BuildConfig {
        error_metric: ErrorMetric::Appearance,
        ..BuildConfig::default()
    };
    let appearance = build(&config);
    eps_bounds_the_distance(&appearance);
    let manifest: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(appearance.dir.join("manifest.json")).unwrap(),
    )
    .unwrap();
    assert_eq!(manifest["config"]["error_metric"], "appearance");
    let parents = |b: &Built| {
        let (mut colours, mut triangles) = (0usize, 0usize);
        for c in b
            .tree
            .clusters()
            .filter(|c| !c.is_leaf() && c.geometry.is_some())
        {
            let m = read_mesh(&b.tree.geometry_file(&b.dir, c.geometry.as_ref().unwrap())).unwrap();
            let distinct: std::collections::HashSet<[u8; 4]> = m
                .colors
                .iter()
                .map(|c| c.map(|v| (v * 255.0).round() as u8))
                .collect();
            colours += distinct.len();
            triangles += m.triangle_count();
        }
        (colours, triangles)
    };
    let (geometric_colours, geometric_triangles) = parents(built());
    let (held_colours, held_triangles) = parents(&appearance);
    assert!(
        held_colours > geometric_colours && held_triangles > geometric_triangles,
        "colours {held_colours} against {geometric_colours}, triangles {held_triangles} against {geometric_triangles}"
    );
}

fn eps_bounds_the_distance(b: &Built) {
    let mut checked = 0;
    for c in b.tree.clusters().filter(|c| {
        !c.is_leaf() && matches!(c.class, ClusterClass::Static | ClusterClass::PseudoDynamic)
    }) {
        if c.id % 5 != 0 {
            continue;
        }
        common::assert_eps_bound(&b.tree, &b.dir, &b.scene, &c);
        checked += 1;
    }
    assert!(checked >= 10, "only {checked} clusters checked");
}

/// What the builder writes is what the schemas describe.
/// The tiny site's tree as served (mapped from `clusters.bin`) is the
/// tree `clusters.json` describes, cluster for cluster, with the same
/// object tables, counts and baseline.
#[test]
fn the_index_describes_the_tree_of_the_json() {
    let b = built();
    let json = hdlod::tree::store::load_json(&b.dir).unwrap();
    assert!(b.tree.index().is_some() && json.index().is_none());
    assert_eq!(b.tree.cluster_count(), json.cluster_count());
    for (a, c) in b.tree.clusters().zip(json.clusters()) {
        assert_eq!(a, c);
    }
    assert_eq!(b.tree, json);
    assert_eq!(b.tree.summary(), json.summary());
    assert_eq!(b.tree.baseline(), json.baseline());
}

#[test]
fn written_files_match_the_schemas() {
    let b = built();
    for (file, schema) in [
        ("manifest.json", "tree-manifest.schema.json"),
        ("clusters.json", "tree-clusters.schema.json"),
    ] {
        let doc: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(b.dir.join(file)).unwrap()).unwrap();
        common::assert_matches_schema(&doc, schema);
    }
}

/// Coarser versions that stand alone above one cluster (a dynamic model's
/// LOD chain, the parent of a cluster with no neighbours) exist only where
/// they pay: each keeps at most `min_reduction` of the triangles below it.
#[test]
fn single_child_parents_reduce_their_child() {
    let t = &built().tree;
    let config = BuildConfig::default();
    let mut found = [0usize; 2];
    for c in t.clusters().filter(|c| c.children.len() == 1) {
        let child = &t.cluster(c.children[0]);
        assert!(
            c.triangles as f64 <= child.triangles as f64 * config.min_reduction,
            "cluster {} keeps {} of {} triangles",
            c.id,
            c.triangles,
            child.triangles
        );
        assert_eq!(c.visibility, child.visibility, "cluster {}", c.id);
        found[usize::from(c.class == ClusterClass::Dynamic)] += 1;
    }
    assert!(
        found[0] > 0 && found[1] > 0,
        "single-child parents (static or pseudo-dynamic, dynamic): {found:?}"
    );
}

/// Every static and pseudo-dynamic cluster GLB carries a feature id per
/// vertex (`_FEATURE_ID_0` with `EXT_mesh_features`), each triangle on one
/// object; a leaf's ids are its object's, a parent's are objects below it;
/// a dynamic cluster's object is named by the tree. The Khronos validator
/// finds no error in any of them.
#[test]
fn every_cluster_glb_carries_its_objects_feature_ids() {
    let b = built();
    let index: HashMap<&str, u32> = b
        .scene
        .objects
        .iter()
        .enumerate()
        .map(|(i, o)| (o.id.as_str(), i as u32))
        .collect();
    let mut files = Vec::new();
    for c in b.tree.clusters() {
        let Some(hash) = &c.geometry else { continue };
        let file = b.tree.geometry_file(&b.dir, hash);
        let mesh = read_mesh(&file).unwrap();
        files.push(file.clone());
        if c.class == ClusterClass::Dynamic {
            // Shared by the model's instances: the tree names the object.
            assert!(mesh.features.is_empty(), "dynamic cluster {}", c.id);
            let object = b
                .tree
                .dynamic_object(c.id)
                .expect("a dynamic cluster's object");
            let leaves = common::leaves_below(&b.tree, c.id);
            assert_eq!(index[b.tree.cluster(leaves[0]).objects[0].as_str()], object);
            continue;
        }
        assert_eq!(
            mesh.features.len(),
            mesh.positions.len(),
            "cluster {}",
            c.id
        );
        for t in mesh.indices.chunks_exact(3) {
            let f = mesh.features[t[0] as usize];
            assert!(
                t.iter().all(|&i| mesh.features[i as usize] == f),
                "cluster {}: a triangle spans two objects",
                c.id
            );
        }
        let below: std::collections::HashSet<u32> = common::leaves_below(&b.tree, c.id)
            .iter()
            .flat_map(|&l| b.tree.cluster(l).objects.clone())
            .map(|o| index[o.as_str()])
            .collect();
        let mut distinct = mesh.features.clone();
        distinct.sort_unstable();
        distinct.dedup();
        assert!(
            distinct.iter().all(|f| below.contains(f)),
            "cluster {}: features {distinct:?}, objects below {below:?}",
            c.id
        );
        if c.is_leaf() {
            assert_eq!(distinct.len(), 1, "leaf {}", c.id);
        }
        let bytes = std::fs::read(&file).unwrap();
        let glb = gltf::binary::Glb::from_slice(&bytes).unwrap();
        let json: serde_json::Value = serde_json::from_slice(&glb.json).unwrap();
        let used = json["extensionsUsed"].as_array().unwrap();
        assert!(used.iter().any(|e| e == "EXT_mesh_features"), "{used:?}");
        let primitive = &json["meshes"][0]["primitives"][0];
        assert!(primitive["attributes"]["_FEATURE_ID_0"].is_u64());
        let ids = &primitive["extensions"]["EXT_mesh_features"]["featureIds"][0];
        assert_eq!(ids["attribute"], 0);
        assert_eq!(ids["featureCount"], distinct.len());
    }
    assert!(files.len() > 10);
    common::assert_no_gltf_errors(&files);
}

/// Feature fidelity: the triangles a cluster gives an object lie within the
/// cluster's `eps_c` of that object's own geometry.
#[test]
fn an_objects_triangles_lie_within_eps_of_the_object() {
    let b = built();
    let clusters: Vec<u32> = b.tree.clusters().map(|c| c.id).collect();
    let distances =
        hdlod::tree::fidelity::feature_distances(&b.dir, &b.tree, &b.scene, &clusters, 1e-4)
            .unwrap();
    assert!(distances.len() >= b.scene.objects.len() / 2);
    // What the measure adds for float rounding (`one_sided_bound`), and its
    // tolerance.
    let largest = b
        .tree
        .bounds
        .min
        .abs()
        .max(b.tree.bounds.max.abs())
        .max_element();
    let slack = 16.0 * f64::from(f32::EPSILON) * largest + 1e-4;
    let mut coarse = 0;
    for d in &distances {
        assert!(
            d.distance <= d.eps + slack,
            "cluster {} object {}: {} triangles up to {} from it, eps {}",
            d.cluster,
            d.feature,
            d.triangles,
            d.distance,
            d.eps
        );
        coarse += usize::from(d.eps > 0.0 && d.distance > 0.0);
    }
    // The check saw reduced geometry, not only leaves.
    assert!(coarse > 10, "{coarse} reduced features");
}

/// Baked colour changes colour only: built without it, the tree has the
/// same clusters with the same errors, boxes and triangles, and every
/// cluster's triangles the same corners and objects in the same order.
/// Built with it, reduced clusters carry a texture that reads back, and
/// those that stand for lattices (the cranes) keep their cover as alpha.
#[test]
fn baked_colour_changes_colour_only() {
    let plain = built();
    let baked = &build(&BuildConfig {
        bake: true,
        ..BuildConfig::default()
    });
    assert_eq!(plain.tree.cluster_count(), baked.tree.cluster_count());
    let path = |b: &Built, hash: &str| b.tree.geometry_file(&b.dir, hash);
    // Each triangle's corners in a fixed order: the index codec of the
    // compact GLB may rotate a triangle's corners.
    let corners = |m: &Mesh| -> Vec<(Vec3, Option<u32>)> {
        m.indices
            .chunks_exact(3)
            .flat_map(|t| {
                let mut c: Vec<_> = t
                    .iter()
                    .map(|&i| (m.positions[i as usize], m.features.get(i as usize).copied()))
                    .collect();
                c.sort_by(|a, b| a.0.to_array().partial_cmp(&b.0.to_array()).unwrap());
                c
            })
            .collect()
    };
    let mut textured = 0;
    let mut translucent = 0;
    let mut files = Vec::new();
    for (a, b) in plain.tree.clusters().zip(baked.tree.clusters()) {
        assert_eq!(
            (a.eps, a.gamma, a.triangles, a.w, a.level, &a.children),
            (b.eps, b.gamma, b.triangles, b.w, b.level, &b.children),
            "cluster {}",
            a.id
        );
        assert_eq!(a.bounds, b.bounds, "cluster {}", a.id);
        let (Some(ga), Some(gb)) = (&a.geometry, &b.geometry) else {
            assert_eq!(a.geometry.is_none(), b.geometry.is_none());
            continue;
        };
        let before = read_mesh(&path(plain, ga)).unwrap();
        let (after, texture) = read_textured_mesh(&path(baked, gb)).unwrap();
        let (x, y) = (corners(&before), corners(&after));
        assert_eq!(x.len(), y.len(), "cluster {}", a.id);
        for ((p, f), (q, g)) in x.iter().zip(&y) {
            // The same point, but for the rounding of the GLB's local origin.
            assert!(
                p.distance(*q) <= 1e-5 * p.length().max(1.0),
                "cluster {}: {p} {q}",
                a.id
            );
            assert_eq!(f, g, "cluster {}", a.id);
        }
        if let Some(t) = texture {
            textured += 1;
            files.push(path(baked, gb));
            assert!(!b.is_leaf(), "leaf {} has a texture", b.id);
            assert_eq!(t.uvs.len(), after.positions.len());
            assert!(
                t.uvs
                    .iter()
                    .all(|uv| (0.0..=1.0).contains(&uv.x) && (0.0..=1.0).contains(&uv.y))
            );
            let atlas = decode_png(&t.png).unwrap();
            let cap = BuildConfig::default().bake_max_texels;
            assert!(
                atlas.width <= cap && atlas.height <= cap,
                "cluster {}",
                b.id
            );
            // A texture with a cover under 1 (a crane's lattice as a box)
            // is blended, and only then.
            let bytes = std::fs::read(path(baked, gb)).unwrap();
            let length = u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize;
            let json: serde_json::Value = serde_json::from_slice(&bytes[20..20 + length]).unwrap();
            let covered = atlas.texels.iter().all(|t| t[3] == 255);
            assert_eq!(
                json["materials"][0]["alphaMode"] == "BLEND",
                !covered,
                "cluster {}",
                b.id
            );
            translucent += usize::from(!covered);
        }
    }
    assert!(textured > 10, "{textured} textured clusters");
    assert!(translucent > 0, "no cluster keeps a cover under 1");
    common::assert_no_gltf_errors(&files);
}

/// A LOD chain moves as one: its keyframes are written once, on the
/// chain's top, and every other level names that cluster (`motion_from`);
/// the JSON and the index read back the motions the builder made.
#[test]
fn a_lod_chain_writes_its_keyframes_once() {
    let b = built();
    let text = std::fs::read_to_string(b.dir.join("clusters.json")).unwrap();
    let json: serde_json::Value = serde_json::from_str(&text).unwrap();
    let clusters = json["clusters"].as_array().unwrap();
    let mut shared = 0;
    for c in clusters.iter().filter(|c| c["class"] == "dynamic") {
        match c.get("motion_from") {
            Some(from) => {
                shared += 1;
                assert!(c["motion"].is_null(), "{}", c["id"]);
                let from = from.as_u64().unwrap();
                assert!(clusters[from as usize]["motion"].is_array(), "{from}");
                // The top is an ancestor: up the chain from this cluster.
                let mut at = c["id"].as_u64().unwrap();
                while at != from {
                    at = clusters[at as usize]["parent"]
                        .as_u64()
                        .expect("reaches the top");
                }
            }
            None => assert!(c["motion"].is_array(), "{}", c["id"]),
        }
    }
    assert!(
        shared > 10,
        "{shared} clusters share their chain's keyframes"
    );
    let from_json = hdlod::tree::store::load_json(&b.dir).unwrap();
    for id in 0..b.tree.cluster_count() as u32 {
        let motion = from_json.cluster(id).motion.clone();
        assert_eq!(motion, b.tree.cluster(id).motion, "cluster {id}");
    }

    // A cluster that names one without keyframes of its own is refused,
    // naming the field.
    let root = json["clusters"]
        .as_array()
        .unwrap()
        .iter()
        .position(|c| c["class"] == "root")
        .unwrap();
    let dir = tempfile::tempdir().unwrap();
    for entry in std::fs::read_dir(&b.dir).unwrap() {
        let path = entry.unwrap().path();
        if path.is_file() && path.file_name().unwrap() != "clusters.bin" {
            std::fs::copy(&path, dir.path().join(path.file_name().unwrap())).unwrap();
        }
    }
    std::os::unix::fs::symlink(b.dir.join("geometry"), dir.path().join("geometry")).unwrap();
    let mut broken = json.clone();
    let k = clusters
        .iter()
        .position(|c| c.get("motion_from").is_some())
        .unwrap();
    broken["clusters"][k]["motion_from"] = root.into();
    std::fs::write(dir.path().join("clusters.json"), broken.to_string()).unwrap();
    let err = load(dir.path()).unwrap_err().to_string();
    assert!(err.contains(&format!("clusters[{k}].motion_from")), "{err}");
    assert!(err.contains("no keyframes of its own"), "{err}");
}
