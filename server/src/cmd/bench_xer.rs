//! `hdlod bench xer [--scale paper] [--out FILE] [--repeats N] [--json]`: a
//! Primavera P6 XER of tens of thousands of activities made from the
//! generated site's schedule, and how long the schedule reader
//! (`hdlod::import::xer::read`) takes over it.
//!
//! Each task of the site becomes a WBS node (under one node per task
//! type) and each element it acts on an activity of its own, the task's
//! span cut into equal parts; the activities of a task follow each other
//! (finish-to-start), each carries its trade as an activity code and its
//! element's id as a user field. So the file has what a real contractor's
//! export has at that size: a deep WBS, a link per activity, codes and
//! user fields.

use std::fmt::Write as _;
use std::path::PathBuf;
use std::time::Instant;

use anyhow::Context;
use hdlod::import::xer;
use hdlod::scene::Scene;
use hdlod_fixtures::{Scale, skyscraper};
use serde::Serialize;

#[derive(clap::Args)]
pub struct Args {
    /// The site's scale: tiny, small or paper.
    #[arg(long, default_value = "paper")]
    scale: String,
    /// Where to write the XER (kept, for `hdlod import`); default: a
    /// temporary file, removed afterwards.
    #[arg(long)]
    out: Option<PathBuf>,
    /// Timed reads (the median is reported).
    #[arg(long, default_value_t = 5)]
    repeats: usize,
    /// Print JSON instead of the text line.
    #[arg(long)]
    json: bool,
}

#[derive(Serialize)]
struct Report {
    scale: String,
    activities: usize,
    wbs_nodes: usize,
    links: usize,
    file_bytes: usize,
    /// Reading the file into tasks (decoding, tables, WBS, links, codes,
    /// user fields, the cycle check): median, fastest, slowest.
    read_ms: [f64; 3],
    /// Tasks read: the activities and the WBS nodes below the project's.
    tasks: usize,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let scale = Scale::parse(&args.scale)?;
    let scene = skyscraper(scale, 1);
    let (text, counts) = xer_of(&scene);
    // Dropped (and removed) at the end; made only when no --out is given.
    let temp = match &args.out {
        Some(_) => None,
        None => Some(
            tempfile::Builder::new()
                .prefix("hdlod-bench-xer-")
                .tempdir()?,
        ),
    };
    let path = match (&args.out, &temp) {
        (Some(p), _) => p.clone(),
        (None, Some(dir)) => dir.path().join("site.xer"),
        (None, None) => unreachable!("a temporary directory without --out"),
    };
    std::fs::write(&path, &text).with_context(|| path.display().to_string())?;
    let mut times = Vec::new();
    let mut tasks = 0;
    for _ in 0..args.repeats.max(1) {
        let start = Instant::now();
        let read = xer::read(&path, None).with_context(|| path.display().to_string())?;
        times.push(start.elapsed().as_secs_f64() * 1e3);
        tasks = read.len();
    }
    times.sort_by(f64::total_cmp);
    let report = Report {
        scale: scale.name().into(),
        activities: counts.0,
        wbs_nodes: counts.1,
        links: counts.2,
        file_bytes: text.len(),
        read_ms: [times[times.len() / 2], times[0], times[times.len() - 1]],
        tasks,
    };
    if args.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        println!(
            "xer ({} site): {} activities, {} WBS nodes, {} links, {:.1} MB; read in {:.0} ms \
             (median of {}; {:.0} to {:.0} ms), {} tasks",
            report.scale,
            report.activities,
            report.wbs_nodes,
            report.links,
            report.file_bytes as f64 / 1e6,
            report.read_ms[0],
            times.len(),
            report.read_ms[1],
            report.read_ms[2],
            report.tasks
        );
    }
    Ok(())
}

/// The site's schedule as XER text, with its activity, WBS node and link
/// counts.
fn xer_of(scene: &Scene) -> (String, (usize, usize, usize)) {
    let date = |t: f64| scene.time.date_at(t).format("%Y-%m-%d %H:%M").to_string();
    let mut out = String::from(
        "ERMHDR\t19.12\t2026-01-01\tProject\tbench\tbench\tdbxDatabaseNoName\tProject Management\tEUR\n",
    );
    out += "%T\tPROJECT\n%F\tproj_id\tproj_short_name\tplan_start_date\n";
    let _ = writeln!(out, "%R\t1\tSITE\t{}", date(0.0));

    // WBS: the project's node, a node per task type, a node per task.
    out += "%T\tPROJWBS\n%F\twbs_id\tproj_id\tseq_num\tproj_node_flag\twbs_short_name\twbs_name\tparent_wbs_id\n";
    out += "%R\t1\t1\t0\tY\tSITE\tThe site\t\n";
    let kinds: Vec<&str> = scene.tasks.iter().map(|t| t.kind.name()).collect();
    let mut kind_ids: Vec<&str> = kinds.clone();
    kind_ids.sort_unstable();
    kind_ids.dedup();
    for (k, kind) in kind_ids.iter().enumerate() {
        let _ = writeln!(
            out,
            "%R\t{}\t1\t{k}\tN\t{}\t{kind}\t1",
            2 + k,
            kind.to_uppercase()
        );
    }
    let task_node = |i: usize| 100 + i;
    for (i, t) in scene.tasks.iter().enumerate() {
        let parent = 2 + kind_ids.iter().position(|k| *k == kinds[i]).unwrap_or(0);
        let _ = writeln!(
            out,
            "%R\t{}\t1\t{i}\tN\tT{i}\t{}\t{parent}",
            task_node(i),
            t.name.replace(['\t', '\n'], " ")
        );
    }

    out += "%T\tACTVTYPE\n%F\tactv_code_type_id\tactv_code_type\tproj_id\n%R\t1\tTrade\t1\n";
    out += "%T\tACTVCODE\n%F\tactv_code_id\tactv_code_type_id\tshort_name\tactv_code_name\n";
    for (k, kind) in kind_ids.iter().enumerate() {
        let _ = writeln!(out, "%R\t{}\t1\t{}\t{kind}", k + 1, kind.to_uppercase());
    }
    out += "%T\tUDFTYPE\n%F\tudf_type_id\ttable_name\tudf_type_label\tlogical_data_type\n%R\t1\tTASK\tElement\tFT_TEXT\n";

    // Activities: one per (task, element), the task's span cut evenly.
    let mut task = String::from(
        "%T\tTASK\n%F\ttask_id\tproj_id\twbs_id\ttask_type\ttask_code\ttask_name\ttarget_start_date\ttarget_end_date\tearly_start_date\tearly_end_date\tlate_start_date\tlate_end_date\tact_start_date\tact_end_date\n",
    );
    let mut pred = String::from(
        "%T\tTASKPRED\n%F\ttask_pred_id\ttask_id\tpred_task_id\tproj_id\tpred_proj_id\tpred_type\tlag_hr_cnt\n",
    );
    let mut actv =
        String::from("%T\tTASKACTV\n%F\ttask_id\tactv_code_type_id\tactv_code_id\tproj_id\n");
    let mut udf = String::from("%T\tUDFVALUE\n%F\tudf_type_id\tfk_id\tproj_id\tudf_text\n");
    let (mut n, mut links) = (0usize, 0usize);
    for (i, t) in scene.tasks.iter().enumerate() {
        let parts = t.objects.len().max(1);
        let step = (t.finish - t.start) / parts as f64;
        let code = 1 + kind_ids.iter().position(|k| *k == kinds[i]).unwrap_or(0);
        for j in 0..parts {
            n += 1;
            let (s, f) = (t.start + step * j as f64, t.start + step * (j + 1) as f64);
            let element = t.objects.get(j).map_or("", String::as_str);
            let (ds, df) = (date(s), date(f));
            let _ = writeln!(
                task,
                "%R\t{n}\t1\t{}\tTT_Task\tA{n:06}\t{} {}\t{ds}\t{df}\t{ds}\t{df}\t{ds}\t{df}\t\t",
                task_node(i),
                t.name.replace(['\t', '\n'], " "),
                j + 1
            );
            if j > 0 {
                links += 1;
                let _ = writeln!(pred, "%R\t{links}\t{n}\t{}\t1\t1\tPR_FS\t0", n - 1);
            }
            let _ = writeln!(actv, "%R\t{n}\t1\t{code}\t1");
            let _ = writeln!(udf, "%R\t1\t{n}\t1\t{element}");
        }
    }
    out += &task;
    out += &pred;
    out += &actv;
    out += &udf;
    out += "%E\n";
    (out, (n, 1 + kind_ids.len() + scene.tasks.len(), links))
}
