//! `hdlod bench build`: build time per object as the scene grows, to show
//! the builder's n log n growth (issue: the scaling benchmark), the table
//! and an SVG plot into docs/ on request; or, given a scene, that scene's
//! build repeated: median wall and CPU time and the peak memory, the
//! figures the build's speed targets are stated in, then as many
//! schedule updates of the tree (a schedule edit and back), geometry
//! updates (a storey moved, by default 2 cm, and back), removals (one
//! more storey each) and additions (those storeys back as new objects).

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::Context;
use hdlod::build::{BuildConfig, BuildStats, How, Silent, build_or_update_to, build_to};
use hdlod::scene::{Scene, TaskType};
use hdlod_fixtures::{Scale, skyscraper};
use plotters::prelude::*;
use serde::Serialize;

#[derive(clap::Args)]
pub struct Args {
    /// A scene (a directory with scene.json, or the file) to build
    /// `--repeats` times instead of the scaling series, then to update
    /// `--repeats` times each: to a schedule edit and back, to a storey
    /// moved and back, removing one more storey, and adding those storeys
    /// back as new objects.
    scene: Option<PathBuf>,
    /// Builds of SCENE; the medians are reported.
    #[arg(long, default_value_t = 3)]
    repeats: usize,
    /// The storey (the objects' `storey` property) a geometry edit moves
    /// `--move` along x, for the geometry updates of a scene; by default
    /// the one in the middle of those the scene names.
    #[arg(long)]
    storey: Option<String>,
    /// How far the geometry edit moves the storey, in scene units (metres):
    /// a small move keeps most clusters above it with a widened error, a
    /// far one makes them again.
    #[arg(long = "move", default_value_t = 0.02, value_name = "METRES")]
    move_by: f32,
    /// Storeys of the paper's tower to build (about 830 objects each).
    #[arg(long, value_delimiter = ',', default_value = "12,24,48,96")]
    storeys: Vec<usize>,
    /// Where the trees are built (removed afterwards); by default a
    /// directory in the system's temporary directory.
    #[arg(long)]
    work: Option<PathBuf>,
    /// Write the table into this markdown file (between the markers
    /// `<!-- build-scaling -->` and `<!-- /build-scaling -->`) and the plot
    /// beside it as build-scaling.svg.
    #[arg(long)]
    docs: Option<PathBuf>,
    #[arg(long)]
    json: bool,
}

#[derive(Serialize)]
struct Row {
    storeys: usize,
    objects: usize,
    triangles: usize,
    clusters: usize,
    seconds: f64,
    micros_per_object: f64,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    // Removed when dropped, killed runs aside; made only without --work.
    let temp = match &args.work {
        Some(_) => None,
        None => Some(
            tempfile::Builder::new()
                .prefix("hdlod-bench-build-")
                .tempdir()?,
        ),
    };
    let work = match (&args.work, &temp) {
        (Some(w), _) => w.clone(),
        (None, Some(t)) => t.path().to_owned(),
        (None, None) => unreachable!("a temporary directory without --work"),
    };
    if let Some(scene) = &args.scene {
        return repeated(&args, scene, &work);
    }
    let mut rows = Vec::new();
    for &storeys in &args.storeys {
        let scene = skyscraper(Scale::Storeys(storeys), 1);
        let triangles = scene
            .objects
            .iter()
            .map(|o| scene.meshes[o.mesh].triangle_count())
            .sum();
        let out = work.join(format!("storeys-{storeys}"));
        let started = Instant::now();
        let (tree, _) = build_to(&scene, &BuildConfig::default(), &out, &Silent)
            .with_context(|| format!("building {}", out.display()))?;
        let seconds = started.elapsed().as_secs_f64();
        std::fs::remove_dir_all(&out).with_context(|| format!("removing {}", out.display()))?;
        let row = Row {
            storeys,
            objects: scene.objects.len(),
            triangles,
            clusters: tree.cluster_count(),
            seconds,
            micros_per_object: seconds * 1e6 / scene.objects.len() as f64,
        };
        if !args.json {
            eprintln!(
                "{} storeys: {} objects, {:.2} s, {:.1} us per object",
                row.storeys, row.objects, row.seconds, row.micros_per_object
            );
        }
        rows.push(row);
    }
    let table = table(&rows);
    if args.json {
        println!("{}", serde_json::to_string_pretty(&rows)?);
    } else {
        print!("{table}");
    }
    if let Some(doc) = &args.docs {
        let svg = doc.with_file_name("build-scaling.svg");
        plot(&rows, &svg)?;
        replace_section(doc, "build-scaling", &table)?;
    }
    Ok(())
}

/// One build of a scene: wall time, and the CPU time (user and system,
/// every thread) of this process over it.
#[derive(Serialize)]
struct Run {
    wall_seconds: f64,
    cpu_seconds: f64,
}

/// What `--json` prints for a scene.
#[derive(Serialize)]
struct Repeated {
    scene: String,
    objects: usize,
    triangles: usize,
    clusters: usize,
    runs: Vec<Run>,
    median_wall_seconds: f64,
    median_cpu_seconds: f64,
    /// Tasks the schedule edit moves a day later: every tenth construct
    /// task of objects that do not move.
    schedule_edit_tasks: usize,
    /// Schedule updates of the last tree built, alternately to the edited
    /// schedule and back to the scene's own (`build_or_update_to`, the
    /// scene already loaded).
    update_runs: Vec<Run>,
    median_update_wall_seconds: f64,
    median_update_cpu_seconds: f64,
    /// The storey the geometry edit moves, and how many of its objects.
    geometry_edit_storey: Option<String>,
    geometry_edit_objects: usize,
    /// Geometry updates of the tree, alternately to the edited storey and
    /// back (`build_or_update_to`, the scene already loaded).
    geometry_update_runs: Vec<Run>,
    median_geometry_update_wall_seconds: f64,
    median_geometry_update_cpu_seconds: f64,
    /// Clusters the first geometry update made again, of all.
    rebuilt_clusters: usize,
    /// How far the geometry edit moved the storey.
    geometry_edit_move: f32,
    /// Clusters the first geometry update kept above the edit, their
    /// error widened by the move.
    widened_clusters: usize,
    /// The first geometry update's phases, in seconds.
    geometry_update_phases: Vec<(String, f64)>,
    /// Table 2 of the tree after the geometry updates against a full build
    /// of the same scene: the largest change of a cell's triangles, in
    /// percent (`hdlod bench paper`'s views).
    table_largest_change_percent: f64,
    /// Geometry updates that each remove one more storey (every object of
    /// it that stands still), from the storey the edit moved upwards.
    removed_storeys: Vec<String>,
    removed_objects: Vec<usize>,
    removal_runs: Vec<Run>,
    median_removal_wall_seconds: f64,
    median_removal_cpu_seconds: f64,
    /// Clusters the first removal made again and dropped.
    removal_rebuilt_clusters: usize,
    removal_dropped_clusters: usize,
    /// The first removal's phases, in seconds.
    removal_phases: Vec<(String, f64)>,
    /// Table 2 after the removals against a full build of the same scene,
    /// as `table_largest_change_percent`.
    removal_table_largest_change_percent: f64,
    /// Geometry updates that each add one of the removed storeys back as
    /// new objects (new ids, as a model re-authored: the old ids stay
    /// tombstones), in the order removed.
    added_storeys: Vec<String>,
    added_objects: Vec<usize>,
    addition_runs: Vec<Run>,
    median_addition_wall_seconds: f64,
    median_addition_cpu_seconds: f64,
    /// Clusters the first addition made again and widened.
    addition_rebuilt_clusters: usize,
    addition_widened_clusters: usize,
    /// The first addition's phases, in seconds.
    addition_phases: Vec<(String, f64)>,
    /// Table 2 after the additions against a full build of the same scene.
    addition_table_largest_change_percent: f64,
    /// The process's peak resident set over every build (and the scene's
    /// load), in bytes.
    peak_rss_bytes: u64,
}

fn repeated(args: &Args, path: &Path, work: &Path) -> anyhow::Result<()> {
    anyhow::ensure!(args.repeats > 0, "--repeats must be at least 1");
    let scene = hdlod::scene::format::load(path)
        .with_context(|| format!("cannot load the scene {}", path.display()))?;
    let triangles = scene
        .objects
        .iter()
        .map(|o| scene.meshes[o.mesh].triangle_count())
        .sum();
    let out = work.join("tree");
    let mut runs = Vec::new();
    let mut clusters = 0;
    for k in 0..args.repeats {
        let (cpu, started) = (cpu_seconds(), Instant::now());
        let (tree, _) = build_to(&scene, &BuildConfig::default(), &out, &Silent)
            .with_context(|| format!("building {}", out.display()))?;
        let run = Run {
            wall_seconds: started.elapsed().as_secs_f64(),
            cpu_seconds: cpu_seconds() - cpu,
        };
        clusters = tree.cluster_count();
        drop(tree);
        if k + 1 < args.repeats {
            std::fs::remove_dir_all(&out).with_context(|| format!("removing {}", out.display()))?;
        }
        if !args.json {
            eprintln!(
                "build {}/{}: {:.2} s wall, {:.2} s CPU",
                k + 1,
                args.repeats,
                run.wall_seconds,
                run.cpu_seconds
            );
        }
        runs.push(run);
    }
    let (edited, moved) = schedule_edit(&scene);
    let mut updates = Vec::new();
    for k in 0..args.repeats {
        let next = if k % 2 == 0 { &edited } else { &scene };
        let (cpu, started) = (cpu_seconds(), Instant::now());
        let (_, _, how) = build_or_update_to(next, &BuildConfig::default(), &out, false, &Silent)
            .with_context(|| format!("updating {}", out.display()))?;
        anyhow::ensure!(
            matches!(how, How::ScheduleUpdate { .. }),
            "the schedule edit was built in full: {how:?}"
        );
        let run = Run {
            wall_seconds: started.elapsed().as_secs_f64(),
            cpu_seconds: cpu_seconds() - cpu,
        };
        if !args.json {
            eprintln!(
                "update {}/{}: {:.2} s wall, {:.2} s CPU",
                k + 1,
                args.repeats,
                run.wall_seconds,
                run.cpu_seconds
            );
        }
        updates.push(run);
    }
    // Back to the scene's own schedule, untimed, so that the geometry
    // updates change geometry alone: after an odd number the tree is on
    // the edited schedule, and the first of them would put it back too.
    if args.repeats % 2 == 1 {
        build_or_update_to(&scene, &BuildConfig::default(), &out, false, &Silent)
            .with_context(|| format!("updating {}", out.display()))?;
    }
    let geometry = geometry_updates(args, &scene, &out, work)?;
    std::fs::remove_dir_all(&out).with_context(|| format!("removing {}", out.display()))?;
    let store = work.join(".tree.geometry");
    if store.exists() {
        std::fs::remove_dir_all(&store).with_context(|| format!("removing {}", store.display()))?;
    }
    let _ = std::fs::remove_dir(work);
    // 0 for no runs (a scene without storeys has no geometry updates).
    let median_of = |runs: &[Run], f: fn(&Run) -> f64| {
        let mut v: Vec<f64> = runs.iter().map(f).collect();
        v.sort_by(f64::total_cmp);
        v.get(v.len() / 2).copied().unwrap_or(0.0)
    };
    let median = |f: fn(&Run) -> f64| median_of(&runs, f);
    let report = Repeated {
        scene: scene.name.clone(),
        objects: scene.objects.len(),
        triangles,
        clusters,
        median_wall_seconds: median(|r| r.wall_seconds),
        median_cpu_seconds: median(|r| r.cpu_seconds),
        peak_rss_bytes: peak_rss_bytes(),
        schedule_edit_tasks: moved,
        median_update_wall_seconds: median_of(&updates, |r| r.wall_seconds),
        median_update_cpu_seconds: median_of(&updates, |r| r.cpu_seconds),
        update_runs: updates,
        geometry_edit_storey: geometry.storey,
        geometry_edit_objects: geometry.objects,
        median_geometry_update_wall_seconds: median_of(&geometry.runs, |r| r.wall_seconds),
        median_geometry_update_cpu_seconds: median_of(&geometry.runs, |r| r.cpu_seconds),
        geometry_update_runs: geometry.runs,
        rebuilt_clusters: geometry.rebuilt,
        widened_clusters: geometry.widened,
        geometry_edit_move: args.move_by,
        geometry_update_phases: geometry.phases,
        table_largest_change_percent: geometry.largest_change,
        median_removal_wall_seconds: median_of(&geometry.removals.runs, |r| r.wall_seconds),
        median_removal_cpu_seconds: median_of(&geometry.removals.runs, |r| r.cpu_seconds),
        removed_storeys: geometry.removals.storeys,
        removed_objects: geometry.removals.objects,
        removal_runs: geometry.removals.runs,
        removal_rebuilt_clusters: geometry.removals.rebuilt,
        removal_dropped_clusters: geometry.removals.dropped,
        removal_phases: geometry.removals.phases,
        removal_table_largest_change_percent: geometry.removals.largest_change,
        median_addition_wall_seconds: median_of(&geometry.additions.runs, |r| r.wall_seconds),
        median_addition_cpu_seconds: median_of(&geometry.additions.runs, |r| r.cpu_seconds),
        added_storeys: geometry.additions.storeys,
        added_objects: geometry.additions.objects,
        addition_runs: geometry.additions.runs,
        addition_rebuilt_clusters: geometry.additions.rebuilt,
        addition_widened_clusters: geometry.additions.widened,
        addition_phases: geometry.additions.phases,
        addition_table_largest_change_percent: geometry.additions.largest_change,
        runs,
    };
    if args.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        println!(
            "{}: {} objects, {} triangles, {} clusters; median of {}: {:.2} s wall, {:.2} s CPU; peak {:.0} MiB",
            report.scene,
            report.objects,
            report.triangles,
            report.clusters,
            args.repeats,
            report.median_wall_seconds,
            report.median_cpu_seconds,
            report.peak_rss_bytes as f64 / (1024.0 * 1024.0)
        );
        println!(
            "schedule updates ({} tasks a day later, and back): median of {}: {:.2} s wall, {:.2} s CPU",
            report.schedule_edit_tasks,
            args.repeats,
            report.median_update_wall_seconds,
            report.median_update_cpu_seconds
        );
        if let Some(storey) = &report.geometry_edit_storey {
            println!(
                "geometry updates ({} objects of {storey} moved {} m, and back; {} of {} clusters \
                 made again, {} widened): median of {}: {:.2} s wall, {:.2} s CPU ({:.1}% of a full build's \
                 wall time); table 2 against a full build: cells within {:.2}%",
                report.geometry_edit_objects,
                report.geometry_edit_move,
                report.rebuilt_clusters,
                report.clusters,
                report.widened_clusters,
                args.repeats,
                report.median_geometry_update_wall_seconds,
                report.median_geometry_update_cpu_seconds,
                100.0 * report.median_geometry_update_wall_seconds / report.median_wall_seconds,
                report.table_largest_change_percent
            );
            println!(
                "  the first one's phases (s): {}",
                phases(&report.geometry_update_phases)
            );
            println!(
                "removals (one more storey each: {}; {:?} objects; the first made {} clusters \
                 again and dropped {}): median of {}: {:.2} s wall, {:.2} s CPU ({:.1}% of a full \
                 build's wall time); table 2 against a full build: cells within {:.2}%",
                report.removed_storeys.join(", "),
                report.removed_objects,
                report.removal_rebuilt_clusters,
                report.removal_dropped_clusters,
                report.removal_runs.len(),
                report.median_removal_wall_seconds,
                report.median_removal_cpu_seconds,
                100.0 * report.median_removal_wall_seconds / report.median_wall_seconds,
                report.removal_table_largest_change_percent
            );
            println!(
                "  the first one's phases (s): {}",
                phases(&report.removal_phases)
            );
            println!(
                "additions (the removed storeys back, one each, as new objects: {:?} objects; the \
                 first made {} clusters again, {} widened): median of {}: {:.2} s wall, {:.2} s \
                 CPU ({:.1}% of a full build's wall time); table 2 against a full build: cells \
                 within {:.2}%",
                report.added_objects,
                report.addition_rebuilt_clusters,
                report.addition_widened_clusters,
                report.addition_runs.len(),
                report.median_addition_wall_seconds,
                report.median_addition_cpu_seconds,
                100.0 * report.median_addition_wall_seconds / report.median_wall_seconds,
                report.addition_table_largest_change_percent
            );
            println!(
                "  the first one's phases (s): {}",
                phases(&report.addition_phases)
            );
        }
    }
    Ok(())
}

#[derive(Default)]
struct GeometryUpdates {
    storey: Option<String>,
    objects: usize,
    runs: Vec<Run>,
    rebuilt: usize,
    widened: usize,
    phases: Vec<(String, f64)>,
    largest_change: f64,
    removals: Removals,
    additions: Additions,
}

#[derive(Default)]
struct Additions {
    storeys: Vec<String>,
    objects: Vec<usize>,
    runs: Vec<Run>,
    rebuilt: usize,
    widened: usize,
    phases: Vec<(String, f64)>,
    largest_change: f64,
}

#[derive(Default)]
struct Removals {
    storeys: Vec<String>,
    objects: Vec<usize>,
    runs: Vec<Run>,
    rebuilt: usize,
    dropped: usize,
    phases: Vec<(String, f64)>,
    largest_change: f64,
}

/// Geometry updates of the tree at `out`, alternately to `scene` with one
/// storey moved and back, then table 2 of the updated tree against a full
/// build of the same scene. None for a scene without storeys.
fn geometry_updates(
    args: &Args,
    scene: &Scene,
    out: &Path,
    work: &Path,
) -> anyhow::Result<GeometryUpdates> {
    let mut storeys: Vec<&str> = scene
        .objects
        .iter()
        .filter_map(|o| o.properties.get("storey").map(String::as_str))
        .collect();
    storeys.sort_unstable();
    storeys.dedup();
    let storey = match &args.storey {
        Some(s) => s.clone(),
        None => match storeys.get(storeys.len() / 2) {
            Some(s) => s.to_string(),
            None => return Ok(GeometryUpdates::default()),
        },
    };
    let mut edited = scene.clone();
    let mut objects = 0;
    for o in &mut edited.objects {
        if stands_on(o, &storey) {
            o.transform.w_axis.x += args.move_by;
            objects += 1;
        }
    }
    anyhow::ensure!(
        objects > 0,
        "no object that stands still is on storey {storey:?}"
    );
    let mut result = GeometryUpdates {
        storey: Some(storey),
        objects,
        ..GeometryUpdates::default()
    };
    for k in 0..args.repeats.max(1) {
        let next = if k % 2 == 0 { &edited } else { scene };
        let (how, stats, run) = timed_update(next, out)?;
        let How::GeometryUpdate {
            rebuilt, widened, ..
        } = how
        else {
            anyhow::bail!("the geometry edit was not a geometry update: {how:?}");
        };
        if k == 0 {
            (result.rebuilt, result.widened) = (rebuilt, widened);
            result.phases = stats.phases;
        }
        if !args.json {
            eprintln!(
                "geometry update {}/{}: {:.2} s wall, {:.2} s CPU, {rebuilt} clusters made again, \
                 {widened} widened",
                k + 1,
                args.repeats,
                run.wall_seconds,
                run.cpu_seconds
            );
        }
        result.runs.push(run);
    }
    // The tree now holds the last scene updated to; a full build of it.
    let last = if args.repeats.max(1) % 2 == 1 {
        &edited
    } else {
        scene
    };
    result.largest_change = against_full(last, out, work)?;
    let first = storeys
        .iter()
        .position(|s| *s == result.storey.as_deref().unwrap_or_default())
        .unwrap_or(0);
    let upwards: Vec<&str> = storeys[first..]
        .iter()
        .take(args.repeats.max(1))
        .copied()
        .collect();
    let (removed, left) = removals(args, last, &upwards, out, work)?;
    result.removals = removed;
    result.additions = additions(args, last, left, &upwards, out, work)?;
    Ok(result)
}

/// Geometry updates of the tree at `out`, which holds `scene`, each
/// removing the objects that stand still on one more of `storeys`; then
/// table 2 against a full build of what is left, which it answers too.
fn removals(
    args: &Args,
    scene: &Scene,
    storeys: &[&str],
    out: &Path,
    work: &Path,
) -> anyhow::Result<(Removals, Scene)> {
    let mut result = Removals::default();
    let mut now = scene.clone();
    for (k, storey) in storeys.iter().enumerate() {
        let gone: std::collections::HashSet<String> = (now.objects.iter())
            .filter(|o| stands_on(o, storey))
            .map(|o| o.id.clone())
            .collect();
        now.objects.retain(|o| !gone.contains(&o.id));
        for task in &mut now.tasks {
            task.objects.retain(|o| !gone.contains(o));
        }
        now.apply_schedule();
        let (how, stats, run) = timed_update(&now, out)?;
        let How::GeometryUpdate {
            rebuilt, dropped, ..
        } = how
        else {
            anyhow::bail!("the removal of {storey} was not a geometry update: {how:?}");
        };
        if k == 0 {
            (result.rebuilt, result.dropped) = (rebuilt, dropped);
            result.phases = stats.phases;
        }
        if !args.json {
            eprintln!(
                "removal {}/{} ({} objects of {storey}): {:.2} s wall, {:.2} s CPU, {rebuilt} \
                 clusters made again, {dropped} dropped",
                k + 1,
                storeys.len(),
                gone.len(),
                run.wall_seconds,
                run.cpu_seconds
            );
        }
        result.storeys.push(storey.to_string());
        result.objects.push(gone.len());
        result.runs.push(run);
    }
    result.largest_change = against_full(&now, out, work)?;
    Ok((result, now))
}

/// Geometry updates of the tree at `out`, which holds `now` (`scene` with
/// `storeys` removed), each adding one of them back as new objects: the
/// objects of `scene` on it that stand still, with new ids, in their
/// places and tasks. Then table 2 against a full build of the result.
fn additions(
    args: &Args,
    scene: &Scene,
    mut now: Scene,
    storeys: &[&str],
    out: &Path,
    work: &Path,
) -> anyhow::Result<Additions> {
    let mut result = Additions::default();
    for (k, storey) in storeys.iter().enumerate() {
        let back: Vec<hdlod::scene::Object> = (scene.objects.iter())
            .filter(|o| stands_on(o, storey))
            .map(|o| hdlod::scene::Object {
                id: format!("{}+", o.id),
                ..o.clone()
            })
            .collect();
        let old_ids: std::collections::HashSet<&str> =
            back.iter().map(|o| o.id.trim_end_matches('+')).collect();
        for (task, was) in now.tasks.iter_mut().zip(&scene.tasks) {
            task.objects.extend(
                (was.objects.iter())
                    .filter(|o| old_ids.contains(o.as_str()))
                    .map(|o| format!("{o}+")),
            );
        }
        let count = back.len();
        now.objects.extend(back);
        now.apply_schedule();
        let (how, stats, run) = timed_update(&now, out)?;
        let How::GeometryUpdate {
            rebuilt, widened, ..
        } = how
        else {
            anyhow::bail!("the addition of {storey} was not a geometry update: {how:?}");
        };
        if k == 0 {
            (result.rebuilt, result.widened) = (rebuilt, widened);
            result.phases = stats.phases;
        }
        if !args.json {
            eprintln!(
                "addition {}/{} ({count} objects of {storey} with new ids): {:.2} s wall, {:.2} \
                 s CPU, {rebuilt} clusters made again, {widened} widened",
                k + 1,
                storeys.len(),
                run.wall_seconds,
                run.cpu_seconds
            );
        }
        result.storeys.push(storey.to_string());
        result.objects.push(count);
        result.runs.push(run);
    }
    result.largest_change = against_full(&now, out, work)?;
    Ok(result)
}

/// An update's phases and their seconds, for the report.
fn phases(phases: &[(String, f64)]) -> String {
    let phases: Vec<String> = (phases.iter())
        .map(|(name, s)| format!("{name} {s:.2}"))
        .collect();
    phases.join(", ")
}

/// Whether object `o` stands still on `storey` (its `storey` property): what
/// the geometry edits move, remove and add back.
fn stands_on(o: &hdlod::scene::Object, storey: &str) -> bool {
    o.properties.get("storey").map(String::as_str) == Some(storey) && o.motion.is_none()
}

/// The tree at `out` updated (or built) to `scene`, timed up to the
/// returned tree, which is dropped untimed.
fn timed_update(scene: &Scene, out: &Path) -> anyhow::Result<(How, BuildStats, Run)> {
    let (cpu, started) = (cpu_seconds(), Instant::now());
    let (tree, stats, how) =
        build_or_update_to(scene, &BuildConfig::default(), out, false, &Silent)
            .with_context(|| format!("updating {}", out.display()))?;
    let run = Run {
        wall_seconds: started.elapsed().as_secs_f64(),
        cpu_seconds: cpu_seconds() - cpu,
    };
    drop(tree);
    Ok((how, stats, run))
}

/// Table 2 of the tree at `out` against a full build of `scene`: the
/// largest change of a cell's triangles, in percent.
fn against_full(scene: &Scene, out: &Path, work: &Path) -> anyhow::Result<f64> {
    let full = work.join("full");
    build_to(scene, &BuildConfig::default(), &full, &Silent)
        .with_context(|| format!("building {}", full.display()))?;
    let (updated, full_tree) = (hdlod::tree::load(out)?, hdlod::tree::load(&full)?);
    let table = |t: &hdlod::tree::Tree| {
        hdlod_fixtures::paper::table(t, &hdlod_fixtures::paper::Frame::whole(t), 30, 1)
    };
    let (a, b) = (table(&updated), table(&full_tree));
    let largest = a
        .rows
        .iter()
        .zip(&b.rows)
        .map(|(a, b)| 100.0 * (a.triangles - b.triangles).abs() / b.triangles.max(1.0))
        .fold(0.0, f64::max);
    std::fs::remove_dir_all(&full).with_context(|| format!("removing {}", full.display()))?;
    Ok(largest)
}

/// `scene` with every tenth construct task of objects that do not move a
/// day later, where it still ends within the period: a schedule-only edit
/// (the same objects in the same classes). Answers how many tasks moved.
fn schedule_edit(scene: &Scene) -> (Scene, usize) {
    const DAY: f64 = 86_400.0;
    let mut edited = scene.clone();
    let still: std::collections::HashSet<&str> = scene
        .objects
        .iter()
        .filter(|o| o.motion.is_none())
        .map(|o| o.id.as_str())
        .collect();
    let mut moved = 0;
    let constructs = edited
        .tasks
        .iter_mut()
        .filter(|t| t.kind == TaskType::Construct);
    for (i, task) in constructs.enumerate() {
        if i % 10 == 0
            && task.finish + DAY < scene.time.seconds
            && task.objects.iter().all(|o| still.contains(o.as_str()))
        {
            task.start += DAY;
            task.finish += DAY;
            moved += 1;
        }
    }
    edited.apply_schedule();
    (edited, moved)
}

fn usage() -> libc::rusage {
    // SAFETY: `getrusage` only writes the struct it is given.
    unsafe {
        let mut usage: libc::rusage = std::mem::zeroed();
        libc::getrusage(libc::RUSAGE_SELF, &mut usage);
        usage
    }
}

/// User and system time of every thread of this process so far.
fn cpu_seconds() -> f64 {
    let u = usage();
    let seconds = |t: libc::timeval| t.tv_sec as f64 + t.tv_usec as f64 * 1e-6;
    seconds(u.ru_utime) + seconds(u.ru_stime)
}

/// The peak resident set of this process so far (Linux gives kilobytes).
fn peak_rss_bytes() -> u64 {
    usage().ru_maxrss.max(0) as u64 * 1024
}

/// The table, with the growth exponent between consecutive sizes:
/// `log(t2/t1) / log(n2/n1)` is 1 for linear time, a little above 1 for
/// n log n, 2 for quadratic.
fn table(rows: &[Row]) -> String {
    let mut out = String::from(
        "| storeys | objects | triangles | clusters | build s | us per object | growth exponent |\n\
         |---|---|---|---|---|---|---|\n",
    );
    for (i, r) in rows.iter().enumerate() {
        let exponent = match i.checked_sub(1).map(|p| &rows[p]) {
            Some(p) => format!(
                "{:.2}",
                (r.seconds / p.seconds).ln() / (r.objects as f64 / p.objects as f64).ln()
            ),
            None => "".into(),
        };
        out += &format!(
            "| {} | {} | {} | {} | {:.2} | {:.1} | {} |\n",
            r.storeys, r.objects, r.triangles, r.clusters, r.seconds, r.micros_per_object, exponent
        );
    }
    out
}

fn plot(rows: &[Row], path: &Path) -> anyhow::Result<()> {
    let max_n = rows.iter().map(|r| r.objects).max().unwrap_or(1) as f64;
    let max_us = rows
        .iter()
        .map(|r| r.micros_per_object)
        .fold(0.0, f64::max)
        .max(1.0);
    let root = SVGBackend::new(path, (640, 400)).into_drawing_area();
    root.fill(&WHITE)?;
    let mut chart = ChartBuilder::on(&root)
        .caption("Build time per object", ("sans-serif", 20))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(56)
        .build_cartesian_2d(0.0..max_n * 1.05, 0.0..max_us * 1.3)?;
    chart
        .configure_mesh()
        .x_desc("objects")
        .y_desc("microseconds per object")
        .draw()?;
    let points: Vec<(f64, f64)> = rows
        .iter()
        .map(|r| (r.objects as f64, r.micros_per_object))
        .collect();
    chart
        .draw_series(LineSeries::new(points.clone(), &BLUE))?
        .label("measured")
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 16, y)], BLUE));
    chart.draw_series(points.iter().map(|&p| Circle::new(p, 4, BLUE.filled())))?;
    // What n log n growth predicts from the smallest size, and what
    // quadratic growth would: the measured line should follow the first.
    if let Some(first) = rows.first() {
        let n0 = first.objects as f64;
        let per = first.micros_per_object;
        let nlogn: Vec<(f64, f64)> = rows
            .iter()
            .map(|r| {
                let n = r.objects as f64;
                (n, per * n.log2() / n0.log2())
            })
            .collect();
        chart
            .draw_series(LineSeries::new(nlogn, &GREEN))?
            .label("n log n from the first point")
            .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 16, y)], GREEN));
        let quadratic: Vec<(f64, f64)> = rows
            .iter()
            .map(|r| (r.objects as f64, per * r.objects as f64 / n0))
            .take_while(|p| p.1 <= max_us * 1.3)
            .collect();
        chart
            .draw_series(LineSeries::new(quadratic, &RED))?
            .label("n^2 from the first point")
            .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 16, y)], RED));
    }
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .draw()?;
    root.present()?;
    Ok(())
}

/// Replaces the text between `<!-- name -->` and `<!-- /name -->` in a
/// markdown file, or appends the section when the markers are missing.
pub fn replace_section(doc: &Path, name: &str, body: &str) -> anyhow::Result<()> {
    let text = std::fs::read_to_string(doc).unwrap_or_default();
    let (open, close) = (format!("<!-- {name} -->"), format!("<!-- /{name} -->"));
    let section = format!("{open}\n{body}{close}");
    let new = match (text.find(&open), text.find(&close)) {
        (Some(a), Some(b)) if a < b => {
            format!("{}{section}{}", &text[..a], &text[b + close.len()..])
        }
        _ => format!("{text}\n{section}\n"),
    };
    std::fs::write(doc, new).with_context(|| format!("writing {}", doc.display()))
}
