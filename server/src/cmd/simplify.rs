//! `hdlod simplify IN OUT --method qem|clustering|vertex-removal (--ratio R | --error E) [--positions-only] [--json]`:
//! simplifies one mesh file and measures the result against the input (the
//! Hausdorff bound, mean and RMS distance, volume and area ratios).
//! The JSON output is described by `schemas/simplify.schema.json`.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::bail;
use hdlod::geometry::{self, Mesh, SimplifyOptions, measure};
use serde::Serialize;

#[derive(Clone, Copy, clap::ValueEnum, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Method {
    /// Quadric edge collapse.
    Qem,
    /// Vertex clustering.
    Clustering,
    /// Vertex removal (Schroeder et al. 1992).
    VertexRemoval,
}

impl From<Method> for geometry::Method {
    fn from(m: Method) -> Self {
        match m {
            Method::Qem => geometry::Method::Qem,
            Method::Clustering => geometry::Method::Clustering,
            Method::VertexRemoval => geometry::Method::VertexRemoval,
        }
    }
}

#[derive(clap::Args)]
#[command(group(clap::ArgGroup::new("goal").required(true).args(["ratio", "error"])))]
pub struct Args {
    /// Input mesh: .obj, .ply, .glb or .gltf (all its meshes, placed).
    input: PathBuf,
    /// Output mesh: .obj or .glb.
    output: PathBuf,
    #[arg(long, value_enum, default_value = "qem")]
    method: Method,
    /// Keep this share of the triangles (0 < R; 1 or more leaves the mesh unchanged).
    #[arg(long)]
    ratio: Option<f64>,
    /// Simplify as far as this absolute error budget (scene units) allows.
    #[arg(long)]
    error: Option<f32>,
    /// Weigh positions alone, as Garland and Heckbert's quadrics (and the
    /// decimation theses' QEM) do: the input's normals and colours are
    /// dropped first, so the output has positions only. Edge collapse is
    /// then faster and its shape error lower, and the shading follows the
    /// input's normals less closely (docs/benchmarks.md).
    #[arg(long)]
    positions_only: bool,
    /// Seed of the surface sample behind the mean and RMS distances.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Print JSON instead of text.
    #[arg(long)]
    json: bool,
}

#[derive(Serialize)]
struct Report {
    method: Method,
    positions_only: bool,
    triangles_in: usize,
    triangles_out: usize,
    seconds: f64,
    hausdorff: f32,
    hausdorff_lower: f32,
    mean: f32,
    rms: f32,
    /// `None` when the input's volume (or area) is zero.
    volume_ratio: Option<f64>,
    area_ratio: Option<f64>,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let mut mesh = hdlod::io::read_mesh(&args.input)?;
    if args.positions_only {
        mesh.normals.clear();
        mesh.colors.clear();
    }
    let n = mesh.triangle_count();
    if n == 0 {
        bail!("{}: the mesh has no triangles", args.input.display());
    }
    let options = match (args.ratio, args.error) {
        (Some(r), _) => {
            if !(r.is_finite() && r > 0.0) {
                bail!("--ratio: {r} is not a positive number");
            }
            SimplifyOptions {
                max_error: f32::INFINITY,
                target_triangles: Some(((r * n as f64).ceil() as usize).max(1)),
                prune: false,
            }
        }
        (None, Some(e)) => {
            if !(e.is_finite() && e >= 0.0) {
                bail!("--error: {e} is not a non-negative number");
            }
            SimplifyOptions {
                max_error: e,
                target_triangles: None,
                prune: false,
            }
        }
        (None, None) => bail!("give --ratio or --error"),
    };

    let start = Instant::now();
    let out = geometry::Method::from(args.method).run(&mesh, &options);
    let seconds = start.elapsed().as_secs_f64();

    write(&out, &args.output)?;
    let h = geometry::distance(&mesh, &out, args.seed);
    let ratio = |a: f64, b: f64| (b != 0.0).then(|| a / b);
    let report = Report {
        method: args.method,
        positions_only: args.positions_only,
        triangles_in: n,
        triangles_out: out.triangle_count(),
        seconds,
        hausdorff: h.bound,
        hausdorff_lower: h.lower,
        mean: h.mean,
        rms: h.rms,
        volume_ratio: ratio(measure::volume(&out), measure::volume(&mesh)),
        area_ratio: ratio(measure::area(&out), measure::area(&mesh)),
    };
    if args.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        let opt = |x: Option<f64>| x.map_or("-".to_string(), |x| format!("{x:.4}"));
        println!(
            "triangles   {} -> {}",
            report.triangles_in, report.triangles_out
        );
        println!("seconds     {:.4}", report.seconds);
        println!(
            "hausdorff   <= {} (>= {})",
            report.hausdorff, report.hausdorff_lower
        );
        println!("mean        {}", report.mean);
        println!("rms         {}", report.rms);
        println!("volume      x {}", opt(report.volume_ratio));
        println!("area        x {}", opt(report.area_ratio));
    }
    Ok(())
}

fn write(mesh: &Mesh, path: &Path) -> anyhow::Result<()> {
    let extension = path
        .extension()
        .and_then(|e| e.to_str())
        .unwrap_or("")
        .to_ascii_lowercase();
    match extension.as_str() {
        "obj" => hdlod::io::obj::write_mesh(mesh, path)?,
        "glb" => hdlod::io::glb::write_mesh(mesh, path)?,
        other => bail!(
            "{}: unknown output format {other:?} (expected .obj or .glb)",
            path.display()
        ),
    }
    Ok(())
}
