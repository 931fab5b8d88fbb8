//! The Hausdorff bound: known distances, bad input, and (proptest) that it
//! bounds every brute-force distance of random surface points; the same for
//! the budgeted bound alone (`bound_within`) and a cluster's direct bound
//! against its objects (`direct_bound_within`).

use glam::{Mat4, Vec3, Vec3A};
use hdlod::geometry::{
    ErrorMetric, HausdorffOptions, Mesh, Part, bound_within, closest_point_on_triangle,
    direct_bound_within, feature_bound_within, hausdorff, merge,
};
use proptest::prelude::*;

fn quad(z: f32, size: f32) -> Mesh {
    mesh(
        &[
            [0.0, 0.0, z],
            [size, 0.0, z],
            [size, size, z],
            [0.0, size, z],
        ],
        &[0, 1, 2, 0, 2, 3],
    )
}

/// A mesh from corner coordinates and triangle indices.
fn mesh(positions: &[[f32; 3]], indices: &[u32]) -> Mesh {
    Mesh {
        positions: positions.iter().map(|p| Vec3::from_array(*p)).collect(),
        indices: indices.to_vec(),
        ..Mesh::default()
    }
}

fn opts(tolerance: f32) -> HausdorffOptions {
    HausdorffOptions { tolerance, seed: 7 }
}

#[test]
fn parallel_planes_are_their_offset_apart() {
    let h = hausdorff(&quad(0.0, 1.0), &quad(0.25, 1.0), &opts(1e-4));
    assert!(h.lower <= 0.25 + 1e-6 && h.bound >= 0.25, "{h:?}");
    assert!(h.bound - 0.25 < 1e-3, "{h:?}");
    assert!(
        (h.mean - 0.25).abs() < 1e-5 && (h.rms - 0.25).abs() < 1e-5,
        "{h:?}"
    );
}

#[test]
fn a_budget_keeps_the_bound_or_refuses_it() {
    let (a, b) = (quad(0.0, 1.0), quad(0.25, 1.0));
    let within =
        bound_within(&a, &b, 1e-4, 0.3, ErrorMetric::Geometry).expect("0.25 apart fits 0.3");
    assert!((0.25..0.25 + 1e-3).contains(&within), "{within}");
    assert_eq!(bound_within(&a, &b, 1e-4, 0.2, ErrorMetric::Geometry), None);
    // Far in one direction only: the small square is near the big one,
    // not the other way round.
    assert_eq!(
        bound_within(
            &quad(0.0, 1.0),
            &quad(0.0, 0.1),
            1e-3,
            1.0,
            ErrorMetric::Geometry
        ),
        None
    );
    let empty = Mesh::default();
    assert_eq!(
        bound_within(&empty, &empty, 1e-3, 0.0, ErrorMetric::Geometry),
        Some(0.0)
    );
    assert_eq!(
        bound_within(&a, &empty, 1e-3, 1e9, ErrorMetric::Geometry),
        None
    );
}

#[test]
fn the_bound_is_tight_where_the_maximum_is_inside_a_triangle() {
    // A big square against a small one at its corner: the farthest point of
    // the big one is its opposite corner, sqrt(2) * 0.9 away in the plane.
    let h = hausdorff(&quad(0.0, 1.0), &quad(0.0, 0.1), &opts(1e-3));
    let exact = (2.0f32).sqrt() * 0.9;
    assert!(h.bound >= exact && h.bound <= exact + 1.1e-3, "{h:?}");
    assert!(h.ba <= 1.1e-3 && h.ab >= exact, "{h:?}");
    // An interior maximum: a tent over a flat square, apex 0.5 high.
    let mut tent = quad(0.0, 1.0);
    tent.positions.push(Vec3::new(0.5, 0.5, 0.5));
    tent.indices = vec![0, 1, 4, 1, 2, 4, 2, 3, 4, 3, 0, 4];
    let h = hausdorff(&quad(0.0, 1.0), &tent, &opts(1e-3));
    assert!(h.bound >= 0.5 && h.bound <= 0.5 + 1.1e-3, "{h:?}");
}

#[test]
fn a_rectangle_over_one_split_the_other_way_is_settled_at_its_corners() {
    // Each triangle of the upper rectangle crosses the lower one's
    // diagonal: no single lower triangle is nearest to all its corners, but
    // the two halves together are a flat convex quadrilateral.
    let lower = quad(0.0, 1.0);
    let mut upper = quad(0.3, 1.0);
    upper.indices = vec![0, 1, 3, 1, 2, 3];
    let h = hausdorff(&upper, &lower, &opts(1e-4));
    assert!(h.ab >= 0.3 && h.ab <= 0.3 + 1e-3, "{h:?}");
}

#[test]
fn a_notch_between_two_triangles_is_not_taken_for_a_convex_pair() {
    // Two triangles sharing the edge (0,0)-(1,0) make an arrowhead with a
    // notch at (1,0). A triangle over it has every corner on one of them,
    // but the middle of its far edge is over the notch, 0.318 away.
    let b = mesh(
        &[
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [1.5, 0.5, 0.0],
            [1.5, -0.5, 0.0],
        ],
        &[0, 1, 2, 0, 3, 1],
    );
    let a = mesh(
        &[[1.45, 0.47, 0.0], [1.45, -0.47, 0.0], [0.5, 0.0, 0.0]],
        &[0, 1, 2],
    );
    let notch = brute_distance(Vec3::new(1.45, 0.0, 0.0), &b);
    assert!(notch > 0.3, "{notch}");
    let h = hausdorff(&a, &b, &opts(1e-4));
    assert!(h.ab >= notch && h.ab <= notch + 1e-3, "{h:?}");
}

#[test]
fn a_sliver_along_the_edge_of_a_notched_pair_is_bounded_within_the_tolerance() {
    // The arrowhead of the notch test, and 0.1 above it a long thin
    // triangle lying along the shared edge, two corners over one half and
    // one over the other, 0.112 from the first: the pair is not convex,
    // and no one half is within the tolerance of every corner, so the
    // search must split it. The bound stays a bound (every sampled point
    // is within it) and is within the tolerance of the true 0.1.
    let b = mesh(
        &[
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [1.5, 0.5, 0.0],
            [1.5, -0.5, 0.0],
        ],
        &[0, 1, 2, 0, 3, 1],
    );
    let a = mesh(
        &[[0.05, 0.001, 0.1], [0.95, 0.002, 0.1], [0.5, -0.05, 0.1]],
        &[0, 1, 2],
    );
    for tolerance in [1e-2, 1e-4] {
        let h = hausdorff(&a, &b, &opts(tolerance));
        assert!(h.ab >= 0.1 && h.ab <= 0.1 + tolerance + 1e-5, "{h:?}");
        let within = bound_within(&a, &b, tolerance, 10.0, ErrorMetric::Geometry).unwrap();
        assert!(
            within >= h.lower && within <= h.bound + tolerance,
            "{within} {h:?}"
        );
        let picks: Vec<(usize, f32, f32)> = (0..200)
            .map(|k| (0, (k % 20) as f32 / 20.0, (k / 20) as f32 / 10.0))
            .collect();
        for p in points_on(&a, &picks) {
            let d = brute_distance(p, &b);
            assert!(d <= h.ab && d <= within, "{d} {h:?}");
        }
    }
}

#[test]
fn a_valley_between_two_triangles_counts_their_fold() {
    // Two faces rising at a slope of 0.5 away from their shared edge (the
    // y axis): a triangle 0.5 above has its corners over the faces, 0.27
    // from them, but the middle of its first edge is over the fold, 0.45
    // away. Seen from above the pair is convex but not flat: the fold
    // must count.
    let b = mesh(
        &[
            [0.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [-1.0, 0.5, 0.5],
            [1.0, 0.5, 0.5],
        ],
        &[0, 1, 2, 0, 3, 1],
    );
    let a = mesh(
        &[[-0.4, 0.3, 0.5], [0.4, 0.3, 0.5], [-0.4, 0.7, 0.5]],
        &[0, 1, 2],
    );
    let fold = brute_distance(Vec3::new(0.0, 0.3, 0.5), &b);
    let corners = a.positions.iter().map(|p| brute_distance(*p, &b));
    let corner = corners.fold(0.0f32, f32::max);
    assert!(fold > 0.44 && corner < 0.28, "{fold} {corner}");
    let h = hausdorff(&a, &b, &opts(1e-4));
    assert!(h.ab >= fold && h.ab <= fold + 1e-3, "{h:?}");
}

#[test]
fn identical_meshes_are_zero_apart() {
    // Coincident surfaces are the worst case of the corner bound: every
    // triangle must shrink to the tolerance before it is settled.
    let h = hausdorff(&quad(1.0, 2.0), &quad(1.0, 2.0), &opts(1e-3));
    assert!(
        h.bound <= 1e-3 + 1e-6 && h.lower < 1e-6 && h.mean < 1e-6,
        "{h:?}"
    );
}

#[test]
fn empty_meshes_have_defined_results() {
    let e = Mesh::default();
    let h = hausdorff(&e, &e, &opts(0.0));
    assert_eq!((h.bound, h.mean, h.rms), (0.0, 0.0, 0.0));
    let h = hausdorff(&e, &quad(0.0, 1.0), &opts(0.0));
    assert!(h.bound.is_infinite() && h.ab.is_infinite() && h.ba.is_infinite());
}

#[test]
fn degenerate_nan_and_duplicate_triangles_do_not_poison_the_result() {
    let mut a = quad(0.0, 1.0);
    // A point triangle, a segment triangle, a duplicate and one with NaN.
    a.positions.push(Vec3::new(f32::NAN, 0.0, 0.0));
    a.indices.extend([0, 0, 0, 0, 1, 1, 0, 1, 2, 0, 1, 4]);
    let h = hausdorff(&a, &quad(0.5, 1.0), &opts(1e-4));
    assert!(
        h.bound.is_finite() && h.mean.is_finite() && h.bound >= 0.5,
        "{h:?}"
    );
    let segment_only = Mesh {
        positions: vec![Vec3::ZERO, Vec3::X, Vec3::X * 2.0],
        indices: vec![0, 1, 2],
        ..Mesh::default()
    };
    let h = hausdorff(&segment_only, &quad(1.0, 2.0), &opts(1e-4));
    assert!(
        h.bound.is_finite() && h.mean.is_finite() && h.bound >= 2.0f32.sqrt(),
        "{h:?}"
    );
}

/// Two runs on equal inputs built apart, one on a pool of one thread and
/// one on a pool of four, agree to the bit: nothing depends on how threads
/// are scheduled or on what an earlier call left behind.
#[test]
fn results_are_deterministic() {
    let run = || {
        let heights: Vec<f32> = (0..53)
            .map(|k| ((k * 29 % 17) as f32 - 8.0) * 0.01)
            .collect();
        let flips: Vec<bool> = (0..41).map(|k| k % 3 == 0).collect();
        let fine = height_field(24, &heights, &flips);
        let coarse = height_field(7, &heights[5..], &flips[2..]);
        (
            hausdorff(&fine, &coarse, &opts(1e-5)),
            bound_within(&fine, &coarse, 1e-5, 1.0, ErrorMetric::Geometry),
        )
    };
    let pool = |threads| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
    };
    let serial = pool(1).install(run);
    let parallel = pool(4).install(run);
    assert!(serial.0.bound > 0.0 && serial.1.is_some(), "{serial:?}");
    assert_eq!(serial, parallel);
}

fn soup(max_triangles: usize) -> impl Strategy<Value = Mesh> {
    prop::collection::vec(
        prop::array::uniform3(prop::array::uniform3(-4.0f32..4.0)),
        1..max_triangles,
    )
    .prop_map(|tris| Mesh {
        positions: tris
            .iter()
            .flatten()
            .map(|p| Vec3::from_array(*p))
            .collect(),
        indices: (0..tris.len() as u32 * 3).collect(),
        ..Mesh::default()
    })
}

/// A height field over the unit square, `n` by `n` cells, each split
/// along the diagonal its flag picks: neighbouring triangles share edges,
/// and with small heights they are nearly flat pairs.
fn height_field(n: usize, heights: &[f32], flips: &[bool]) -> Mesh {
    let side = n + 1;
    let positions = (0..side * side)
        .map(|k| {
            let (x, y) = (k % side, k / side);
            Vec3::new(
                x as f32 / n as f32,
                y as f32 / n as f32,
                heights[k % heights.len()],
            )
        })
        .collect();
    let mut indices = Vec::new();
    for y in 0..n {
        for x in 0..n {
            let k = (y * side + x) as u32;
            let (a, b, c, d) = (k, k + 1, k + side as u32 + 1, k + side as u32);
            if flips[(y * n + x) % flips.len()] {
                indices.extend([a, b, c, a, c, d]);
            } else {
                indices.extend([a, b, d, b, c, d]);
            }
        }
    }
    Mesh {
        positions,
        indices,
        ..Mesh::default()
    }
}

/// A fan around the middle of the unit square: consecutive triangles share
/// an edge, and with uneven radii many such pairs are not convex.
fn fan(radii: &[f32], heights: &[f32]) -> Mesh {
    let k = radii.len();
    let mut positions = vec![Vec3::new(0.5, 0.5, 0.0)];
    positions.extend((0..k).map(|i| {
        let angle = i as f32 / k as f32 * std::f32::consts::TAU;
        Vec3::new(
            0.5 + radii[i] * angle.cos(),
            0.5 + radii[i] * angle.sin(),
            heights[i % heights.len()],
        )
    }));
    let indices = (0..k as u32)
        .flat_map(|i| [0, 1 + i, 1 + (i + 1) % k as u32])
        .collect();
    Mesh {
        positions,
        indices,
        ..Mesh::default()
    }
}

/// The meshes as one, the `k`-th as object `first + k`.
fn objects(meshes: &[Mesh], first: u32) -> Mesh {
    let parts: Vec<Part> = (meshes.iter().zip(first..))
        .map(|(mesh, k)| Part {
            mesh,
            transform: Mat4::IDENTITY,
            color: [1.0; 4],
            feature: Some(k),
        })
        .collect();
    merge(&parts, 0.0)
}

fn brute_distance(p: Vec3, m: &Mesh) -> f32 {
    m.triangles()
        .map(|[a, b, c]| {
            let p = Vec3A::from(p);
            closest_point_on_triangle(p, a.into(), b.into(), c.into()).distance(p)
        })
        .fold(f32::INFINITY, f32::min)
}

/// Points on the surface of `m` from `(triangle, u, v)` triples.
fn points_on(m: &Mesh, picks: &[(usize, f32, f32)]) -> Vec<Vec3> {
    let tris: Vec<_> = m.triangles().collect();
    picks
        .iter()
        .map(|&(i, u, v)| {
            let [a, b, c] = tris[i % tris.len()];
            let (u, v) = if u + v > 1.0 {
                (1.0 - u, 1.0 - v)
            } else {
                (u, v)
            };
            a + (b - a) * u + (c - a) * v
        })
        .collect()
}

/// Every picked point of `a` is within `ab` of `b`, and of `b` within `ba`
/// of `a`, by brute force.
fn points_within(
    a: &Mesh,
    b: &Mesh,
    picks: &[(usize, f32, f32)],
    ab: f32,
    ba: f32,
) -> Result<(), TestCaseError> {
    for p in points_on(a, picks) {
        let d = brute_distance(p, b);
        prop_assert!(d <= ab, "a point of A is {d} from B, bound {ab}");
    }
    for p in points_on(b, picks) {
        let d = brute_distance(p, a);
        prop_assert!(d <= ba, "a point of B is {d} from A, bound {ba}");
    }
    Ok(())
}

/// Points on a grid of `steps` by `steps` over each triangle of `m`
/// (corners and edges included): where a bound from a piece's corners and
/// cuts would fail, it fails between sample points too.
fn grid_on(m: &Mesh, steps: usize) -> Vec<Vec3> {
    let mut out = Vec::new();
    for [a, b, c] in m.triangles() {
        for i in 0..=steps {
            for j in 0..=steps - i {
                let (u, v) = (i as f32 / steps as f32, j as f32 / steps as f32);
                out.push(a + (b - a) * u + (c - a) * v);
            }
        }
    }
    out
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    #[test]
    fn the_bound_bounds_every_sampled_distance(
        a in soup(60),
        b in soup(60),
        picks in prop::collection::vec((0usize..1000, 0.0f32..1.0, 0.0f32..1.0), 64),
        tolerance in 0.0f32..0.5,
    ) {
        let h = hausdorff(&a, &b, &opts(tolerance));
        prop_assert!(h.bound.is_finite() && h.lower.is_finite() && h.mean.is_finite() && h.rms.is_finite());
        prop_assert!(h.lower <= h.bound && h.mean <= h.rms + 1e-4 && h.rms <= h.bound);
        prop_assert!(h.bound - h.lower <= tolerance.max(1e-4) + 1e-3, "{h:?}");
        points_within(&a, &b, &picks, h.ab, h.ba)?;
    }

    #[test]
    fn a_budgeted_bound_is_a_bound_and_refuses_only_what_exceeds(
        a in soup(40),
        b in soup(40),
        picks in prop::collection::vec((0usize..1000, 0.0f32..1.0, 0.0f32..1.0), 32),
        tolerance in 0.0f32..0.5,
        budget in 0.0f32..8.0,
    ) {
        let full = hausdorff(&a, &b, &opts(tolerance)).bound;
        let gap = tolerance.max(1e-4) + 1e-3;
        match bound_within(&a, &b, tolerance, budget, ErrorMetric::Geometry) {
            Some(bound) => {
                prop_assert!(bound <= budget && (bound - full).abs() <= gap, "{bound} against {full}");
                points_within(&a, &b, &picks, bound, bound)?;
            }
            None => prop_assert!(full > budget - gap, "refused {budget} with a bound of {full}"),
        }
    }

    #[test]
    fn the_direct_bound_holds_object_by_object_and_matches_the_three_searches(
        originals in prop::collection::vec(soup(16), 1..4),
        reduced in prop::collection::vec(soup(12), 1..4),
        near in 0.0f32..1.0,
        picks in prop::collection::vec((0usize..1000, 0.0f32..1.0, 0.0f32..1.0), 32),
        tolerance in 0.001f32..0.2,
        budget in 0.0f32..10.0,
    ) {
        // Objects 0..n, each an original and a cluster's triangles of it:
        // drawn near it (`near` of the way from a soup to the original) so
        // that the bounds are neither all tiny nor all refused.
        let n = originals.len().min(reduced.len());
        let near_own: Vec<Mesh> = (0..n).map(|k| {
            let (o, r) = (&originals[k], &reduced[k]);
            let positions = r.positions.iter().enumerate()
                .map(|(i, p)| o.positions[i % o.positions.len()].lerp(*p, near))
                .collect();
            Mesh { positions, ..r.clone() }
        }).collect();
        let mesh = objects(&near_own, 0);
        let originals: Vec<Mesh> = (0..n as u32)
            .map(|k| objects(std::slice::from_ref(&originals[k as usize]), k))
            .collect();
        let refs: Vec<&Mesh> = originals.iter().collect();
        let union = objects(&originals, 0);
        // The merge leaves degenerate triangles out.
        prop_assume!(mesh.triangle_count() > 0 && originals.iter().all(|o| o.triangle_count() > 0));
        let geometry = ErrorMetric::Geometry;
        // What the cluster's error stood for before: the whole distance
        // and each object's apart, three searches.
        let three = bound_within(&mesh, &union, tolerance, f32::INFINITY, geometry)
            .zip(feature_bound_within(&mesh, &refs, tolerance, f32::INFINITY, geometry))
            .map(|(whole, own)| whole.max(own))
            .expect("an infinite budget fits");
        let gap = tolerance + 1e-3;
        match direct_bound_within(&mesh, &refs, tolerance, budget, geometry) {
            Some(d) => {
                prop_assert!(d <= budget && (d - three).abs() <= gap, "{d} against {three}");
                points_within(&mesh, &union, &picks, d, d)?;
                for (k, own) in originals.iter().enumerate() {
                    let mine: Vec<Vec3> = points_on(&mesh, &picks)
                        .into_iter()
                        .zip(&picks)
                        .filter(|&(_, &(t, _, _))| {
                            let t = t % mesh.triangle_count();
                            mesh.features[mesh.indices[t * 3] as usize] == k as u32
                        })
                        .map(|(p, _)| p)
                        .collect();
                    for p in mine {
                        let e = brute_distance(p, own);
                        prop_assert!(e <= d, "a point of object {k} is {e} from its own, bound {d}");
                    }
                }
            }
            None => prop_assert!(three > budget - gap, "refused {budget} with {three}"),
        }
    }

    #[test]
    fn the_bound_holds_over_nearly_flat_pairs_convex_or_not(
        n in 1usize..5,
        heights in prop::collection::vec(-0.05f32..0.05, 1..36),
        flat in any::<bool>(),
        flips in prop::collection::vec(any::<bool>(), 1..25),
        radii in prop::collection::vec(0.05f32..0.5, 3..12),
        use_fan in any::<bool>(),
        a in soup(12),
        picks in prop::collection::vec((0usize..1000, 0.0f32..1.0, 0.0f32..1.0), 64),
    ) {
        let heights = if flat { vec![0.0] } else { heights };
        let b = if use_fan { fan(&radii, &heights) } else { height_field(n, &heights, &flips) };
        // A near B: the soup squeezed into a slab just above the field.
        let a = Mesh {
            positions: a
                .positions
                .iter()
                .map(|p| Vec3::new(p.x / 8.0 + 0.5, p.y / 8.0 + 0.5, p.z / 40.0 + 0.15))
                .collect(),
            ..a
        };
        let h = hausdorff(&a, &b, &opts(1e-4));
        points_within(&a, &b, &picks, h.ab, h.ba)?;
    }

    #[test]
    fn the_bound_holds_where_a_lies_across_fans_and_creases(
        radii in prop::collection::vec(0.05f32..0.5, 3..16),
        heights in prop::collection::vec(-0.2f32..0.2, 1..16),
        flat in any::<bool>(),
        apex in -0.3f32..0.3,
        picks in prop::collection::vec((0usize..1000, 0.0f32..1.0, 0.0f32..1.0), 3..24),
        lift in prop::collection::vec(-0.01f32..0.01, 1..8),
        tolerance in 0.0005f32..0.05,
    ) {
        // B: a fan, flat (a plate's tessellation) or folded at every spoke
        // with its apex raised (a cone's cap); A: triangles between points
        // on B, just off it, so that A's pieces lie across B's spokes and
        // around its apex, where the cut and star bounds apply.
        let mut b = fan(&radii, if flat { &[0.0] } else { &heights });
        if !flat {
            b.positions[0].z = apex;
        }
        let points = points_on(&b, &picks);
        let mut a = Mesh::default();
        for (k, w) in points.windows(3).enumerate() {
            let base = a.positions.len() as u32;
            a.positions.extend(w.iter().map(|p| *p + Vec3::Z * lift[k % lift.len()]));
            a.indices.extend([base, base + 1, base + 2]);
        }
        // The apex itself as a corner of A, as a simplification keeps it.
        let base = a.positions.len() as u32;
        a.positions.extend([b.positions[0], points[0], points[1]]);
        a.indices.extend([base, base + 1, base + 2]);
        let h = hausdorff(&a, &b, &opts(tolerance));
        for p in grid_on(&a, 12) {
            let d = brute_distance(p, &b);
            prop_assert!(d <= h.ab, "a point of A is {d} from B, bound {}", h.ab);
        }
        for p in grid_on(&b, 12) {
            let d = brute_distance(p, &a);
            prop_assert!(d <= h.ba, "a point of B is {d} from A, bound {}", h.ba);
        }
        prop_assert!(h.bound - h.lower <= tolerance + 1e-4, "{h:?}");
    }
}
