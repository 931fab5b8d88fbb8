//! A small synthetic tree in the `hdlod-tree/1` format, for tests,
//! benchmarks of the serving side and demos before a real build exists: a
//! ground of static slabs, a tower of pseudo-dynamic elements installed
//! floor by floor (with temporary scaffolding), and moving cranes with a
//! two-step LOD chain. Its structure and its `v`, `w` and `gamma` follow
//! DESIGN.md section 2 exactly; geometry is boxes and a parent's geometry is
//! the box of its children. Its `eps` is synthetic, not measured: the
//! children's largest `eps` plus 1% of the parent's diagonal, which keeps
//! `eps` growing upwards like a real tree's so that cuts coarsen with
//! distance.

use std::path::Path;

use glam::{DVec3, Quat, Vec3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use super::{Aabb, Cluster, ClusterClass, Steps, Tree, TreeWriter};
use crate::error::Result;
use crate::geometry::Mesh;
use crate::io::glb::mesh_to_glb;
use crate::scene::{Keyframe, Motion, Up};
use crate::time::{TimeSpan, parse_date};

/// An axis-aligned box with each face cut into `k x k` quads.
fn box_mesh(b: &Aabb, k: u32) -> Mesh {
    let (lo, hi) = (b.min.as_vec3(), b.max.as_vec3());
    let mut mesh = Mesh::default();
    for axis in 0..3 {
        for side in [0.0f32, 1.0] {
            let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
            let base = mesh.positions.len() as u32;
            for i in 0..=k {
                for j in 0..=k {
                    let mut p = Vec3::ZERO;
                    p[axis] = lo[axis] + side * (hi[axis] - lo[axis]);
                    p[u] = lo[u] + (hi[u] - lo[u]) * i as f32 / k as f32;
                    p[v] = lo[v] + (hi[v] - lo[v]) * j as f32 / k as f32;
                    mesh.positions.push(p);
                }
            }
            for i in 0..k {
                for j in 0..k {
                    let a = base + i * (k + 1) + j;
                    let (b, c, d) = (a + k + 1, a + 1, a + k + 2);
                    mesh.indices.extend_from_slice(&[a, b, c, c, b, d]);
                }
            }
        }
    }
    mesh
}

const MAX_STEPS: usize = 64;

/// `sum w_i v_i(t) / sum w_i` as steps at the children's breakpoints.
fn weighted(children: &[(f64, &Steps)]) -> Steps {
    let mut times: Vec<f64> = children
        .iter()
        .flat_map(|(_, s)| s.steps().iter().map(|s| s.0))
        .collect();
    times.sort_by(f64::total_cmp);
    times.dedup();
    // Like a real build, keep a bounded number of steps (the loss shows in
    // gamma, which is measured against the leaves).
    if times.len() > MAX_STEPS {
        let n = times.len();
        times = (0..MAX_STEPS).map(|i| times[i * n / MAX_STEPS]).collect();
    }
    let total: f64 = children.iter().map(|c| c.0).sum();
    let steps = times
        .into_iter()
        .map(|t| {
            let v = children
                .iter()
                .map(|(w, s)| w * f64::from(s.at(t)))
                .sum::<f64>()
                / total;
            (t, v.clamp(0.0, 1.0) as f32)
        })
        .collect();
    Steps::new(steps).expect("sorted, deduplicated, in [0, 1]")
}

/// `(1/T) * integral_0^T |a(t) - b(t)| dt` of two step functions.
fn mean_gap(a: &Steps, b: &Steps, span: f64) -> f64 {
    let mut cuts: Vec<f64> = a
        .steps()
        .iter()
        .chain(b.steps())
        .map(|s| s.0.clamp(0.0, span))
        .collect();
    cuts.extend([0.0, span]);
    cuts.sort_by(f64::total_cmp);
    cuts.dedup();
    let sum: f64 = cuts
        .windows(2)
        .map(|w| (w[1] - w[0]) * f64::from((a.at(w[0]) - b.at(w[0])).abs()))
        .sum();
    sum / span
}

struct Builder<'w> {
    writer: &'w TreeWriter,
    clusters: Vec<Cluster>,
    span: f64,
}

impl Builder<'_> {
    fn leaf(
        &mut self,
        id: &str,
        class: ClusterClass,
        bounds: Aabb,
        k: u32,
        visibility: Steps,
        motion: Option<Motion>,
    ) -> Result<u32> {
        let mesh = box_mesh(&bounds, k);
        let hash = self.writer.put_geometry(&mesh_to_glb(&mesh))?;
        let n = self.clusters.len() as u32;
        self.clusters.push(Cluster {
            id: n,
            parent: None,
            children: vec![],
            level: 0,
            class,
            bounds,
            w: bounds.diagonal(),
            eps: 0.0,
            gamma: 0.0,
            visibility,
            motion,
            geometry: Some(hash),
            triangles: mesh.triangle_count() as u64,
            objects: vec![id.into()],
        });
        Ok(n)
    }

    /// The leaves under `id`.
    fn leaves(&self, id: u32) -> Vec<u32> {
        let c = &self.clusters[id as usize];
        if c.is_leaf() {
            vec![id]
        } else {
            c.children.iter().flat_map(|&ch| self.leaves(ch)).collect()
        }
    }

    fn parent(&mut self, class: ClusterClass, children: &[u32]) -> Result<u32> {
        let n = self.clusters.len() as u32;
        let first = &self.clusters[children[0] as usize];
        let bounds = children.iter().fold(first.bounds, |b, &c| {
            b.union(&self.clusters[c as usize].bounds)
        });
        let parts: Vec<(f64, &Steps)> = children
            .iter()
            .map(|&c| {
                (
                    self.clusters[c as usize].w,
                    &self.clusters[c as usize].visibility,
                )
            })
            .collect();
        let visibility = weighted(&parts);
        let gamma = self
            .leaves(children[0])
            .into_iter()
            .chain(children[1..].iter().flat_map(|&c| self.leaves(c)))
            .map(|l| {
                mean_gap(
                    &visibility,
                    &self.clusters[l as usize].visibility,
                    self.span,
                )
            })
            .fold(0.0, f64::max);
        let max_eps = children
            .iter()
            .map(|&c| self.clusters[c as usize].eps)
            .fold(0.0, f64::max);
        let level = children
            .iter()
            .map(|&c| self.clusters[c as usize].level)
            .max()
            .unwrap_or(0)
            + 1;
        let motion = first.motion.clone();
        let (geometry, triangles) = if class == ClusterClass::Root {
            (None, 0)
        } else {
            let mesh = box_mesh(&bounds, 1);
            (
                Some(self.writer.put_geometry(&mesh_to_glb(&mesh))?),
                mesh.triangle_count() as u64,
            )
        };
        for &c in children {
            self.clusters[c as usize].parent = Some(n);
        }
        self.clusters.push(Cluster {
            id: n,
            parent: None,
            children: children.to_vec(),
            level,
            class,
            bounds,
            w: bounds.diagonal(),
            eps: if class == ClusterClass::Root {
                max_eps
            } else {
                max_eps + bounds.diagonal() * 0.01
            },
            gamma,
            visibility,
            motion,
            geometry,
            triangles,
            objects: vec![],
        });
        Ok(n)
    }

    /// Groups `ids` in runs of `fan` under new parents until one is left.
    fn group(&mut self, class: ClusterClass, mut ids: Vec<u32>, fan: usize) -> Result<u32> {
        while ids.len() > 1 {
            let mut next = Vec::new();
            for chunk in ids.chunks(fan) {
                next.push(if chunk.len() == 1 {
                    chunk[0]
                } else {
                    self.parent(class, chunk)?
                });
            }
            ids = next;
        }
        Ok(ids[0])
    }
}

/// Writes the sample tree to `dir` (replacing what is there) and returns it.
/// `floors` scales the tower: each floor has 8 elements and scaffolding.
pub fn write_sample_tree(dir: &Path, seed: u64, floors: usize) -> Result<Tree> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let span = 100.0 * 86400.0;
    let writer = TreeWriter::create(dir)?;
    let mut b = Builder {
        writer: &writer,
        clusters: vec![],
        span,
    };
    let at = |x: f64, y: f64, z: f64, sx: f64, sy: f64, sz: f64| {
        Aabb::new(DVec3::new(x, y, z), DVec3::new(x + sx, y + sy, z + sz))
    };

    let mut ground = Vec::new();
    for i in 0..6 {
        for j in 0..6 {
            let bounds = at(
                i as f64 * 20.0 - 60.0,
                -1.0,
                j as f64 * 20.0 - 60.0,
                19.0,
                1.0,
                19.0,
            );
            ground.push(b.leaf(
                &format!("ground-{i}-{j}"),
                ClusterClass::Static,
                bounds,
                rng.random_range(1..4),
                Steps::constant(1.0),
                None,
            )?);
        }
    }
    let mut tower = Vec::new();
    for f in 0..floors {
        let installed = span * (f as f64 + 0.5) / (floors as f64 + 1.0);
        let y = f as f64 * 4.0;
        let mut floor = Vec::new();
        for e in 0..8 {
            let (x, z) = ((e % 4) as f64 * 6.0 - 12.0, (e / 4) as f64 * 12.0 - 12.0);
            let when = installed + rng.random_range(0.0..0.3) * span / floors as f64;
            let vis = Steps::new(vec![(when, 1.0)]).expect("one step");
            floor.push(b.leaf(
                &format!("floor{f}-e{e}"),
                ClusterClass::PseudoDynamic,
                at(x, y, z, 5.5, 3.8, 11.5),
                rng.random_range(1..5),
                vis,
                None,
            )?);
        }
        let up = installed - 0.05 * span;
        let down = installed + 0.4 * span;
        let vis = Steps::new(vec![(up.max(0.0), 1.0), (down, 0.0)]).expect("two steps");
        floor.push(b.leaf(
            &format!("scaffold{f}"),
            ClusterClass::PseudoDynamic,
            at(-14.0, y, -14.0, 28.0, 4.0, 1.0),
            2,
            vis,
            None,
        )?);
        tower.push(b.group(ClusterClass::PseudoDynamic, floor, 4)?);
    }

    let mut roots = vec![
        b.group(ClusterClass::Static, ground, 4)?,
        b.group(ClusterClass::PseudoDynamic, tower, 2)?,
    ];
    for crane in 0..4 {
        let base = DVec3::new(crane as f64 * 30.0 - 45.0, 0.0, 40.0);
        let keys = (0..4)
            .map(|k| Keyframe {
                t: span * k as f64 / 3.0,
                translation: (base + DVec3::new(k as f64 * 5.0, 0.0, -(k as f64) * 8.0)).as_vec3(),
                rotation: Quat::from_rotation_y(k as f32 * 0.7 + crane as f32),
                scale: Vec3::ONE,
            })
            .collect();
        let motion = Motion::new(keys).expect("sorted, finite keyframes");
        let gone = span * rng.random_range(0.6..1.2);
        let vis =
            Steps::new(vec![(span * 0.02 * crane as f64, 1.0), (gone, 0.0)]).expect("two steps");
        let leaf = b.leaf(
            &format!("crane{crane}"),
            ClusterClass::Dynamic,
            at(-2.0, 0.0, -2.0, 4.0, 30.0, 4.0),
            6,
            vis,
            Some(motion),
        )?;
        roots.push(b.parent(ClusterClass::Dynamic, &[leaf])?);
    }
    let root = b.parent(ClusterClass::Root, &roots)?;
    let bounds = b.clusters[..root as usize]
        .iter()
        .map(|c| match &c.motion {
            Some(m) => m.keyframes().iter().fold(c.bounds, |acc, k| {
                acc.union(&c.bounds.transformed(&k.matrix().as_dmat4()))
            }),
            None => c.bounds,
        })
        .fold(b.clusters[root as usize].bounds, |a, c| a.union(&c));
    let tree = Tree {
        scene: format!("sample-{seed}"),
        time: TimeSpan {
            start: parse_date("2024-03-01").expect("a date"),
            seconds: span,
        },
        bounds,
        up: Up::Y,
        root,
        config: serde_json::json!({"generator": "sample", "seed": seed, "floors": floors}),
        stats: serde_json::json!({"clusters": b.clusters.len()}),
        clusters: b.clusters,
        presence: Default::default(),
        nodes: Default::default(),
    };
    writer.finish(&tree)?;
    Ok(tree)
}
