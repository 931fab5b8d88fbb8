//! A parent's geometry and its error: the children's union reduced within
//! the level's budget, and `eps_c` measured, never estimated
//! (docs/method.md section 2). Also the parent a lone cluster gets of its
//! own, and the reduction the dynamic LOD chains share.

use std::borrow::Borrow;
use std::sync::{Arc, Mutex};

use glam::Mat4;

use super::config::Thresholds;
use super::context::{Active, Context};
use super::outputs::QUANTIZATION_SHARE;
use crate::Result;
use crate::geometry::bake::{self, BakeOptions, Baked, Source};
use crate::geometry::{self, ErrorMetric, Mesh, Part, Parts, SimplifyOptions, Strategy};

/// A parent made by `make_parent`: its geometry, `eps_c`, geometry hash,
/// baked colour and the originals below it (if kept).
pub(super) struct Parent {
    pub mesh: Mesh,
    pub eps: f64,
    pub hash: String,
    pub baked: Option<Baked>,
    pub originals: Option<Vec<Arc<Mesh>>>,
}

/// Merges the children's geometry, simplifies it within the level's budget
/// and measures the spatial error: `eps_c = D_H(g_c, union g_c') + max
/// eps_c'`, with `D_H` a computed upper bound (see `reduce_within`). When
/// nothing removes triangles, the parent is the union (`D_H = 0`).
pub(super) fn make_parent(
    ctx: &Context,
    active: &[Active],
    group: &[usize],
    th: &Thresholds,
) -> Result<Parent> {
    let children: Vec<&Active> = group.iter().map(|&i| &active[i]).collect();
    let child_eps = children.iter().map(|c| c.eps).fold(0.0, f64::max);
    let parts: Vec<Part> = children
        .iter()
        .map(|c| Part {
            mesh: &c.mesh,
            transform: Mat4::IDENTITY,
            color: [1.0; 4],
            feature: None,
        })
        .collect();
    let union = geometry::merge(&parts, 0.0);
    let budget = (th.eps - child_eps) as f32;
    let tolerance = (ctx.config.hausdorff_fraction * th.eps) as f32;
    let metric = ctx.config.error_metric;
    let (mesh, h) = reduce_within(&union, budget, tolerance, metric).unwrap_or((union, 0.0));
    let originals = originals_of(&children);
    let eps = stored_eps(&mesh, h, child_eps, originals.as_deref(), tolerance, metric);
    let sources: Vec<Source> = children.iter().map(|c| c.source()).collect();
    let baked = bake_colour(ctx, &mesh, eps, &sources, originals.as_deref());
    let stored = ctx
        .sink
        .put(&mesh, baked.as_ref(), eps * QUANTIZATION_SHARE)?;
    Ok(Parent {
        mesh,
        // The stored positions lie up to `moved` from the mesh's.
        eps: eps + stored.moved,
        hash: stored.hash,
        baked,
        originals,
    })
}

/// The baked colour of a cluster's `mesh` of error `eps`, made from
/// `children` (their geometry and baked colour), when the build bakes
/// (docs/method.md section 3, "Baked colour"). The colour is that of the
/// original objects where they are kept (the full detail, exact), else of
/// the children's geometry with its own baked colour: both lie within
/// `eps` of the mesh, which is how far in front of and behind a texel the
/// colour is looked for. A texel is `eps` wide: about a pixel where the
/// cut draws the cluster at its budget.
pub(super) fn bake_colour(
    ctx: &Context,
    mesh: &Mesh,
    eps: f64,
    children: &[Source],
    originals: Option<&[Arc<Mesh>]>,
) -> Option<Baked> {
    if !ctx.config.bake {
        return None;
    }
    let sources: Vec<Source> = match originals {
        Some(o) => o
            .iter()
            .map(|m| Source {
                mesh: m,
                baked: None,
            })
            .collect(),
        None => children.to_vec(),
    };
    let options = BakeOptions {
        texel: eps as f32,
        reach: eps as f32,
        max_size: ctx.config.bake_max_texels,
    };
    bake::bake(mesh, &sources, &options)
}

/// Clusters whose original objects have at most this many triangles in all
/// get `direct_eps`: the measure costs what a parent's own does, and on the
/// paper scene this covers the static surroundings and the lower levels.
pub(super) const DIRECT_MAX_TRIANGLES: usize = 20_000;

/// The originals below `children`, if all of them kept theirs and there
/// are few enough.
fn originals_of(children: &[&Active]) -> Option<Vec<Arc<Mesh>>> {
    let mut out = Vec::new();
    let mut triangles = 0;
    for c in children {
        for m in c.originals.as_ref()? {
            triangles += m.triangle_count();
            out.push(m.clone());
        }
    }
    (triangles <= DIRECT_MAX_TRIANGLES).then_some(out)
}

/// The `eps_c` stored for geometry `mesh` made within the measured bound
/// `h` of children whose largest error is `child_eps`. The recursive
/// `h + child_eps` of docs/method.md section 2 bounds `D_H(g_c, union of the
/// original objects of c)` through the triangle inequality, adding each
/// level's bound to the one below; where the `originals` were kept, that
/// distance is also measured directly, often half the sum, and the
/// smaller of the two is stored (both are bounds), never below a child's,
/// so errors still grow upwards. A smaller `eps_c` lets the cut stop
/// higher in the tree.
fn stored_eps(
    mesh: &Mesh,
    h: f32,
    child_eps: f64,
    originals: Option<&[Arc<Mesh>]>,
    tolerance: f32,
    metric: ErrorMetric,
) -> f64 {
    let recursive = f64::from(h) + child_eps;
    // Nothing removed: no direct bound could go below the children's.
    // Children without error are the originals: `h` already measured the
    // distance to them.
    if h == 0.0 || child_eps == 0.0 {
        return recursive;
    }
    originals.map_or(recursive, |o| {
        direct_eps(mesh, o, tolerance, recursive, metric)
            .map_or(recursive, |direct| direct.min(recursive))
            .max(child_eps)
    })
}

/// A bound of `D_H(mesh, union of originals)`, measured, if it is at most
/// `budget`.
fn direct_eps(
    mesh: &Mesh,
    originals: &[Arc<Mesh>],
    tolerance: f32,
    budget: f64,
    metric: ErrorMetric,
) -> Option<f64> {
    // The recursive bound holds object by object as well (each object's
    // triangles come from that object's below), and a viewer picks and
    // hides objects inside a cluster: the direct bound stands in for it
    // only where it does too (docs/method.md, "Object identity").
    let originals: Vec<&Mesh> = originals.iter().map(|m| m.as_ref()).collect();
    geometry::direct_bound_within(mesh, &originals, tolerance, budget as f32, metric).map(f64::from)
}

/// A parent of its own for a lone cluster: its geometry, error and baked
/// colour.
pub(super) struct Single {
    pub mesh: Mesh,
    pub eps: f64,
    pub baked: Option<Baked>,
}

/// The paper's loop moves a cluster with no neighbours up unchanged; an
/// element longer than `w(l)` then stays a leaf until a level whose error
/// may be more than one pixel where the cut reaches it, so the cut draws
/// the leaf. Instead it gets a parent of its own: its geometry reduced
/// within `eps(l)`, when that keeps at most `min_reduction` of its
/// triangles.
pub(super) fn single_parent(ctx: &Context, child: &Active, th: &Thresholds) -> Option<Single> {
    // A cluster that stays alone keeps its parts from level to level: the
    // next level's budget is about twice this one's, so its half is
    // answered by what this one measured.
    let cache = child
        .parts
        .get_or_init(|| Mutex::new(Parts::new(child.mesh.clone())));
    let mut parts = cache.lock().expect("no panic while holding");
    let (mesh, h) = reduce_lone(ctx, &mut parts, child.eps, th)?;
    drop(parts);
    let tolerance = (ctx.config.hausdorff_fraction * th.eps) as f32;
    let eps = stored_eps(
        &mesh,
        h,
        child.eps,
        child.originals.as_deref(),
        tolerance,
        ctx.config.error_metric,
    );
    let baked = bake_colour(
        ctx,
        &mesh,
        eps,
        &[child.source()],
        child.originals.as_deref(),
    );
    Some(Single { mesh, eps, baked })
}

/// A lone cluster's `mesh` (of error `child_eps`) reduced within the
/// level's budget and the measured bound, when that keeps at most
/// `min_reduction` of its triangles.
pub(super) fn reduce_lone<M: Borrow<Mesh>>(
    ctx: &Context,
    parts: &mut Parts<M>,
    child_eps: f64,
    th: &Thresholds,
) -> Option<(Mesh, f32)> {
    let triangles = parts.mesh().triangle_count();
    if (triangles as f64) * ctx.config.min_reduction < QUAD_TRIANGLES {
        return None;
    }
    let budget = (th.eps - child_eps) as f32;
    let tolerance = (ctx.config.hausdorff_fraction * th.eps) as f32;
    let cap = (triangles as f64 * ctx.config.min_reduction) as usize;
    let (reduced, h) = reduce_parts_within(parts, budget, tolerance, ctx.config.error_metric, cap)?;
    (reduced.triangle_count() <= cap).then_some((reduced, h))
}

/// The fewest triangles a part is reduced to (a quad): a cluster with fewer
/// left after the reduction gains nothing from a parent of its own.
pub(super) const QUAD_TRIANGLES: f64 = 2.0;

/// `mesh` reduced within `budget` (scene units) and the measured bound of
/// its Hausdorff distance to `mesh`, if some candidate removes triangles.
/// The candidates: part by part (`geometry::reduce_parts`: per-part boxes
/// or simplifications and a greedy cover) at half and all of the budget,
/// the latter also followed by meshoptimizer on what is left of the
/// budget, and, where those keep more than half, meshoptimizer on the
/// whole. The cut draws a cluster once its error is small enough on
/// screen, so a smaller error is worth some triangles: of the candidates
/// within `EPS_PREFERENCE` times the fewest triangles, the one with the
/// least error wins.
pub(super) fn reduce_within(
    mesh: &Mesh,
    budget: f32,
    tolerance: f32,
    metric: ErrorMetric,
) -> Option<(Mesh, f32)> {
    reduce_parts_within(&mut Parts::new(mesh), budget, tolerance, metric, usize::MAX)
}

/// [`reduce_within`] of the mesh of `parts`, with what they measured
/// before.
fn reduce_parts_within<M: Borrow<Mesh>>(
    parts: &mut Parts<M>,
    budget: f32,
    tolerance: f32,
    metric: ErrorMetric,
    cap: usize,
) -> Option<(Mesh, f32)> {
    if budget <= 0.0 {
        return None;
    }
    let mut candidates: Vec<(Mesh, f32)> = Vec::new();
    // The whole budget first: what it measured answers most of the half's
    // questions without measuring again (a part's stand-in over the whole
    // is over the half; one measured within half of it fits the half).
    // The other order measured twice what failed the half and fits the
    // whole, the most common outcome. Past `cap` the whole budget's parts
    // give up (a lone cluster would keep too many triangles for a parent),
    // and meshoptimizer on the whole mesh is all that is left to try.
    let Some(whole) = parts.reduce_until(budget, tolerance, metric, |t, _| t > cap) else {
        return simplified_within(parts.mesh(), budget, tolerance, metric, cap);
    };
    if let Some((m, h)) = simplified_within(
        &whole.mesh,
        budget - whole.bound,
        tolerance,
        metric,
        usize::MAX,
    ) {
        candidates.push((m, h + whole.bound));
    }
    candidates.push((whole.mesh, whole.bound));
    // The half budget's parts stop once they could not be chosen below,
    // or once they could only be chosen to be thrown away: past
    // `EPS_PREFERENCE` times the fewest triangles so far; past `cap` with
    // an error no less than a candidate within it (the others are all
    // within it). Reductions made only to be thrown away were a fifth of
    // a steel model's build.
    let beatable = reach(&candidates);
    let least_error = candidates
        .iter()
        .map(|(_, h)| *h)
        .fold(f32::INFINITY, f32::min);
    let give_up = |t: usize, h: f32| t > beatable || (t > cap && h >= least_error);
    if let Some(half) = parts.reduce_until(budget * 0.5, tolerance * 0.5, metric, give_up) {
        candidates.push((half.mesh, half.bound));
    }
    let mesh = parts.mesh();
    // Worth its cost only where the parts gave little.
    if candidates
        .iter()
        .all(|(m, _)| m.triangle_count() * 2 > mesh.triangle_count())
    {
        // Past the reach of the choice it need not be measured.
        let beatable = reach(&candidates);
        candidates.extend(simplified_within(mesh, budget, tolerance, metric, beatable));
    }
    let beatable = reach(&candidates);
    candidates
        .into_iter()
        .filter(|(m, h)| {
            *h <= budget
                && m.triangle_count() < mesh.triangle_count()
                && m.triangle_count() <= beatable
        })
        .min_by(|a, b| {
            a.1.total_cmp(&b.1)
                .then(a.0.triangle_count().cmp(&b.0.triangle_count()))
        })
}

/// How many times the fewest triangles a candidate parent may keep and
/// still win by a smaller error.
const EPS_PREFERENCE: f64 = 1.5;

/// The most triangles a candidate may keep and still be chosen among
/// `candidates` (`EPS_PREFERENCE` times their fewest): a later candidate
/// only lowers it.
fn reach(candidates: &[(Mesh, f32)]) -> usize {
    candidates
        .iter()
        .map(|(m, _)| m.triangle_count())
        .min()
        .map_or(usize::MAX, |f| (EPS_PREFERENCE * f as f64) as usize)
}

/// meshoptimizer's simplification of `mesh` within `budget` and its
/// measured Hausdorff bound, if it removed triangles, keeps at most
/// `max_triangles` (else it is not measured) and the bound fits.
fn simplified_within(
    mesh: &Mesh,
    budget: f32,
    tolerance: f32,
    metric: ErrorMetric,
    max_triangles: usize,
) -> Option<(Mesh, f32)> {
    if budget <= 0.0 {
        return None;
    }
    let s = geometry::simplify(
        mesh,
        &SimplifyOptions {
            max_error: budget,
            target_triangles: None,
            prune: true,
        },
    );
    if s.strategy == Strategy::Unchanged
        || s.triangles >= mesh.triangle_count()
        || s.triangles > max_triangles
    {
        return None;
    }
    geometry::bound_within(&s.mesh, mesh, tolerance, budget, metric).map(|h| (s.mesh, h))
}
