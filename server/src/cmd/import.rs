//! `hdlod import ifc MODEL.ifc|.ifczip ... [--schedule FILE [--project ID]] [--actual LOG.csv]...
//! [--links RULES.json] [--dates planned|actual] --out SCENE [--name NAME]
//! [--json]`: BIM models and their schedule, with what was built when, into
//! an `hdlod-scene/1` scene (docs/import.md).

use std::path::PathBuf;

use anyhow::Context;
use hdlod::build::Progress;
use hdlod::import::{Options, Report, import};
use hdlod::scene::{Dates, format};

use super::progress::Report as Bars;

#[derive(clap::Subcommand)]
pub enum Import {
    /// IFC 2x3 / IFC4 / IFC4X3 models (.ifc, .ifczip) with an optional
    /// schedule.
    Ifc(Args),
}

#[derive(clap::Args)]
pub struct Args {
    /// The IFC models (.ifc or .ifczip); their elements make one scene.
    #[arg(required = true)]
    models: Vec<PathBuf>,
    /// A schedule: Primavera P6 (.xer, or P6 XML .xml), Microsoft Project
    /// XML (.xml), a task list (.xlsx), element-task links (.csv) or IFC
    /// work schedules (.ifc/.ifczip). The tasks inside the models are
    /// always read.
    #[arg(long)]
    schedule: Option<PathBuf>,
    /// The project to read of a P6 schedule that holds several: its short
    /// name (or proj_id). Without it, such a file is an error that lists
    /// them.
    #[arg(long, value_name = "ID")]
    project: Option<String>,
    /// An as-built log (.csv, element-task rows): its dates are the actual
    /// dates of the schedule's tasks, matched by task id, else by name.
    /// Repeatable.
    #[arg(long, value_name = "LOG.csv")]
    actual: Vec<PathBuf>,
    /// Linking rules (hdlod-links/1, schemas/links.schema.json) that attach
    /// objects to the schedule's tasks.
    #[arg(long)]
    links: Option<PathBuf>,
    /// The dates the scene's presence follows: the plan, or the actual
    /// dates (a task without any has not started).
    #[arg(long, value_enum, default_value = "planned")]
    dates: DatesArg,
    /// The scene directory to write (replaced atomically on success).
    #[arg(long)]
    out: PathBuf,
    /// The scene's name (default: the name of the output directory).
    #[arg(long)]
    name: Option<String>,
    /// Print the report as JSON on stdout (schemas/import-report.schema.json).
    #[arg(long)]
    json: bool,
}

#[derive(Clone, Copy, clap::ValueEnum)]
enum DatesArg {
    Planned,
    Actual,
}

pub fn run(command: Import) -> anyhow::Result<()> {
    let Import::Ifc(args) = command;
    let name = match &args.name {
        Some(n) => n.clone(),
        None => args
            .out
            .file_name()
            .map(|f| f.to_string_lossy().into_owned())
            .context("--out has no directory name to name the scene after; give --name")?,
    };
    let options = Options {
        name,
        schedule: args.schedule.clone(),
        links: args.links.clone(),
        actual: args.actual.clone(),
        project: args.project.clone(),
        dates: match args.dates {
            DatesArg::Planned => Dates::Planned,
            DatesArg::Actual => Dates::Actual,
        },
    };
    let bars = Bars::new(args.json);
    bars.phase("reading IFC", args.models.len() as u64);
    let (scene, report) =
        import(&args.models, &options, &|_| bars.advance(1)).context("cannot import the models")?;
    bars.finish();
    format::save(&scene, &args.out)
        .with_context(|| format!("cannot write the scene {}", args.out.display()))?;
    if args.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        print_report(&report, &args.out.display().to_string());
    }
    for w in &report.warnings {
        eprintln!("warning: {w}");
    }
    Ok(())
}

fn print_report(r: &Report, out: &str) {
    println!(
        "{:<44} {:>8} {:>10} {:>8} {:>7}",
        "file", "elements", "triangles", "skipped", "s"
    );
    for f in &r.files {
        println!(
            "{:<44} {:>8} {:>10} {:>8} {:>7.2}",
            f.file, f.elements, f.triangles, f.skipped, f.seconds
        );
    }
    println!(
        "{:<44} {:>8} {:>10}",
        format!("total ({} files)", r.files.len()),
        r.elements,
        r.triangles
    );
    let failed: usize = r.files.iter().map(|f| f.failed).sum();
    if failed > 0 {
        println!(
            "{failed} elements whose geometry failed or came out empty (named in the warnings)"
        );
    }
    if !r.skipped.is_empty() {
        println!("\nskipped entities:");
        for (class, reasons) in &r.skipped {
            for (reason, n) in reasons {
                println!("  {class:<32} {n:>6}  {reason}");
            }
        }
    }
    if !r.rules.is_empty() {
        println!("\nrules (objects matched -> task):");
        for rule in &r.rules {
            println!(
                "  {:>5}  {:<40} -> {} {:?} ({})",
                rule.matched,
                rule.name,
                rule.task,
                rule.task_name,
                serde_json::to_value(rule.kind)
                    .ok()
                    .and_then(|v| v.as_str().map(str::to_string))
                    .unwrap_or_default()
            );
        }
    }
    if r.tasks > 0 {
        println!(
            "\nschedule: {} tasks, {} acting on objects; {} objects scheduled, {} unmatched (shown throughout)",
            r.tasks,
            r.scene_tasks,
            r.scheduled,
            r.unmatched.len()
        );
        for id in r.unmatched.iter().take(10) {
            println!("  unmatched: {id}");
        }
        if r.unmatched.len() > 10 {
            println!(
                "  ... and {} more (--json lists them all)",
                r.unmatched.len() - 10
            );
        }
        if r.summary_tasks > 0 {
            println!(
                "  {} summary tasks kept (without objects) to group them",
                r.summary_tasks
            );
        }
        if r.links + r.links_outside > 0 {
            println!(
                "  {} links between the scene's tasks; {} to tasks acting on no object left out",
                r.links, r.links_outside
            );
        }
        println!(
            "  {} tasks (summary tasks aside) act on no object",
            r.unmatched_tasks
        );
        for t in &r.unmatched_task_examples {
            println!("  unmatched task: {t}");
        }
    }
    if let Some(a) = &r.actual {
        println!(
            "\nas built: {} rows, {} tasks ({} matched by id, {} by name); {} schedule tasks \
             dated, {} of the scene; {} rows match no task",
            a.rows, a.tasks, a.by_id, a.by_name, a.dated, r.actual_tasks, a.unmatched_rows
        );
        for u in a.unmatched.iter().take(10) {
            println!("  unmatched: {u}");
        }
    } else if r.actual_tasks > 0 {
        println!("\n{} tasks with actual dates", r.actual_tasks);
    }
    println!(
        "\nscene {out}: {} to {}, {:.2} s",
        r.time.start, r.time.end, r.seconds
    );
}
