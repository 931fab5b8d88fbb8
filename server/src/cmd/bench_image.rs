//! `hdlod bench image TREE [--json]`: what the eye sees of the cut. The
//! tree is served on loopback and `tools/browser/image.mjs` renders each
//! cell of table 2 in headless chromium through the web viewer twice, the
//! cut at the pixel budget and full detail (every present leaf), and
//! compares the pictures over the scene's pixels: the share that differ by
//! more than 16/255 and 48/255 in some channel, and the PSNR. The pictures
//! are kept in `--out`. The cut's bytes are those the viewer fetched (the
//! GLBs as the tree stores them, compact in trees built now) and, from the
//! tree's files, those of the same GLBs in the plain form
//! (`?encoding=plain`); the header gives both for the whole tree.
//! `--supersample N` renders N x N device pixels to a pixel and averages
//! them (the same cut: the viewer's pixel error is scaled to match);
//! `--jitter M` draws each picture M x M times, the projection moved within
//! a device pixel, and averages them, for pictures close to converged. Each
//! cell also gives full detail against itself moved by one device pixel
//! (a whole pixel, or 1/N with `--supersample`): the share a displacement
//! that small makes alone, under what the cut's error allows. Needs
//! `node` and the npm tools of `tools/`
//! (`npm ci --prefix tools`, as `scripts/test` runs) and Debian's chromium.

use std::path::PathBuf;

use anyhow::{Context, bail};
use serde::{Deserialize, Serialize};

use super::browser;

#[derive(clap::Args)]
pub struct Args {
    /// The tree.
    tree: PathBuf,
    /// Print the JSON report instead of the table.
    #[arg(long)]
    json: bool,
    /// The browser window, in CSS pixels.
    #[arg(long, default_value_t = 1280)]
    width: u32,
    #[arg(long, default_value_t = 720)]
    height: u32,
    /// The cut's pixel error.
    #[arg(long, default_value_t = 1.0)]
    pixel_error: f64,
    /// Device pixels along each side of a pixel, averaged: samples beyond
    /// the GPU's multisampling, for pixels with sub-pixel detail.
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..=4))]
    supersample: u32,
    /// Frames along each side of a device pixel, the projection moved by a
    /// stratified offset each time, averaged: M x M times the samples again.
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..=16))]
    jitter: u32,
    /// Where the picture pairs go.
    #[arg(long, default_value = "target/bench-image")]
    out: PathBuf,
    /// The repository's `tools` directory (the driver and its npm packages).
    #[arg(long, default_value = "tools")]
    tools: PathBuf,
}

/// The driver's report (`tools/browser/image.mjs`).
#[derive(Debug, Serialize, Deserialize)]
struct Report {
    width: u32,
    height: u32,
    #[serde(rename = "pixelError")]
    pixel_error: f64,
    supersample: u32,
    jitter: u32,
    cells: Vec<Cell>,
    errors: Vec<String>,
}

#[derive(Debug, Serialize, Deserialize)]
struct Cell {
    time: String,
    screen: String,
    cut: Render,
    full: Render,
    #[serde(rename = "scenePixels")]
    scene_pixels: u64,
    /// The cut's GLB bytes in the plain form, set here from the tree.
    #[serde(rename = "plainBytes", default)]
    plain_bytes: u64,
    share16: f64,
    share48: f64,
    /// None when the pictures are equal.
    psnr: Option<f64>,
    /// Full detail against itself moved across.
    shifted: Shifted,
    pictures: Vec<String>,
}

#[derive(Debug, Serialize, Deserialize)]
struct Shifted {
    /// How far, in pixels.
    pixels: f64,
    share16: f64,
    share48: f64,
}

#[derive(Debug, Serialize, Deserialize)]
struct Render {
    triangles: u64,
    clusters: u64,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    leaves: Option<u64>,
    /// The clusters drawn (the cut's only).
    #[serde(default, skip_serializing)]
    ids: Vec<u32>,
    /// GLB bytes of the distinct geometry drawn, textures included.
    bytes: u64,
    /// Of those, the textures' PNG bytes.
    #[serde(rename = "textureBytes")]
    texture_bytes: u64,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let driver = browser::driver(&args.tools, "image.mjs")?;
    let served = browser::serve(&args.tree)?;
    let scene = served.scene.clone();
    eprintln!(
        "rendering the 12 cells of {scene:?} twice at {}x{}, {} x {} device pixels a pixel, {} frames each (pictures in {})",
        args.width,
        args.height,
        args.supersample,
        args.supersample,
        args.jitter * args.jitter,
        args.out.display()
    );
    let mut report: Report = browser::drive(
        &driver,
        &[
            served.base.clone(),
            scene.clone(),
            args.width.to_string(),
            args.height.to_string(),
            args.pixel_error.to_string(),
            args.out.display().to_string(),
            args.supersample.to_string(),
            args.jitter.to_string(),
        ],
    )?;
    if let Some(e) = report.errors.first() {
        bail!("the page failed: {e} ({} errors)", report.errors.len());
    }
    let sizes = GeometrySizes::of(&args.tree)?;
    let loaded = served.state.scenes();
    let tree = &loaded[&scene].tree;
    for c in &mut report.cells {
        let mut hashes: Vec<String> = c
            .cut
            .ids
            .iter()
            .filter(|&&id| (id as usize) < tree.cluster_count())
            .filter_map(|&id| tree.geometry_of(id).map(|h| h.into_owned()))
            .collect();
        hashes.sort_unstable();
        hashes.dedup();
        c.plain_bytes = hashes.iter().map(|h| sizes.plain(h)).sum();
    }
    if args.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
        return Ok(());
    }
    println!(
        "Scene `{scene}`, {}x{} ({} x {} device pixels a pixel, {} jittered frames a picture), pixel error {}; \
         full detail: every present leaf; moved: full detail against itself {} px across.",
        report.width,
        report.height,
        report.supersample,
        report.supersample,
        report.jitter * report.jitter,
        report.pixel_error,
        1.0 / f64::from(report.supersample)
    );
    println!(
        "Geometry: {} GLB files, {} bytes as stored, {} bytes in the plain form.\n",
        sizes.files(),
        sizes.stored_total(),
        sizes.plain_total()
    );
    println!(
        "| time | screen | cut triangles | full triangles | cut bytes (textures) | plain bytes | scene pixels | differ > 16/255 | differ > 48/255 | PSNR (dB) | moved: > 16/255 | > 48/255 |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|---|---|");
    for c in &report.cells {
        println!(
            "| {} | {} | {} | {} | {} ({}) | {} | {} | {:.2}% | {:.2}% | {} | {:.2}% | {:.2}% |",
            c.time,
            c.screen,
            c.cut.triangles,
            c.full.triangles,
            c.cut.bytes,
            c.cut.texture_bytes,
            c.plain_bytes,
            c.scene_pixels,
            100.0 * c.share16,
            100.0 * c.share48,
            c.psnr.map_or("equal".into(), |p| format!("{p:.1}")),
            100.0 * c.shifted.share16,
            100.0 * c.shifted.share48
        );
    }
    Ok(())
}

/// Each GLB of a tree with its size as stored and in the plain form.
struct GeometrySizes(std::collections::HashMap<String, (u64, u64)>);

impl GeometrySizes {
    fn of(tree: &std::path::Path) -> anyhow::Result<GeometrySizes> {
        let mut sizes = std::collections::HashMap::new();
        for (hash, path) in hdlod::tree::store::geometry_files(tree)? {
            let bytes = std::fs::read(&path).with_context(|| path.display().to_string())?;
            let plain = hdlod::io::compact::plain(&bytes)
                .map_err(|m| anyhow::anyhow!("{}: {m}", path.display()))?
                .len();
            sizes.insert(hash, (bytes.len() as u64, plain as u64));
        }
        Ok(GeometrySizes(sizes))
    }

    fn plain(&self, hash: &str) -> u64 {
        self.0.get(hash).map_or(0, |s| s.1)
    }

    fn files(&self) -> usize {
        self.0.len()
    }

    fn stored_total(&self) -> u64 {
        self.0.values().map(|s| s.0).sum()
    }

    fn plain_total(&self) -> u64 {
        self.0.values().map(|s| s.1).sum()
    }
}
