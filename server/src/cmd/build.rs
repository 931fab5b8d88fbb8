//! `hdlod build SCENE --out TREE [--config FILE] [--full] [--json]`: a
//! full build, or, when TREE holds a tree of the same geometry and
//! configuration, an update of its schedule.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::Context;
use hdlod::build::{BuildConfig, BuildStats, How, LevelStats, build_or_update_to};
use hdlod::scene::format;
use serde::Serialize;

use super::progress::Report;

#[derive(clap::Args)]
pub struct Args {
    /// The scene: a directory with scene.json (hdlod-scene/1), or the file.
    scene: PathBuf,
    /// The tree directory to write (replaced atomically on success). When
    /// it holds a tree built from this scene's geometry with the same
    /// configuration, only the schedule changed, that tree is updated
    /// without remaking any geometry.
    #[arg(long)]
    out: PathBuf,
    /// Build in full even where the tree at --out could be updated.
    #[arg(long)]
    full: bool,
    /// Build configuration (JSON, the fields of `BuildConfig`; see
    /// docs/formats.md). Missing fields take their defaults.
    #[arg(long)]
    config: Option<PathBuf>,
    /// Print a JSON summary on stdout instead of a table.
    #[arg(long)]
    json: bool,
}

/// The `--json` summary (schemas/build-summary.schema.json).
#[derive(Serialize)]
struct Summary<'a> {
    scene: &'a str,
    out: String,
    /// `full`, `schedule-update` or `geometry-update`.
    mode: &'static str,
    /// Why the tree at `out` was not updated, when there was one.
    #[serde(skip_serializing_if = "Option::is_none")]
    not_updated: Option<String>,
    /// What an update kept of the old tree.
    #[serde(skip_serializing_if = "Option::is_none")]
    reused: Option<Reused>,
    seconds: f64,
    objects: usize,
    clusters: usize,
    levels: u32,
    absent_objects: usize,
    phases: Vec<Phase<'a>>,
    classes: Vec<ClassLevels<'a>>,
}

#[derive(Serialize)]
struct Reused {
    clusters: usize,
    #[serde(skip_serializing_if = "Option::is_none")]
    rebuilt_clusters: Option<usize>,
    /// Of the clusters kept, those above an edit whose error was widened
    /// by how far the objects below them moved.
    #[serde(skip_serializing_if = "Option::is_none")]
    widened_clusters: Option<usize>,
    #[serde(skip_serializing_if = "Option::is_none")]
    edited_objects: Option<usize>,
    #[serde(skip_serializing_if = "Option::is_none")]
    added_objects: Option<usize>,
    #[serde(skip_serializing_if = "Option::is_none")]
    removed_objects: Option<usize>,
    #[serde(skip_serializing_if = "Option::is_none")]
    dropped_clusters: Option<usize>,
    geometry_files: usize,
    dissolved_groups: usize,
}

#[derive(Serialize)]
struct Phase<'a> {
    name: &'a str,
    seconds: f64,
}

#[derive(Serialize)]
struct ClassLevels<'a> {
    class: &'static str,
    levels: &'a [LevelStats],
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let started = Instant::now();
    let config = match &args.config {
        Some(path) => read_config(path)?,
        None => BuildConfig::default(),
    };
    let report = Report::new(args.json);
    let scene = format::load(&args.scene)
        .with_context(|| format!("cannot load the scene {}", args.scene.display()))?;
    let load_seconds = started.elapsed().as_secs_f64();
    let (tree, stats, how) = build_or_update_to(&scene, &config, &args.out, args.full, &report)
        .with_context(|| format!("cannot build the tree {}", args.out.display()))?;
    report.finish();
    let mut phases = vec![Phase {
        name: "load",
        seconds: load_seconds,
    }];
    phases.extend(stats.phases.iter().map(|(name, seconds)| Phase {
        name,
        seconds: *seconds,
    }));
    let (mode, not_updated, reused) = match how {
        How::Full { why } => ("full", why, None),
        How::ScheduleUpdate {
            geometry_files,
            dissolved,
        } => (
            "schedule-update",
            None,
            Some(Reused {
                clusters: tree.cluster_count(),
                rebuilt_clusters: None,
                widened_clusters: None,
                edited_objects: None,
                added_objects: None,
                removed_objects: None,
                dropped_clusters: None,
                geometry_files,
                dissolved_groups: dissolved,
            }),
        ),
        How::GeometryUpdate {
            edited_objects,
            added_objects,
            removed_objects,
            rebuilt,
            widened,
            dropped,
            geometry_files,
            dissolved,
        } => (
            "geometry-update",
            None,
            Some(Reused {
                clusters: tree.cluster_count().saturating_sub(rebuilt),
                rebuilt_clusters: Some(rebuilt),
                widened_clusters: Some(widened),
                edited_objects: Some(edited_objects),
                added_objects: Some(added_objects),
                removed_objects: Some(removed_objects),
                dropped_clusters: Some(dropped),
                geometry_files,
                dissolved_groups: dissolved,
            }),
        ),
    };
    let summary = Summary {
        scene: &scene.name,
        out: args.out.display().to_string(),
        mode,
        not_updated,
        reused,
        seconds: started.elapsed().as_secs_f64(),
        objects: scene.objects.len(),
        clusters: tree.cluster_count(),
        levels: stats.levels,
        absent_objects: stats.absent_objects.len(),
        phases,
        classes: class_levels(&stats),
    };
    if args.json {
        println!("{}", serde_json::to_string_pretty(&summary)?);
    } else {
        print!("{}", table(&summary));
    }
    Ok(())
}

fn class_levels(stats: &BuildStats) -> Vec<ClassLevels<'_>> {
    vec![
        ClassLevels {
            class: "static",
            levels: &stats.static_levels,
        },
        ClassLevels {
            class: "pseudo_dynamic",
            levels: &stats.pseudo_dynamic_levels,
        },
        ClassLevels {
            class: "dynamic",
            levels: &stats.dynamic_levels,
        },
    ]
}

fn read_config(path: &Path) -> anyhow::Result<BuildConfig> {
    let text = hdlod::input::read_to_string(path)?;
    let config: BuildConfig =
        serde_json::from_str(&text).map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?;
    config
        .validate()
        .map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?;
    Ok(config)
}

fn table(s: &Summary) -> String {
    let mut out = match &s.reused {
        None => format!(
            "built {} -> {}: {} objects, {} clusters, {} levels, {:.2} s\n",
            s.scene, s.out, s.objects, s.clusters, s.levels, s.seconds
        ),
        Some(r) if r.rebuilt_clusters.is_some() => format!(
            "updated the geometry of {} -> {}: {} objects ({} edited, {} added, {} removed), \
             {} clusters made again, {} dropped, {} kept ({} of them widened) with {} geometry \
             files ({} groups dissolved), {:.2} s\n",
            s.scene,
            s.out,
            s.objects,
            r.edited_objects.unwrap_or(0),
            r.added_objects.unwrap_or(0),
            r.removed_objects.unwrap_or(0),
            r.rebuilt_clusters.unwrap_or(0),
            r.dropped_clusters.unwrap_or(0),
            r.clusters,
            r.widened_clusters.unwrap_or(0),
            r.geometry_files,
            r.dissolved_groups,
            s.seconds
        ),
        Some(r) => format!(
            "updated the schedule of {} -> {}: {} objects, {} clusters kept with {} geometry \
             files ({} groups dissolved), {:.2} s\n",
            s.scene, s.out, s.objects, r.clusters, r.geometry_files, r.dissolved_groups, s.seconds
        ),
    };
    if let Some(why) = &s.not_updated {
        out += &format!("built in full, not updated: {why}\n");
    }
    if s.absent_objects > 0 {
        out += &format!(
            "{} objects are never visible and were left out\n",
            s.absent_objects
        );
    }
    out += &format!(
        "\n{:<16} {:>5} {:>9} {:>11} {:>7} {:>10} {:>9}\n",
        "class", "level", "clusters", "triangles", "ratio", "max eps", "max gamma"
    );
    for c in &s.classes {
        for l in c.levels {
            let ratio = if l.children_triangles > 0 {
                l.triangles as f64 / l.children_triangles as f64
            } else {
                1.0
            };
            out += &format!(
                "{:<16} {:>5} {:>9} {:>11} {:>6.0}% {:>10.4} {:>9.4}\n",
                c.class,
                l.level,
                l.clusters,
                l.triangles,
                ratio * 100.0,
                l.max_eps,
                l.max_gamma
            );
        }
    }
    out += "\nphase              seconds\n";
    for p in &s.phases {
        out += &format!("{:<16} {:>9.3}\n", p.name, p.seconds);
    }
    out
}
