//! Time slices as 3D Tiles 1.1 on the tree built from the committed tiny
//! fixture: the files follow the official 3D Tiles 1.1 JSON schemas, and a
//! 3D Tiles traversal of them (transforms composed down the tiles, external
//! tilesets followed, content URIs resolved) reproduces the cut. A skinned
//! object's tiles hold its mesh posed at the slice's time.

mod common;

use std::collections::BTreeMap;
use std::sync::OnceLock;

use common::{schema_errors, tileset_validator};
use glam::{DMat4, DVec3};
use hdlod::build::{BuildConfig, Silent, build_to};
use hdlod::io::gltf::read_skinned_mesh;
use hdlod::scene::{Up, format};
use hdlod::tiles::{
    ContentNames, DEFAULT_MAX_BYTES, Frame, Options, Tile, Tileset, TimeSlice, Y_UP_TO_Z_UP,
    root_transform, time_slice,
};
use hdlod::tree::{Aabb, CameraSpec, Tree, View, Viewport, cut, load};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

struct Built {
    tree: Tree,
    _tmp: tempfile::TempDir,
}

fn tree() -> &'static Tree {
    static BUILT: OnceLock<Built> = OnceLock::new();
    &BUILT
        .get_or_init(|| {
            let fixture = common::repo().join("fixtures/skyscraper-tiny");
            let scene = format::load(&fixture).expect("the tiny fixture loads");
            // A static is never dropped: in cargo's temporary directory
            // for tests, which `cargo clean` empties, not the system's.
            let tmp = tempfile::tempdir_in(env!("CARGO_TARGET_TMPDIR")).unwrap();
            let dir = tmp.path().join("tree");
            build_to(&scene, &BuildConfig::default(), &dir, &Silent).expect("the build succeeds");
            Built {
                tree: load(&dir).expect("the written tree loads"),
                _tmp: tmp,
            }
        })
        .tree
}

fn times(tree: &Tree) -> [f64; 5] {
    let s = tree.time.seconds;
    [0.0, s / 3.0, s / 2.0, 2.0 * s / 3.0, s]
}

fn disk(max_bytes: usize) -> Options {
    Options {
        max_bytes,
        ..Options::new("geometry", "tilesets")
    }
}

#[test]
fn slices_follow_the_3d_tiles_schemas() {
    let Some(validator) = tileset_validator() else {
        return;
    };
    let tree = tree();
    // The schema bites: a tileset without its root is refused.
    let mut broken = serde_json::to_value(
        time_slice(tree, 0.0, &disk(DEFAULT_MAX_BYTES))
            .unwrap()
            .root,
    )
    .unwrap();
    let mut negative = broken.clone();
    broken.as_object_mut().unwrap().remove("root");
    assert!(!schema_errors(&validator, &broken).is_empty());
    // ... and so do the schemas it refers to (tile, bounding volume).
    negative["root"]["geometricError"] = serde_json::json!(-1.0);
    assert!(!schema_errors(&validator, &negative).is_empty());
    let mut short_box = negative.clone();
    short_box["root"]["geometricError"] = serde_json::json!(1.0);
    assert!(schema_errors(&validator, &short_box).is_empty());
    short_box["root"]["boundingVolume"]["box"] = serde_json::json!(vec![0.0; 11]);
    assert!(!schema_errors(&validator, &short_box).is_empty());

    let mut split_seen = 0;
    for t in times(tree) {
        for max_bytes in [DEFAULT_MAX_BYTES, 16 * 1024] {
            let slice = time_slice(tree, t, &disk(max_bytes)).unwrap();
            let files = std::iter::once((None, &slice.root))
                .chain(slice.external.iter().map(|(id, s)| (Some(*id), s)));
            for (id, tileset) in files {
                let json = serde_json::to_value(tileset).unwrap();
                let errors = schema_errors(&validator, &json);
                assert!(errors.is_empty(), "t = {t}, file {id:?}: {errors:?}");
                let bytes = serde_json::to_vec(tileset).unwrap().len();
                assert!(bytes <= max_bytes, "t = {t}, file {id:?}: {bytes} bytes");
                assert_eq!(tileset.asset.version, "1.1");
            }
            if max_bytes == DEFAULT_MAX_BYTES {
                assert!(slice.external.is_empty(), "the tiny tree fits one file");
            } else if slice.external.len() > 1 {
                split_seen += 1;
            }
        }
    }
    assert!(
        split_seen >= 3,
        "a small budget splits the slices ({split_seen})"
    );
}

/// One tile as a client sees it: its composed transform and the file that
/// holds it (`None` for the root file).
struct Visit<'a> {
    tile: &'a Tile,
    chain: DMat4,
    file: Option<u32>,
}

/// The 3D Tiles reading of a time slice: `chain` composes the transforms,
/// stubs whose content is a `.json` lead into external tilesets.
struct Client<'a> {
    slice: &'a TimeSlice,
    options: &'a Options,
}

impl<'a> Client<'a> {
    /// Resolves `uri` from the file it is in, relative to the root file's
    /// directory, with `..` removed.
    fn resolve(&self, file: Option<u32>, uri: &str) -> String {
        let mut parts: Vec<&str> = match file {
            None => vec![],
            Some(_) => vec![self.options.subtileset_dir.as_str()],
        };
        for part in uri.split('/') {
            match part {
                ".." => {
                    if parts.pop().is_none() {
                        parts.push("..");
                    }
                }
                p => parts.push(p),
            }
        }
        parts.join("/")
    }

    /// The children of a visit, through an external tileset if it is a stub.
    fn children(&self, visit: &Visit<'a>) -> Vec<Visit<'a>> {
        let mut out = Vec::new();
        if let Some(content) = &visit.tile.content
            && content.uri.ends_with(".json")
        {
            let path = self.resolve(visit.file, &content.uri);
            let id: u32 = path
                .strip_prefix(&format!("{}/", self.options.subtileset_dir))
                .and_then(|p| p.strip_suffix(".json"))
                .and_then(|p| p.parse().ok())
                .unwrap_or_else(|| panic!("{path} is an external tileset's path"));
            let external: &Tileset = &self.slice.external[&id];
            assert!(visit.tile.children.is_empty(), "a stub has no children");
            out.push(self.visit(&external.root, visit.chain, Some(id)));
        }
        for child in &visit.tile.children {
            out.push(self.visit(child, visit.chain, visit.file));
        }
        out
    }

    fn visit(&self, tile: &'a Tile, parent: DMat4, file: Option<u32>) -> Visit<'a> {
        let own = tile
            .transform
            .map_or(DMat4::IDENTITY, |m| DMat4::from_cols_array(&m));
        Visit {
            tile,
            chain: parent * own,
            file,
        }
    }

    /// The tile's box in the z-up world: the bounds of its 8 corners.
    fn world_box(visit: &Visit) -> Aabb {
        let b = &visit.tile.bounding_volume.obb;
        let c = DVec3::new(b[0], b[1], b[2]);
        let axes = [
            DVec3::new(b[3], b[4], b[5]),
            DVec3::new(b[6], b[7], b[8]),
            DVec3::new(b[9], b[10], b[11]),
        ];
        let mut lo = DVec3::INFINITY;
        let mut hi = DVec3::NEG_INFINITY;
        for i in 0..8 {
            let mut p = c;
            for (k, a) in axes.iter().enumerate() {
                p += if i >> k & 1 == 0 { -*a } else { *a };
            }
            let p = visit.chain.transform_point3(p);
            lo = lo.min(p);
            hi = hi.max(p);
        }
        Aabb::new(lo, hi)
    }

    /// Every tile with its visit, depth first.
    fn all(&self) -> Vec<Visit<'a>> {
        let mut stack = vec![self.visit(&self.slice.root.root, DMat4::IDENTITY, None)];
        let mut out = Vec::new();
        while let Some(v) = stack.pop() {
            stack.extend(self.children(&v));
            out.push(v);
        }
        out
    }

    /// The content tiles a 3D Tiles client draws with `REPLACE` refinement:
    /// refine where `error * scale / distance >= r` (`scale` the largest of
    /// the composed transform's), draw content where a tile is not refined.
    /// `error` picks the geometric error of a tile.
    fn draw(&self, view: &View, error: &dyn Fn(&Tile) -> f64) -> Vec<(u32, String)> {
        let mut out = Vec::new();
        let mut stack = vec![self.visit(&self.slice.root.root, DMat4::IDENTITY, None)];
        while let Some(v) = stack.pop() {
            let b = Self::world_box(&v);
            if view.outside(&b) {
                continue;
            }
            let children = self.children(&v);
            let stub = v
                .tile
                .content
                .as_ref()
                .is_some_and(|c| c.uri.ends_with(".json"));
            // As CesiumJS does, the error grows with the largest scale of
            // the composed transform (a scaled pose stretches the tile).
            let scale = [v.chain.x_axis, v.chain.y_axis, v.chain.z_axis]
                .iter()
                .map(|a| a.truncate().length())
                .fold(0.0, f64::max);
            let refine = !children.is_empty()
                && (stub || error(v.tile) * scale >= view.r() * view.distance(&b));
            if refine {
                stack.extend(children.into_iter().rev());
            } else if let Some(content) = &v.tile.content {
                let id = v.tile.extras.unwrap().cluster;
                out.push((id, self.resolve(v.file, &content.uri)));
            }
        }
        out
    }
}

/// The scene frame to the tileset's z-up world.
fn to_world(up: Up) -> DMat4 {
    root_transform(up, None).unwrap() * Y_UP_TO_Z_UP
}

/// The tiny tree turned to `up`, in its local frame (not placed on Earth).
fn tree_with_up(up: Up) -> Tree {
    let mut t = tree().clone();
    t.up = up;
    t.georeference = None;
    t
}

/// The tiny site is placed on Earth: its root maps the local frame to ECEF
/// at its origin, unless the local frame is asked for.
#[test]
fn a_georeferenced_slice_lands_on_the_globe() {
    let tree = tree();
    let g = tree.georeference.expect("the fixture has a site");
    let t = tree.time.seconds / 2.0;
    let slice = time_slice(tree, t, &disk(DEFAULT_MAX_BYTES)).unwrap();
    let m = DMat4::from_cols_array(&slice.root.root.transform.expect("a root transform"));
    assert!(m.abs_diff_eq(g.to_ecef().unwrap().unwrap(), 1e-6));
    // The site's centre lies within its own size of the origin on Earth,
    // some 6,365 km from the Earth's centre at that latitude.
    let centre = (tree.bounds.min + tree.bounds.max) / 2.0;
    let ecef = m.transform_point3(Y_UP_TO_Z_UP.transform_point3(centre));
    let origin = g.geographic().unwrap().unwrap().origin_ecef();
    assert!(ecef.distance(origin) < tree.bounds.diagonal());
    assert!((6.36e6..6.37e6).contains(&ecef.length()), "{ecef}");
    let local = Options {
        frame: Frame::Local,
        ..disk(DEFAULT_MAX_BYTES)
    };
    let slice = time_slice(tree, t, &local).unwrap();
    assert_eq!(slice.root.root.transform, None);
}

#[test]
fn boxes_transforms_and_content_are_the_cuts() {
    let mut moving = 0;
    for up in [Up::Y, Up::Z] {
        let tree = tree_with_up(up);
        let world = to_world(up);
        for t in times(&tree) {
            let options = disk(16 * 1024);
            let slice = time_slice(&tree, t, &options).unwrap();
            let client = Client {
                slice: &slice,
                options: &options,
            };
            let mut seen = 0;
            for visit in client.all() {
                if visit
                    .tile
                    .content
                    .as_ref()
                    .is_some_and(|c| c.uri.ends_with(".json"))
                {
                    continue;
                }
                seen += 1;
                let id = visit.tile.extras.unwrap().cluster;
                let c = &tree.cluster(id);
                let v = c.visibility.at(t);
                assert!(v > 0.0, "cluster {id} is absent at {t} but has a tile");
                let (pose, cut_box) = match &c.motion {
                    Some(m) => {
                        let pose = m.at(t).as_dmat4();
                        moving += 1;
                        (pose, c.bounds.transformed(&pose))
                    }
                    None => (DMat4::IDENTITY, c.bounds),
                };
                // The tile's box in the world is the cut's box in the world.
                let expected = cut_box.transformed(&world);
                let got = Client::world_box(&visit);
                let tol = 1e-6 * (1.0 + tree.bounds.diagonal());
                assert!(
                    got.min.abs_diff_eq(expected.min, tol)
                        && got.max.abs_diff_eq(expected.max, tol),
                    "{up:?} t = {t} cluster {id}: {got:?} vs {expected:?}"
                );
                // The content, turned y-up to z-up as a client loads glTF and
                // placed by the tile transforms, lands where the cut puts it.
                if let Some(content) = &visit.tile.content {
                    assert!(v >= 0.5);
                    let hash = c.geometry.as_ref().unwrap();
                    assert_eq!(
                        client.resolve(visit.file, &content.uri),
                        format!("geometry/{hash}.glb")
                    );
                    let placed = visit.chain * Y_UP_TO_Z_UP;
                    let wanted = world * pose;
                    assert!(
                        placed.abs_diff_eq(wanted, 1e-9 * (1.0 + tree.bounds.diagonal())),
                        "{up:?} t = {t} cluster {id}: content placed by {placed} instead of {wanted}"
                    );
                } else {
                    assert!(
                        v < 0.5 || c.geometry.is_none(),
                        "cluster {id} lost its content"
                    );
                }
                // Errors shrink strictly downwards and bound delta_c(t).
                assert!(visit.tile.geometric_error >= c.delta(v));
                for child in &visit.tile.children {
                    assert!(child.geometric_error < visit.tile.geometric_error);
                }
            }
            let present = tree.clusters().filter(|c| c.visibility.at(t) > 0.0).count();
            assert_eq!(
                seen, present,
                "{up:?} t = {t}: one tile per present cluster"
            );
        }
    }
    assert!(moving > 0, "moving clusters were checked");
}

fn random_views(tree: &Tree, up: Up, n: usize) -> Vec<(CameraSpec, Viewport, f64)> {
    let world = to_world(up);
    let centre = (tree.bounds.min + tree.bounds.max) / 2.0;
    let size = tree.bounds.diagonal();
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    (0..n)
        .map(|_| {
            let mut point = |spread: f64| {
                centre
                    + DVec3::new(
                        rng.random_range(-1.0..1.0),
                        rng.random_range(0.0..1.0),
                        rng.random_range(-1.0..1.0),
                    ) * spread
            };
            let eye = point(size * 0.8);
            let target = point(size * 0.1);
            let up_axis = world.transform_vector3(DVec3::Y);
            let spec = CameraSpec {
                position: Some(world.transform_point3(eye).to_array()),
                target: Some(world.transform_point3(target).to_array()),
                up: Some(up_axis.to_array()),
                ..Default::default()
            };
            let viewport = Viewport {
                width: 1280,
                height: 720,
            };
            (spec, viewport, 1.0)
        })
        .collect()
}

/// A camera in the scene frame from one in the tileset's world.
fn scene_camera(spec: &CameraSpec, up: Up) -> CameraSpec {
    let back = to_world(up).inverse();
    let p = |v: [f64; 3]| back.transform_point3(DVec3::from_array(v)).to_array();
    let d = |v: [f64; 3]| back.transform_vector3(DVec3::from_array(v)).to_array();
    CameraSpec {
        position: spec.position.map(p),
        target: spec.target.map(p),
        up: spec.up.map(d),
        ..spec.clone()
    }
}

#[test]
fn a_3d_tiles_traversal_draws_the_cut() {
    let mut total_cut = 0u64;
    let mut total_tiles = 0u64;
    for up in [Up::Y, Up::Z] {
        let tree = tree_with_up(up);
        for t in times(&tree) {
            for max_bytes in [DEFAULT_MAX_BYTES, 16 * 1024] {
                let options = disk(max_bytes);
                let slice = time_slice(&tree, t, &options).unwrap();
                let client = Client {
                    slice: &slice,
                    options: &options,
                };
                for (spec, viewport, pixel_error) in random_views(&tree, up, 40) {
                    let world_view = View::new(&spec, viewport, pixel_error, DVec3::Z).unwrap();
                    let scene_view =
                        View::new(&scene_camera(&spec, up), viewport, pixel_error, DVec3::Y)
                            .unwrap();
                    let expected: Vec<u32> = cut(&tree, &scene_view, t)
                        .items
                        .iter()
                        .map(|i| i.id)
                        .collect();
                    // With the cut's own errors, the tileset is the cut.
                    let delta = |tile: &Tile| {
                        let x = tile.extras.unwrap();
                        tree.cluster(x.cluster).delta(x.visibility)
                    };
                    let drawn = client.draw(&world_view, &delta);
                    let ids: Vec<u32> = drawn.iter().map(|d| d.0).collect();
                    assert_eq!(ids, expected, "{up:?} t = {t}, {spec:?}");
                    for (id, path) in &drawn {
                        let hash = tree.geometry_of(*id).unwrap();
                        assert_eq!(path, &format!("geometry/{hash}.glb"));
                    }
                    // With the written errors (raised to shrink downwards) a
                    // client draws at least as finely, about as much.
                    let tiles: u64 = client
                        .draw(&world_view, &|tile: &Tile| tile.geometric_error)
                        .iter()
                        .map(|d| tree.cluster(d.0).triangles)
                        .sum();
                    let cut_triangles: u64 =
                        expected.iter().map(|&i| tree.cluster(i).triangles).sum();
                    total_cut += cut_triangles;
                    total_tiles += tiles;
                }
            }
        }
    }
    let ratio = total_tiles as f64 / total_cut as f64;
    eprintln!("triangles: tileset {total_tiles}, cut {total_cut}, ratio {ratio:.4}");
    assert!(total_cut > 0);
    assert!((0.95..=1.05).contains(&ratio), "ratio {ratio}");
}

#[test]
fn bad_arguments_are_named() {
    let tree = tree();
    let err = time_slice(tree, f64::NAN, &disk(DEFAULT_MAX_BYTES)).unwrap_err();
    assert!(err.to_string().starts_with("time"), "{err}");
    let err = time_slice(tree, 0.0, &Options::new("geometry", "a/b")).unwrap_err();
    assert!(err.to_string().starts_with("subtileset_dir"), "{err}");
    let err = time_slice(tree, 0.0, &disk(100)).unwrap_err();
    assert!(err.to_string().starts_with("max_bytes"), "{err}");
    let files: BTreeMap<u32, Tileset> = time_slice(tree, -1e6, &disk(DEFAULT_MAX_BYTES))
        .unwrap()
        .external;
    assert!(files.is_empty());
}

/// A skinned cluster's tile names content made for the slice's time, its
/// mesh posed by its skeleton then, inside its tile's box; rigid tiles name
/// what they always did. A skinned cluster whose GLB lost its joints is an
/// error naming the file and the attribute.
#[test]
fn a_skinned_cluster_s_content_is_its_mesh_posed_at_the_slice_s_time() {
    let validator = tileset_validator();
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("tree");
    let scene = common::skinned_bar_scene();
    build_to(&scene, &BuildConfig::default(), &dir, &Silent).unwrap();
    let tree = load(&dir).unwrap();
    let tables = tree.objects.as_ref().expect("a build writes object tables");
    let skin = scene.objects[0].skin.as_ref().unwrap();
    let glb_of = |id: u32| tree.geometry_file(&dir, &tree.geometry_of(id).unwrap());
    let mut skinned = Vec::new();
    for t in [12.0, 19.0] {
        let options = Options {
            content: ContentNames::Cluster,
            posed_dir: format!("posed/{t}"),
            ..Options::new("content", "tilesets")
        };
        let slice = time_slice(&tree, t, &options).unwrap();
        if let Some(validator) = &validator {
            let json = serde_json::to_value(&slice.root).unwrap();
            let errors = schema_errors(validator, &json);
            assert!(errors.is_empty(), "t = {t}: {errors:?}");
        }
        let client = Client {
            slice: &slice,
            options: &options,
        };
        let mut rigid = 0;
        for visit in client.all() {
            let Some(content) = &visit.tile.content else {
                continue;
            };
            let id = visit.tile.extras.unwrap().cluster;
            let Some(skeleton) = tree.skeleton_of(id) else {
                assert_eq!(content.uri, format!("content/{id}.glb"), "rigid, as before");
                rigid += 1;
                continue;
            };
            assert_eq!(content.uri, format!("posed/{t}/{id}.glb"));
            let glb = hdlod::tiles::content::cluster(&tree, tables, id, &glb_of(id), Some(t), None)
                .unwrap();
            let file = tmp.path().join(format!("{t}-{id}.glb"));
            std::fs::write(&file, glb).unwrap();
            let posed = hdlod::io::read_mesh(&file).unwrap();
            // The stored bind-pose mesh moved by the skeleton's matrices.
            let (stored, vertices) = read_skinned_mesh(&glb_of(id), skeleton.joints.len()).unwrap();
            let mut matrices = Vec::new();
            skeleton.matrices_into(t, &mut matrices);
            let expected = vertices.pose(&stored, &matrices);
            assert_eq!(posed.positions.len(), expected.positions.len());
            for (p, q) in posed.positions.iter().zip(&expected.positions) {
                assert!(
                    p.distance(*q) < 1e-4,
                    "t = {t}, cluster {id}: {p} against {q}"
                );
            }
            // ... each a vertex of the scene's bar posed then, inside the
            // tile's box.
            let scene_posed = skin.pose(&scene.meshes[1], t);
            let b = Client::world_box(&visit);
            for p in &posed.positions {
                let near = scene_posed
                    .positions
                    .iter()
                    .map(|q| p.distance(*q))
                    .fold(f32::INFINITY, f32::min);
                assert!(near < 1e-4, "t = {t}: {p} is {near} from the posed bar");
                let z_up = Y_UP_TO_Z_UP.transform_point3(p.as_dvec3());
                assert!(
                    b.min.cmple(z_up + 1e-6).all() && b.max.cmpge(z_up - 1e-6).all(),
                    "t = {t}: {z_up} outside the tile's box {b:?}"
                );
            }
            skinned.push((t, id, posed.positions));
        }
        assert!(rigid > 0, "t = {t}: the box is drawn");
    }
    let leaf = |t: f64| {
        skinned
            .iter()
            .filter(|s| s.0 == t)
            .max_by_key(|s| s.2.len())
            .unwrap_or_else(|| panic!("t = {t}: no skinned tile"))
    };
    let (early, late) = (leaf(12.0), leaf(19.0));
    assert_eq!(early.1, late.1, "the same cluster at both times");
    assert_ne!(early.2, late.2, "posed differently");

    // A skinned cluster's GLB without its joints and weights.
    let id = early.1;
    hdlod::io::glb::write_mesh(&scene.meshes[1], &glb_of(id)).unwrap();
    let err = hdlod::tiles::content::cluster(&tree, tables, id, &glb_of(id), Some(12.0), None)
        .unwrap_err()
        .to_string();
    let name = glb_of(id)
        .file_name()
        .unwrap()
        .to_string_lossy()
        .into_owned();
    assert!(err.contains(&name) && err.contains("JOINTS_0"), "{err}");
}
