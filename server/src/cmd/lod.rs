//! `hdlod lod IN OUT.glb --levels 1,0.5,0.25,0.1 --method ...`: a discrete
//! LOD chain of one mesh (the use the first decimation thesis makes of its
//! simplifiers) in one GLB with the MSFT_lod extension, so that engines and
//! three.js can switch levels themselves. Each level is simplified from the
//! full mesh (not from the level before, so errors do not add up) and its
//! Hausdorff bound against the full mesh is measured and printed.
//!
//! Screen coverage hints: a level keeping the share `r` of the triangles is
//! drawn while the mesh covers at least `r / 2` of the screen, which keeps
//! the triangles per pixel about constant (full detail from half the
//! screen up); the coarsest level has 0, so the mesh never disappears.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{bail, ensure};
use hdlod::geometry::{self, SimplifyOptions};
use serde::Serialize;

use super::simplify::Method;

#[derive(clap::Args)]
pub struct Args {
    /// Input mesh: .obj, .ply, .glb or .gltf.
    input: PathBuf,
    /// Output: a .glb file.
    output: PathBuf,
    /// The share of the triangles each level keeps, finest first, each in
    /// (0, 1] and below the one before.
    #[arg(long, value_delimiter = ',', default_value = "1,0.5,0.25,0.1")]
    levels: Vec<f64>,
    #[arg(long, value_enum, default_value = "qem")]
    method: Method,
    /// Seed of the surface sample behind the mean distance.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Print JSON instead of text.
    #[arg(long)]
    json: bool,
}

#[derive(Serialize)]
struct Level {
    ratio: f64,
    triangles: usize,
    screen_coverage: f32,
    seconds: f64,
    hausdorff: f32,
    mean: f32,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    ensure!(!args.levels.is_empty(), "--levels: give at least one level");
    for (i, r) in args.levels.iter().enumerate() {
        if !(r.is_finite() && *r > 0.0 && *r <= 1.0) {
            bail!("--levels: level {i} is {r}, not in (0, 1]");
        }
        if i > 0 && *r >= args.levels[i - 1] {
            bail!(
                "--levels: level {i} ({r}) is not below level {} ({})",
                i - 1,
                args.levels[i - 1]
            );
        }
    }
    match args.output.extension().and_then(|e| e.to_str()) {
        Some(e) if e.eq_ignore_ascii_case("glb") => {}
        _ => bail!("{}: the output must be a .glb file", args.output.display()),
    }
    let mesh = hdlod::io::read_mesh(&args.input)?;
    let n = mesh.triangle_count();
    ensure!(n > 0, "{}: the mesh has no triangles", args.input.display());

    let method = geometry::Method::from(args.method);
    let last = args.levels.len() - 1;
    let mut meshes = Vec::new();
    let mut report = Vec::new();
    for (i, &ratio) in args.levels.iter().enumerate() {
        let start = Instant::now();
        let options = SimplifyOptions {
            max_error: f32::INFINITY,
            target_triangles: Some(((ratio * n as f64).ceil() as usize).max(1)),
            prune: false,
        };
        let level = method.run(&mesh, &options);
        let seconds = start.elapsed().as_secs_f64();
        let h = geometry::distance(&mesh, &level, args.seed);
        report.push(Level {
            ratio,
            triangles: level.triangle_count(),
            screen_coverage: if i == last { 0.0 } else { (ratio / 2.0) as f32 },
            seconds,
            hausdorff: h.bound,
            mean: h.mean,
        });
        meshes.push(level);
    }
    let coverage: Vec<f32> = report.iter().map(|l| l.screen_coverage).collect();
    hdlod::io::glb::write_lod(&meshes, &coverage, &args.output)?;
    if args.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        println!("level  ratio  triangles  coverage  hausdorff    mean         seconds");
        for (i, l) in report.iter().enumerate() {
            println!(
                "{i:>5}  {:>5}  {:>9}  {:>8}  <= {:<9.6}  {:<11.6}  {:.4}",
                l.ratio, l.triangles, l.screen_coverage, l.hausdorff, l.mean, l.seconds
            );
        }
        println!("written {}", args.output.display());
    }
    Ok(())
}
