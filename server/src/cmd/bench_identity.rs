//! `hdlod bench presence` and `hdlod bench features`: what object identity
//! inside clusters gives and how faithful it is, on a tree and the scene
//! it was built from. `presence`: the temporal error of the paper's
//! presence rule and of the exact one in the table's 12 cells
//! (`hdlod_fixtures::paper::temporal_errors`). `features`: for sampled
//! clusters, how far each object's triangles lie from the object, against
//! the cluster's `eps_c` (`hdlod::tree::fidelity`).

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use anyhow::Context;
use hdlod::geometry::measure;
use hdlod::scene::{Scene, format};
use hdlod::tree::fidelity::feature_distances;
use hdlod_fixtures::paper;
use rand::SeedableRng;
use rand::seq::SliceRandom;
use serde::Serialize;

#[derive(clap::Args)]
pub struct PresenceArgs {
    /// The tree.
    tree: PathBuf,
    /// The scene the tree was built from (`hdlod-scene/1`): the objects'
    /// areas.
    #[arg(long)]
    scene: PathBuf,
    /// Print JSON rows instead of the table.
    #[arg(long)]
    json: bool,
}

#[derive(clap::Args)]
pub struct FeaturesArgs {
    /// The tree.
    tree: PathBuf,
    /// The scene the tree was built from (`hdlod-scene/1`).
    #[arg(long)]
    scene: PathBuf,
    /// Clusters measured, drawn at random among those with geometry (all
    /// of them when there are fewer).
    #[arg(long, default_value_t = 2000)]
    sample: usize,
    #[arg(long, default_value_t = 1)]
    seed: u64,
    #[arg(long)]
    json: bool,
}

fn load(tree: &Path, scene: &Path) -> anyhow::Result<(hdlod::tree::Tree, Scene)> {
    let tree = hdlod::tree::load(tree)?;
    let scene = format::load(scene)?;
    anyhow::ensure!(
        scene.name == tree.scene,
        "the tree was built from scene {:?}, not {:?}",
        tree.scene,
        scene.name
    );
    Ok((tree, scene))
}

pub fn presence(args: PresenceArgs) -> anyhow::Result<()> {
    let (tree, scene) = load(&args.tree, &args.scene)?;
    let areas: HashMap<&str, f64> = scene
        .objects
        .iter()
        .map(|o| {
            let placed = scene.meshes[o.mesh].transformed(&o.transform);
            (o.id.as_str(), measure::area(&placed))
        })
        .collect();
    let rows = paper::temporal_errors(&tree, &|id| areas.get(id).copied().unwrap_or(0.0));
    if args.json {
        println!("{}", serde_json::to_string_pretty(&rows)?);
        return Ok(());
    }
    println!(
        "| time | screen | paper: temporal error | exact: temporal error | paper: clusters / triangles | exact: clusters / triangles |"
    );
    println!("|---|---|---:|---:|---:|---:|");
    for r in &rows {
        println!(
            "| {} | {} | {:.2}% | {:.2}% | {} / {} | {} / {} |",
            r.time,
            r.screen,
            100.0 * r.paper.temporal_error,
            100.0 * r.exact.temporal_error,
            r.paper.clusters,
            r.paper.triangles,
            r.exact.clusters,
            r.exact.triangles
        );
    }
    Ok(())
}

#[derive(Serialize)]
struct FeaturesReport {
    clusters: usize,
    /// (cluster, object) pairs measured.
    pairs: usize,
    /// Pairs whose distance exceeds `eps_c` plus the measure's own slack.
    over_eps: usize,
    /// The largest distance over `eps_c` among pairs with `eps_c > 0`.
    max_ratio: f64,
    p99_ratio: f64,
    median_ratio: f64,
}

pub fn features(args: FeaturesArgs) -> anyhow::Result<()> {
    let (tree, scene) = load(&args.tree, &args.scene)?;
    let mut ids: Vec<u32> = tree
        .clusters()
        .filter(|c| c.geometry.is_some())
        .map(|c| c.id)
        .collect();
    ids.shuffle(&mut rand_chacha::ChaCha8Rng::seed_from_u64(args.seed));
    ids.truncate(args.sample);
    let tolerance = (1e-5 * tree.bounds.diagonal()) as f32;
    let distances = feature_distances(&args.tree, &tree, &scene, &ids, tolerance)
        .context("measuring the features")?;
    // What `one_sided_bound` adds for rounding, and its tolerance.
    let largest = tree
        .bounds
        .min
        .abs()
        .max(tree.bounds.max.abs())
        .max_element();
    let slack = 16.0 * f64::from(f32::EPSILON) * largest + f64::from(tolerance);
    let mut ratios: Vec<f64> = distances
        .iter()
        .filter(|d| d.eps > 0.0)
        .map(|d| d.distance / d.eps)
        .collect();
    ratios.sort_by(f64::total_cmp);
    let at = |p: f64| paper::percentile(&ratios, p);
    let report = FeaturesReport {
        clusters: ids.len(),
        pairs: distances.len(),
        over_eps: distances
            .iter()
            .filter(|d| d.distance > d.eps + slack)
            .count(),
        max_ratio: at(1.0),
        p99_ratio: at(0.99),
        median_ratio: at(0.5),
    };
    if args.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        println!(
            "{} clusters, {} (cluster, object) pairs: {} farther from their object than eps_c; distance / eps_c median {:.3}, p99 {:.3}, max {:.3}",
            report.clusters,
            report.pairs,
            report.over_eps,
            report.median_ratio,
            report.p99_ratio,
            report.max_ratio
        );
    }
    Ok(())
}
