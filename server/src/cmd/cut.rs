//! `hdlod cut TREE --time T (--camera-json FILE | --position .. --target ..)
//! --pixel-error P [--viewport WxH] [--json]`: one cut from the command
//! line; `--json` prints the same JSON as `POST /api/v1/scenes/{scene}/cut`.

use std::path::PathBuf;

use anyhow::Context;

use crate::protocol::{self, Flags};

#[derive(clap::Args)]
pub struct Args {
    /// A tree directory (an hdlod tree).
    tree: PathBuf,
    /// Seconds since the scene's start, or an ISO 8601 date.
    #[arg(long)]
    time: String,
    /// A file holding the `camera` object of the HTTP request.
    #[arg(long, conflicts_with_all = ["position", "target", "up", "fov"])]
    camera_json: Option<PathBuf>,
    /// Eye position `x,y,z`.
    #[arg(long, required_unless_present = "camera_json")]
    position: Option<String>,
    /// Point looked at, `x,y,z`.
    #[arg(long, required_unless_present = "camera_json")]
    target: Option<String>,
    /// Up vector `x,y,z` (default: the scene's up axis).
    #[arg(long)]
    up: Option<String>,
    /// Vertical field of view in degrees.
    #[arg(long)]
    fov: Option<f64>,
    #[arg(long, default_value_t = 1.0)]
    pixel_error: f64,
    /// `WIDTHxHEIGHT`.
    #[arg(long, default_value = "1920x1080")]
    viewport: String,
    /// `paper` (clusters at least half present, the paper's rule) or
    /// `exact` (every cluster partly present; the client hides absent
    /// objects by their feature ids).
    #[arg(long, default_value = "paper")]
    presence: String,
    /// `hdlod` (the cut) or `none` (every present leaf at full detail, in
    /// view or not: drawing without levels of detail).
    #[arg(long, default_value = "hdlod")]
    lod: String,
    /// Print the HTTP answer's JSON.
    #[arg(long)]
    json: bool,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let tree = hdlod::tree::load(&args.tree)?;
    let camera =
        match &args.camera_json {
            Some(file) => {
                let text = std::fs::read(file).with_context(|| file.display().to_string())?;
                let mut de = serde_json::Deserializer::from_slice(&text);
                Some(serde_path_to_error::deserialize(&mut de).map_err(|e| {
                    anyhow::anyhow!("{}: {}: {}", file.display(), e.path(), e.inner())
                })?)
            }
            None => None,
        };
    let request = protocol::parse_flags(Flags {
        time: &args.time,
        camera,
        position: args.position.as_deref(),
        target: args.target.as_deref(),
        up: args.up.as_deref(),
        fov_y_deg: args.fov,
        viewport: &args.viewport,
        pixel_error: args.pixel_error,
        presence: &args.presence,
        lod: &args.lod,
    })?;
    let baseline = hdlod::tree::Baseline::of(&tree);
    let answer = protocol::answer(&tree, &baseline, &request)?;
    if args.json {
        println!("{}", serde_json::to_string_pretty(&answer)?);
        return Ok(());
    }
    println!(
        "{} at {} (t = {} s): {} clusters, {} triangles, {} visited, {:.1} us",
        tree.scene,
        answer.date,
        answer.time,
        answer.stats.clusters,
        answer.stats.triangles,
        answer.stats.visited,
        answer.stats.micros
    );
    println!(
        "{:>8} {:>15} {:>5} {:>10} {:>10} {:>6}",
        "id", "class", "level", "triangles", "error", "v"
    );
    for c in &answer.clusters {
        println!(
            "{:>8} {:>15} {:>5} {:>10} {:>10.4} {:>6.3}",
            c.id, c.class, c.level, c.triangles, c.error, c.visibility
        );
    }
    Ok(())
}
