//! Part-wise reduction within a Hausdorff budget, for meshes made of many
//! separate elements (a storey's columns, beams, panels and pipes), where
//! whole-mesh simplifiers overshoot: vertex clustering drops small elements
//! whole and edge collapse shortens open tubes along their axis.
//!
//! Each connected part is handled on its own, and every step keeps a
//! measured bound:
//! - a part becomes the first of its quad (its box squashed across its
//!   thinnest axis), its box (the box proxies of BIM viewers) and its own
//!   simplification (`simplify`, and edge collapse with vertex placement,
//!   on the part alone, where edge collapse works well) that is within the
//!   budget of it;
//! - a part is dropped when all of it lies within the budget of the parts
//!   kept so far, largest first (a greedy cover: a bracket next to a
//!   column, the columns between two slabs once the budget exceeds half a
//!   storey). This is the set-cover view of simplification of Cohen et
//!   al., "Simplification envelopes" (SIGGRAPH 1996): any point of the
//!   input within the budget of the output, and the reverse.
//!
//! `D_H(union of outputs, union of inputs) <= max` over the parts of
//! `D_H(output_i, input_i)` for the kept ones and of
//! `sup_{p in input_j} d(p, output)` for the dropped ones (every output
//! point lies on a kept part's output, every input point is either on a
//! kept part or covered), so the bound returned is a bound.

use std::borrow::Borrow;

use glam::Vec3;

use super::Mesh;
use super::color_bound::{ColoredSet, ErrorMetric, bound_within_target};
use super::ellipsoid::{Shape, off_ellipsoid, push_ellipsoid};
use super::hausdorff::Target;
use super::proxy::{Look, part_bounds, part_look, parts, push_box, push_quad, push_triangles};
use super::simplify::{SimplifyOptions, Strategy, edge_collapse_placed, simplify};

/// A box has 12 triangles and a quad 2: parts with no more gain nothing
/// from one.
const BOX_TRIANGLES: usize = 12;
const QUAD_TRIANGLES: usize = 2;

/// The result of `reduce_parts`.
#[derive(Debug, Clone)]
pub struct Reduced {
    pub mesh: Mesh,
    /// Upper bound of the Hausdorff distance between `mesh` and the input.
    pub bound: f32,
}

/// Reduces `mesh` part by part within `budget` (scene units) of `metric`;
/// `tolerance` is the gap allowed between the measured bounds and the
/// true distances. Never returns more triangles than it was given.
pub fn reduce_parts(mesh: &Mesh, budget: f32, tolerance: f32, metric: ErrorMetric) -> Reduced {
    Parts::new(mesh).reduce(budget, tolerance, metric)
}

/// A mesh split into its parts once, with every stand-in measured for a
/// part so far: reducing it at several budgets measures a candidate again
/// only where no earlier measurement answers (a stand-in that fit a
/// smaller budget fits a larger one; one over a larger budget is over a
/// smaller one). A builder reduces every cluster at two shares of its
/// budget, and the Hausdorff bounds of the candidates are most of a
/// build's time. The mesh is borrowed or owned (`M`): a builder keeps the
/// parts of a cluster that stays alone from level to level, and measures
/// only what the larger budget asks anew.
pub struct Parts<M: Borrow<Mesh>> {
    mesh: M,
    parts: Vec<PartState>,
}

struct PartState {
    input: Mesh,
    /// `input` as its candidates are measured against it, made on first
    /// use.
    target: Option<Target>,
    welded: Option<Mesh>,
    lo: Vec3,
    hi: Vec3,
    look: Look,
    /// How far the part lies off the ellipsoid in its box
    /// (`ellipsoid::off_ellipsoid`).
    off_ellipsoid: f32,
    tried: Vec<Tried>,
}

/// A stand-in of one part, made and measured once.
#[derive(Clone, Copy, PartialEq)]
enum Candidate {
    Quad,
    Box,
    /// meshoptimizer at this `max_error` (its bits).
    Simplified(u32),
    /// Edge collapse with vertex placement to this many triangles.
    Placed(usize),
    /// A polytope over the part's box (`ellipsoid`).
    Ellipsoid(Shape),
}

/// What measuring a candidate found.
enum Outcome {
    /// Within this measured bound of the part.
    Fits(Mesh, f32),
    /// Farther than this budget.
    Over(f32),
    /// It cannot stand in (empty, or no fewer triangles), at any budget.
    Unusable,
}

impl Outcome {
    /// What the measurement says at `budget`: `Some(fits)`, or `None` when
    /// it must be measured again (it failed at a smaller budget). A bound
    /// measured with a looser tolerance than `budget`'s call would use is
    /// still a bound; a candidate that failed a larger budget is taken to
    /// fail a smaller one, which at worst keeps more triangles.
    fn at(&self, budget: f32) -> Option<Option<(Mesh, f32)>> {
        match self {
            Outcome::Fits(mesh, e) => Some((*e <= budget).then(|| (mesh.clone(), *e))),
            Outcome::Over(over) => (budget <= *over).then_some(None),
            Outcome::Unusable => Some(None),
        }
    }
}

struct Tried {
    candidate: Candidate,
    outcome: Outcome,
}

impl PartState {
    /// `candidate` as earlier measured (`Outcome::at`), or made by `make`
    /// (`None`: it cannot stand in), measured against the part within
    /// `budget` and remembered.
    fn try_candidate(
        &mut self,
        candidate: Candidate,
        make: impl FnOnce(&mut PartState) -> Option<Mesh>,
        budget: f32,
        tolerance: f32,
        metric: ErrorMetric,
    ) -> Option<(Mesh, f32)> {
        let known = self.tried.iter().position(|t| t.candidate == candidate);
        if let Some(found) = known.and_then(|k| self.tried[k].outcome.at(budget)) {
            return found;
        }
        let outcome = match make(self) {
            Some(m) => match bound_within_target(
                &m,
                &self.input,
                self.target.get_or_insert_with(|| Target::new(&self.input)),
                tolerance,
                budget,
                metric,
            ) {
                Some(e) => Outcome::Fits(m, e),
                None => Outcome::Over(budget),
            },
            None => Outcome::Unusable,
        };
        let found = outcome.at(budget).flatten();
        let tried = Tried { candidate, outcome };
        match known {
            Some(k) => self.tried[k] = tried,
            None => self.tried.push(tried),
        }
        found
    }

    /// Whether `candidate` was found unable to stand in.
    fn unusable(&self, candidate: Candidate) -> bool {
        self.tried
            .iter()
            .any(|t| t.candidate == candidate && matches!(t.outcome, Outcome::Unusable))
    }

    fn welded(&mut self) -> &Mesh {
        self.welded.get_or_insert_with(|| self.input.welded())
    }

    /// The part's stand-in within `budget`: the first of its quad, its
    /// box and its simplification that fits, or the part itself.
    fn stand_in(&mut self, budget: f32, tolerance: f32, metric: ErrorMetric) -> (Mesh, f32) {
        let (lo, hi, look) = (self.lo, self.hi, self.look);
        let n = self.input.triangle_count();
        let proxy = |push: fn(&mut Mesh, Vec3, Vec3, Look)| {
            move |_: &mut PartState| {
                let mut proxy = Mesh::default();
                push(&mut proxy, lo, hi, look);
                Some(proxy)
            }
        };
        // Half the thickness is how far the quad's plane is from the
        // part's outer faces: no quad fits a budget below it.
        let quad = budget > 0.0 && n > QUAD_TRIANGLES && (hi - lo).min_element() / 2.0 <= budget;
        let mut reduced = quad
            .then(|| {
                self.try_candidate(Candidate::Quad, proxy(push_quad), budget, tolerance, metric)
            })
            .flatten();
        // A round part: the fewest triangles of the polytopes that fit,
        // before its box, which stands farther off it than the octahedron.
        if reduced.is_none() && budget > 0.0 && self.off_ellipsoid <= budget {
            for shape in Shape::ALL.into_iter().filter(|s| s.triangles() < n) {
                let polytope = move |_: &mut PartState| {
                    let mut proxy = Mesh::default();
                    push_ellipsoid(&mut proxy, lo, hi, look, shape);
                    Some(proxy)
                };
                let candidate = Candidate::Ellipsoid(shape);
                reduced = self.try_candidate(candidate, polytope, budget, tolerance, metric);
                if reduced.is_some() {
                    break;
                }
            }
        }
        if reduced.is_none() && budget > 0.0 && n > BOX_TRIANGLES {
            reduced = self
                .try_candidate(Candidate::Box, proxy(push_box), budget, tolerance, metric)
                .or_else(|| self.simplified_within(budget, tolerance, metric));
        }
        reduced.unwrap_or_else(|| (self.input.clone(), 0.0))
    }

    /// The part simplified (welded, then flat-shaded again) and its
    /// measured bound: the fewer triangles of vertex selection at the
    /// first request within `budget` and of vertex placement at the fewest
    /// triangles within it.
    fn simplified_within(
        &mut self,
        budget: f32,
        tolerance: f32,
        metric: ErrorMetric,
    ) -> Option<(Mesh, f32)> {
        let n = self.input.triangle_count();
        let mut best: Option<(Mesh, f32)> = None;
        for request in REQUESTS {
            let max_error = budget * request;
            let candidate = Candidate::Simplified(max_error.to_bits());
            let simplified = |part: &mut PartState| {
                let s = simplify(
                    part.welded(),
                    &SimplifyOptions {
                        max_error,
                        target_triangles: None,
                        prune: false,
                    },
                );
                (s.strategy != Strategy::Unchanged && s.triangles < n).then_some(s.mesh)
            };
            let found = self.try_candidate(candidate, simplified, budget, tolerance, metric);
            // A request that changes nothing stops the search: smaller
            // ones would not either.
            if self.unusable(candidate) {
                break;
            }
            if found.is_some() {
                best = found;
                break;
            }
        }
        let (mut share, mut step) = (0.5, 0.25);
        for _ in 0..PLACED_STEPS {
            let target = (n as f64 * share) as usize;
            let fewer = best.as_ref().is_none_or(|b| target < b.0.triangle_count());
            let fits = (target > 0 && fewer)
                .then(|| {
                    let placed = |part: &mut PartState| {
                        Some(edge_collapse_placed(part.welded(), target))
                            .filter(|m| !m.is_empty() && m.triangle_count() < n)
                    };
                    self.try_candidate(Candidate::Placed(target), placed, budget, tolerance, metric)
                })
                .flatten();
            // Fewer triangles when this fits (or was not worth trying,
            // being no fewer than the best), more when it does not.
            match fits {
                Some(found) => {
                    best = Some(found);
                    share -= step;
                }
                None if !fewer => share -= step,
                None => share += step,
            }
            step /= 2.0;
        }
        best.map(|(mesh, error)| (flat_shaded(&mesh), error))
    }
}

impl<M: Borrow<Mesh>> Parts<M> {
    pub fn new(mesh: M) -> Self {
        let whole: &Mesh = mesh.borrow();
        let mut parts: Vec<PartState> = parts(whole)
            .into_iter()
            .map(|triangles| {
                let mut input = Mesh::default();
                push_triangles(&mut input, whole, &triangles);
                let (lo, hi) = part_bounds(whole, &triangles);
                let look = part_look(whole, &triangles);
                PartState {
                    off_ellipsoid: off_ellipsoid(input.positions.iter().copied(), lo, hi),
                    input,
                    target: None,
                    welded: None,
                    lo,
                    hi,
                    look,
                    tried: Vec::new(),
                }
            })
            .collect();
        // Largest first, the order the cover takes them in at every budget.
        let size = |p: &PartState| (p.hi - p.lo).length();
        parts.sort_by(|a, b| size(b).total_cmp(&size(a)));
        Parts { mesh, parts }
    }

    /// The mesh the parts are of.
    pub fn mesh(&self) -> &Mesh {
        self.mesh.borrow()
    }

    /// The mesh reduced part by part within `budget` (scene units) of
    /// `metric`; `tolerance` is the gap allowed between the measured
    /// bounds and the true distances. Never returns more triangles than it
    /// was given.
    pub fn reduce(&mut self, budget: f32, tolerance: f32, metric: ErrorMetric) -> Reduced {
        self.reduce_until(budget, tolerance, metric, |_, _| false)
            .expect("never gives up")
    }

    /// [`Parts::reduce`], or `None` as soon as `give_up(triangles, bound)`
    /// holds for the triangles of the parts kept so far and the bound so
    /// far. Both only grow as the parts are taken in turn, so a caller
    /// that gives up on a result at least that large loses nothing.
    pub fn reduce_until(
        &mut self,
        budget: f32,
        tolerance: f32,
        metric: ErrorMetric,
        give_up: impl Fn(usize, f32) -> bool,
    ) -> Option<Reduced> {
        // The parts come largest first (`Parts::new`): the cover keeps large
        // parts and drops what they cover. A part's stand-in is made only
        // once the part is found not covered: the cover tests the part's
        // input against the outputs kept before it, so the stand-ins of
        // dropped parts would be measured for nothing.
        //
        // Kept outputs are searched through a set rebuilt whenever the
        // outputs kept since outnumber it (so O(n log n) in all); a part
        // tested against the older set alone is only kept more often.
        let mut kept: Vec<Mesh> = Vec::new();
        let mut indexed = 0usize;
        let mut set = ColoredSet::new([], metric);
        let mut set_triangles = 0usize;
        let mut pending_triangles = 0usize;
        let mut bound = 0.0f32;
        for i in 0..self.parts.len() {
            if pending_triangles > 0 && pending_triangles >= set_triangles {
                set = ColoredSet::new(&kept, metric);
                indexed = kept.len();
                set_triangles += pending_triangles;
                pending_triangles = 0;
            }
            let input = &self.parts[i].input;
            // Any surface near every vertex first: a cheap test that most
            // parts which are not covered fail.
            let covered = indexed > 0
                && input.positions.iter().all(|p| {
                    set.nearest_squared(*p)
                        .is_some_and(|d| d <= budget * budget)
                })
                && match set.one_sided_within(input, tolerance, budget) {
                    Some(d) => {
                        bound = bound.max(d);
                        true
                    }
                    None => false,
                };
            if !covered {
                let (output, error) = self.parts[i].stand_in(budget, tolerance, metric);
                bound = bound.max(error);
                pending_triangles += output.triangle_count();
                kept.push(output);
                if give_up(set_triangles + pending_triangles, bound) {
                    return None;
                }
            }
        }

        let mesh: &Mesh = self.mesh.borrow();
        let mut out = Mesh::default();
        for o in &kept {
            let all: Vec<usize> = (0..o.triangle_count()).collect();
            push_triangles(&mut out, o, &all);
        }
        if mesh.colors.is_empty() {
            out.colors.clear();
        }
        if out.triangle_count() >= mesh.triangle_count() {
            return Some(Reduced {
                mesh: mesh.clone(),
                bound: 0.0,
            });
        }
        Some(Reduced { mesh: out, bound })
    }
}

/// Requests tried, as fractions of the budget: meshoptimizer's error is a
/// relative quadric estimate, and its results on closed parts (a tree's
/// crown) come back up to about twice the request away.
const REQUESTS: [f32; 3] = [1.0, 0.5, 0.25];

/// Halvings of the search for the fewest triangles that edge collapse with
/// vertex placement keeps within the budget (shares 1/2, then 1/4 or 3/4,
/// ... of the part's triangles): each costs one measured bound.
const PLACED_STEPS: usize = 4;

/// `mesh` with a vertex per triangle corner and the triangle's normal: the
/// look of the flat-shaded input.
fn flat_shaded(mesh: &Mesh) -> Mesh {
    let mut out = Mesh::default();
    for t in mesh.indices.chunks_exact(3) {
        let [a, b, c] = [0, 1, 2].map(|k| mesh.positions[t[k] as usize]);
        let normal = (b - a).cross(c - a).normalize_or_zero();
        for &i in t {
            out.indices.push(out.positions.len() as u32);
            out.positions.push(mesh.positions[i as usize]);
            out.normals.push(normal);
            out.colors
                .push(mesh.colors.get(i as usize).copied().unwrap_or([1.0; 4]));
            out.features.extend(mesh.features.get(i as usize));
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::{HausdorffOptions, hausdorff};

    /// An open tube along y at `(x, z)`.
    fn tube(segments: usize, radius: f32, length: f32, x: f32, z: f32) -> Mesh {
        let mut m = Mesh::default();
        for s in 0..segments {
            let a = s as f32 / segments as f32 * std::f32::consts::TAU;
            let b = (s + 1) as f32 / segments as f32 * std::f32::consts::TAU;
            let p = |ang: f32, y: f32| Vec3::new(x + radius * ang.cos(), y, z + radius * ang.sin());
            let base = m.positions.len() as u32;
            m.positions
                .extend([p(a, 0.0), p(b, 0.0), p(b, length), p(a, length)]);
            m.indices
                .extend([base, base + 1, base + 2, base, base + 2, base + 3]);
        }
        m
    }

    fn joined(meshes: &[Mesh]) -> Mesh {
        let mut out = Mesh::default();
        for m in meshes {
            let offset = out.positions.len() as u32;
            out.positions.extend(&m.positions);
            out.colors.extend(&m.colors);
            out.indices.extend(m.indices.iter().map(|i| i + offset));
        }
        out
    }

    fn measured(a: &Mesh, b: &Mesh) -> f32 {
        hausdorff(
            a,
            b,
            &HausdorffOptions {
                tolerance: 1e-4,
                seed: 0,
            },
        )
        .bound
    }

    #[test]
    fn boxes_thin_parts_and_drops_covered_ones() {
        // A thick tube and, 0.1 away, a thin one: with a budget of 0.5 the
        // thick one becomes its quad (0.3 from its axis) and the thin one
        // is covered by it.
        let m = joined(&[tube(16, 0.3, 4.0, 0.0, 0.0), tube(16, 0.02, 4.0, 0.4, 0.0)]);
        let r = reduce_parts(&m, 0.5, 1e-3, ErrorMetric::Geometry);
        assert_eq!(r.mesh.triangle_count(), 2, "{r:?}");
        let truth = measured(&r.mesh, &m);
        assert!(truth <= r.bound + 1e-3, "{truth} > {}", r.bound);
        assert!(r.bound <= 0.5);
    }

    #[test]
    fn a_larger_budget_measures_only_what_the_smaller_one_did_not_answer() {
        let m = joined(&[tube(16, 0.02, 4.0, 0.0, 0.0), tube(16, 0.3, 4.0, 3.0, 0.0)]);
        let mut parts = Parts::new(&m);
        let half = parts.reduce(0.25, 5e-4, ErrorMetric::Geometry);
        // The parts are held largest first.
        let (thick, thin) = (0, 1);
        assert!(parts.parts[thin].hi.x - parts.parts[thin].lo.x < 0.1);
        let tried: Vec<usize> = parts.parts.iter().map(|p| p.tried.len()).collect();
        // The thin tube's quad fits a quarter: nothing of it is measured
        // again at a half. The thick one (0.6 across) has no quad within a
        // quarter: its quad is measured at a half.
        let whole = parts.reduce(0.5, 1e-3, ErrorMetric::Geometry);
        let again: Vec<usize> = parts.parts.iter().map(|p| p.tried.len()).collect();
        assert_eq!(again[thin], tried[thin], "{tried:?} then {again:?}");
        assert!(again[thick] > tried[thick], "{tried:?} then {again:?}");
        assert!(whole.mesh.triangle_count() <= half.mesh.triangle_count());
        assert_eq!(
            whole.mesh.triangle_count(),
            4,
            "both tubes are quads within 0.5"
        );
        for r in [&half, &whole] {
            assert!(
                measured(&r.mesh, &m) <= r.bound + 1e-3,
                "{} > {}",
                measured(&r.mesh, &m),
                r.bound
            );
        }
        assert!(whole.bound <= 0.5 && half.bound <= 0.25);
    }

    #[test]
    fn gives_up_once_the_parts_kept_exceed_the_cap() {
        // Two thin tubes 3 apart within 0.05: each keeps a quad, 4
        // triangles in all, and neither covers the other.
        let m = joined(&[tube(16, 0.02, 4.0, 0.0, 0.0), tube(16, 0.02, 4.0, 3.0, 0.0)]);
        let mut parts = Parts::new(&m);
        let capped = parts.reduce_until(0.05, 1e-3, ErrorMetric::Geometry, |t, _| t > 4);
        let r = capped.expect("4 triangles are within a cap of 4");
        assert_eq!(r.mesh.triangle_count(), 4);
        assert_eq!(
            r.bound,
            parts.reduce(0.05, 1e-3, ErrorMetric::Geometry).bound
        );
        // The second quad takes them past 3: no result, not a worse one.
        let over = Parts::new(&m).reduce_until(0.05, 1e-3, ErrorMetric::Geometry, |t, _| t > 3);
        assert!(over.is_none(), "{over:?}");
    }

    #[test]
    fn keeps_what_the_budget_does_not_allow() {
        // Two thin tubes 3 apart, budget 0.05: each becomes its quad
        // (within its radius), neither covers the other.
        let m = joined(&[tube(16, 0.02, 4.0, 0.0, 0.0), tube(16, 0.02, 4.0, 3.0, 0.0)]);
        let r = reduce_parts(&m, 0.05, 1e-3, ErrorMetric::Geometry);
        assert_eq!(r.mesh.triangle_count(), 4);
        // Below half their thickness no quad fits (nor a box: its caps'
        // centres are 0.02 from the open tube): each keeps a coarser tube.
        let r = reduce_parts(&m, 0.019, 1e-4, ErrorMetric::Geometry);
        assert!(r.mesh.triangle_count() > 4, "{r:?}");
        assert!(r.bound <= 0.019 && measured(&r.mesh, &m) <= r.bound + 1e-4);
        assert!(measured(&r.mesh, &m) <= r.bound + 1e-3);
        // With no budget at all nothing changes.
        let r = reduce_parts(&m, 0.0, 1e-3, ErrorMetric::Geometry);
        assert_eq!(r.mesh.triangle_count(), m.triangle_count());
        assert_eq!(r.bound, 0.0);
    }

    #[test]
    fn keeps_a_band_of_its_own_colour_where_the_geometry_would_drop_it() {
        // A 10 x 10 wall, 0.2 thick, and a band 1.4 wide 0.05 in front:
        // within 0.3 the wall becomes its quad and covers the band, unless
        // the band's colour is held to its own.
        let paint = |mut m: Mesh, c: [f32; 4]| {
            m.colors = vec![c; m.positions.len()];
            m
        };
        let grey = [0.5, 0.5, 0.5, 1.0];
        let blue = [0.2, 0.4, 0.8, 1.0];
        let wall = paint(
            Mesh::cuboid(Vec3::new(0.0, 0.0, -0.2), Vec3::new(10.0, 10.0, 0.0), 2),
            grey,
        );
        let band = paint(
            Mesh::cuboid(Vec3::new(0.5, 4.0, 0.0), Vec3::new(9.5, 5.4, 0.05), 2),
            blue,
        );
        let m = joined(&[wall, band]);
        let blues = |r: &Reduced| {
            let m = &r.mesh;
            m.indices
                .chunks_exact(3)
                .filter(|t| m.colors[t[0] as usize] == blue)
                .count()
        };
        let geometry = reduce_parts(&m, 0.3, 1e-3, ErrorMetric::Geometry);
        assert_eq!(geometry.mesh.triangle_count(), 2, "{geometry:?}");
        assert_eq!(blues(&geometry), 0);
        let appearance = reduce_parts(&m, 0.3, 1e-3, ErrorMetric::Appearance);
        assert_eq!(appearance.mesh.triangle_count(), 4, "{appearance:?}");
        assert_eq!(blues(&appearance), 2);
        assert!(appearance.bound <= 0.3);
    }
}
