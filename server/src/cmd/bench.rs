//! `hdlod bench paper TREE [--json] [--doc FILE]`: the paper's table 2 on
//! a tree (`hdlod_fixtures::paper`) with each cell's bytes per cut,
//! printed, and written into FILE when asked.
//! `hdlod bench ws --url .. --tree TREE`: many WebSocket viewers updating
//! their view at a fixed rate, bounded in time, reporting update latency.
//! `build`, `simplify`, `objects`, `image`, `viewer` and `xer` are in their
//! own files.

use std::path::PathBuf;
use std::time::{Duration, Instant};

use anyhow::Context;
use futures_util::{SinkExt, StreamExt};
use hdlod_fixtures::paper;
use tokio_tungstenite::tungstenite::Message;

#[derive(clap::Subcommand)]
pub enum Bench {
    /// The paper's table 2: cut against drawing every present object.
    Paper(PaperArgs),
    /// Concurrent WebSocket viewers against a running server.
    Ws(WsArgs),
    /// Build time per object as the scene grows (n log n, not n^2).
    Build(super::bench_build::Args),
    /// The three simplifiers on real meshes, as the decimation theses compare them.
    Simplify(super::bench_simplify::Args),
    /// Levels of a skinned limb weighed in several poses against its bind
    /// pose alone: their error over the poses.
    Skin(super::bench_skin::Args),
    /// Temporal error of the paper's presence rule and the exact one in
    /// the table's 12 cells.
    Presence(super::bench_identity::PresenceArgs),
    /// How far each object's triangles in a cluster lie from the object,
    /// against the cluster's error.
    Features(super::bench_identity::FeaturesArgs),
    /// Loading a tree's object and task tables, and a search of them.
    Objects(super::bench_objects::Args),
    /// What the eye sees: each cell rendered in headless chromium at the
    /// pixel budget and at full detail, the pictures compared.
    Image(super::bench_image::Args),
    /// How fast the web viewer shows a site: the first frame, a week's
    /// step, and frame time with the cut against every present object.
    Viewer(super::bench_viewer::Args),
    /// Reading a Primavera P6 XER of tens of thousands of activities made
    /// from the generated site's schedule.
    #[cfg(feature = "ifc")]
    Xer(super::bench_xer::Args),
}

#[derive(clap::Args)]
pub struct PaperArgs {
    tree: PathBuf,
    /// Print JSON rows instead of the table.
    #[arg(long)]
    json: bool,
    /// Frames of the animation across the period.
    #[arg(long, default_value_t = 300)]
    frames: usize,
    /// Timings per cell (the median is reported).
    #[arg(long, default_value_t = 21)]
    repeats: usize,
    /// Frame the views on the objects whose property KEY is VALUE rather
    /// than on the whole scene: their box, the period to their tasks' last
    /// finish, and their leaves alone in the baseline. `--frame "site=Site
    /// 1"` gives a district's first site the views of a lone site.
    #[arg(long, value_name = "KEY=VALUE")]
    frame: Option<String>,
    /// Markdown file whose "paper table" section is replaced. A benchmark
    /// writes no file unless asked, so without it the table is only printed.
    #[arg(long)]
    doc: Option<PathBuf>,
}

#[derive(clap::Args)]
pub struct WsArgs {
    /// The stream URL, ws://HOST:PORT/api/v1/scenes/NAME/stream.
    #[arg(long)]
    url: String,
    /// The tree the server serves (for the scene's bounds and period).
    #[arg(long)]
    tree: PathBuf,
    #[arg(long, default_value_t = 100)]
    clients: usize,
    /// View updates per second per client.
    #[arg(long, default_value_t = 30.0)]
    rate: f64,
    #[arg(long, default_value_t = 10.0)]
    seconds: f64,
    #[arg(long)]
    json: bool,
}

pub fn run(bench: Bench) -> anyhow::Result<()> {
    match bench {
        Bench::Paper(a) => paper_table(a),
        Bench::Build(a) => super::bench_build::run(a),
        Bench::Simplify(a) => super::bench_simplify::run(a),
        Bench::Skin(a) => super::bench_skin::run(a),
        Bench::Presence(a) => super::bench_identity::presence(a),
        Bench::Features(a) => super::bench_identity::features(a),
        Bench::Objects(a) => super::bench_objects::run(a),
        Bench::Image(a) => super::bench_image::run(a),
        Bench::Viewer(a) => super::bench_viewer::run(a),
        #[cfg(feature = "ifc")]
        Bench::Xer(a) => super::bench_xer::run(a),
        Bench::Ws(a) => ws(a),
    }
}

const BEGIN: &str = "<!-- bench paper: begin -->";
const END: &str = "<!-- bench paper: end -->";

fn markdown(tree: &hdlod::tree::Tree, frame: Option<&str>, report: &paper::Report) -> String {
    let framed = frame.map_or(String::new(), |f| format!(", framed on `{f}`"));
    let mut out = format!(
        "{BEGIN}\nScene `{}`, {} clusters{framed}; `hdlod bench paper`: 1920x1080, fov_y 60 degrees, 1 pixel of error.{}\n\n\
         | time | screen | triangles | clusters | baseline triangles | baseline draws | ratio | bytes | plain bytes | bytes / plain | cut (us) | visited |\n\
         |---|---|---|---|---|---|---|---|---|---|---|---|\n",
        tree.scene,
        tree.cluster_count(),
        report.tree_bytes.map_or(String::new(), |b| format!(
            " The tree's geometry: {b} bytes as stored; a cell's bytes are those of its cut's distinct GLB files."
        ))
    );
    for r in &report.rows {
        let bytes = r.bytes.map_or("| - | - | - |".to_owned(), |b| {
            format!(
                "| {} | {} | {:.1}% |",
                b.stored,
                b.plain,
                100.0 * b.stored as f64 / b.plain.max(1) as f64
            )
        });
        out.push_str(&format!(
            "| {} | {} | {:.0} | {:.0} | {:.0} | {:.0} | {:.1}x {bytes} {:.1} | {:.0} |\n",
            r.time,
            r.screen,
            r.triangles,
            r.clusters,
            r.baseline_triangles,
            r.baseline_draws,
            r.baseline_triangles / r.triangles.max(1.0),
            r.micros,
            r.visited
        ));
    }
    out.push_str(&format!(
        "\nCut time over all {} views: median {:.1} us, p99 {:.1} us; per cluster visited, median {:.1} ns.\n{END}\n",
        report.cuts, report.median_micros, report.p99_micros, report.median_nanos_per_visited
    ));
    out
}

fn paper_table(args: PaperArgs) -> anyhow::Result<()> {
    let tree = hdlod::tree::load(&args.tree)?;
    let frame = match &args.frame {
        None => paper::Frame::whole(&tree),
        Some(spec) => {
            let (key, value) = spec
                .split_once('=')
                .with_context(|| format!("--frame {spec:?}: expected KEY=VALUE"))?;
            paper::Frame::of_objects(&tree, key, value).with_context(|| {
                format!(
                    "--frame {spec:?}: no object of {} that stands still has property {key:?} = {value:?}{}",
                    args.tree.display(),
                    if tree.objects.is_none() { " (the tree has no object tables)" } else { "" }
                )
            })?
        }
    };
    let mut report = paper::table(&tree, &frame, args.frames, args.repeats);
    weigh(&tree, &args.tree, &frame, &mut report)?;
    let table = markdown(&tree, args.frame.as_deref(), &report);
    if args.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        print!("{table}");
    }
    if let Some(path) = &args.doc {
        let old = std::fs::read_to_string(path).unwrap_or_else(|_| "# Benchmarks\n".into());
        let new = match (old.find(BEGIN), old.find(END)) {
            // The table ends in a newline; a blank line keeps the
            // section after it apart.
            (Some(a), Some(b)) if a < b => format!(
                "{}{table}\n{}",
                &old[..a],
                &old[b + END.len()..].trim_start_matches('\n')
            ),
            _ => format!("{}\n\n## The paper's table 2\n\n{table}", old.trim_end()),
        };
        std::fs::write(path, new).with_context(|| path.display().to_string())?;
        eprintln!("table written into {}", path.display());
    }
    Ok(())
}

/// The cells' bytes per cut and the tree's geometry bytes, read from the
/// tree's files in `dir`.
fn weigh(
    tree: &hdlod::tree::Tree,
    dir: &std::path::Path,
    frame: &paper::Frame,
    report: &mut paper::Report,
) -> anyhow::Result<()> {
    paper::weigh(
        tree,
        frame,
        report,
        |hash| -> anyhow::Result<paper::Bytes> {
            let path = tree.geometry_file(dir, hash);
            let glb = std::fs::read(&path).with_context(|| path.display().to_string())?;
            let plain = hdlod::io::compact::plain(&glb)
                .map_err(|m| anyhow::anyhow!("{}: {m}", path.display()))?;
            Ok(paper::Bytes {
                stored: glb.len() as u64,
                plain: plain.len() as u64,
            })
        },
    )?;
    let mut total = 0;
    for (_, path) in hdlod::tree::store::geometry_files(dir)? {
        total += std::fs::metadata(&path)
            .with_context(|| path.display().to_string())?
            .len();
    }
    report.tree_bytes = Some(total);
    Ok(())
}

#[derive(Default)]
struct ClientResult {
    latencies: Vec<f64>,
    errors: usize,
}

/// One viewer orbiting the scene while time runs over the period.
async fn client(
    url: String,
    index: usize,
    tree: std::sync::Arc<hdlod::tree::Tree>,
    rate: f64,
    seconds: f64,
) -> ClientResult {
    let mut result = ClientResult::default();
    let Ok((mut socket, _)) = tokio_tungstenite::connect_async(&url).await else {
        result.errors += 1;
        return result;
    };
    let start = Instant::now();
    let mut tick = tokio::time::interval(Duration::from_secs_f64(1.0 / rate));
    let mut frame = 0usize;
    while start.elapsed().as_secs_f64() < seconds {
        tick.tick().await;
        let phase = index as f64 * 0.37 + frame as f64 * 0.02;
        let factor = 1.0 + (index % 4) as f64;
        let mut camera = paper::camera(&tree, factor);
        if let (Some(p), Some(c)) = (camera.position.as_mut(), camera.target) {
            let (dx, dz) = (p[0] - c[0], p[2] - c[2]);
            p[0] = c[0] + dx * phase.cos() - dz * phase.sin();
            p[2] = c[2] + dx * phase.sin() + dz * phase.cos();
        }
        let t =
            tree.time.seconds * ((frame as f64 / (rate * seconds)) + index as f64 / 100.0).fract();
        let request = serde_json::json!({"time": t, "camera": camera, "viewport": {"width": 1920, "height": 1080}, "pixel_error": 1.0});
        let sent = Instant::now();
        if socket
            .send(Message::text(request.to_string()))
            .await
            .is_err()
        {
            result.errors += 1;
            break;
        }
        match socket.next().await {
            Some(Ok(Message::Text(text))) if !text.as_str().starts_with("{\"error\"") => {
                result.latencies.push(sent.elapsed().as_secs_f64() * 1000.0);
            }
            _ => result.errors += 1,
        }
        frame += 1;
    }
    let _ = socket.close(None).await;
    result
}

fn ws(args: WsArgs) -> anyhow::Result<()> {
    anyhow::ensure!(
        args.rate > 0.0 && args.rate <= 1000.0,
        "--rate must be in (0, 1000]"
    );
    anyhow::ensure!(
        args.seconds > 0.0 && args.seconds <= 600.0,
        "--seconds must be in (0, 600]"
    );
    anyhow::ensure!(
        args.clients > 0 && args.clients <= 2000,
        "--clients must be in [1, 2000]"
    );
    let tree = std::sync::Arc::new(hdlod::tree::load(&args.tree)?);
    let runtime = tokio::runtime::Runtime::new()?;
    let results = runtime.block_on(async {
        let tasks: Vec<_> = (0..args.clients)
            .map(|i| {
                tokio::spawn(client(
                    args.url.clone(),
                    i,
                    tree.clone(),
                    args.rate,
                    args.seconds,
                ))
            })
            .collect();
        let mut all = Vec::new();
        for task in tasks {
            all.push(task.await.unwrap_or_else(|_| ClientResult {
                latencies: vec![],
                errors: 1,
            }));
        }
        all
    });
    let errors: usize = results.iter().map(|r| r.errors).sum();
    let mut latencies: Vec<f64> = results.into_iter().flat_map(|r| r.latencies).collect();
    latencies.sort_by(f64::total_cmp);
    let pick = |p: f64| {
        latencies
            .get(((latencies.len().max(1) - 1) as f64 * p).round() as usize)
            .copied()
            .unwrap_or(0.0)
    };
    let summary = serde_json::json!({
        "clients": args.clients, "rate": args.rate, "seconds": args.seconds,
        "updates": latencies.len(), "errors": errors,
        "updates_per_second": latencies.len() as f64 / args.seconds,
        "latency_ms": {"p50": pick(0.5), "p90": pick(0.9), "p99": pick(0.99), "max": pick(1.0)},
    });
    if args.json {
        println!("{}", serde_json::to_string_pretty(&summary)?);
    } else {
        println!(
            "{} clients x {}/s for {} s: {} updates, {} errors, latency p50 {:.2} ms, p99 {:.2} ms, max {:.2} ms",
            args.clients,
            args.rate,
            args.seconds,
            latencies.len(),
            errors,
            pick(0.5),
            pick(0.99),
            pick(1.0)
        );
    }
    anyhow::ensure!(errors == 0, "{errors} errors");
    Ok(())
}
