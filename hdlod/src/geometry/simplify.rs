//! Simplification to an absolute error budget, with meshoptimizer:
//! quadric edge collapse (Garland and Heckbert, "Surface simplification
//! using quadric error metrics", SIGGRAPH 1997) weighing normals and
//! colours, then the same with pruning of small disconnected components,
//! then vertex clustering (Rossignac and Borrel 1993; meshoptimizer's
//! "sloppy" simplifier) for inputs made of many small parts, where edge
//! collapse stalls on topology.
//!
//! Meshes of 40,000 triangles or more go through edge collapse in spatial
//! parts on parallel threads (`parallel`: meshoptimizer's sparse
//! simplification with the cut vertices locked, as Nanite simplifies its
//! cluster groups); smaller ones, such as a tree builder's clusters, take
//! one pass.
//!
//! meshoptimizer's own error figure is a quadric estimate, not a distance:
//! the caller measures the result (`hausdorff`) and uses that.

use std::borrow::Cow;

use meshopt::{SimplifyOptions as Flags, VertexDataAdapter, typed_to_bytes};

use super::{Mesh, features, parallel};

/// What to simplify to.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SimplifyOptions {
    /// The error budget, absolute (scene units). Infinite: no limit but the
    /// triangle target.
    pub max_error: f32,
    /// Stop at this many triangles even if the budget allows fewer.
    pub target_triangles: Option<usize>,
    /// Allow removing small disconnected components.
    pub prune: bool,
}

/// Which step produced the result.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Strategy {
    /// Nothing to do (empty input, target at or above the input size, or no
    /// step removed a triangle): the input, cleaned of invalid triangles.
    Unchanged,
    EdgeCollapse,
    /// Edge collapse that also removed small components.
    Pruned,
    Clustering,
}

#[derive(Debug, Clone)]
pub struct Simplified {
    pub mesh: Mesh,
    pub strategy: Strategy,
    pub triangles: usize,
}

/// Edge collapse "stalls" when it keeps more than this share of the
/// triangles while the budget or target asks for fewer.
const STALL_RATIO: f32 = 0.5;
/// A fallback must do at least this much better than the step before it
/// to be worth its lower quality.
const FALLBACK_GAIN: f32 = 0.8;
/// Attribute weights relative to the position error (meshoptimizer's
/// convention): colours matter as much as shape, normals a little less.
const NORMAL_WEIGHT: f32 = 0.5;
const COLOR_WEIGHT: f32 = 1.0;

/// Simplifies `mesh` within `options.max_error` (and down to
/// `options.target_triangles` at most, if given): edge collapse first, then
/// with pruning (if allowed), then clustering, each tried only when the one
/// before stalls. Triangles with an out-of-range index or a non-finite
/// corner are dropped first. Never returns more triangles than it was given,
/// and never an empty mesh for a non-empty input.
pub fn simplify(mesh: &Mesh, options: &SimplifyOptions) -> Simplified {
    let mesh = cleaned(mesh);
    let n = mesh.triangle_count();
    let target = options.target_triangles.unwrap_or(0);
    if n == 0 || target >= n {
        return unchanged(mesh.into_owned());
    }
    let stalled = |t: usize| t > target && t as f32 > STALL_RATIO * n as f32;

    // An empty result (the budget let a step remove every component) is no
    // result: a cluster must keep some geometry.
    let mut best: Option<(Vec<u32>, Strategy)> = None;
    let consider = |indices: Vec<u32>, strategy, best: &mut Option<(Vec<u32>, Strategy)>| {
        let current = best.as_ref().map_or(3 * n, |(b, _)| b.len());
        let gain = if best.is_some() { FALLBACK_GAIN } else { 1.0 };
        if !indices.is_empty() && (indices.len() as f32) < gain * current as f32 {
            *best = Some((indices, strategy));
        }
    };
    let count = |best: &Option<(Vec<u32>, Strategy)>| best.as_ref().map_or(n, |(b, _)| b.len() / 3);
    consider(
        edge_collapse_indices(&mesh, options, false),
        Strategy::EdgeCollapse,
        &mut best,
    );
    if options.prune && stalled(count(&best)) {
        consider(
            edge_collapse_indices(&mesh, options, true),
            Strategy::Pruned,
            &mut best,
        );
    }
    if stalled(count(&best)) {
        consider(
            clustering_indices(&mesh, options),
            Strategy::Clustering,
            &mut best,
        );
    }
    let Some((indices, strategy)) = best else {
        return unchanged(mesh.into_owned());
    };
    let mesh = compact(&mesh, &indices);
    Simplified {
        triangles: mesh.triangle_count(),
        mesh,
        strategy,
    }
}

/// Quadric edge collapse alone (with pruning if `options.prune`). Meshes
/// of 40,000 triangles or more are simplified in parts in parallel (see
/// [`edge_collapse_in_parts`]; the number of parts depends on the size
/// only, so the result is the same on every machine).
pub fn edge_collapse(mesh: &Mesh, options: &SimplifyOptions) -> Mesh {
    run_step(mesh, options, |m| {
        edge_collapse_indices(m, options, options.prune)
    })
}

/// Quadric edge collapse split into `parts` spatial parts simplified in
/// parallel, their shared vertices locked so that they still meet; each part
/// goes to its share of `options.target_triangles`, rounded down, so the
/// total never exceeds it. `parts` of 1 (or 0) is the single-thread pass
/// over the whole mesh.
pub fn edge_collapse_in_parts(mesh: &Mesh, options: &SimplifyOptions, parts: usize) -> Mesh {
    run_step(mesh, options, |m| {
        edge_collapse_indices_in(m, options, options.prune, parts)
    })
}

/// Quadric edge collapse that also moves the kept vertices to where the
/// quadric error is least (meshoptimizer's `simplifyWithUpdate`), on
/// positions alone, down to `target_triangles`: a closed curved part (a
/// tree's crown) keeps far fewer triangles than with vertex selection
/// alone at the same measured distance. meshoptimizer's error estimate
/// says little about that distance here, so the caller gives a count and
/// measures. Vertices keep their colour.
pub fn edge_collapse_placed(mesh: &Mesh, target_triangles: usize) -> Mesh {
    let mesh = cleaned(mesh);
    if mesh.is_empty() || target_triangles >= mesh.triangle_count() {
        return mesh.into_owned();
    }
    let mut indices = mesh.indices.clone();
    let mut positions: Vec<[f32; 3]> = mesh.positions.iter().map(|p| p.to_array()).collect();
    // No attributes: the crate still wants a buffer with a stride.
    let mut attributes = vec![0.0f32; positions.len()];
    let kept = meshopt::simplify_with_update(
        &mut indices,
        &mut positions,
        &mut attributes,
        &[],
        std::mem::size_of::<f32>(),
        None,
        3 * target_triangles,
        f32::MAX,
        Flags::None,
        None,
    );
    indices.truncate(kept);
    let moved = Mesh {
        positions: positions.into_iter().map(glam::Vec3::from_array).collect(),
        normals: Vec::new(),
        colors: mesh.colors.clone(),
        features: mesh.features.clone(),
        indices: Vec::new(),
    };
    compact(&moved, &indices)
}

/// One simplifier on its own, for comparing them (`hdlod simplify
/// --method`, `hdlod bench simplify`, `hdlod lod`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Method {
    /// Quadric edge collapse ([`edge_collapse`]).
    Qem,
    /// Vertex clustering ([`clustering`]).
    Clustering,
    /// Vertex removal ([`super::vertex_removal()`]).
    VertexRemoval,
}

impl Method {
    pub const ALL: [Method; 3] = [Method::Qem, Method::Clustering, Method::VertexRemoval];

    /// The name used on the command line and in JSON.
    pub fn name(self) -> &'static str {
        match self {
            Method::Qem => "qem",
            Method::Clustering => "clustering",
            Method::VertexRemoval => "vertex-removal",
        }
    }

    /// Runs this simplifier alone on `mesh`.
    pub fn run(self, mesh: &Mesh, options: &SimplifyOptions) -> Mesh {
        match self {
            Method::Qem => edge_collapse(mesh, options),
            Method::Clustering => clustering(mesh, options),
            Method::VertexRemoval => super::vertex_removal(mesh, options),
        }
    }
}

/// Vertex clustering alone.
pub fn clustering(mesh: &Mesh, options: &SimplifyOptions) -> Mesh {
    run_step(mesh, options, |m| clustering_indices(m, options))
}

fn run_step(mesh: &Mesh, options: &SimplifyOptions, step: impl Fn(&Mesh) -> Vec<u32>) -> Mesh {
    let mesh = cleaned(mesh);
    if mesh.is_empty() || options.target_triangles.unwrap_or(0) >= mesh.triangle_count() {
        return mesh.into_owned();
    }
    let indices = step(&mesh);
    if indices.is_empty() {
        return mesh.into_owned();
    }
    compact(&mesh, &indices)
}

fn unchanged(mesh: Mesh) -> Simplified {
    Simplified {
        triangles: mesh.triangle_count(),
        mesh,
        strategy: Strategy::Unchanged,
    }
}

/// The mesh without the triangles meshoptimizer must not see: out-of-range
/// indices (undefined behaviour in C) and non-finite corners. Attribute
/// arrays of the wrong length are dropped rather than trusted. A mesh with
/// nothing to drop is borrowed: copying a large one costs a share of the
/// simplification itself.
pub(super) fn cleaned(mesh: &Mesh) -> Cow<'_, Mesh> {
    let n = mesh.positions.len();
    let ok = |i: u32| (i as usize) < n && mesh.positions[i as usize].is_finite();
    let fits = |len: usize| len == 0 || len == n;
    if mesh.indices.len().is_multiple_of(3)
        && fits(mesh.normals.len())
        && fits(mesh.colors.len())
        && fits(mesh.features.len())
        && mesh.indices.iter().all(|&i| ok(i))
    {
        return Cow::Borrowed(mesh);
    }
    let indices = mesh
        .indices
        .chunks_exact(3)
        .filter(|t| t.iter().all(|&i| ok(i)))
        .flatten()
        .copied()
        .collect();
    Cow::Owned(Mesh {
        positions: mesh.positions.clone(),
        normals: if mesh.normals.len() == n {
            mesh.normals.clone()
        } else {
            Vec::new()
        },
        colors: if mesh.colors.len() == n {
            mesh.colors.clone()
        } else {
            Vec::new()
        },
        features: if mesh.features.len() == n {
            mesh.features.clone()
        } else {
            Vec::new()
        },
        indices,
    })
}

pub(super) fn adapter(mesh: &Mesh) -> VertexDataAdapter<'_> {
    VertexDataAdapter::new(typed_to_bytes(&mesh.positions), 12, 0)
        .expect("a Vec3 slice is a whole number of 12-byte vertices")
}

/// The absolute budget as meshoptimizer's error relative to the mesh extent.
fn relative_error(mesh: &Mesh, options: &SimplifyOptions) -> f32 {
    let scale = meshopt::simplify_scale(&adapter(mesh));
    if !(options.max_error.is_finite()) || scale <= 0.0 {
        // No limit but the target (or a mesh of one point: anything goes).
        return f32::MAX;
    }
    (options.max_error.max(0.0) / scale).min(f32::MAX)
}

fn edge_collapse_indices(mesh: &Mesh, options: &SimplifyOptions, prune: bool) -> Vec<u32> {
    edge_collapse_indices_in(
        mesh,
        options,
        prune,
        parallel::part_count(mesh.triangle_count()),
    )
}

/// Edge collapse in `parts` parts (see `parallel`); one part is the plain
/// single-thread pass over the whole mesh.
fn edge_collapse_indices_in(
    mesh: &Mesh,
    options: &SimplifyOptions,
    prune: bool,
    parts: usize,
) -> Vec<u32> {
    let target = options.target_triangles.unwrap_or(0);
    let flags = if prune { Flags::Prune } else { Flags::None };
    let vertices = adapter(mesh);
    let mut weights = Vec::new();
    if !mesh.normals.is_empty() {
        weights.extend([NORMAL_WEIGHT; 3]);
    }
    if !mesh.colors.is_empty() {
        weights.extend([COLOR_WEIGHT; 4]);
    }
    let mut attributes = Vec::with_capacity(mesh.positions.len() * weights.len());
    for i in 0..mesh.positions.len() {
        if let Some(n) = mesh.normals.get(i) {
            attributes.extend(n.to_array());
        }
        if let Some(c) = mesh.colors.get(i) {
            attributes.extend(c);
        }
    }
    let collapse = |indices: &[u32], locks: &[bool], target: usize, error: f32, flags: Flags| {
        let mut reached = 0.0;
        let kept = if weights.is_empty() {
            meshopt::simplify_with_locks(
                indices,
                &vertices,
                locks,
                target,
                error,
                flags,
                Some(&mut reached),
            )
        } else {
            meshopt::simplify_with_attributes_and_locks(
                indices,
                &vertices,
                &attributes,
                &weights,
                weights.len() * 4,
                locks,
                target,
                error,
                flags,
                Some(&mut reached),
            )
        };
        (kept, reached)
    };
    if parts > 1 && mesh.triangle_count() >= 2 * parts {
        let error = if options.max_error.is_finite() {
            options.max_error.max(0.0)
        } else {
            f32::MAX
        };
        return parallel::collapse_in_parts(mesh, parts, target, error, flags, &collapse);
    }
    // The wrapper passes the lock array's pointer on even when it is empty,
    // so it gets one (unlocked) entry per vertex.
    let locks = vec![false; mesh.positions.len()];
    collapse(
        &mesh.indices,
        &locks,
        3 * target,
        relative_error(mesh, options),
        flags,
    )
    .0
}

/// Vertex clustering; a mesh with feature ids is clustered feature by
/// feature (`features::clustering_per_feature`).
fn clustering_indices(mesh: &Mesh, options: &SimplifyOptions) -> Vec<u32> {
    if !mesh.features.is_empty() {
        return features::clustering_per_feature(
            mesh,
            options.target_triangles.unwrap_or(0),
            |m, target| {
                let error = relative_error(m, options);
                meshopt::simplify_sloppy(&m.indices, &adapter(m), 3 * target, error, None)
            },
        );
    }
    let target = options.target_triangles.unwrap_or(0) * 3;
    let error = relative_error(mesh, options);
    meshopt::simplify_sloppy(&mesh.indices, &adapter(mesh), target, error, None)
}

/// The mesh made of `indices` (into `mesh`'s vertices) with only the
/// vertices they use, in first-use order, each triangle on one feature
/// (`features::one_per_triangle`).
pub(super) fn compact(mesh: &Mesh, indices: &[u32]) -> Mesh {
    let mut remap = vec![u32::MAX; mesh.positions.len()];
    let mut out = Mesh::default();
    out.indices.reserve(indices.len());
    for &i in indices {
        let slot = &mut remap[i as usize];
        if *slot == u32::MAX {
            *slot = out.positions.len() as u32;
            out.positions.push(mesh.positions[i as usize]);
            if let Some(n) = mesh.normals.get(i as usize) {
                out.normals.push(*n);
            }
            if let Some(c) = mesh.colors.get(i as usize) {
                out.colors.push(*c);
            }
            out.features.extend(mesh.features.get(i as usize));
        }
        out.indices.push(*slot);
    }
    features::one_per_triangle(&mut out, mesh);
    out
}
