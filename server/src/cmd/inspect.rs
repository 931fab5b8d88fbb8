//! `hdlod inspect PATH [--json]`: the library's summary, printed.

use std::path::{Path, PathBuf};

use anyhow::Context;
use hdlod::scene::{SceneSummary, format};
use hdlod::time::format_date;
use hdlod::tree::{LevelSummary, Tree};
use serde::Serialize;

#[derive(clap::Args)]
pub struct Args {
    /// A scene directory (or its scene.json).
    path: PathBuf,
    /// Print JSON instead of a table.
    #[arg(long)]
    json: bool,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    // A directory with a manifest.json is a tree (hdlod-tree/2 or /1).
    if args.path.join("manifest.json").is_file() {
        let tree = hdlod::tree::load(&args.path)
            .with_context(|| format!("cannot load the tree {}", args.path.display()))?;
        let summary = TreeSummary::of(&tree);
        if args.json {
            println!("{}", serde_json::to_string_pretty(&summary)?);
        } else {
            print!("{}", tree_table(&summary));
        }
        return Ok(());
    }
    let summary = scene_summary(&args.path)?;
    if args.json {
        println!("{}", serde_json::to_string_pretty(&summary)?);
    } else {
        print!("{}", table(&summary));
    }
    Ok(())
}

fn scene_summary(path: &Path) -> anyhow::Result<SceneSummary> {
    let scene =
        format::load(path).with_context(|| format!("cannot load the scene {}", path.display()))?;
    Ok(SceneSummary::of(&scene))
}

fn table(s: &SceneSummary) -> String {
    let mut out = format!(
        "scene {}: {} objects, {} distinct meshes, {} triangles\n",
        s.name,
        thousands(s.objects),
        thousands(s.meshes),
        thousands(s.triangles)
    );
    out += &format!(
        "time    {} .. {} ({:.1} days)\n",
        s.time.start,
        s.time.end,
        s.time.seconds / 86400.0
    );
    match &s.bounds {
        Some(b) => {
            let v = |p: [f32; 3]| format!("[{:.2}, {:.2}, {:.2}]", p[0], p[1], p[2]);
            out += &format!("bounds  {} .. {}\n", v(b.min), v(b.max));
        }
        None => out += "bounds  none (no geometry)\n",
    }
    out += &format!("\n{:<16} {:>10} {:>14}\n", "class", "objects", "triangles");
    for (class, c) in &s.classes {
        out += &format!(
            "{:<16} {:>10} {:>14}\n",
            class.name(),
            thousands(c.objects),
            thousands(c.triangles)
        );
    }
    out += &format!(
        "{:<16} {:>10} {:>14}\n",
        "total",
        thousands(s.objects),
        thousands(s.triangles)
    );
    out += &format!("\n{:<16} {:>10}\n", "visibility type", "objects");
    for (kind, n) in &s.visibility_types {
        let name = serde_json::to_value(kind)
            .ok()
            .and_then(|v| v.as_str().map(str::to_owned))
            .unwrap_or_default();
        out += &format!("{name:<16} {:>10}\n", thousands(*n));
    }
    let w = &s.schedule;
    out += &format!(
        "\nschedule {} tasks: {} summary tasks, {} levels of work breakdown; {} tasks linked by {} \
         links\n",
        thousands(w.tasks),
        thousands(w.summary_tasks),
        w.depth,
        thousands(w.linked_tasks),
        thousands(w.links)
    );
    out
}

/// 4260057 -> "4,260,057".
fn thousands(n: usize) -> String {
    let digits = n.to_string();
    let mut out = String::new();
    for (i, c) in digits.chars().enumerate() {
        if i > 0 && (digits.len() - i).is_multiple_of(3) {
            out.push(',');
        }
        out.push(c);
    }
    out
}

/// `inspect --json` of a tree (schemas/inspect-tree.schema.json).
#[derive(Serialize)]
struct TreeSummary {
    kind: &'static str,
    name: String,
    clusters: usize,
    leaves: usize,
    leaf_triangles: u64,
    time: TreeTime,
    bounds: TreeBounds,
    /// Clusters per class.
    classes: std::collections::BTreeMap<&'static str, usize>,
    /// Level 0 holds the original objects.
    levels: Vec<LevelSummary>,
}

#[derive(Serialize)]
struct TreeTime {
    start: String,
    end: String,
    seconds: f64,
}

#[derive(Serialize)]
struct TreeBounds {
    min: [f64; 3],
    max: [f64; 3],
}

impl TreeSummary {
    fn of(tree: &Tree) -> TreeSummary {
        let s = tree.summary();
        TreeSummary {
            kind: "tree",
            name: tree.scene.clone(),
            clusters: s.clusters,
            leaves: s.leaves,
            leaf_triangles: s.leaf_triangles,
            time: TreeTime {
                start: format_date(tree.time.start),
                end: format_date(tree.time.end()),
                seconds: tree.time.seconds,
            },
            bounds: TreeBounds {
                min: tree.bounds.min.to_array(),
                max: tree.bounds.max.to_array(),
            },
            classes: s.classes,
            levels: s.levels,
        }
    }
}

fn tree_table(s: &TreeSummary) -> String {
    let mut out = format!(
        "tree {}: {} clusters, {} leaves with {} triangles\n",
        s.name,
        thousands(s.clusters),
        thousands(s.leaves),
        thousands(s.leaf_triangles as usize)
    );
    out += &format!("time    {} .. {}\n", s.time.start, s.time.end);
    let v = |p: [f64; 3]| format!("[{:.2}, {:.2}, {:.2}]", p[0], p[1], p[2]);
    out += &format!("bounds  {} .. {}\n\n", v(s.bounds.min), v(s.bounds.max));
    out += &format!("{:<16} {:>10}\n", "class", "clusters");
    for (class, n) in &s.classes {
        out += &format!("{class:<16} {:>10}\n", thousands(*n));
    }
    out += &format!(
        "\n{:>5} {:>10} {:>12} {:>10} {:>10}\n",
        "level", "clusters", "triangles", "max eps", "max gamma"
    );
    for l in &s.levels {
        out += &format!(
            "{:>5} {:>10} {:>12} {:>10.4} {:>10.4}\n",
            l.level,
            thousands(l.clusters),
            thousands(l.triangles as usize),
            l.max_eps,
            l.max_gamma
        );
    }
    out
}
