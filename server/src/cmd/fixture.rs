//! `hdlod fixture ...`: generated test scenes.

use std::path::PathBuf;

use clap::Subcommand;

#[derive(Subcommand)]
pub enum Fixture {
    /// A construction site with a tower built floor by floor.
    Skyscraper {
        #[arg(long, default_value = "tiny")]
        scale: String,
        #[arg(long, default_value_t = 1)]
        seed: u64,
        #[arg(long)]
        out: PathBuf,
    },
}

pub fn run(_fixture: Fixture) -> anyhow::Result<()> {
    anyhow::bail!("not yet implemented")
}
