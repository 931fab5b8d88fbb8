//! `hdlod bench objects TREE`: how long the object and task tables of a
//! tree (`objects.json`) take to load, and a search of them, so that a
//! server's start and reload stay short on large scenes.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::Context;
use hdlod::tree::format::OBJECTS_FILE;
use hdlod::tree::objects::{ObjectTables, ObjectsRecord};
use hdlod::tree::store::load_objects;
use serde::Serialize;

#[derive(clap::Args)]
pub struct Args {
    tree: PathBuf,
    /// Timed loads of the tables (the median is reported).
    #[arg(long, default_value_t = 5)]
    repeats: usize,
    /// Print JSON instead of the text lines.
    #[arg(long)]
    json: bool,
}

#[derive(Serialize)]
struct Report {
    scene: String,
    objects: usize,
    tasks: usize,
    file_bytes: u64,
    /// Loading the tables as a server does (`store::load_objects`:
    /// `objects.bin` mapped and checked when the tree has it, else
    /// `objects.json` read and parsed; checks against the clusters, the
    /// indexes): median, fastest, slowest.
    load_ms: [f64; 3],
    /// Its parts, medians: reading the file, parsing it into records,
    /// making the tables of the records (checks and indexes).
    read_ms: f64,
    parse_ms: f64,
    tables_ms: f64,
    /// The whole tree's load (clusters, tables, the cut's indexes), once.
    tree_load_ms: f64,
    /// A search that scans every object (a query that matches none), and
    /// the first page of all objects: medians.
    search_all_ms: f64,
    first_page_ms: f64,
}

fn millis(since: Instant) -> f64 {
    since.elapsed().as_secs_f64() * 1e3
}

/// Median, fastest and slowest of `n` timings (`n` >= 1) of `run`. What a
/// run makes is dropped after its timing: freeing is not loading.
fn timed<T>(n: usize, mut run: impl FnMut() -> anyhow::Result<T>) -> anyhow::Result<[f64; 3]> {
    let mut times = Vec::with_capacity(n);
    for _ in 0..n.max(1) {
        let start = Instant::now();
        let made = run()?;
        times.push(millis(start));
        drop(made);
    }
    times.sort_by(f64::total_cmp);
    Ok([times[times.len() / 2], times[0], times[times.len() - 1]])
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let start = Instant::now();
    let tree = hdlod::tree::load(&args.tree)?;
    let tree_load_ms = millis(start);
    let file = args.tree.join(OBJECTS_FILE);
    let tables = tree.objects.as_ref().with_context(|| {
        format!(
            "{} has no object and task tables ({} is missing)",
            args.tree.display(),
            file.display()
        )
    })?;
    let file_bytes = std::fs::metadata(&file)
        .with_context(|| file.display().to_string())?
        .len();
    let load_ms = timed(args.repeats, || Ok(load_objects(&args.tree, &tree)?))?;
    let bytes = std::fs::read(&file).with_context(|| file.display().to_string())?;
    let read_ms = timed(args.repeats, || Ok(std::fs::read(&file)?))?[0];
    let parse = || -> anyhow::Result<ObjectsRecord> { Ok(serde_json::from_slice(&bytes)?) };
    let parse_ms = timed(args.repeats, parse)?[0];
    // Each run gets its own parsed records, made outside the timing.
    let mut records = (0..args.repeats.max(1))
        .map(|_| parse())
        .collect::<anyhow::Result<Vec<_>>>()?;
    let tables_ms = timed(args.repeats, || {
        let record = records.pop().expect("one record per run");
        Ok(ObjectTables::from_record(record, &tree, &file)?)
    })?[0];
    let search =
        |query: &'static str| timed(args.repeats, || Ok(tables.search_objects(query, 0, 50)));
    let report = Report {
        scene: tree.scene.clone(),
        objects: tables.object_count(),
        tasks: tables.tasks().len(),
        file_bytes,
        load_ms,
        read_ms,
        parse_ms,
        tables_ms,
        tree_load_ms,
        search_all_ms: search("\u{1}no such object\u{1}")?[0],
        first_page_ms: search("")?[0],
    };
    if args.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
        return Ok(());
    }
    println!(
        "{}: {} objects, {} tasks, {} ({:.1} MB)",
        report.scene,
        report.objects,
        report.tasks,
        file.display(),
        report.file_bytes as f64 / 1e6
    );
    println!(
        "tables load: median {:.1} ms (fastest {:.1}, slowest {:.1}) of {} loads",
        load_ms[0], load_ms[1], load_ms[2], args.repeats
    );
    println!(
        "  of which: read {read_ms:.1} ms, parse {parse_ms:.1} ms, checks and indexes {tables_ms:.1} ms"
    );
    println!("whole tree load, tables included: {tree_load_ms:.0} ms");
    println!(
        "search scanning every object: {:.2} ms; first page of all: {:.3} ms",
        report.search_all_ms, report.first_page_ms
    );
    Ok(())
}
