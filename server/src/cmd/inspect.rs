//! `hdlod inspect PATH [--json]`: the library's summary, printed.

use std::path::{Path, PathBuf};

use anyhow::Context;
use hdlod::scene::{Summary, format};

#[derive(clap::Args)]
pub struct Args {
    /// A scene directory (or its scene.json).
    path: PathBuf,
    /// Print JSON instead of a table.
    #[arg(long)]
    json: bool,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    // A directory with a manifest.json is a tree (hdlod-tree/1).
    if args.path.join("manifest.json").is_file() {
        anyhow::bail!(
            "{}: inspecting an HDLOD tree is not supported yet",
            args.path.display()
        );
    }
    let summary = scene_summary(&args.path)?;
    if args.json {
        println!("{}", serde_json::to_string_pretty(&summary)?);
    } else {
        print!("{}", table(&summary));
    }
    Ok(())
}

fn scene_summary(path: &Path) -> anyhow::Result<Summary> {
    let scene =
        format::load(path).with_context(|| format!("cannot load the scene {}", path.display()))?;
    Ok(Summary::of(&scene))
}

fn table(s: &Summary) -> String {
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
