//! The `hdlod` command: one subcommand per job, each in its own module under
//! `cmd/`. The HDLOD logic lives in the `hdlod` library; this crate parses
//! arguments, reports progress and serves HTTP, and `protocol/` holds the
//! cut requests and answers that the API and the CLI share.

mod api;
mod cmd;
mod protocol;

use std::process::ExitCode;

use clap::{Parser, Subcommand};

// mimalloc rather than the system allocator: the build's many small meshes
// and the update's large tables spent a fifth of their time in glibc's
// malloc and free (docs/benchmarks.md, "The allocator"). `no_thp` keeps it
// off transparent huge pages, whose zeroing on first touch cost more
// system time than the allocator saved.
#[global_allocator]
static ALLOCATOR: mimalloc::MiMalloc = mimalloc::MiMalloc;

#[derive(Parser)]
#[command(
    name = "hdlod",
    version,
    about = "Hierarchical dynamic LOD for 4D construction scenes"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
    /// The largest input file (model, scene, schedule, rules) in bytes; a
    /// larger one is an error naming it and the cap.
    #[arg(long, global = true, value_name = "BYTES", default_value_t = hdlod::input::DEFAULT_MAX_BYTES)]
    max_input_bytes: u64,
    /// Let paths named inside input files (a scene's models, a glTF's
    /// buffers) lead outside that file's directory: absolute, through
    /// `..` or a symbolic link.
    #[arg(long, global = true)]
    allow_outside_paths: bool,
}

#[derive(Subcommand)]
enum Command {
    /// Generate a test scene.
    #[command(subcommand)]
    Fixture(cmd::fixture::Fixture),
    /// Describe a scene (or a tree): counts per class, time span, bounds.
    Inspect(cmd::inspect::Args),
    /// The main job: generate the demo scene, build its tree, serve it.
    Demo(cmd::demo::Args),
    /// Build the HDLOD tree of a scene.
    Build(cmd::build::Args),
    /// The cut of a tree for a time and camera.
    Cut(cmd::cut::Args),
    /// Write a tree's serving indexes (clusters.bin, objects.bin) from its JSON files.
    Index(cmd::index::Args),
    /// Bring a tree to the current format in place (hdlod-tree/1 to hdlod-tree/2).
    Migrate(cmd::migrate::Args),
    /// Write the time slice of a tree at one date as 3D Tiles 1.1.
    ExportTiles(cmd::export_tiles::Args),
    /// Serve trees over HTTP and WebSocket.
    Serve(cmd::serve::Args),
    /// Benchmarks: the paper's table, WebSocket load.
    #[command(subcommand)]
    Bench(cmd::bench::Bench),
    /// Simplify one mesh file and measure the result against it.
    Simplify(cmd::simplify::Args),
    /// A discrete LOD chain of one mesh in one GLB (MSFT_lod).
    Lod(cmd::lod::Args),
    /// Import BIM models and their schedule into a scene.
    #[cfg(feature = "ifc")]
    #[command(subcommand)]
    Import(cmd::import::Import),
    /// Not in this build: it was compiled without the `ifc` feature. Kept
    /// so that the command answers why instead of "unrecognized subcommand".
    #[cfg(not(feature = "ifc"))]
    #[command(hide = true)]
    Import {
        #[arg(trailing_var_arg = true, allow_hyphen_values = true)]
        args: Vec<String>,
    },
}

fn main() -> ExitCode {
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env().unwrap_or_else(|_| "info".into()),
        )
        .with_writer(std::io::stderr)
        .init();
    let cli = Cli::parse();
    hdlod::input::set_limits(hdlod::input::Limits {
        max_bytes: cli.max_input_bytes,
        outside: cli.allow_outside_paths,
    });
    let result = match cli.command {
        Command::Fixture(c) => cmd::fixture::run(c),
        Command::Inspect(a) => cmd::inspect::run(a),
        Command::Build(a) => cmd::build::run(a),
        Command::Demo(a) => cmd::demo::run(a),
        Command::Cut(a) => cmd::cut::run(a),
        Command::Index(a) => cmd::index::run(a),
        Command::Migrate(a) => cmd::migrate::run(a),
        Command::ExportTiles(a) => cmd::export_tiles::run(a),
        Command::Serve(a) => cmd::serve::run(a),
        Command::Bench(b) => cmd::bench::run(b),
        Command::Simplify(a) => cmd::simplify::run(a),
        Command::Lod(a) => cmd::lod::run(a),
        #[cfg(feature = "ifc")]
        Command::Import(c) => cmd::import::run(c),
        #[cfg(not(feature = "ifc"))]
        Command::Import { .. } => Err(anyhow::anyhow!(
            "this hdlod was built without IFC import: rebuild it with the `ifc` cargo feature \
             (on by default; left out by --no-default-features)"
        )),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::FAILURE
        }
    }
}
