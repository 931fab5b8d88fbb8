//! `hdlod bench viewer TREE [--json]`: how fast the web viewer shows a
//! site. The tree is served on loopback and `tools/browser/delivery.mjs`
//! drives the viewer in headless chromium: the first frame from
//! navigation (2/3 of the period, table 2's nearest and farthest camera,
//! the geometry as stored and in the plain form), a one-week step, and
//! the frame time of each cell of table 2 with the cut against drawing
//! every present leaf (`lod=none`, the paper's comparison). Needs `node`
//! and the npm tools of `tools/` (`npm ci --prefix tools`, as
//! `scripts/test` runs) and Debian's chromium. The paper's frame times were
//! measured on a GPU; here chromium rasterises in software (SwiftShader),
//! so the ratio of the two columns is what compares.

use std::path::PathBuf;

use anyhow::bail;
use serde::{Deserialize, Serialize};

use super::browser;

#[derive(clap::Args)]
pub struct Args {
    /// The tree.
    tree: PathBuf,
    /// Print the JSON report instead of the tables.
    #[arg(long)]
    json: bool,
    /// The browser window, in CSS pixels.
    #[arg(long, default_value_t = 1280)]
    width: u32,
    #[arg(long, default_value_t = 720)]
    height: u32,
    /// Frames timed per cell and mode (the median is reported).
    #[arg(long, default_value_t = 10, value_parser = clap::value_parser!(u32).range(1..=1000))]
    frames: u32,
    /// The repository's `tools` directory (the driver and its npm packages).
    #[arg(long, default_value = "tools")]
    tools: PathBuf,
}

/// The driver's report (`tools/browser/delivery.mjs`), with the tree's
/// geometry bytes added here.
#[derive(Debug, Serialize, Deserialize)]
struct Report {
    width: u32,
    height: u32,
    frames: u32,
    open: Vec<Open>,
    step: Option<Step>,
    cells: Vec<Cell>,
    errors: Vec<String>,
    /// The tree's GLB files as stored, in bytes.
    #[serde(rename = "treeBytes", default)]
    tree_bytes: u64,
}

/// A first frame: navigation until the complete cut is drawn.
#[derive(Debug, Serialize, Deserialize)]
struct Open {
    screen: String,
    /// `compact` (as stored) or `plain`.
    encoding: String,
    ms: f64,
    clusters: u64,
    triangles: u64,
    #[serde(flatten)]
    fetched: Fetched,
}

#[derive(Debug, Serialize, Deserialize)]
struct Fetched {
    /// Geometry requests (a batch counts once).
    requests: u64,
    /// Their bodies as sent (compressed by the server when the browser
    /// accepts it).
    #[serde(rename = "wireBytes")]
    wire_bytes: u64,
    #[serde(rename = "decodedBytes")]
    decoded_bytes: u64,
}

#[derive(Debug, Serialize, Deserialize)]
struct Step {
    days: u32,
    /// The median over the steps made in a row, and each.
    ms: f64,
    all: Vec<f64>,
    /// Frames drawn with the old cut while the steps' cuts loaded.
    #[serde(rename = "staleFrames")]
    stale_frames: u64,
    /// Of the first step.
    clusters: u64,
    triangles: u64,
    #[serde(flatten)]
    fetched: Fetched,
}

#[derive(Debug, Serialize, Deserialize)]
struct Cell {
    time: String,
    screen: String,
    hdlod: Frames,
    none: Frames,
}

#[derive(Debug, Serialize, Deserialize)]
struct Frames {
    clusters: u64,
    triangles: u64,
    /// The triangles of every object present (the server's baseline).
    baseline: Option<u64>,
    /// The median frame, in milliseconds.
    ms: f64,
    all: Vec<f64>,
    /// Draw calls of a frame, the clusters batched as the viewer draws them.
    #[serde(rename = "drawCalls")]
    draw_calls: u64,
    /// The median frame with a draw call per cluster.
    #[serde(rename = "aloneMs")]
    alone_ms: f64,
    #[serde(rename = "aloneDrawCalls")]
    alone_draw_calls: u64,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let driver = browser::driver(&args.tools, "delivery.mjs")?;
    let served = browser::serve(&args.tree)?;
    let scene = served.scene.clone();
    eprintln!(
        "opening {scene:?} in fresh browsers and timing {} frames of each of the 12 cells at {}x{}",
        args.frames, args.width, args.height
    );
    let mut report: Report = browser::drive(
        &driver,
        &[
            served.base.clone(),
            scene.clone(),
            args.width.to_string(),
            args.height.to_string(),
            args.frames.to_string(),
        ],
    )?;
    if let Some(e) = report.errors.first() {
        bail!("the page failed: {e} ({} errors)", report.errors.len());
    }
    report.tree_bytes = tree_bytes(&args.tree)?;
    if args.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
        return Ok(());
    }
    print!("{}", markdown(&scene, &report));
    Ok(())
}

/// The bytes of the tree's GLB files, as stored.
fn tree_bytes(tree: &std::path::Path) -> anyhow::Result<u64> {
    let mut total = 0;
    for (_, path) in hdlod::tree::store::geometry_files(tree)? {
        total += std::fs::metadata(&path)
            .map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?
            .len();
    }
    Ok(total)
}

fn markdown(scene: &str, r: &Report) -> String {
    let mut out = format!(
        "Scene `{scene}`, {}x{}; the tree's geometry: {} bytes as stored.\n\n\
         First frame at 2/3 of the period (a fresh browser, from navigation to the complete cut drawn):\n\n\
         | screen | geometry | ms | clusters | triangles | geometry requests | bytes on the wire | bytes decoded | decoded / tree |\n\
         |---|---|---|---|---|---|---|---|---|\n",
        r.width, r.height, r.tree_bytes
    );
    for o in &r.open {
        out += &format!(
            "| {} | {} | {:.0} | {} | {} | {} | {} | {} | {:.2}% |\n",
            o.screen,
            o.encoding,
            o.ms,
            o.clusters,
            o.triangles,
            o.fetched.requests,
            o.fetched.wire_bytes,
            o.fetched.decoded_bytes,
            100.0 * o.fetched.decoded_bytes as f64 / r.tree_bytes.max(1) as f64
        );
    }
    if let Some(s) = &r.step {
        out += &format!(
            "\n{} {}-day steps in a row from the nearest view: {:.0} ms until the new cut is complete (median; each: {}), {} frames drawn with the old cut meanwhile. The first: {} clusters, {} triangles; {} geometry requests, {} bytes on the wire.\n",
            s.all.len(),
            s.days,
            s.ms,
            s.all
                .iter()
                .map(|ms| format!("{ms:.0}"))
                .collect::<Vec<_>>()
                .join(", "),
            s.stale_frames,
            s.clusters,
            s.triangles,
            s.fetched.requests,
            s.fetched.wire_bytes
        );
    }
    out += &format!(
        "\nFrame time, the median of {} frames each drawn and read back (ms):\n\n\
         | time | screen | HDLOD triangles | HDLOD clusters | HDLOD draw calls | HDLOD ms | a call per cluster | none triangles | none draw calls | none ms | a call per cluster | none / HDLOD |\n\
         |---|---|---|---|---|---|---|---|---|---|---|---|\n",
        r.frames
    );
    for c in &r.cells {
        out += &format!(
            "| {} | {} | {} | {} | {} | {:.1} | {:.1} | {} | {} | {:.1} | {:.1} | {:.1}x |\n",
            c.time,
            c.screen,
            c.hdlod.triangles,
            c.hdlod.clusters,
            c.hdlod.draw_calls,
            c.hdlod.ms,
            c.hdlod.alone_ms,
            c.none.triangles,
            c.none.draw_calls,
            c.none.ms,
            c.none.alone_ms,
            c.none.ms / c.hdlod.ms.max(1e-9)
        );
    }
    out
}
