//! `hdlod fixture ...`: generated test scenes.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::Context;
use clap::Subcommand;
use hdlod::scene::{SceneSummary, format};
use hdlod_fixtures::{Scale, check_table_1, skyscraper};

#[derive(Subcommand)]
pub enum Fixture {
    /// A construction site with a tower built floor by floor.
    Skyscraper {
        /// tiny (a few hundred objects), small (about 5,000: the demo),
        /// paper (the counts of the paper's table 1), storeys-N (the paper's
        /// tower with N storeys) or district-N (N paper sites side by side,
        /// started 13 weeks apart: about 4.3 M triangles each).
        #[arg(long, default_value = "tiny")]
        scale: String,
        #[arg(long, default_value_t = 1)]
        seed: u64,
        /// Directory to write the scene to (hdlod-scene/1); replaced only
        /// when the whole scene is written.
        #[arg(long, required_unless_present = "check")]
        out: Option<PathBuf>,
        /// Fail unless every count is within 3% of the paper's table 1.
        #[arg(long)]
        check: bool,
    },
}

pub fn run(fixture: Fixture) -> anyhow::Result<()> {
    let Fixture::Skyscraper {
        scale,
        seed,
        out,
        check,
    } = fixture;
    let scale = Scale::parse(&scale)?;
    anyhow::ensure!(
        !check || scale == Scale::Paper,
        "--check compares with the paper's table 1: use it with --scale paper"
    );
    let started = Instant::now();
    let scene = skyscraper(scale, seed);
    let generated = started.elapsed().as_secs_f64();
    let summary = SceneSummary::of(&scene);
    println!(
        "{}: {} objects, {} meshes, {} tasks, {:.0} days",
        scene.name,
        scene.objects.len(),
        scene.meshes.len(),
        scene.tasks.len(),
        scene.time.seconds / 86_400.0
    );
    println!("{:<16} {:>9} {:>11}", "class", "objects", "triangles");
    for (class, counts) in &summary.classes {
        println!(
            "{:<16} {:>9} {:>11}",
            class.name(),
            counts.objects,
            counts.triangles
        );
    }
    let types: Vec<String> = summary
        .visibility_types
        .iter()
        .map(|(kind, n)| format!("{kind:?} {n}"))
        .collect();
    println!("visibility types: {}", types.join(", "));
    println!("generated in {generated:.2} s");
    if let Some(dir) = out {
        let started = Instant::now();
        format::save(&scene, &dir)
            .with_context(|| format!("cannot write the scene to {}", dir.display()))?;
        println!(
            "written to {} in {:.2} s",
            dir.display(),
            started.elapsed().as_secs_f64()
        );
    }
    if check {
        check_table_1(&summary)
            .map_err(anyhow::Error::msg)
            .context("--check")?;
        println!("within 3% of table 1");
    }
    Ok(())
}
