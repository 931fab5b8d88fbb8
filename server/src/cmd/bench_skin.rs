//! `hdlod bench skin [--rings N] [--sides N] [--json]`: levels of detail of
//! the fixture's skinned limb (`hdlod_fixtures::models::skinned_limb`),
//! reduced with their collapses weighed in sampled poses of a bending knee
//! against reductions of the bind pose alone to as many triangles, and the
//! error of each over those poses: the largest and the mean of the
//! measured Hausdorff bounds (`hdlod::geometry::skin`).

use std::fmt::Write as _;

use glam::{Mat4, Vec3};
use hdlod::geometry::skin::{PoseError, chain_pose, pose_error, reduce_posed};
use hdlod_fixtures::models::skinned_limb;
use serde::Serialize;

#[derive(clap::Args)]
pub struct Args {
    /// Rings of the limb's cylinder.
    #[arg(long, default_value_t = 40)]
    rings: usize,
    /// Vertices of each ring.
    #[arg(long, default_value_t = 12)]
    sides: usize,
    /// Print JSON instead of the table.
    #[arg(long)]
    json: bool,
}

/// The knee's bends of the sampled poses, in radians.
const BENDS: [f32; 4] = [0.0, 0.5, 1.0, 1.5];

#[derive(Serialize)]
struct Row {
    /// The level keeps this share of the triangles (1/share).
    share: usize,
    triangles: usize,
    bind_pose: Error,
    multi_pose: Error,
    /// How much lower the multi-pose level's errors are, in percent.
    largest_lower_percent: f64,
    mean_lower_percent: f64,
}

#[derive(Serialize)]
struct Error {
    largest: f64,
    mean: f64,
}

impl From<PoseError> for Error {
    fn from(e: PoseError) -> Error {
        Error {
            largest: e.largest,
            mean: e.mean,
        }
    }
}

pub fn run(args: Args) -> anyhow::Result<()> {
    anyhow::ensure!(
        args.rings >= 2 && args.sides >= 3,
        "--rings must be at least 2 and --sides at least 3"
    );
    let (mesh, skin, joints) = skinned_limb(args.rings, args.sides);
    let poses: Vec<Vec<Mat4>> = BENDS
        .iter()
        .map(|&bend| chain_pose(&joints, Vec3::Z, &[0.0, bend]))
        .collect();
    let lower = |a: f64, b: f64| if a > 0.0 { 100.0 * (a - b) / a } else { 0.0 };
    let rows: Vec<Row> = [2, 3, 4, 6, 8, 12]
        .into_iter()
        .map(|share| {
            let target = mesh.triangle_count() / share;
            let bind = reduce_posed(&mesh, &skin, &[], target);
            let posed = reduce_posed(&mesh, &skin, &poses, target);
            let (b, p) = (
                pose_error(&mesh, &bind, &skin, &poses),
                pose_error(&mesh, &posed, &skin, &poses),
            );
            Row {
                share,
                triangles: posed.len() / 3,
                largest_lower_percent: lower(b.largest, p.largest),
                mean_lower_percent: lower(b.mean, p.mean),
                bind_pose: b.into(),
                multi_pose: p.into(),
            }
        })
        .collect();
    if args.json {
        println!("{}", serde_json::to_string_pretty(&rows)?);
        return Ok(());
    }
    let mut out = format!(
        "limb of {} triangles, knee bent {BENDS:?} rad; errors in mm over the poses\n\
         | share | triangles | bind pose largest / mean | multi-pose largest / mean | lower |\n\
         |---|---|---|---|---|\n",
        mesh.triangle_count()
    );
    for r in &rows {
        writeln!(
            out,
            "| 1/{} | {} | {:.1} / {:.1} | {:.1} / {:.1} | {:.0}% / {:.0}% |",
            r.share,
            r.triangles,
            1e3 * r.bind_pose.largest,
            1e3 * r.bind_pose.mean,
            1e3 * r.multi_pose.largest,
            1e3 * r.multi_pose.mean,
            r.largest_lower_percent,
            r.mean_lower_percent
        )?;
    }
    print!("{out}");
    Ok(())
}
