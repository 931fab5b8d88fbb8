//! The error bound the builder measures: the Hausdorff distance with each
//! point held to its own colour, so that a reduction keeps what a viewer
//! sees at the budget, not only where the surface is.
//!
//! A window band glued to a wall, a glass pane behind its frame: the wall
//! or the frame's proxy is within a few centimetres of them, so a purely
//! geometric bound lets them go, and a building's storeys of glazing turn
//! into one concrete box while still many pixels tall. Appearance-preserving
//! simplification (Cohen, Olano and Manocha, SIGGRAPH 1998) bounds how far
//! a colour moves on screen; for vertex-coloured surfaces the same idea is a
//! distance between like-coloured parts of the two meshes:
//!
//! `e(p) = min(d(p, B_c), max(d(p, B), s(p)))` for a point `p` of A whose
//! colour is `c`, with `B_c` the triangles of B of that colour and `s(p)`
//! the size of `p`'s colour region in A (its connected triangles of one
//! colour): the square root of its area. A colour stays within the
//! distance of its own colour, unless its whole region has less area than
//! a square of that side: then, seen at a pixel of that size, it covers
//! at most one pixel, and may take the colour around it. The bound is
//! `max(sup_A e, sup_B e)`, each side against the other.
//!
//! `e(p) >= d(p, B)`, so this bounds the geometric Hausdorff distance too:
//! every `eps_c` stays a geometric bound. Colours are compared in 8 bits
//! per channel; a triangle whose corners differ in colour is a blend and
//! matches only the same blend.

use rustc_hash::FxHashMap;

use glam::{Mat4, Vec3};
use serde::{Deserialize, Serialize};

use super::Mesh;
use super::closest::TriangleSet;
use super::hausdorff::{
    self, finite_triangle, finite_triangles, one_way_above, one_way_within, search_scale,
};
use super::merge::{Part, merge};
use super::proxy::push_triangles;
use super::union_find::UnionFind;

/// What the builder's error bounds measure.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ErrorMetric {
    /// The Hausdorff distance alone, as the paper: colours may change
    /// where surfaces are near.
    #[default]
    Geometry,
    /// Each point held to its own colour (this module).
    Appearance,
}

/// A triangle's colour: its corners' colours in 8 bits per channel, sorted.
type Class = [[u8; 4]; 3];

/// The triangles of a mesh with their colour classes.
struct Colored {
    triangles: Vec<[Vec3; 3]>,
    classes: Vec<Class>,
}

impl Colored {
    /// Under `ErrorMetric::Geometry` every triangle has one class.
    fn of<'a>(meshes: impl IntoIterator<Item = &'a Mesh>, metric: ErrorMetric) -> Self {
        let mut out = Colored {
            triangles: Vec::new(),
            classes: Vec::new(),
        };
        for m in meshes {
            let n = m.positions.len();
            for t in m.indices.chunks_exact(3) {
                let t = [t[0], t[1], t[2]];
                if t.iter()
                    .any(|&i| i as usize >= n || !m.positions[i as usize].is_finite())
                {
                    continue;
                }
                out.triangles.push(t.map(|i| m.positions[i as usize]));
                let mut class = match metric {
                    ErrorMetric::Appearance => t.map(|i| quantized(m.colors.get(i as usize))),
                    ErrorMetric::Geometry => [[255; 4]; 3],
                };
                class.sort_unstable();
                out.classes.push(class);
            }
        }
        out
    }

    /// The one class of every triangle, if there is one.
    fn single(&self) -> Option<Class> {
        let first = *self.classes.first()?;
        self.classes.iter().all(|c| *c == first).then_some(first)
    }

    /// Each triangle's colour region size: the square root of the area of
    /// the triangles of its class connected to it through shared corners.
    fn region_sizes(&self) -> Vec<f32> {
        let n = self.triangles.len();
        let mut sets = UnionFind::new(n);
        let mut first: FxHashMap<([u32; 3], Class), u32> =
            FxHashMap::with_capacity_and_hasher(3 * n, Default::default());
        for (k, (t, class)) in self.triangles.iter().zip(&self.classes).enumerate() {
            for p in t {
                let at = *first
                    .entry((p.to_array().map(f32::to_bits), *class))
                    .or_insert(k as u32);
                sets.union(at, k as u32);
            }
        }
        let roots: Vec<u32> = (0..n as u32).map(|k| sets.find(k)).collect();
        let mut areas: FxHashMap<u32, f32> = FxHashMap::default();
        for (t, root) in self.triangles.iter().zip(&roots) {
            *areas.entry(*root).or_default() += (t[1] - t[0]).cross(t[2] - t[0]).length() / 2.0;
        }
        roots.iter().map(|r| areas[r].sqrt()).collect()
    }
}

/// A mesh's triangles prepared for nearest queries, all of them and by
/// colour class.
pub(crate) struct ColoredSet {
    all: TriangleSet,
    /// `None` when every triangle has the one class `single`.
    by_class: Option<FxHashMap<Class, TriangleSet>>,
    single: Option<Class>,
    /// How the triangles measured against the set are classed.
    metric: ErrorMetric,
}

impl ColoredSet {
    pub(crate) fn new<'a>(meshes: impl IntoIterator<Item = &'a Mesh>, metric: ErrorMetric) -> Self {
        Self::of(&Colored::of(meshes, metric), metric)
    }

    fn of(c: &Colored, metric: ErrorMetric) -> Self {
        let all = TriangleSet::new(c.triangles.iter().copied());
        let single = c.single();
        let by_class = single.is_none().then(|| {
            let mut groups: FxHashMap<Class, Vec<[Vec3; 3]>> = FxHashMap::default();
            for (t, class) in c.triangles.iter().zip(&c.classes) {
                groups.entry(*class).or_default().push(*t);
            }
            groups
                .into_iter()
                .map(|(class, tris)| (class, TriangleSet::new(tris.into_iter())))
                .collect()
        });
        ColoredSet {
            all,
            by_class,
            single,
            metric,
        }
    }

    fn class(&self, class: &Class) -> Option<&TriangleSet> {
        match &self.by_class {
            Some(map) => map.get(class),
            None => (self.single == Some(*class)).then_some(&self.all),
        }
    }

    /// The nearest triangle of any colour.
    pub(crate) fn nearest_squared(&self, p: Vec3) -> Option<f32> {
        self.all.nearest(p, None).map(|n| n.distance_squared)
    }

    /// A bound of `sup_{p in A} e(p)` for the triangles of `a` against this
    /// set, if at most `within` (no slack added).
    fn one_sided(&self, a: &Colored, tolerance: f32, within: f32) -> Option<f32> {
        let mut groups: FxHashMap<Class, Vec<usize>> = FxHashMap::default();
        for (k, class) in a.classes.iter().enumerate() {
            groups.entry(*class).or_default().push(k);
        }
        let pick = |ks: &[usize]| ks.iter().map(|&k| a.triangles[k]).collect::<Vec<_>>();
        let mut sizes: Option<Vec<f32>> = None;
        let mut bound = 0.0f32;
        for (class, ks) in &groups {
            let own = self.class(class);
            let tris = pick(ks);
            if let Some(d) = own.and_then(|s| one_way_within(&tris, s, tolerance, within)) {
                bound = bound.max(d);
                continue;
            }
            // Not every point has its colour near: regions smaller than
            // the distance may fall back to the nearest surface.
            let sizes = sizes.get_or_insert_with(|| a.region_sizes());
            let (small, large): (Vec<usize>, Vec<usize>) =
                ks.iter().partition(|&&k| sizes[k] <= within);
            if !large.is_empty() {
                bound = bound.max(one_way_within(&pick(&large), own?, tolerance, within)?);
            }
            if !small.is_empty() {
                let tris = pick(&small);
                let size = small.iter().map(|&k| sizes[k]).fold(0.0, f32::max);
                let matched = own.and_then(|s| one_way_within(&tris, s, tolerance, within));
                let nearest =
                    one_way_within(&tris, &self.all, tolerance, within).map(|d| d.max(size));
                let d = match (matched, nearest) {
                    (Some(m), Some(n)) => m.min(n),
                    (m, n) => m.or(n)?,
                };
                bound = bound.max(d);
            }
        }
        Some(bound)
    }

    /// A bound of `sup_{p in a} e(p)` against this set, if at most
    /// `budget`: the one side of the greedy cover, where `a` is a part
    /// that may be dropped for what is kept.
    pub(crate) fn one_sided_within(&self, a: &Mesh, tolerance: f32, budget: f32) -> Option<f32> {
        let a = Colored::of([a], self.metric);
        if a.triangles.is_empty() {
            return Some(0.0);
        }
        let (tolerance, slack) = search_scale(&a.triangles, &[], tolerance);
        let bound = self.one_sided(&a, tolerance, budget - slack)? + slack;
        (bound <= budget).then_some(bound)
    }
}

/// A bound of how far each object's triangles in `mesh` lie from that
/// object's own geometry among `originals` (by feature id), if at most
/// `budget`: the largest over the objects of `sup_{p in mesh_f} e(p,
/// originals_f)`. `None` also when an object of `mesh` has no original.
/// A mesh without feature ids is one object.
pub fn feature_bound_within(
    mesh: &Mesh,
    originals: &[&Mesh],
    tolerance: f32,
    budget: f32,
    metric: ErrorMetric,
) -> Option<f32> {
    objects_within(mesh, by_object(mesh), originals, tolerance, budget, metric)
}

/// [`feature_bound_within`] of `mesh`'s triangles as grouped by
/// [`by_object`].
fn objects_within(
    mesh: &Mesh,
    objects: FxHashMap<Option<u32>, Vec<usize>>,
    originals: &[&Mesh],
    tolerance: f32,
    budget: f32,
    metric: ErrorMetric,
) -> Option<f32> {
    if objects.len() <= 1 {
        // One object: the whole mesh's bound is its own.
        return Some(0.0);
    }
    let mut by_feature = originals_by_object(originals);
    let mut bound = 0.0f32;
    for (feature, ks) in objects {
        let own = by_feature.remove(&feature)?;
        let mut part = Mesh::default();
        push_triangles(&mut part, mesh, &ks);
        let set = ColoredSet::new(own, metric);
        bound = bound.max(set.one_sided_within(&part, tolerance, budget)?);
    }
    Some(bound)
}

/// The object (feature id) of a mesh's `k`-th triangle.
fn feature_of(m: &Mesh, k: usize) -> Option<u32> {
    m.features.get(m.indices[k * 3] as usize).copied()
}

/// A mesh's triangles by object.
fn by_object(mesh: &Mesh) -> FxHashMap<Option<u32>, Vec<usize>> {
    let mut triangles: FxHashMap<Option<u32>, Vec<usize>> = FxHashMap::default();
    for k in 0..mesh.triangle_count() {
        triangles.entry(feature_of(mesh, k)).or_default().push(k);
    }
    triangles
}

/// The original objects by their feature id (each original is one object).
fn originals_by_object<'a>(originals: &[&'a Mesh]) -> FxHashMap<Option<u32>, Vec<&'a Mesh>> {
    let mut by_feature: FxHashMap<Option<u32>, Vec<&Mesh>> = FxHashMap::default();
    for o in originals.iter().filter(|o| o.triangle_count() > 0) {
        by_feature.entry(feature_of(o, 0)).or_default().push(o);
    }
    by_feature
}

/// A cluster's direct bound: the larger of the distance `metric` between
/// `mesh` and the union of the `originals` (`bound_within`) and of how far
/// each object's triangles in `mesh` lie from that object's own
/// (`feature_bound_within`), if at most `budget`.
pub fn direct_bound_within(
    mesh: &Mesh,
    originals: &[&Mesh],
    tolerance: f32,
    budget: f32,
    metric: ErrorMetric,
) -> Option<f32> {
    let objects = by_object(mesh);
    if metric == ErrorMetric::Geometry && objects.len() > 1 {
        return objects_and_back_within(mesh, objects, originals, tolerance, budget);
    }
    let parts: Vec<Part> = originals
        .iter()
        .map(|m| Part {
            mesh: m,
            transform: Mat4::IDENTITY,
            color: [1.0; 4],
            feature: None,
        })
        .collect();
    let union = merge(&parts, 0.0);
    let whole = bound_within(mesh, &union, tolerance, budget, metric)?;
    let own = objects_within(mesh, objects, originals, tolerance, budget, metric)?;
    Some(whole.max(own))
}

/// [`direct_bound_within`] of a mesh of several `objects` under the
/// geometric metric, in two one-sided searches where the general case
/// takes three: a point of an object is no nearer to its own object's
/// originals than to all of them, so how far each object lies from its
/// own also bounds the mesh's side of the Hausdorff distance, and the
/// originals' side is all that is left. On the paper scene the direct
/// bound was the largest share of a build's time.
fn objects_and_back_within(
    mesh: &Mesh,
    objects: FxHashMap<Option<u32>, Vec<usize>>,
    originals: &[&Mesh],
    tolerance: f32,
    budget: f32,
) -> Option<f32> {
    let back: Vec<[Vec3; 3]> = originals.iter().flat_map(|o| finite_triangles(o)).collect();
    let front = finite_triangles(mesh);
    if back.is_empty() || front.is_empty() {
        return (back.is_empty() && front.is_empty()).then_some(0.0);
    }
    let (tolerance, slack) = search_scale(&back, &front, tolerance);
    let within = budget - slack;
    // The originals' side first, against the smaller set, as
    // `hausdorff::bound_within` does; each object's then only as far as it
    // could raise that.
    let mut bound = one_way_within(
        &back,
        &TriangleSet::new(front.into_iter()),
        tolerance,
        within,
    )?;
    let mut own = originals_by_object(originals);
    for (object, ks) in objects {
        let set: Vec<[Vec3; 3]> = own
            .remove(&object)?
            .into_iter()
            .flat_map(finite_triangles)
            .collect();
        let tris: Vec<[Vec3; 3]> = ks
            .iter()
            .filter_map(|&k| finite_triangle(mesh, k))
            .collect();
        bound = one_way_above(
            &tris,
            &TriangleSet::new(set.into_iter()),
            tolerance,
            within,
            bound,
        )?;
    }
    let bound = bound + slack;
    (bound <= budget).then_some(bound)
}

/// A bound of the distance `metric` between `a` and `b` (under
/// `Appearance`, see the module's comment) within `tolerance` of it, if
/// at most `budget`.
pub fn bound_within(
    a: &Mesh,
    b: &Mesh,
    tolerance: f32,
    budget: f32,
    metric: ErrorMetric,
) -> Option<f32> {
    let (ca, cb) = (Colored::of([a], metric), Colored::of([b], metric));
    if ca.triangles.is_empty() || cb.triangles.is_empty() || same_single(&ca, &cb) {
        return hausdorff::bound_within(a, b, tolerance, budget);
    }
    let (tolerance, slack) = search_scale(&ca.triangles, &cb.triangles, tolerance);
    let within = budget - slack;
    // The smaller side's sets first, as `hausdorff::bound_within` does.
    let (first, second) = if ca.triangles.len() <= cb.triangles.len() {
        (&ca, &cb)
    } else {
        (&cb, &ca)
    };
    let mut bound = ColoredSet::of(first, metric).one_sided(second, tolerance, within)?;
    bound = bound.max(ColoredSet::of(second, metric).one_sided(first, tolerance, within)?);
    let bound = bound + slack;
    (bound <= budget).then_some(bound)
}

/// [`bound_within`] of `a` against `b`, a mesh that candidates are
/// measured against one after another, with what `target` (made of `b`)
/// kept from the candidates before: under the geometric metric, `b`'s
/// search structure.
pub(crate) fn bound_within_target(
    a: &Mesh,
    b: &Mesh,
    target: &mut hausdorff::Target,
    tolerance: f32,
    budget: f32,
    metric: ErrorMetric,
) -> Option<f32> {
    match metric {
        ErrorMetric::Geometry => hausdorff::bound_within_target(a, target, tolerance, budget),
        ErrorMetric::Appearance => bound_within(a, b, tolerance, budget, metric),
    }
}

fn same_single(a: &Colored, b: &Colored) -> bool {
    a.single().is_some_and(|c| b.single() == Some(c))
}

fn quantized(color: Option<&[f32; 4]>) -> [u8; 4] {
    color
        .copied()
        .unwrap_or([1.0; 4])
        .map(|v| (v.clamp(0.0, 1.0) * 255.0).round() as u8)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn colored(mut m: Mesh, color: [f32; 4]) -> Mesh {
        m.colors = vec![color; m.positions.len()];
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

    const GREY: [f32; 4] = [0.5, 0.5, 0.5, 1.0];
    const BLUE: [f32; 4] = [0.2, 0.4, 0.8, 1.0];

    /// A 10 x 10 wall and, 0.05 in front of it, a 10 x 1.4 band.
    fn wall_and_band() -> (Mesh, Mesh) {
        let wall = colored(
            Mesh::cuboid(Vec3::new(0.0, 0.0, -0.2), Vec3::new(10.0, 10.0, 0.0), 1),
            GREY,
        );
        let band = colored(
            Mesh::cuboid(Vec3::new(0.5, 4.0, 0.0), Vec3::new(9.5, 5.4, 0.05), 1),
            BLUE,
        );
        (wall, band)
    }

    #[test]
    fn a_colour_held_to_its_own_keeps_a_band_the_geometry_lets_go() {
        let (wall, band) = wall_and_band();
        let both = joined(&[wall.clone(), band]);
        // The wall alone is within 0.05 of both, geometrically.
        let geometric = hausdorff::bound_within(&wall, &both, 1e-4, 1.0).unwrap();
        assert!(geometric <= 0.06, "{geometric}");
        // Held to its colour, the band's points are far from any blue: the
        // band's box has 26.24 of area, so it may not take the wall's
        // colour below its square root.
        assert_eq!(
            bound_within(&wall, &both, 1e-4, 1.0, ErrorMetric::Appearance),
            None
        );
        let held = bound_within(&wall, &both, 1e-4, 20.0, ErrorMetric::Appearance).unwrap();
        assert!((5.12..=5.13).contains(&held), "{held}");
        // A grey band is the wall's colour: the geometric bound holds.
        let grey = joined(&[wall.clone(), colored(wall_and_band().1, GREY)]);
        let d = bound_within(&wall, &grey, 1e-4, 1.0, ErrorMetric::Appearance).unwrap();
        assert!((d - geometric).abs() <= 1e-3, "{d} {geometric}");
    }

    #[test]
    fn a_colour_may_move_to_its_own_within_the_budget() {
        // Two blue bands 3 apart; keeping one holds the other's colour
        // within the distance between them.
        let (wall, band) = wall_and_band();
        let mut other = band.clone();
        for p in &mut other.positions {
            p.y += 3.0;
        }
        let input = joined(&[wall.clone(), band.clone(), other]);
        let output = joined(&[wall, band]);
        let d = bound_within(&output, &input, 1e-4, 10.0, ErrorMetric::Appearance).unwrap();
        assert!((3.0..=3.1).contains(&d), "{d}");
    }

    #[test]
    fn a_small_colour_region_may_take_the_colour_around_it() {
        // A 0.3 x 0.3 x 0.01 blue patch, 0.192 of area: within 0.44 it may
        // become the wall.
        let wall = colored(
            Mesh::cuboid(Vec3::new(0.0, 0.0, -0.2), Vec3::new(10.0, 10.0, 0.0), 1),
            GREY,
        );
        let patch = colored(
            Mesh::cuboid(Vec3::new(5.0, 5.0, 0.0), Vec3::new(5.3, 5.3, 0.01), 1),
            BLUE,
        );
        let input = joined(&[wall.clone(), patch]);
        let d = bound_within(&wall, &input, 1e-4, 0.5, ErrorMetric::Appearance).unwrap();
        assert!((0.438..=0.439).contains(&d), "{d}");
        assert_eq!(
            bound_within(&wall, &input, 1e-4, 0.43, ErrorMetric::Appearance),
            None
        );
    }
}
