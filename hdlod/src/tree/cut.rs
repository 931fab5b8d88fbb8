//! The cut (Semenov et al. 2020, appendix 1; DESIGN.md section 4): the
//! clusters a viewer draws at time `t` for a view.
//!
//! ```text
//! display(c): if v_c(t) == 0: return
//!             if box of c at t is outside the frustum: return
//!             if delta_c(t) / distance(eye, box) < r: (emit c if v_c(t) >= 0.5); return
//!             for child in children(c): display(child)
//! ```
//!
//! Two readings the pseudo-code leaves open: a leaf cannot be refined, so it
//! is emitted (when `v >= 0.5`) even if its error is too large, which happens
//! only at distance 0 (the eye inside its box) since a leaf's `delta` is 0
//! unless its visibility is fractional; and the root has no geometry, so it
//! is always refined. The root's children are taken from its presence
//! index (`presence`): those that may be present at `t`, in order, rather
//! than every one of them. The traversal reads the tree's compact copy
//! (`nodes`), is iterative with one reused stack;
//! children are pushed in reverse so that clusters come out in the order of
//! the recursive definition.

use glam::Mat4;

use super::{Tree, View};

/// One emitted cluster.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CutItem {
    pub id: u32,
    /// The cluster's pose at `t` (dynamic clusters only).
    pub transform: Option<Mat4>,
    /// `v_c(t)`.
    pub visibility: f32,
    /// `delta_c(t)`, in world units.
    pub error: f64,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct CutStats {
    pub clusters: usize,
    pub triangles: u64,
    /// Clusters examined (calls of `display`).
    pub visited: usize,
}

#[derive(Debug, Clone, PartialEq, Default)]
pub struct Cut {
    pub items: Vec<CutItem>,
    pub stats: CutStats,
}

/// The cut of `tree` at `t` (seconds since the scene's start) for `view`.
pub fn cut(tree: &Tree, view: &View, t: f64) -> Cut {
    let mut out = Cut::default();
    let mut stack = Vec::new();
    cut_into(tree, view, t, &mut out, &mut stack);
    out
}

/// [`cut`] into reused buffers: no allocation once they have grown. The
/// stack holds node indices of the tree's compact copy (`nodes`).
pub fn cut_into(tree: &Tree, view: &View, t: f64, out: &mut Cut, stack: &mut Vec<u32>) {
    out.items.clear();
    out.stats = CutStats::default();
    stack.clear();
    let nodes = tree.nodes();
    stack.push(0);
    let r = view.r();
    let mut sampled = (u32::MAX, Mat4::IDENTITY);
    while let Some(i) = stack.pop() {
        out.stats.visited += 1;
        let c = &nodes.nodes[i as usize];
        let v = nodes.visibility(c, t);
        if v <= 0.0 {
            continue;
        }
        let (bounds, transform) = if c.motion != u32::MAX {
            // The levels of a chain come one after another and share it.
            if sampled.0 != c.motion {
                let motion = tree.clusters[c.motion as usize]
                    .motion
                    .as_ref()
                    .expect("a motion source has a motion");
                sampled = (c.motion, motion.at(t));
            }
            (
                c.bounds().transformed(&sampled.1.as_dmat4()),
                Some(sampled.1),
            )
        } else {
            (c.bounds(), None)
        };
        if view.outside(&bounds) {
            continue;
        }
        let delta = c.delta(v);
        let leaf = c.child_count == 0;
        let refine = !leaf && (!c.has_geometry || delta >= r * view.distance(&bounds));
        if refine && i == 0 {
            let candidates = tree.presence().candidates(t);
            stack.extend(
                candidates
                    .iter()
                    .rev()
                    .map(|&id| nodes.node_of[id as usize]),
            );
        } else if refine {
            stack.extend((c.first_child..c.first_child + c.child_count).rev());
        } else if v >= 0.5 && c.has_geometry {
            out.stats.clusters += 1;
            out.stats.triangles += tree.clusters[c.id as usize].triangles;
            out.items.push(CutItem {
                id: c.id,
                transform,
                visibility: v,
                error: delta,
            });
        }
    }
}

#[cfg(test)]
mod tests {
    use glam::{DMat4, DVec3, DVec4, Vec4Swizzles};
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    use super::*;
    use crate::tree::{Aabb, CameraSpec, Viewport, sample};

    /// A plain recursive reading of the paper's `display`, written from the
    /// pseudo-code with its own frustum test: a box is outside when all 8 of
    /// its corners, taken to clip space, fail the same clip inequality.
    struct Reference {
        m: DMat4,
        eye: DVec3,
        r: f64,
        far: bool,
    }

    impl Reference {
        fn outside(&self, b: &Aabb) -> bool {
            let corners: Vec<DVec4> = (0..8)
                .map(|i| {
                    let p = DVec3::new(
                        [b.min.x, b.max.x][i & 1],
                        [b.min.y, b.max.y][(i >> 1) & 1],
                        [b.min.z, b.max.z][(i >> 2) & 1],
                    );
                    self.m * p.extend(1.0)
                })
                .collect();
            let tests: [fn(&DVec4) -> bool; 6] = [
                |c| c.x >= -c.w,
                |c| c.x <= c.w,
                |c| c.y >= -c.w,
                |c| c.y <= c.w,
                |c| c.z >= -c.w,
                |c| c.z <= c.w,
            ];
            let n = if self.far { 6 } else { 5 };
            tests[..n]
                .iter()
                .any(|inside| corners.iter().all(|c| !inside(c)))
        }

        fn distance(&self, b: &Aabb) -> f64 {
            let mut d2 = 0.0;
            for k in 0..3 {
                let (e, lo, hi) = (self.eye[k], b.min[k], b.max[k]);
                let gap = if e < lo {
                    lo - e
                } else if e > hi {
                    e - hi
                } else {
                    0.0
                };
                d2 += gap * gap;
            }
            d2.sqrt()
        }

        fn display(&self, tree: &Tree, id: u32, t: f64, out: &mut Vec<u32>, visited: &mut usize) {
            *visited += 1;
            let c = &tree.clusters[id as usize];
            let v = c.visibility.at(t);
            if v == 0.0 {
                return;
            }
            let b = match &c.motion {
                None => c.bounds,
                Some(m) => {
                    let mat = m.at(t).as_dmat4();
                    let pts: Vec<DVec3> = (0..8)
                        .map(|i| {
                            let p = DVec3::new(
                                [c.bounds.min.x, c.bounds.max.x][i & 1],
                                [c.bounds.min.y, c.bounds.max.y][(i >> 1) & 1],
                                [c.bounds.min.z, c.bounds.max.z][(i >> 2) & 1],
                            );
                            (mat * p.extend(1.0)).xyz()
                        })
                        .collect();
                    let lo = pts.iter().fold(DVec3::INFINITY, |a, p| a.min(*p));
                    let hi = pts.iter().fold(DVec3::NEG_INFINITY, |a, p| a.max(*p));
                    Aabb::new(lo, hi)
                }
            };
            if self.outside(&b) {
                return;
            }
            let delta = c.eps + 2.0 * c.w * f64::from(v.min(1.0 - v));
            let d = self.distance(&b);
            let fine = d > 0.0 && delta / d < self.r;
            if c.geometry.is_some() && (fine || c.children.is_empty()) {
                if v >= 0.5 {
                    out.push(id);
                }
                return;
            }
            for &ch in &c.children {
                self.display(tree, ch, t, out, visited);
            }
        }
    }

    #[test]
    fn fast_cut_matches_the_reference() {
        let dir = tempfile::tempdir().unwrap();
        let tree = sample::write_sample_tree(&dir.path().join("t"), 7, 8).unwrap();
        let span = tree.time.seconds;
        let centre = (tree.bounds.min + tree.bounds.max) / 2.0;
        let size = tree.bounds.diagonal();
        let mut rng = ChaCha8Rng::seed_from_u64(42);
        let mut emitted_total = 0;
        for case in 0..2000 {
            let rand_point = |rng: &mut ChaCha8Rng, spread: f64| {
                centre
                    + DVec3::new(
                        rng.random_range(-1.0..1.0),
                        rng.random_range(-1.0..1.0),
                        rng.random_range(-1.0..1.0),
                    ) * spread
            };
            let spread = size * rng.random_range(0.1..3.0);
            let eye = rand_point(&mut rng, spread);
            let target = rand_point(&mut rng, size * 0.3);
            let fov: f64 = rng.random_range(20.0..100.0);
            let aspect: f64 = rng.random_range(0.5..2.5);
            let height = rng.random_range(100..2000);
            let pixel_error = rng.random_range(0.3..20.0);
            let far = if case % 2 == 0 {
                Some(size * rng.random_range(0.3..4.0))
            } else {
                None
            };
            let near = 0.05;
            let t = rng.random_range(-0.1..1.1) * span;
            let spec = CameraSpec {
                position: Some(eye.to_array()),
                target: Some(target.to_array()),
                fov_y_deg: Some(fov),
                aspect: Some(aspect),
                near: Some(near),
                far,
                ..Default::default()
            };
            let viewport = Viewport {
                width: 1000,
                height,
            };
            let view = View::new(&spec, viewport, pixel_error, DVec3::Y).unwrap();
            let fast = cut(&tree, &view, t);

            let reference = Reference {
                m: glam::dcamera::rh::proj::opengl::perspective(
                    fov.to_radians(),
                    aspect,
                    near,
                    far.unwrap_or(1.0),
                ) * glam::dcamera::rh::view::look_at_mat4(eye, target, DVec3::Y),
                eye,
                r: pixel_error * 2.0 * (fov.to_radians() / 2.0).tan() / f64::from(height),
                far: far.is_some(),
            };
            let (mut expected, mut visited) = (Vec::new(), 0);
            reference.display(&tree, tree.root, t, &mut expected, &mut visited);
            let got: Vec<u32> = fast.items.iter().map(|i| i.id).collect();
            assert_eq!(got, expected, "case {case}: t = {t}, eye = {eye}");
            // The root's presence index skips children absent at t.
            assert!(fast.stats.visited <= visited, "case {case}");
            let triangles: u64 = expected
                .iter()
                .map(|&i| tree.clusters[i as usize].triangles)
                .sum();
            assert_eq!(fast.stats.triangles, triangles);
            for item in &fast.items {
                let c = &tree.clusters[item.id as usize];
                assert_eq!(item.transform.is_some(), c.motion.is_some());
                assert!(item.visibility >= 0.5);
                assert!(item.error >= c.eps);
            }
            emitted_total += got.len();
        }
        assert!(
            emitted_total > 2000,
            "the random views see something ({emitted_total})"
        );
    }

    #[test]
    fn coarser_with_distance_and_error_budget() {
        let dir = tempfile::tempdir().unwrap();
        let tree = sample::write_sample_tree(&dir.path().join("t"), 3, 6).unwrap();
        let centre = (tree.bounds.min + tree.bounds.max) / 2.0;
        let size = tree.bounds.diagonal();
        let at = |distance: f64, pixel_error: f64| {
            let spec = CameraSpec {
                position: Some(
                    (centre + DVec3::new(0.6, 0.5, 0.6).normalize() * distance).to_array(),
                ),
                target: Some(centre.to_array()),
                ..Default::default()
            };
            let view = View::new(&spec, Viewport::default(), pixel_error, DVec3::Y).unwrap();
            cut(&tree, &view, tree.time.seconds).stats
        };
        let near = at(size * 0.8, 1.0);
        let far = at(size * 100.0, 1.0);
        let loose = at(size * 0.8, 400.0);
        assert!(far.triangles < near.triangles, "{far:?} vs {near:?}");
        assert!(loose.triangles < near.triangles, "{loose:?} vs {near:?}");
        let leaves_present: u64 = tree
            .clusters
            .iter()
            .filter(|c| c.is_leaf() && c.visibility.at(tree.time.seconds) >= 0.5)
            .map(|c| c.triangles)
            .sum();
        assert!(near.triangles <= leaves_present);
    }
}
