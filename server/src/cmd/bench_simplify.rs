//! `hdlod bench simplify [--meshes DIR] [--json] [--docs FILE]`: the three
//! simplifiers (quadric edge collapse, vertex clustering, vertex removal)
//! on the real meshes, compared as the decimation theses compare them
//! (docs/method.md section 6): for each model, method and target share of the
//! triangles, the time (median of `--runs`), the measured Hausdorff bound
//! and mean distance to the input, and the volume and area ratios; the
//! thesis's own times beside ours for the models it shares. JSON rows are
//! described by `schemas/bench-simplify.schema.json`.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, bail};
use hdlod::geometry::{self, Mesh, SimplifyOptions, measure};
use plotters::prelude::*;
use serde::Serialize;

use super::bench_build::replace_section;
use super::simplify::Method;

#[derive(clap::Args)]
pub struct Args {
    /// Directory of the meshes (.obj, .ply, .glb, .gltf); default:
    /// `$HDLOD_DATA/meshes`.
    #[arg(long)]
    meshes: Option<PathBuf>,
    /// Only these models (file names without extension).
    #[arg(long, value_delimiter = ',')]
    models: Vec<String>,
    /// Shares of the triangles to reduce to.
    #[arg(long, value_delimiter = ',', default_value = "0.1,0.04,0.02")]
    ratios: Vec<f64>,
    #[arg(
        long,
        value_enum,
        value_delimiter = ',',
        default_value = "qem,clustering,vertex-removal"
    )]
    methods: Vec<Method>,
    /// Timed runs per case at least (the median wall time is reported).
    #[arg(long, default_value_t = 3)]
    runs: usize,
    /// Print JSON rows instead of the table.
    #[arg(long)]
    json: bool,
    /// Markdown file whose "bench-simplify" section is replaced; the chart
    /// goes beside it as simplifiers.svg.
    #[arg(long)]
    docs: Option<PathBuf>,
}

#[derive(Serialize)]
struct Row {
    model: String,
    method: Method,
    ratio: f64,
    triangles_in: usize,
    triangles_out: usize,
    seconds: f64,
    /// Mean time the process's threads spent on a CPU per run (Linux), `None`
    /// elsewhere: on a shared machine wall time also counts waits for a core.
    cpu_seconds: Option<f64>,
    hausdorff: f32,
    mean: f32,
    /// Hausdorff bound over the input's bounding-box diagonal.
    hausdorff_relative: f32,
    /// `None` when the input's volume (or area) is zero.
    volume_ratio: Option<f64>,
    area_ratio: Option<f64>,
    /// The thesis's time for this model, method and ratio, where it has one.
    thesis_seconds: Option<f64>,
}

/// The thesis's times to 10% (docs/method.md section 6), 2008-era PC.
fn thesis_seconds(model: &str, method: Method, ratio: f64) -> Option<f64> {
    if (ratio - 0.1).abs() > 1e-9 {
        return None;
    }
    let [vr, qem, cl] = match model {
        "bunny" | "stanford-bunny" => [5.300, 2.146, 0.298],
        "horse" => [7.738, 3.109, 0.403],
        "dragon" => [141.410, 47.834, 4.050],
        "blade" => [481.440, 131.850, 8.368],
        _ => return None,
    };
    Some(match method {
        Method::VertexRemoval => vr,
        Method::Qem => qem,
        Method::Clustering => cl,
    })
}

/// `$HDLOD_DATA/meshes`: the test data's classic meshes, where the user
/// says they are (the repository does not hold them).
fn default_meshes() -> anyhow::Result<PathBuf> {
    let data = std::env::var_os("HDLOD_DATA").context(
        "no meshes to measure: give --meshes DIR, or set HDLOD_DATA to the directory whose \
         meshes/ holds the classic meshes (stanford-bunny.obj, horse.ply, fandisk.obj, \
         rocker-arm.obj from github.com/alecjacobson/common-3d-test-models, folder data/)",
    )?;
    Ok(PathBuf::from(data).join("meshes"))
}

fn models(dir: &Path, only: &[String]) -> anyhow::Result<Vec<(String, PathBuf)>> {
    let entries = std::fs::read_dir(dir).with_context(|| format!("reading {}", dir.display()))?;
    let mut out = Vec::new();
    for e in entries {
        let path = e.with_context(|| dir.display().to_string())?.path();
        let ext = path
            .extension()
            .and_then(|e| e.to_str())
            .unwrap_or("")
            .to_ascii_lowercase();
        let Some(name) = path.file_stem().and_then(|s| s.to_str()) else {
            continue;
        };
        if ["obj", "ply", "glb", "gltf"].contains(&ext.as_str())
            && (only.is_empty() || only.iter().any(|o| o == name))
        {
            out.push((name.to_string(), path.clone()));
        }
    }
    out.sort();
    if out.is_empty() {
        bail!("{}: no mesh files to benchmark", dir.display());
    }
    Ok(out)
}

pub fn run(args: Args) -> anyhow::Result<()> {
    for r in &args.ratios {
        if !(r.is_finite() && *r > 0.0 && *r < 1.0) {
            bail!("--ratios: {r} is not in (0, 1)");
        }
    }
    if args.runs == 0 || args.runs > 100 {
        bail!("--runs must be in [1, 100]");
    }
    let dir = match &args.meshes {
        Some(d) => d.clone(),
        None => default_meshes()?,
    };
    let mut rows = Vec::new();
    for (model, path) in models(&dir, &args.models)? {
        let mesh = hdlod::io::read_mesh(&path)?;
        for &method in &args.methods {
            for &ratio in &args.ratios {
                let row = case(&model, &mesh, method, ratio, args.runs);
                if !args.json {
                    eprintln!(
                        "{model} {} {}%: {} triangles in {:.4} s",
                        geometry::Method::from(method).name(),
                        ratio * 100.0,
                        row.triangles_out,
                        row.seconds
                    );
                }
                rows.push(row);
            }
        }
    }
    let table = table(&rows);
    if args.json {
        println!("{}", serde_json::to_string_pretty(&rows)?);
    } else {
        print!("{table}");
    }
    if let Some(doc) = &args.docs {
        plot(&rows, &doc.with_file_name("simplifiers.svg"))?;
        replace_section(doc, "bench-simplify", &table)?;
    }
    Ok(())
}

fn case(model: &str, mesh: &Mesh, method: Method, ratio: f64, runs: usize) -> Row {
    let n = mesh.triangle_count();
    let options = SimplifyOptions {
        max_error: f32::INFINITY,
        target_triangles: Some(((ratio * n as f64).ceil() as usize).max(1)),
        prune: false,
    };
    let run = geometry::Method::from(method);
    // At least `runs` runs, and more for the fast cases until a quarter
    // second has passed: the CPU clock ticks in milliseconds, so the CPU
    // time is the total over all runs divided by their number.
    let mut times = Vec::with_capacity(runs);
    let mut out = Mesh::default();
    let (total, cpu_start) = (Instant::now(), process_cpu_ns());
    while times.len() < runs || (total.elapsed().as_secs_f64() < 0.25 && times.len() < 1000) {
        let start = Instant::now();
        out = run.run(mesh, &options);
        times.push(start.elapsed().as_secs_f64());
    }
    let cpu_seconds = cpu_start
        .zip(process_cpu_ns())
        .map(|(a, b)| b.saturating_sub(a) as f64 * 1e-9 / times.len() as f64);
    times.sort_by(f64::total_cmp);
    let h = geometry::distance(mesh, &out, 1);
    let diagonal = mesh.bounds().map_or(0.0, |(lo, hi)| (hi - lo).length());
    let quotient = |a: f64, b: f64| (b != 0.0).then(|| a / b);
    Row {
        model: model.to_string(),
        method,
        ratio,
        triangles_in: n,
        triangles_out: out.triangle_count(),
        seconds: times[times.len() / 2],
        cpu_seconds,
        hausdorff: h.bound,
        mean: h.mean,
        hausdorff_relative: if diagonal > 0.0 {
            h.bound / diagonal
        } else {
            0.0
        },
        volume_ratio: quotient(measure::volume(&out), measure::volume(mesh)),
        area_ratio: quotient(measure::area(&out), measure::area(mesh)),
        thesis_seconds: thesis_seconds(model, method, ratio),
    }
}

/// Nanoseconds the threads of this process have spent on a CPU (Linux's
/// per-thread schedstat, summed): the simplifiers may run on rayon's pool,
/// whose threads live as long as the process, so none is lost between two
/// readings.
fn process_cpu_ns() -> Option<u64> {
    let mut total = 0;
    for task in std::fs::read_dir("/proc/self/task").ok()? {
        let s = std::fs::read_to_string(task.ok()?.path().join("schedstat")).ok()?;
        total += s.split_whitespace().next()?.parse::<u64>().ok()?;
    }
    Some(total)
}

fn table(rows: &[Row]) -> String {
    let mut out = String::from(
        "| model | method | kept | triangles | ms (wall) | ms (CPU) | thesis ms | Hausdorff bound | % of diagonal | mean | volume ratio | area ratio |\n\
         |---|---|---|---|---|---|---|---|---|---|---|---|\n",
    );
    let opt = |x: Option<f64>| x.map_or("-".to_string(), |x| format!("{x:.4}"));
    for r in rows {
        out += &format!(
            "| {} | {} | {}% | {} -> {} | {:.1} | {} | {} | {:.6} | {:.3} | {:.6} | {} | {} |\n",
            r.model,
            geometry::Method::from(r.method).name(),
            r.ratio * 100.0,
            r.triangles_in,
            r.triangles_out,
            r.seconds * 1e3,
            r.cpu_seconds
                .map_or("-".to_string(), |s| format!("{:.1}", s * 1e3)),
            r.thesis_seconds
                .map_or("-".to_string(), |s| format!("{:.0}", s * 1e3)),
            r.hausdorff,
            r.hausdorff_relative * 100.0,
            r.mean,
            opt(r.volume_ratio),
            opt(r.area_ratio),
        );
    }
    out
}

/// Time against error, one colour per method: where each simplifier sits
/// between fast and accurate.
fn plot(rows: &[Row], path: &Path) -> anyhow::Result<()> {
    let positive = |x: f64| x.is_finite() && x > 0.0;
    let ms = |r: &Row| r.cpu_seconds.unwrap_or(r.seconds) * 1e3;
    let xs: Vec<f64> = rows.iter().map(ms).filter(|x| positive(*x)).collect();
    let ys: Vec<f64> = rows
        .iter()
        .map(|r| f64::from(r.hausdorff_relative) * 100.0)
        .filter(|y| positive(*y))
        .collect();
    let range = |v: &[f64]| {
        let lo = v.iter().copied().fold(f64::INFINITY, f64::min);
        let hi = v.iter().copied().fold(0.0, f64::max);
        if lo.is_finite() && hi > lo {
            (lo / 1.5, hi * 1.5)
        } else {
            (0.01, 10.0)
        }
    };
    let ((x0, x1), (y0, y1)) = (range(&xs), range(&ys));
    let root = SVGBackend::new(path, (720, 440)).into_drawing_area();
    root.fill(&WHITE)?;
    let mut chart = ChartBuilder::on(&root)
        .caption(
            "Simplifiers: time against Hausdorff bound",
            ("sans-serif", 20),
        )
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(64)
        .build_cartesian_2d((x0..x1).log_scale(), (y0..y1).log_scale())?;
    chart
        .configure_mesh()
        .x_desc("milliseconds of CPU (log)")
        .y_desc("Hausdorff bound, % of diagonal (log)")
        .x_label_formatter(&|x| format!("{x}"))
        .y_label_formatter(&|y| format!("{y:.2}"))
        .y_labels(8)
        .draw()?;
    for (method, colour) in [
        (Method::Qem, BLUE),
        (Method::Clustering, RED),
        (Method::VertexRemoval, GREEN),
    ] {
        let points: Vec<(f64, f64)> = rows
            .iter()
            .filter(|r| geometry::Method::from(r.method) == geometry::Method::from(method))
            .map(|r| (ms(r), f64::from(r.hausdorff_relative) * 100.0))
            .filter(|(x, y)| positive(*x) && positive(*y))
            .collect();
        chart
            .draw_series(points.iter().map(|&p| Circle::new(p, 4, colour.filled())))?
            .label(geometry::Method::from(method).name())
            .legend(move |(x, y)| Circle::new((x + 8, y), 4, colour.filled()));
    }
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::LowerLeft)
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .draw()?;
    root.present()?;
    Ok(())
}
