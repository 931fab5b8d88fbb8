//! `hdlod demo [--scale small] [--addr ...]`: the main job in one command.
//! Generates the skyscraper scene if it is missing, builds its tree if it is
//! missing or older than the scene, then serves it and prints the URLs.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::Context;
use hdlod::build::{BuildConfig, build_to};
use hdlod::scene::format;
use hdlod_fixtures::{Scale, skyscraper};

use super::progress::Report;

#[derive(clap::Args)]
pub struct Args {
    /// Scene size: tiny, small (about 5,000 objects) or paper.
    #[arg(long, default_value = "small")]
    scale: String,
    #[arg(long, default_value = "127.0.0.1:8080")]
    addr: String,
    /// Where the scene and the tree are kept between runs.
    #[arg(long, default_value = "out/demo")]
    dir: PathBuf,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let scale = Scale::parse(&args.scale)?;
    let scene_dir = args.dir.join(format!("skyscraper-{}", args.scale));
    let tree_dir = args.dir.join(format!("skyscraper-{}-tree", args.scale));
    let scene_file = scene_dir.join(format::SCENE_FILE);
    if !scene_file.is_file() {
        let started = Instant::now();
        eprintln!(
            "generating the {} skyscraper scene into {}",
            args.scale,
            scene_dir.display()
        );
        format::save(&skyscraper(scale, 1), &scene_dir)
            .with_context(|| format!("cannot write {}", scene_dir.display()))?;
        eprintln!("generated in {:.1} s", started.elapsed().as_secs_f64());
    }
    if stale(&tree_dir.join("manifest.json"), &scene_file) {
        let started = Instant::now();
        eprintln!("building the HDLOD tree into {}", tree_dir.display());
        let scene = format::load(&scene_dir)?;
        let report = Report::new(false);
        let (tree, _) = build_to(&scene, &BuildConfig::default(), &tree_dir, &report)
            .with_context(|| format!("cannot build {}", tree_dir.display()))?;
        report.finish();
        eprintln!(
            "built {} clusters in {:.1} s",
            tree.cluster_count(),
            started.elapsed().as_secs_f64()
        );
    }
    eprintln!(
        "serving; open the viewer at http://{0}/?scene=skyscraper-{1} \
         (the API: curl 'http://{0}/api/v1/scenes/skyscraper-{1}')",
        args.addr, args.scale
    );
    super::serve::serve(&args.addr, vec![tree_dir])
}

/// True when `output` is missing or older than `input`.
fn stale(output: &Path, input: &Path) -> bool {
    let modified = |p: &Path| std::fs::metadata(p).and_then(|m| m.modified()).ok();
    match (modified(output), modified(input)) {
        (Some(out), Some(inp)) => out < inp,
        _ => true,
    }
}
