//! `hdlod inspect PATH [--json]`.

use std::path::PathBuf;

#[derive(clap::Args)]
pub struct Args {
    /// A scene directory (or its scene.json).
    path: PathBuf,
    /// Print JSON instead of a table.
    #[arg(long)]
    json: bool,
}

pub fn run(_args: Args) -> anyhow::Result<()> {
    anyhow::bail!("not yet implemented")
}
